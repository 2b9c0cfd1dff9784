/* The test harness behind harness.h. */
#include "harness.h"

#include <dirent.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ----- checks ---------------------------------------------------------------------------- */

static int tests_passed, tests_failed, failures_in_test;

void check_at(int ok, const char *file, int line, const char *text) {
  if (!ok) {
    failures_in_test++;
    printf("  %s:%d: check failed: %s\n", file, line, text);
  }
}

void check_near_at(double actual, double expected, double tolerance, const char *file, int line,
                   const char *text) {
  if (!(fabs(actual - expected) <= tolerance)) {
    failures_in_test++;
    printf("  %s:%d: %s = %.9g, expected %.9g ± %.3g\n", file, line, text, actual, expected,
           tolerance);
  }
}

int current_test_failures(void) { return failures_in_test; }

void run_test(const char *name, void (*test)(void)) {
  failures_in_test = 0;
  log_clear();
  test();
  if (failures_in_test == 0) {
    tests_passed++;
    printf("ok   %s\n", name);
  } else {
    tests_failed++;
    log_print();
    printf("FAIL %s\n", name);
  }
  fflush(stdout);
}

int test_summary(void) {
  printf("%d passed, %d failed\n", tests_passed, tests_failed);
  fflush(stdout);
  return tests_failed == 0 ? 0 : 1;
}

/* ----- status messages ------------------------------------------------------------------- */

StatusLog status_log;
static pthread_mutex_t log_mutex = PTHREAD_MUTEX_INITIALIZER;

void record_status(const void *user_data, ANARIDevice device, ANARIObject source,
                   ANARIDataType source_type, ANARIStatusSeverity severity,
                   ANARIStatusCode code, const char *message) {
  StatusLog *log = (StatusLog *)user_data;
  (void)device;
  pthread_mutex_lock(&log_mutex);
  if (log->count < LOG_CAPACITY) {
    StatusEntry *entry = &log->entries[log->count];
    entry->severity = severity;
    entry->code = code;
    entry->source = source;
    entry->source_type = source_type;
    snprintf(entry->text, LOG_TEXT, "%s", message ? message : "(NULL message)");
  }
  log->count++;
  pthread_mutex_unlock(&log_mutex);
}

void log_clear(void) {
  pthread_mutex_lock(&log_mutex);
  status_log.count = 0;
  pthread_mutex_unlock(&log_mutex);
}

static int stored(void) { return status_log.count < LOG_CAPACITY ? status_log.count : LOG_CAPACITY; }

int log_error_count(void) {
  int n = 0;
  pthread_mutex_lock(&log_mutex);
  for (int i = 0; i < stored(); i++)
    n += status_log.entries[i].severity <= ANARI_SEVERITY_ERROR;
  pthread_mutex_unlock(&log_mutex);
  return n;
}

int log_count_severity(int severity) {
  int n = 0;
  pthread_mutex_lock(&log_mutex);
  for (int i = 0; i < stored(); i++)
    n += status_log.entries[i].severity == severity;
  pthread_mutex_unlock(&log_mutex);
  return n;
}

const StatusEntry *log_find(int code, int max_severity, ...) {
  const StatusEntry *found = NULL;
  pthread_mutex_lock(&log_mutex);
  for (int i = 0; i < stored() && !found; i++) {
    const StatusEntry *entry = &status_log.entries[i];
    if (entry->code != code || entry->severity > max_severity)
      continue;
    int all = 1;
    va_list words;
    va_start(words, max_severity);
    for (const char *word = va_arg(words, const char *); word; word = va_arg(words, const char *))
      all = all && strstr(entry->text, word) != NULL;
    va_end(words);
    if (all)
      found = entry;
  }
  pthread_mutex_unlock(&log_mutex);
  return found;
}

void log_print(void) {
  pthread_mutex_lock(&log_mutex);
  for (int i = 0; i < stored(); i++)
    printf("  status: severity %d code %d: %s\n", status_log.entries[i].severity,
           status_log.entries[i].code, status_log.entries[i].text);
  pthread_mutex_unlock(&log_mutex);
}

int thread_count(void) {
  DIR *tasks = opendir("/proc/self/task");
  if (!tasks)
    return -1;
  int n = 0;
  for (struct dirent *entry = readdir(tasks); entry; entry = readdir(tasks))
    n += entry->d_name[0] != '.';
  closedir(tasks);
  return n;
}

int thread_count_settled(int expected) {
  int n = thread_count();
  for (int i = 0; i < 1000 && n != expected; i++) {
    struct timespec millisecond = {0, 1000000};
    nanosleep(&millisecond, NULL);
    n = thread_count();
  }
  return n;
}
