/* Object lifetimes, parameter staging and every error path, through the C API. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

static const float EYE[3] = {0, 0, 0};
static const float FORWARD[3] = {0, 0, -1};
static const float FOVY = 1.0471975512f; /* 60° */

/* The depth and colour at the centre pixel of a 16×16 frame. */
static float centre_depth(ANARIDevice device, ANARIFrame frame) {
  render_and_wait(device, frame);
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  float d = depth ? pixel_depth(depth, 16, 8, 8) : NAN;
  free(depth);
  return d;
}

static void centre_color(ANARIDevice device, ANARIFrame frame, float rgba[4]) {
  render_and_wait(device, frame);
  float *color = copy_channel(device, frame, "channel.color", ANARI_FLOAT32_VEC4, 16, NULL, NULL);
  for (int i = 0; i < 4; i++)
    rgba[i] = color ? pixel_color(color, 16, 8, 8)[i] : NAN;
  free(color);
}

/* ----- lifetimes ------------------------------------------------------------------------- */

typedef struct {
  int calls;
  const void *memory;
} DeleterRecord;

static void count_delete(const void *user, const void *memory) {
  DeleterRecord *record = (DeleterRecord *)user;
  record->calls++;
  record->memory = memory;
  free((void *)memory);
}

static void captured_array_deleted_once_after_last_user(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  static const float square[18] = {-1, -1, -2, 1, -1, -2, 1, 1, -2, -1, -1, -2, 1, 1, -2, -1, 1, -2};
  float *memory = malloc(sizeof square);
  memcpy(memory, square, sizeof square);
  DeleterRecord record = {0, NULL};
  ANARIArray1D positions =
      anariNewArray1D(device, memory, count_delete, &record, ANARI_FLOAT32_VEC3, 6);
  CHECK(positions != NULL);
  ANARIGeometry geometry = anariNewGeometry(device, "triangle");
  anariSetParameter(device, geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, geometry);
  anariRelease(device, positions);
  CHECK(record.calls == 0); /* the geometry still uses it */
  ANARISurface surface = matte_surface(device, geometry, 1, 0, 0, 1);
  anariRelease(device, geometry);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  anariRelease(device, surface);
  ANARICamera camera = perspective_camera(device, EYE, FORWARD, FOVY);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 16, 16, world, camera, renderer);
  anariRelease(device, world);
  CHECK(record.calls == 0);
  CHECK_NEAR(centre_depth(device, frame), 2.0, 0.01); /* the captured data is what renders */
  CHECK(record.calls == 0);
  anariRelease(device, frame); /* the last user of the world, hence of the array */
  CHECK(record.calls == 1);
  CHECK(record.memory == memory);
  anariRelease(device, camera);
  anariRelease(device, renderer);
  close_device(library, device);
  CHECK(record.calls == 1); /* exactly once */
  CHECK(log_error_count() == 0);
}

static void captured_array_deleted_at_device_release_when_never_released(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  DeleterRecord record = {0, NULL};
  float *memory = calloc(12, sizeof(float));
  ANARIArray1D array = anariNewArray1D(device, memory, count_delete, &record, ANARI_FLOAT32, 12);
  CHECK(array != NULL);
  CHECK(record.calls == 0);
  close_device(library, device);
  CHECK(record.calls == 1);
  CHECK(record.memory == memory);
}

static void failed_array_creation_never_calls_the_deleter(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  DeleterRecord record = {0, NULL};
  float value = 0;
  ANARIArray1D array = anariNewArray1D(device, &value, count_delete, &record, 4242, 1);
  CHECK(array == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewArray1D", NULL));
  close_device(library, device);
  CHECK(record.calls == 0); /* the device never took the memory */
}

static void retain_adds_a_reference_the_application_must_release(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariRetain(device, material);
  anariRelease(device, material);
  anariCommitParameters(device, material); /* still alive: one reference left */
  CHECK(log_error_count() == 0);
  anariRelease(device, material);
  anariCommitParameters(device, material);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariCommitParameters",
                 "not a live object", NULL));
  close_device(library, device);
}

