/* Loads libcavetrace.so at run time (path in argv[1]) twice in one process: each time resolves
 * every API function with dlsym, renders a frame, releases everything and unloads the library,
 * then checks that no thread was left behind. */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

/* Every exported function, typed from the header's own prototypes. */
#define FUNCTIONS(X)                                                                       \
  X(anariLoadLibrary) X(anariUnloadLibrary) X(anariLoadModule) X(anariUnloadModule)            \
  X(anariNewDevice) X(anariNewInitializedDevice) X(anariNewArray1D) X(anariNewArray2D)         \
  X(anariNewArray3D) X(anariMapArray) X(anariUnmapArray) X(anariNewLight) X(anariNewCamera)    \
  X(anariNewGeometry) X(anariNewSpatialField) X(anariNewVolume) X(anariNewSurface)             \
  X(anariNewMaterial) X(anariNewSampler) X(anariNewGroup) X(anariNewInstance)                  \
  X(anariNewWorld) X(anariNewObject) X(anariSetParameter) X(anariUnsetParameter)               \
  X(anariUnsetAllParameters) X(anariMapParameterArray1D) X(anariMapParameterArray2D)           \
  X(anariMapParameterArray3D) X(anariUnmapParameterArray) X(anariCommitParameters)             \
  X(anariRelease) X(anariRetain) X(anariGetDeviceSubtypes) X(anariGetDeviceExtensions)         \
  X(anariGetObjectSubtypes) X(anariGetObjectInfo) X(anariGetParameterInfo) X(anariGetProperty) \
  X(anariNewFrame) X(anariMapFrame) X(anariUnmapFrame) X(anariNewRenderer)                     \
  X(anariRenderFrame) X(anariFrameReady) X(anariDiscardFrame) X(anariDeviceGetProcAddress)     \
  X(cavetraceLiveDeviceCount) X(cavetraceWriteFramePNG) X(cavetraceWriteImagePNG)            \
  X(cavetraceOffAxisMatrices) X(cavetraceOffAxisPerspective) X(cavetracePerspectiveFromMatrices)

#define MEMBER(name) __typeof__(&name) name;
typedef struct {
  FUNCTIONS(MEMBER)
} Api;

static const char *library_path;

