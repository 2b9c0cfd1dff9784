/*
 * soak: renders SOAK_FRAMES frames (default 10000) from 4 threads on one device; every frame
 * creates, changes and releases its scene (vertex array, geometry, material, surface, world,
 * camera, renderer, frame). Prints resident memory (VmRSS) after a warm-up and at the end,
 * frames per second and the status messages reported. Exits non-zero when resident memory grew
 * by more than 32 MiB after the warm-up, when a message of severity WARNING or worse arrived,
 * or when a device is still live at the end.
 *
 *   SOAK_FRAMES=400 soak
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cavetrace.h"

#define THREADS 4
#define WARMUP_FRAMES 200

static _Atomic long messages, serious_messages, frames_done;
static ANARIDevice device;
static long frames_per_thread;

static void on_status(const void *user, ANARIDevice d, ANARIObject source, ANARIDataType type,
                      ANARIStatusSeverity severity, ANARIStatusCode code, const char *message) {
  (void)user, (void)d, (void)source, (void)type, (void)code;
  atomic_fetch_add(&messages, 1);
  if (severity <= ANARI_SEVERITY_WARNING) {
    if (atomic_fetch_add(&serious_messages, 1) < 5)
      fprintf(stderr, "soak: %s\n", message);
  }
}

static long resident_kib(void) {
  FILE *f = fopen("/proc/self/status", "r");
  char line[256];
  long kib = -1;
  while (f && fgets(line, sizeof line, f))
    if (!strncmp(line, "VmRSS:", 6))
      kib = atol(line + 6);
  if (f)
    fclose(f);
  return kib;
}

static void render_one(unsigned seed) {
  ANARIDevice d = device;
  float shift = (float)(seed % 100) * 0.01f;
  float xyz[9] = {-1 + shift, -1, 3, 1, -1, 3, 0, 1, 3};
  ANARIArray1D vertices = anariNewArray1D(d, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  memcpy(anariMapArray(d, vertices), xyz, sizeof xyz);
  anariUnmapArray(d, vertices);
  ANARIGeometry geometry = anariNewGeometry(d, "triangle");
  anariSetParameter(d, geometry, "vertex.position", ANARI_ARRAY1D, &vertices);
  anariCommitParameters(d, geometry);
  ANARIMaterial material = anariNewMaterial(d, "matte");
  float color[3] = {shift, 0.5f, 1.0f - shift};
  anariSetParameter(d, material, "color", ANARI_FLOAT32_VEC3, color);
  anariCommitParameters(d, material);
  ANARISurface surface = anariNewSurface(d);
  anariSetParameter(d, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(d, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(d, surface);
  ANARIArray1D surfaces = anariNewArray1D(d, &surface, NULL, NULL, ANARI_SURFACE, 1);
  ANARIWorld world = anariNewWorld(d);
  anariSetParameter(d, world, "surface", ANARI_ARRAY1D, &surfaces);
  anariCommitParameters(d, world);
  ANARICamera camera = anariNewCamera(d, "perspective");
  float aspect = 1.0f;
  anariSetParameter(d, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariCommitParameters(d, camera);
  ANARIRenderer renderer = anariNewRenderer(d, "default");
  anariCommitParameters(d, renderer);
  ANARIFrame frame = anariNewFrame(d);
  uint32_t size[2] = {32, 32};
  ANARIDataType channel = ANARI_UFIXED8_RGBA_SRGB;
  anariSetParameter(d, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(d, frame, "channel.color", ANARI_DATA_TYPE, &channel);
  anariSetParameter(d, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(d, frame, "camera", ANARI_CAMERA, &camera);
  anariSetParameter(d, frame, "renderer", ANARI_RENDERER, &renderer);
  anariCommitParameters(d, frame);
  /* Released before the render: the frame keeps what it uses alive. */
  anariRelease(d, vertices);
  anariRelease(d, geometry);
  anariRelease(d, material);
  anariRelease(d, surface);
  anariRelease(d, surfaces);
  anariRenderFrame(d, frame);
  anariFrameReady(d, frame, ANARI_WAIT);
  uint32_t width, height;
  ANARIDataType type;
  const void *pixels = anariMapFrame(d, frame, "channel.color", &width, &height, &type);
  (void)pixels;
  anariUnmapFrame(d, frame, "channel.color");
  anariRelease(d, world);
  anariRelease(d, camera);
  anariRelease(d, renderer);
  anariRelease(d, frame);
  atomic_fetch_add(&frames_done, 1);
}

static void *work(void *argument) {
  unsigned seed = (unsigned)(size_t)argument;
  for (long i = 0; i < frames_per_thread; i++)
    render_one(seed + (unsigned)i * 7u);
  return NULL;
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

int main(void) {
  const char *env = getenv("SOAK_FRAMES");
  long frames = env ? atol(env) : 10000;
  if (frames < THREADS)
    frames = THREADS;
  ANARILibrary library = anariLoadLibrary("cavetrace", on_status, NULL);
  device = anariNewDevice(library, "default");
  long rss_before = resident_kib();
  /* Warm-up: thread pools, allocator arenas and caches reach their working size. */
  frames_per_thread = WARMUP_FRAMES / THREADS;
  pthread_t ids[THREADS];
  for (size_t t = 0; t < THREADS; t++)
    pthread_create(&ids[t], NULL, work, (void *)t);
  for (size_t t = 0; t < THREADS; t++)
    pthread_join(ids[t], NULL);
  long rss_start = resident_kib();
  atomic_store(&frames_done, 0);
  frames_per_thread = frames / THREADS;
  double start = now();
  for (size_t t = 0; t < THREADS; t++)
    pthread_create(&ids[t], NULL, work, (void *)(t + 100));
  for (size_t t = 0; t < THREADS; t++)
    pthread_join(ids[t], NULL);
  double seconds = now() - start;
  long rss_end = resident_kib();
  anariRelease(device, device);
  anariUnloadLibrary(library);
  long growth = rss_end - rss_start;
  const long bound_kib = 32 * 1024;
  printf("soak: %ld frames (32x32, a new scene each) from %d threads in %.1f s: %.0f frames/s\n",
         atomic_load(&frames_done), THREADS, seconds, (double)atomic_load(&frames_done) / seconds);
  printf("soak: resident memory %ld KiB before, %ld KiB after %d warm-up frames, %ld KiB at the "
         "end (growth %ld KiB, bound %ld KiB: %s)\n",
         rss_before, rss_start, WARMUP_FRAMES, rss_end, growth, bound_kib,
         growth <= bound_kib ? "holds" : "EXCEEDED");
  printf("soak: %ld status messages (%ld of severity WARNING or worse), %llu devices live\n",
         atomic_load(&messages), atomic_load(&serious_messages),
         (unsigned long long)cavetraceLiveDeviceCount());
  return growth <= bound_kib && atomic_load(&serious_messages) == 0 &&
                 cavetraceLiveDeviceCount() == 0
             ? 0
             : 1;
}