static void devices_are_counted_and_retained(void) {
  uint64_t before = cavetraceLiveDeviceCount();
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  CHECK(cavetraceLiveDeviceCount() == before + 1);
  ANARIDevice second = anariNewDevice(library, "cavetrace");
  CHECK(second != NULL && second != device);
  CHECK(cavetraceLiveDeviceCount() == before + 2);
  anariRelease(second, second);
  CHECK(cavetraceLiveDeviceCount() == before + 1);
  anariRetain(device, device);
  anariRelease(device, device);
  CHECK(cavetraceLiveDeviceCount() == before + 1); /* retained once: still alive */
  anariRelease(device, device);
  CHECK(cavetraceLiveDeviceCount() == before);
  anariUnloadLibrary(library);
  CHECK(log_error_count() == 0);
}

static void objects_in_use_outlive_their_handles(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry geometry = square_at(device, 0, 0, -4, 2);
  ANARISurface surface = matte_surface(device, geometry, 0, 1, 0, 3);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  ANARICamera camera = perspective_camera(device, EYE, FORWARD, FOVY);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 16, 16, world, camera, renderer);
  anariRelease(device, geometry);
  anariRelease(device, surface);
  anariRelease(device, world);
  anariRelease(device, camera);
  anariRelease(device, renderer);
  float rgba[4];
  centre_color(device, frame, rgba);
  CHECK_NEAR(rgba[1], 1.0, 0.01);
  CHECK_NEAR(centre_depth(device, frame), 4.0, 0.01);
  /* The handles themselves are gone for the application. */
  anariCommitParameters(device, world);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "not a live object", NULL));
  anariRelease(device, frame);
  close_device(library, device);
}

/* ----- parameter staging ----------------------------------------------------------------- */

typedef struct {
  ANARILibrary library;
  ANARIDevice device;
  ANARIGeometry geometry;
  ANARIMaterial material;
  ANARISurface surface;
  ANARIWorld world;
  ANARICamera camera;
  ANARIRenderer renderer;
  ANARIFrame frame;
} Scene;

/* A red 2×2 square 2 m in front of the camera, rendered at 16×16. */
static Scene red_square_scene(void) {
  Scene s;
  s.device = open_device(&s.library);
  s.geometry = square_at(s.device, 0, 0, -2, 2);
  s.material = anariNewMaterial(s.device, "matte");
  float red[3] = {1, 0, 0};
  anariSetParameter(s.device, s.material, "color", ANARI_FLOAT32_VEC3, red);
  anariCommitParameters(s.device, s.material);
  s.surface = anariNewSurface(s.device);
  anariSetParameter(s.device, s.surface, "geometry", ANARI_GEOMETRY, &s.geometry);
  anariSetParameter(s.device, s.surface, "material", ANARI_MATERIAL, &s.material);
  anariCommitParameters(s.device, s.surface);
  s.world = world_of_surfaces(s.device, &s.surface, 1);
  s.camera = perspective_camera(s.device, EYE, FORWARD, FOVY);
  s.renderer = albedo_renderer(s.device);
  s.frame = new_frame(s.device, 16, 16, s.world, s.camera, s.renderer);
  return s;
}

static void release_scene(Scene *s) {
  ANARIObject objects[] = {s->geometry, s->material, s->surface, s->world,
                           s->camera,   s->renderer, s->frame};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(s->device, objects[i]);
  close_device(s->library, s->device);
}

static void set_takes_effect_only_at_commit(void) {
  Scene s = red_square_scene();
  float rgba[4];
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 1.0, 0.01);
  CHECK_NEAR(rgba[1], 0.0, 0.01);
  float green[3] = {0, 1, 0};
  anariSetParameter(s.device, s.material, "color", ANARI_FLOAT32_VEC3, green);
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 1.0, 0.01); /* staged, not committed */
  anariCommitParameters(s.device, s.material);
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 0.0, 0.01);
  CHECK_NEAR(rgba[1], 1.0, 0.01);

  /* New vertex positions: also only at commit. */
  float far_square[18] = {-4, -4, -5, 4, -4, -5, 4, 4, -5, -4, -4, -5, 4, 4, -5, -4, 4, -5};
  ANARIArray1D positions = managed_array(s.device, ANARI_FLOAT32_VEC3, far_square, 6, 12);
  anariSetParameter(s.device, s.geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  anariRelease(s.device, positions);
  CHECK_NEAR(centre_depth(s.device, s.frame), 2.0, 0.01);
  anariCommitParameters(s.device, s.geometry);
  CHECK_NEAR(centre_depth(s.device, s.frame), 5.0, 0.01);
  CHECK(log_error_count() == 0);
  release_scene(&s);
}