/* Resolves every function; returns how many are missing. */
static int resolve(void *handle, Api *api) {
  int missing = 0;
#define RESOLVE(name)                                                                           \
  {                                                                                             \
    void *symbol = dlsym(handle, #name);                                                        \
    if (!symbol) {                                                                              \
      printf("  dlsym(%s): %s\n", #name, dlerror());                                            \
      missing++;                                                                                \
    }                                                                                           \
    memcpy(&api->name, &symbol, sizeof symbol);                                                 \
  }
  FUNCTIONS(RESOLVE)
#undef RESOLVE
  return missing;
}

static int status_errors;

static void count_errors(const void *user, ANARIDevice device, ANARIObject source,
                         ANARIDataType type, ANARIStatusSeverity severity, ANARIStatusCode code,
                         const char *message) {
  (void)user, (void)device, (void)source, (void)type, (void)code;
  if (severity <= ANARI_SEVERITY_ERROR) {
    status_errors++;
    printf("  status: %s\n", message);
  }
}

/* Renders a blue triangle through the resolved pointers; returns the centre pixel's blue. */
static float render_triangle(const Api *a) {
  ANARILibrary library = a->anariLoadLibrary("cavetrace", count_errors, NULL);
  ANARIDevice d = a->anariNewDevice(library, "default");
  CHECK(a->cavetraceLiveDeviceCount() == 1);
  const float vertices[9] = {-1, -1, -3, 1, -1, -3, 0, 1, -3};
  ANARIArray1D positions = a->anariNewArray1D(d, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  void *memory = a->anariMapArray(d, positions);
  if (memory)
    memcpy(memory, vertices, sizeof vertices);
  a->anariUnmapArray(d, positions);
  ANARIGeometry geometry = a->anariNewGeometry(d, "triangle");
  a->anariSetParameter(d, geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  a->anariCommitParameters(d, geometry);
  ANARIMaterial material = a->anariNewMaterial(d, "matte");
  const float blue[3] = {0, 0, 1};
  a->anariSetParameter(d, material, "color", ANARI_FLOAT32_VEC3, blue);
  a->anariCommitParameters(d, material);
  ANARISurface surface = a->anariNewSurface(d);
  a->anariSetParameter(d, surface, "geometry", ANARI_GEOMETRY, &geometry);
  a->anariSetParameter(d, surface, "material", ANARI_MATERIAL, &material);
  a->anariCommitParameters(d, surface);
  ANARIArray1D surfaces = a->anariNewArray1D(d, NULL, NULL, NULL, ANARI_SURFACE, 1);
  ANARISurface *slot = a->anariMapArray(d, surfaces);
  if (slot)
    slot[0] = surface;
  a->anariUnmapArray(d, surfaces);
  ANARIWorld world = a->anariNewWorld(d);
  a->anariSetParameter(d, world, "surface", ANARI_ARRAY1D, &surfaces);
  a->anariCommitParameters(d, world);
  ANARICamera camera = a->anariNewCamera(d, "perspective");
  const float origin[3] = {0, 0, 0};
  a->anariSetParameter(d, camera, "position", ANARI_FLOAT32_VEC3, origin);
  a->anariCommitParameters(d, camera);
  ANARIRenderer renderer = a->anariNewRenderer(d, "default");
  const float one = 1.0f; /* ambient radiance 1: matte surfaces show their albedo */
  a->anariSetParameter(d, renderer, "ambientRadiance", ANARI_FLOAT32, &one);
  a->anariCommitParameters(d, renderer);
  ANARIFrame frame = a->anariNewFrame(d);
  const uint32_t size[2] = {32, 32};
  const ANARIDataType color_type = ANARI_FLOAT32_VEC4;
  a->anariSetParameter(d, frame, "size", ANARI_UINT32_VEC2, size);
  a->anariSetParameter(d, frame, "channel.color", ANARI_DATA_TYPE, &color_type);
  a->anariSetParameter(d, frame, "world", ANARI_WORLD, &world);
  a->anariSetParameter(d, frame, "camera", ANARI_CAMERA, &camera);
  a->anariSetParameter(d, frame, "renderer", ANARI_RENDERER, &renderer);
  a->anariCommitParameters(d, frame);
  a->anariRenderFrame(d, frame);
  CHECK(a->anariFrameReady(d, frame, ANARI_WAIT) == 1);
  float centre_blue = NAN;
  const float *pixels = a->anariMapFrame(d, frame, "channel.color", NULL, NULL, NULL);
  if (pixels)
    centre_blue = pixels[4 * (16 * 32 + 16) + 2];
  a->anariUnmapFrame(d, frame, "channel.color");
  ANARIObject objects[] = {positions, geometry, material, surface, surfaces,
                           world,     camera,   renderer, frame};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    a->anariRelease(d, objects[i]);
  a->anariRelease(d, d);
  CHECK(a->cavetraceLiveDeviceCount() == 0);
  a->anariUnloadLibrary(library);
  return centre_blue;
}

static int round_number;

static void load_render_unload(void) {
  int threads_before = thread_count();
  CHECK(threads_before >= 1);
  void *handle = dlopen(library_path, RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    printf("  dlopen(%s): %s\n", library_path, dlerror());
    CHECK(handle != NULL);
    return;
  }
  Api api;
  CHECK(resolve(handle, &api) == 0);
  if (current_test_failures() == 0) {
    status_errors = 0;
    CHECK_NEAR(render_triangle(&api), 1.0, 0.01);
    CHECK(status_errors == 0);
  }
  CHECK(dlclose(handle) == 0);
  CHECK(thread_count_settled(threads_before) == threads_before);
  /* Informational: glibc keeps a library mapped while thread-local destructors it registered
   * are pending; either way it must not crash and must leave no threads. */
  void *still = dlopen(library_path, RTLD_NOW | RTLD_NOLOAD);
  printf("  round %d: after dlclose the library is %s\n", round_number,
         still ? "still mapped" : "unmapped");
  if (still)
    dlclose(still);
}

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s path/to/libcavetrace.so\n", argv[0]);
    return 2;
  }
  library_path = argv[1];
  round_number = 1;
  run_test("dlopen_render_dlclose_first_time", load_render_unload);
  round_number = 2;
  run_test("dlopen_render_dlclose_second_time", load_render_unload);
  return test_summary();
}
