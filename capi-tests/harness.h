/*
 * A small C99 test harness for cavetrace's C API (libc and libm only).
 *
 * Each program calls run_test() once per test; every test prints one line ("ok   name" or
 * "FAIL name", failed checks above it) and test_summary() closes with "N passed, M failed" and
 * returns the exit status.
 */
#ifndef CAVETRACE_HARNESS_H
#define CAVETRACE_HARNESS_H

#include <stddef.h>
#include <stdint.h>

#include "cavetrace.h"

/* ----- checks ---------------------------------------------------------------------------- */

void check_at(int ok, const char *file, int line, const char *text);
void check_near_at(double actual, double expected, double tolerance, const char *file, int line,
                   const char *text);

#define CHECK(condition) check_at((condition) != 0, __FILE__, __LINE__, #condition)
#define CHECK_NEAR(actual, expected, tolerance)                                               \
  check_near_at((actual), (expected), (tolerance), __FILE__, __LINE__, #actual)

void run_test(const char *name, void (*test)(void));
/* Prints "N passed, M failed"; returns 0 when nothing failed. */
int test_summary(void);
/* Failed checks so far in the current test. */
int current_test_failures(void);

/* ----- status messages ------------------------------------------------------------------- */

#define LOG_CAPACITY 64
#define LOG_TEXT 512

typedef struct {
  int severity;
  int code;
  ANARIDataType source_type;
  void *source;
  char text[LOG_TEXT];
} StatusEntry;

/* Messages received by the status callback (thread-safe; the oldest LOG_CAPACITY are kept). */
typedef struct {
  StatusEntry entries[LOG_CAPACITY];
  int count;
} StatusLog;

extern StatusLog status_log;

void record_status(const void *user_data, ANARIDevice device, ANARIObject source,
                   ANARIDataType source_type, ANARIStatusSeverity severity,
                   ANARIStatusCode code, const char *message);
void log_clear(void);
/* Messages of severity ERROR or worse since the last clear. */
int log_error_count(void);
/* Messages of exactly this severity since the last clear. */
int log_count_severity(int severity);
/* The first message with this code and severity ≤ max_severity that contains every one of the
 * NULL-terminated substrings, or NULL. */
const StatusEntry *log_find(int code, int max_severity, ...);
/* Prints every message (for failing tests). */
void log_print(void);

/* ----- devices and scenes ---------------------------------------------------------------- */

/* A library and device whose messages go to status_log. */
ANARIDevice open_device(ANARILibrary *library);
void close_device(ANARILibrary library, ANARIDevice device);

/* A managed 1D array filled with count elements of element_size bytes. */
ANARIArray1D managed_array(ANARIDevice device, ANARIDataType type, const void *data,
                           uint64_t count, size_t element_size);
ANARIArray1D object_array(ANARIDevice device, ANARIDataType type, const ANARIObject *objects,
                          uint64_t count);

/* Triangles from consecutive vertex triples. */
ANARIGeometry triangle_geometry(ANARIDevice device, const float *xyz, uint64_t vertex_count);
/* A geometry of axis-aligned squares at depth z: centers (x, y), side `side`. */
ANARIGeometry square_at(ANARIDevice device, float x, float y, float z, float side);
/* A surface of `geometry` with a matte material of rgb and the given id. */
ANARISurface matte_surface(ANARIDevice device, ANARIGeometry geometry, float r, float g, float b,
                           uint32_t id);
ANARIWorld world_of_surfaces(ANARIDevice device, const ANARISurface *surfaces, uint64_t count);
/* A perspective camera at eye looking along dir, up +y, with vertical field of view fovy. */
ANARICamera perspective_camera(ANARIDevice device, const float eye[3], const float dir[3],
                               float fovy);
/* A "default" renderer with black background and ambient light that makes a matte surface's
 * rendered colour equal its albedo (radiance π, no other light). */
ANARIRenderer albedo_renderer(ANARIDevice device);
/* A frame with color (FLOAT32_VEC4), depth, primitiveId, objectId and instanceId. */
ANARIFrame new_frame(ANARIDevice device, uint32_t width, uint32_t height, ANARIWorld world,
                     ANARICamera camera, ANARIRenderer renderer);

/* Renders and waits. */
void render_and_wait(ANARIDevice device, ANARIFrame frame);
/* Copies a channel out (malloc'ed; width·height elements of element_size); NULL when it cannot
 * be mapped or is not of expected_type. */
void *copy_channel(ANARIDevice device, ANARIFrame frame, const char *channel,
                   ANARIDataType expected_type, size_t element_size, uint32_t *width,
                   uint32_t *height);

/* Pixel readers for frames copied with copy_channel (x from the left, y from the bottom). */
float pixel_depth(const float *depth, uint32_t width, uint32_t x, uint32_t y);
uint32_t pixel_id(const uint32_t *ids, uint32_t width, uint32_t x, uint32_t y);
const float *pixel_color(const float *rgba, uint32_t width, uint32_t x, uint32_t y);

/* The number of threads of this process (entries of /proc/self/task), or -1. */
int thread_count(void);
/* thread_count() once it equals `expected`, waiting up to a second for joined threads to leave
 * /proc (the kernel wakes the joiner slightly before it removes the thread's entry). */
int thread_count_settled(int expected);

#endif /* CAVETRACE_HARNESS_H */