static void unset_takes_effect_only_at_commit(void) {
  Scene s = red_square_scene();
  /* Move the camera 1 m back; then unset the position: back to the default (origin). */
  float back[3] = {0, 0, 1};
  anariSetParameter(s.device, s.camera, "position", ANARI_FLOAT32_VEC3, back);
  anariCommitParameters(s.device, s.camera);
  CHECK_NEAR(centre_depth(s.device, s.frame), 3.0, 0.01);
  anariUnsetParameter(s.device, s.camera, "position");
  CHECK_NEAR(centre_depth(s.device, s.frame), 3.0, 0.01);
  anariCommitParameters(s.device, s.camera);
  CHECK_NEAR(centre_depth(s.device, s.frame), 2.0, 0.01);

  /* The material colour falls back to matte's default 0.8 grey. */
  anariUnsetParameter(s.device, s.material, "color");
  float rgba[4];
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[1], 0.0, 0.01);
  anariCommitParameters(s.device, s.material);
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 0.8, 0.01);
  CHECK_NEAR(rgba[1], 0.8, 0.01);
  CHECK(log_error_count() == 0);
  release_scene(&s);
}

static void unset_all_takes_effect_only_at_commit(void) {
  Scene s = red_square_scene();
  float rgba[4];
  anariUnsetAllParameters(s.device, s.renderer);
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 1.0, 0.01); /* the cleared parameters are only staged */
  anariCommitParameters(s.device, s.renderer);
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 0.0, 0.001); /* no ambient light, no lights: black */
  CHECK(log_error_count() == 0);
  release_scene(&s);
}

static void mapped_parameter_arrays_apply_at_commit(void) {
  Scene s = red_square_scene();
  uint64_t stride = 0;
  float *xyz = anariMapParameterArray1D(s.device, s.geometry, "vertex.position",
                                        ANARI_FLOAT32_VEC3, 3, &stride);
  CHECK(xyz != NULL);
  CHECK(stride == 12);
  if (xyz) {
    float triangle[9] = {-3, -3, -6, 3, -3, -6, 0, 3, -6};
    memcpy(xyz, triangle, sizeof triangle);
  }
  anariUnmapParameterArray(s.device, s.geometry, "vertex.position");
  CHECK_NEAR(centre_depth(s.device, s.frame), 2.0, 0.01);
  anariCommitParameters(s.device, s.geometry);
  CHECK_NEAR(centre_depth(s.device, s.frame), 6.0, 0.01);
  CHECK(log_error_count() == 0);
  release_scene(&s);
}

static void parameters_changed_while_rendering_apply_to_the_next_frame(void) {
  Scene s = red_square_scene();
  anariRenderFrame(s.device, s.frame);
  float far_position[3] = {0, 0, 3};
  anariSetParameter(s.device, s.camera, "position", ANARI_FLOAT32_VEC3, far_position);
  anariCommitParameters(s.device, s.camera);
  anariFrameReady(s.device, s.frame, ANARI_WAIT);
  float *depth = copy_channel(s.device, s.frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  CHECK(depth && fabsf(pixel_depth(depth, 16, 8, 8) - 2.0f) < 0.01f);
  free(depth);
  CHECK_NEAR(centre_depth(s.device, s.frame), 5.0, 0.01);
  release_scene(&s);
}

/* ----- error paths ----------------------------------------------------------------------- */

static void null_device_is_refused_without_a_crash(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  CHECK(anariNewGeometry(NULL, "triangle") == NULL);
  CHECK(anariNewArray1D(NULL, NULL, NULL, NULL, ANARI_FLOAT32, 4) == NULL);
  float value = 1;
  anariSetParameter(NULL, device, "x", ANARI_FLOAT32, &value);
  anariCommitParameters(NULL, device);
  anariRelease(NULL, device);
  CHECK(anariMapFrame(NULL, NULL, "channel.color", NULL, NULL, NULL) == NULL);
  CHECK(anariFrameReady(NULL, NULL, ANARI_WAIT) == 0);
  int version = 0;
  CHECK(anariGetProperty(NULL, NULL, "version", ANARI_INT32, &version, 4, ANARI_WAIT) == 0);
  CHECK(anariGetObjectSubtypes(NULL, ANARI_GEOMETRY) == NULL);
  /* A pointer that is not a device is refused the same way. */
  int not_a_device;
  CHECK(anariNewWorld(&not_a_device) == NULL);
  /* No device to report through: each call is reported through the callback given to
   * anariLoadLibrary (the only library loaded), naming the function and the handle. */
  CHECK(status_log.count == 10);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewGeometry",
                 "device handle is NULL", NULL));
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariGetObjectSubtypes",
                 "device handle is NULL", NULL));
  const StatusEntry *foreign = log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR,
                                        "anariNewWorld", "not a live cavetrace device", NULL);
  CHECK(foreign && foreign->source == (void *)&not_a_device &&
        foreign->source_type == ANARI_DEVICE);
  CHECK(cavetraceLiveDeviceCount() >= 1); /* the release with a NULL device did nothing */
  close_device(library, device);
}

static void null_and_released_handles_are_reported(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  float value = 1;
  anariSetParameter(device, NULL, "radius", ANARI_FLOAT32, &value);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariSetParameter",
                 "NULL", NULL));
  log_clear();
  ANARIGeometry sphere = anariNewGeometry(device, "sphere");
  anariRelease(device, sphere);
  anariSetParameter(device, sphere, "radius", ANARI_FLOAT32, &value);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariSetParameter",
                 "not a live object", NULL));
  log_clear();
  anariRelease(device, sphere);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariRelease",
                 "not a live object", NULL));
  log_clear();
  anariRenderFrame(device, NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariRenderFrame",
                 NULL));
  close_device(library, device);
}

static void wrong_handle_kinds_are_reported(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  ANARISurface surface = anariNewSurface(device);
  /* A material handle declared as a geometry. */
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &material);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'geometry'",
                 "ANARI_GEOMETRY", "material", NULL));
  log_clear();
  /* Frame functions on a material; array functions on a surface. */
  CHECK(anariMapFrame(device, material, "channel.color", NULL, NULL, NULL) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariMapFrame",
                 "not a frame", NULL));
  log_clear();
  CHECK(anariMapArray(device, surface) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariMapArray",
                 "not an array", NULL));
  log_clear();
  /* An array of surfaces holding a material. */
  ANARIArray1D array = object_array(device, ANARI_SURFACE, &material, 1);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "element 0", NULL));
  anariRelease(device, array);
  anariRelease(device, material);
  anariRelease(device, surface);
  close_device(library, device);
}

static void unknown_subtypes_warn_and_still_make_objects(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry teapot = anariNewGeometry(device, "teapot");
  CHECK(teapot != NULL);
  CHECK(log_find(ANARI_STATUS_NO_ERROR, ANARI_SEVERITY_WARNING, "teapot", "triangle", NULL));
  CHECK(log_error_count() == 0);
  log_clear();
  float value = 2;
  anariSetParameter(device, teapot, "spout", ANARI_FLOAT32, &value);
  anariCommitParameters(device, teapot);
  CHECK(log_error_count() == 0); /* a valid object: parameters and commits are accepted */
  /* In a scene it is ignored: the frame renders only the background. */
  ANARISurface surface = matte_surface(device, teapot, 1, 1, 1, 0);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  ANARICamera camera = perspective_camera(device, EYE, FORWARD, FOVY);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 16, 16, world, camera, renderer);
  CHECK(isinf(centre_depth(device, frame)));
  ANARIObject objects[] = {teapot, surface, world, camera, renderer, frame};
  for (size_t i = 0; i < 6; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void null_names_are_reported(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  CHECK(anariNewGeometry(device, NULL) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewGeometry", "NULL",
                 NULL));
  log_clear();
  ANARIMaterial material = anariNewMaterial(device, "matte");
  float value = 1;
  anariSetParameter(device, material, NULL, ANARI_FLOAT32, &value);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'name' is NULL", NULL));
  log_clear();
  anariUnsetParameter(device, material, NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariUnsetParameter",
                 "NULL", NULL));
  log_clear();
  CHECK(anariNewObject(device, NULL, "matte") == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewObject", "NULL",
                 NULL));
  log_clear();
  ANARIFrame frame = anariNewFrame(device);
  CHECK(anariMapFrame(device, frame, NULL, NULL, NULL, NULL) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariMapFrame",
                 "'channel' is NULL", NULL));
  log_clear();
  int version = 0;
  CHECK(anariGetProperty(device, device, NULL, ANARI_INT32, &version, 4, ANARI_WAIT) == 0);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariGetProperty",
                 "NULL", NULL));
  log_clear();
  /* A NULL value pointer. */
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'color'", "NULL", NULL));
  anariRelease(device, material);
  anariRelease(device, frame);
  close_device(library, device);
}

static void invalid_data_types_are_reported(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  float value[4] = {1, 2, 3, 4};
  anariSetParameter(device, material, "color", 31337, value);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "31337",
                 "not an ANARI data type", NULL));
  log_clear();
  CHECK(anariNewArray1D(device, NULL, NULL, NULL, 31337, 4) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewArray1D", "31337",
                 NULL));
  log_clear();
  CHECK(anariMapParameterArray1D(device, material, "color", -5, 4, NULL) == NULL);
  CHECK(log_error_count() == 1);
  log_clear();
  /* A frame channel of a type it cannot be mapped as. */
  ANARIFrame frame = anariNewFrame(device);
  ANARIDataType wrong = ANARI_FLOAT64;
  anariSetParameter(device, frame, "channel.depth", ANARI_DATA_TYPE, &wrong);
  anariCommitParameters(device, frame);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "channel.depth",
                 "ANARI_FLOAT64", NULL));
  anariRelease(device, frame);
  anariRelease(device, material);
  close_device(library, device);
}

static void array_mapping_misuse_is_reported(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIArray1D array = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32, 8);
  CHECK(anariMapArray(device, array) != NULL);
  CHECK(anariMapArray(device, array) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "anariMapArray",
                 "already mapped", NULL));
  log_clear();
  anariUnmapArray(device, array);
  CHECK(log_error_count() == 0);
  anariUnmapArray(device, array);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "anariUnmapArray",
                 "not mapped", NULL));
  log_clear();
  ANARIGeometry geometry = anariNewGeometry(device, "triangle");
  anariUnmapParameterArray(device, geometry, "vertex.position");
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR,
                 "anariUnmapParameterArray", "'vertex.position'", NULL));
  anariRelease(device, geometry);
  anariRelease(device, array);
  close_device(library, device);
}

static void overflowing_array_sizes_are_out_of_memory(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  CHECK(anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC4, UINT64_MAX / 8) == NULL);
  CHECK(log_find(ANARI_STATUS_OUT_OF_MEMORY, ANARI_SEVERITY_ERROR, "anariNewArray1D", NULL));
  log_clear();
  CHECK(anariNewArray2D(device, NULL, NULL, NULL, ANARI_UINT8, (uint64_t)1 << 40,
                        (uint64_t)1 << 40) == NULL);
  CHECK(log_find(ANARI_STATUS_OUT_OF_MEMORY, ANARI_SEVERITY_ERROR, "anariNewArray2D", NULL));
  log_clear();
  CHECK(anariNewArray3D(device, NULL, NULL, NULL, ANARI_FLOAT64, (uint64_t)1 << 22,
                        (uint64_t)1 << 22, (uint64_t)1 << 22) == NULL);
  CHECK(log_find(ANARI_STATUS_OUT_OF_MEMORY, ANARI_SEVERITY_ERROR, "anariNewArray3D", NULL));
  CHECK(log_error_count() == 1);
  close_device(library, device);
}

static void wrong_parameter_types_name_object_parameter_and_types(void) {
  Scene s = red_square_scene();
  float grey = 0.5f;
  anariSetParameter(s.device, s.material, "color", ANARI_FLOAT32, &grey);
  const StatusEntry *e = log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR,
                                  "anariSetParameter", "material 'matte'", "'color'",
                                  "ANARI_FLOAT32", "ANARI_FLOAT32_VEC3", NULL);
  CHECK(e != NULL);
  CHECK(e && e->source == s.material && e->source_type == ANARI_MATERIAL);
  anariCommitParameters(s.device, s.material);
  float rgba[4];
  centre_color(s.device, s.frame, rgba);
  CHECK_NEAR(rgba[0], 1.0, 0.01); /* the bad value had no effect */
  log_clear();
  uint32_t size = 64;
  anariSetParameter(s.device, s.frame, "size", ANARI_UINT32, &size);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "frame", "'size'",
                 "ANARI_UINT32_VEC2", NULL));
  release_scene(&s);
}

/* What applications written for other devices send: ANARI_ARRAY and ANARI_OBJECT as the
 * declared type, and object arrays of ANARI_OBJECT elements; checked by the handles' real kinds. */
static void generic_handle_and_element_types_are_taken_by_their_real_kind(void) {
  Scene s = red_square_scene();
  /* The square's geometry again, from a vertex array declared ANARI_OBJECT; the surface's
   * geometry and material declared ANARI_OBJECT. */
  static const float square[18] = {-1, -1, -2, 1, -1, -2, 1, 1, -2, -1, -1, -2, 1, 1, -2, -1, 1, -2};
  ANARIArray1D positions = managed_array(s.device, ANARI_FLOAT32_VEC3, square, 6, 12);
  ANARIGeometry geometry = anariNewGeometry(s.device, "triangle");
  anariSetParameter(s.device, geometry, "vertex.position", ANARI_OBJECT, &positions);
  anariCommitParameters(s.device, geometry);
  ANARISurface surface = anariNewSurface(s.device);
  anariSetParameter(s.device, surface, "geometry", ANARI_OBJECT, &geometry);
  anariSetParameter(s.device, surface, "material", ANARI_OBJECT, &s.material);
  uint32_t id = 4;
  anariSetParameter(s.device, surface, "id", ANARI_UINT32, &id);
  anariCommitParameters(s.device, surface);
  /* The world's surfaces as ANARI_ARRAY of ANARI_OBJECT elements, one of them a material. */
  ANARIObject elements[2] = {s.material, surface};
  ANARIArray1D surfaces = object_array(s.device, ANARI_OBJECT, elements, 2);
  anariSetParameter(s.device, s.world, "surface", ANARI_ARRAY, &surfaces);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "world", "'surface'",
                 "element 0", "ANARI_MATERIAL", NULL));
  CHECK(log_error_count() == 1);
  anariCommitParameters(s.device, s.world);
  render_and_wait(s.device, s.frame);
  uint32_t *ids = copy_channel(s.device, s.frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  CHECK(ids && pixel_id(ids, 16, 8, 8) == 4); /* the surface renders, the material is left out */
  free(ids);
  /* A real kind that does not fit is still refused. */
  log_clear();
  anariSetParameter(s.device, surface, "material", ANARI_OBJECT, &geometry);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'material'",
                 "ANARI_GEOMETRY", "ANARI_MATERIAL", NULL));
  ANARIArray2D image = anariNewArray2D(s.device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 2, 2);
  anariSetParameter(s.device, geometry, "vertex.position", ANARI_ARRAY, &image);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'vertex.position'",
                 "ANARI_ARRAY2D", "ANARI_ARRAY1D", NULL));
  CHECK(log_error_count() == 2);
  ANARIObject objects[] = {positions, geometry, surface, surfaces, image};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(s.device, objects[i]);
  release_scene(&s);
}

static void frame_misuse_is_reported(void) {
  Scene s = red_square_scene();
  render_and_wait(s.device, s.frame);
  CHECK(anariMapFrame(s.device, s.frame, "channel.albedo", NULL, NULL, NULL) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "channel.albedo", NULL));
  log_clear();
  anariUnmapFrame(s.device, s.frame, "channel.color");
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "anariUnmapFrame",
                 "not mapped", NULL));
  log_clear();
  ANARIFrame empty = anariNewFrame(s.device);
  anariRenderFrame(s.device, empty);
  anariFrameReady(s.device, empty, ANARI_WAIT);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "anariRenderFrame",
                 "'size'", NULL));
  log_clear();
  uint32_t huge[2] = {1u << 20, 1u << 20};
  anariSetParameter(s.device, empty, "size", ANARI_UINT32_VEC2, huge);
  anariCommitParameters(s.device, empty);
  anariRenderFrame(s.device, empty);
  CHECK(log_find(ANARI_STATUS_OUT_OF_MEMORY, ANARI_SEVERITY_ERROR, "anariRenderFrame", NULL));
  anariRelease(s.device, empty);
  release_scene(&s);
}

static void library_module_and_device_names_are_checked(void) {
  ANARILibrary other = anariLoadLibrary("helide", record_status, &status_log);
  CHECK(other == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariLoadLibrary",
                 "'helide'", NULL));
  log_clear();
  CHECK(anariLoadLibrary(NULL, record_status, &status_log) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "NULL", NULL));
  log_clear();
  ANARILibrary library = anariLoadLibrary("default", record_status, &status_log);
  CHECK(library != NULL);
  CHECK(anariNewDevice(library, "vulkan") == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewDevice",
                 "vulkan", NULL));
  log_clear();
  anariLoadModule(library, "usd");
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "anariLoadModule", "usd",
                 NULL));
  log_clear();
  ANARIDevice device = anariNewDevice(library, "default");
  CHECK(anariNewObject(device, "teapot", "x") == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariNewObject",
                 "'teapot'", NULL));
  close_device(library, device);
}

int main(void) {
  run_test("captured_array_deleted_once_after_last_user",
           captured_array_deleted_once_after_last_user);
  run_test("captured_array_deleted_at_device_release_when_never_released",
           captured_array_deleted_at_device_release_when_never_released);
  run_test("failed_array_creation_never_calls_the_deleter",
           failed_array_creation_never_calls_the_deleter);
  run_test("retain_adds_a_reference_the_application_must_release",
           retain_adds_a_reference_the_application_must_release);
  run_test("devices_are_counted_and_retained", devices_are_counted_and_retained);
  run_test("objects_in_use_outlive_their_handles", objects_in_use_outlive_their_handles);
  run_test("set_takes_effect_only_at_commit", set_takes_effect_only_at_commit);
  run_test("unset_takes_effect_only_at_commit", unset_takes_effect_only_at_commit);
  run_test("unset_all_takes_effect_only_at_commit", unset_all_takes_effect_only_at_commit);
  run_test("mapped_parameter_arrays_apply_at_commit", mapped_parameter_arrays_apply_at_commit);
  run_test("parameters_changed_while_rendering_apply_to_the_next_frame",
           parameters_changed_while_rendering_apply_to_the_next_frame);
  run_test("null_device_is_refused_without_a_crash", null_device_is_refused_without_a_crash);
  run_test("null_and_released_handles_are_reported", null_and_released_handles_are_reported);
  run_test("wrong_handle_kinds_are_reported", wrong_handle_kinds_are_reported);
  run_test("unknown_subtypes_warn_and_still_make_objects",
           unknown_subtypes_warn_and_still_make_objects);
  run_test("null_names_are_reported", null_names_are_reported);
  run_test("invalid_data_types_are_reported", invalid_data_types_are_reported);
  run_test("array_mapping_misuse_is_reported", array_mapping_misuse_is_reported);
  run_test("overflowing_array_sizes_are_out_of_memory", overflowing_array_sizes_are_out_of_memory);
  run_test("wrong_parameter_types_name_object_parameter_and_types",
           wrong_parameter_types_name_object_parameter_and_types);
  run_test("generic_handle_and_element_types_are_taken_by_their_real_kind",
           generic_handle_and_element_types_are_taken_by_their_real_kind);
  run_test("frame_misuse_is_reported", frame_misuse_is_reported);
  run_test("library_module_and_device_names_are_checked",
           library_module_and_device_names_are_checked);
  return test_summary();
}
