/* Properties (anariGetProperty) and introspection (anariGetObjectSubtypes/Info/ParameterInfo). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

static int list_contains(const char *const *list, const char *name) {
  for (; list && *list; list++)
    if (strcmp(*list, name) == 0)
      return 1;
  return 0;
}

static int list_length(const char *const *list) {
  int n = 0;
  for (; list && *list; list++)
    n++;
  return n;
}

/* Every byte of buffer equals value. */
static int untouched(const unsigned char *buffer, size_t size, unsigned char value) {
  for (size_t i = 0; i < size; i++)
    if (buffer[i] != value)
      return 0;
  return 1;
}

static void device_version_and_limits(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  int32_t version = -1, major = -1, minor = -1, patch = -1;
  CHECK(anariGetProperty(device, device, "version", ANARI_INT32, &version, 4, ANARI_WAIT) == 1);
  CHECK(anariGetProperty(device, device, "version.major", ANARI_INT32, &major, 4, ANARI_WAIT));
  CHECK(anariGetProperty(device, device, "version.minor", ANARI_INT32, &minor, 4, ANARI_WAIT));
  CHECK(anariGetProperty(device, device, "version.patch", ANARI_INT32, &patch, 4, ANARI_WAIT));
  CHECK(major >= 0 && minor >= 0 && patch >= 0);
  CHECK(version == major * 10000 + minor * 100 + patch);
  const char *name = NULL;
  CHECK(anariGetProperty(device, device, "version.name", ANARI_STRING, &name, sizeof name,
                         ANARI_WAIT) == 1);
  CHECK(name && strncmp(name, "cavetrace", 9) == 0);
  uint64_t max_index = 0;
  CHECK(anariGetProperty(device, device, "geometryMaxIndex", ANARI_UINT64, &max_index, 8,
                         ANARI_WAIT) == 1);
  CHECK(max_index == 0xFFFFFFFEull);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void extension_lists_agree(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const char **from_device = NULL;
  CHECK(anariGetProperty(device, device, "extension", ANARI_STRING_LIST, &from_device,
                         sizeof from_device, ANARI_WAIT) == 1);
  const char **from_library = anariGetDeviceExtensions(library, "default");
  CHECK(from_device != NULL && from_library != NULL);
  CHECK(list_length(from_device) == list_length(from_library));
  for (const char **e = from_device; e && *e; e++)
    CHECK(list_contains(from_library, *e));
  CHECK(list_contains(from_device, "ANARI_KHR_GEOMETRY_TRIANGLE"));
  CHECK(list_contains(from_device, "ANARI_KHR_GEOMETRY_SPHERE"));
  CHECK(list_contains(from_device, "ANARI_KHR_FRAME_COMPLETION_CALLBACK"));
  CHECK(list_contains(from_device, "ANARI_KHR_SPATIAL_FIELD_STRUCTURED_REGULAR"));
  CHECK(list_contains(from_device, "ANARI_KHR_GEOMETRY_CYLINDER"));
  CHECK(list_contains(from_device, "ANARI_KHR_LIGHT_SPOT"));
  CHECK(list_contains(from_device, "ANARI_KHR_LIGHT_HDRI"));
  CHECK(list_contains(from_device, "ANARI_CAVETRACE_CAMERA_LIGHT_FIELD"));
  CHECK(list_contains(from_device, "ANARI_KHR_MATERIAL_PHYSICALLY_BASED"));
  CHECK(list_contains(from_device, "ANARI_KHR_CAMERA_OMNIDIRECTIONAL"));
  CHECK(list_contains(from_device, "ANARI_CAVETRACE_CAMERA_FISHEYE"));
  CHECK(list_contains(from_device, "ANARI_KHR_SPATIAL_FIELD_UNSTRUCTURED"));
  CHECK(list_contains(from_device, "ANARI_KHR_GEOMETRY_ISOSURFACE"));
  CHECK(list_contains(from_device, "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"));
  /* Nothing the device does not implement: MPI only in the build with the `mpi` feature. */
  CHECK(!list_contains(from_device, "ANARI_KHR_DATA_PARALLEL_MPI"));
  CHECK(anariGetDeviceExtensions(library, "vulkan") == NULL);
  const char **devices = anariGetDeviceSubtypes(library);
  CHECK(list_contains(devices, "default"));
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void world_bounds_and_frame_duration(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry a = square_at(device, 0, 0, -2, 2);
  ANARIGeometry b = square_at(device, 3, 1, -6, 1);
  ANARISurface surfaces[2] = {matte_surface(device, a, 1, 0, 0, 0),
                              matte_surface(device, b, 0, 1, 0, 1)};
  ANARIWorld world = world_of_surfaces(device, surfaces, 2);
  float box[6] = {0};
  CHECK(anariGetProperty(device, world, "bounds", ANARI_FLOAT32_BOX3, box, sizeof box,
                         ANARI_WAIT) == 1);
  const float expected[6] = {-1, -1, -6, 3.5f, 1.5f, -2};
  for (int i = 0; i < 6; i++)
    CHECK_NEAR(box[i], expected[i], 1e-6);
  float eye[3] = {0, 0, 0}, dir[3] = {0, 0, -1};
  ANARICamera camera = perspective_camera(device, eye, dir, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 32, 32, world, camera, renderer);
  anariRenderFrame(device, frame);
  float duration = -1;
  /* ANARI_WAIT: the property waits for the render. */
  CHECK(anariGetProperty(device, frame, "duration", ANARI_FLOAT32, &duration, 4, ANARI_WAIT) ==
        1);
  CHECK(duration > 0 && duration < 60);
  CHECK(anariFrameReady(device, frame, ANARI_NO_WAIT) == 1);
  ANARIObject objects[] = {a, b, surfaces[0], surfaces[1], world, camera, renderer, frame};
  for (size_t i = 0; i < 8; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void properties_never_write_past_size(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  unsigned char buffer[32];
  memset(buffer, 0xAA, sizeof buffer);
  CHECK(anariGetProperty(device, device, "version", ANARI_INT32, buffer, 3, ANARI_WAIT) == 0);
  CHECK(untouched(buffer, sizeof buffer, 0xAA));
  CHECK(anariGetProperty(device, device, "geometryMaxIndex", ANARI_UINT64, buffer, 7,
                         ANARI_WAIT) == 0);
  CHECK(untouched(buffer, sizeof buffer, 0xAA));
  CHECK(anariGetProperty(device, device, "version.name", ANARI_STRING, buffer,
                         sizeof(char *) - 1, ANARI_WAIT) == 0);
  CHECK(untouched(buffer, sizeof buffer, 0xAA));
  /* Wrong type and unknown names: 0, nothing written. */
  CHECK(anariGetProperty(device, device, "version", ANARI_FLOAT32, buffer, 32, ANARI_WAIT) == 0);
  CHECK(anariGetProperty(device, device, "colour", ANARI_INT32, buffer, 32, ANARI_WAIT) == 0);
  CHECK(untouched(buffer, sizeof buffer, 0xAA));
  ANARIWorld world = anariNewWorld(device);
  anariCommitParameters(device, world);
  CHECK(anariGetProperty(device, world, "bounds", ANARI_FLOAT32_BOX3, buffer, 23, ANARI_WAIT) ==
        0);
  CHECK(untouched(buffer, sizeof buffer, 0xAA));
  /* Exactly large enough: written, and not one byte more. */
  CHECK(anariGetProperty(device, device, "version", ANARI_INT32, buffer, 4, ANARI_WAIT) == 1);
  CHECK(untouched(buffer + 4, sizeof buffer - 4, 0xAA));
  anariRelease(device, world);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void object_subtypes(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const char **geometries = anariGetObjectSubtypes(device, ANARI_GEOMETRY);
  CHECK(list_contains(geometries, "triangle"));
  CHECK(list_contains(geometries, "quad"));
  CHECK(list_contains(geometries, "sphere"));
  CHECK(list_contains(geometries, "cylinder"));
  CHECK(!list_contains(geometries, "teapot"));
  const char **renderers = anariGetObjectSubtypes(device, ANARI_RENDERER);
  CHECK(renderers && renderers[0] && strcmp(renderers[0], "default") == 0);
  CHECK(list_contains(anariGetObjectSubtypes(device, ANARI_CAMERA), "perspective"));
  CHECK(list_contains(anariGetObjectSubtypes(device, ANARI_MATERIAL), "matte"));
  CHECK(list_contains(anariGetObjectSubtypes(device, ANARI_SAMPLER), "image1D"));
  CHECK(list_contains(anariGetObjectSubtypes(device, ANARI_LIGHT), "directional"));
  const char **volumes = anariGetObjectSubtypes(device, ANARI_VOLUME);
  CHECK(list_length(volumes) == 1 && list_contains(volumes, "transferFunction1D"));
  CHECK(list_contains(anariGetObjectSubtypes(device, ANARI_SPATIAL_FIELD), "structuredRegular"));
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void object_info(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const char *description =
      anariGetObjectInfo(device, ANARI_GEOMETRY, "sphere", "description", ANARI_STRING);
  CHECK(description && strlen(description) > 0);
  const ANARIParameter *params =
      anariGetObjectInfo(device, ANARI_GEOMETRY, "sphere", "parameter", ANARI_PARAMETER_LIST);
  CHECK(params != NULL);
  int found_radius = 0, found_position = 0, count = 0;
  for (const ANARIParameter *p = params; p && p->name; p++, count++) {
    found_radius |= strcmp(p->name, "radius") == 0 && p->type == ANARI_FLOAT32;
    found_position |= strcmp(p->name, "vertex.position") == 0 && p->type == ANARI_ARRAY1D;
  }
  CHECK(found_radius && found_position && count > 3);
  const char *const *channels =
      anariGetObjectInfo(device, ANARI_FRAME, NULL, "channel", ANARI_STRING_LIST);
  CHECK(list_contains(channels, "channel.color"));
  CHECK(list_contains(channels, "channel.depth"));
  CHECK(list_contains(channels, "channel.primitiveId"));
  const char *const *extensions =
      anariGetObjectInfo(device, ANARI_GEOMETRY, "triangle", "extension", ANARI_STRING_LIST);
  CHECK(list_contains(extensions, "ANARI_KHR_GEOMETRY_TRIANGLE"));
  /* Unknown subtype or info name: NULL. */
  CHECK(anariGetObjectInfo(device, ANARI_GEOMETRY, "teapot", "description", ANARI_STRING) ==
        NULL);
  CHECK(anariGetObjectInfo(device, ANARI_GEOMETRY, "sphere", "flavour", ANARI_STRING) == NULL);
  CHECK(anariGetObjectInfo(device, ANARI_GEOMETRY, "sphere", "description", ANARI_INT32) ==
        NULL);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void parameter_info(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const float *radius = anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "radius",
                                              ANARI_FLOAT32, "default", ANARI_FLOAT32);
  CHECK(radius && *radius == 1.0f);
  const char *required = anariGetParameterInfo(device, ANARI_SURFACE, NULL, "geometry",
                                               ANARI_GEOMETRY, "required", ANARI_BOOL);
  CHECK(required && *required == 1);
  const char *optional = anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "radius",
                                               ANARI_FLOAT32, "required", ANARI_BOOL);
  CHECK(optional && *optional == 0);
  const char *description = anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "radius",
                                                  ANARI_FLOAT32, "description", ANARI_STRING);
  CHECK(description && strlen(description) > 0);
  const char *const *filters = anariGetParameterInfo(device, ANARI_SAMPLER, "image1D", "filter",
                                               ANARI_STRING, "value", ANARI_STRING_LIST);
  CHECK(list_contains(filters, "nearest") && list_contains(filters, "linear") &&
        list_length(filters) == 2);
  const int32_t *samples_min = anariGetParameterInfo(device, ANARI_RENDERER, "default",
                                                     "pixelSamples", ANARI_INT32, "minimum",
                                                     ANARI_INT32);
  CHECK(samples_min && *samples_min == 1);
  const ANARIDataType *color_types =
      anariGetParameterInfo(device, ANARI_FRAME, NULL, "channel.color", ANARI_DATA_TYPE, "value",
                            ANARI_DATA_TYPE_LIST);
  int found_float4 = 0;
  for (const ANARIDataType *t = color_types; t && *t != ANARI_UNKNOWN; t++)
    found_float4 |= *t == ANARI_FLOAT32_VEC4;
  CHECK(found_float4);
  /* Unknown parameter, parameter of another type, unknown info: NULL. */
  CHECK(anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "spout", ANARI_FLOAT32,
                              "default", ANARI_FLOAT32) == NULL);
  CHECK(anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "radius", ANARI_INT32,
                              "default", ANARI_INT32) == NULL);
  CHECK(anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", "radius", ANARI_FLOAT32,
                              "flavour", ANARI_STRING) == NULL);
  CHECK(log_error_count() == 0);
  /* NULL names are errors. */
  CHECK(anariGetParameterInfo(device, ANARI_GEOMETRY, "sphere", NULL, ANARI_FLOAT32, "default",
                              ANARI_FLOAT32) == NULL);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "anariGetParameterInfo",
                 "NULL", NULL));
  close_device(library, device);
}

typedef uint64_t (*LiveDeviceCount)(void);

static void proc_address_finds_cavetrace_functions(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIProcAddress address = anariDeviceGetProcAddress(device, "cavetraceLiveDeviceCount");
  CHECK(address != NULL);
  if (address) {
    LiveDeviceCount count = (LiveDeviceCount)address;
    CHECK(count() == cavetraceLiveDeviceCount());
    CHECK(count() >= 1);
  }
  CHECK(anariDeviceGetProcAddress(device, "cavetraceMakeCoffee") == NULL);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

int main(void) {
  run_test("device_version_and_limits", device_version_and_limits);
  run_test("extension_lists_agree", extension_lists_agree);
  run_test("world_bounds_and_frame_duration", world_bounds_and_frame_duration);
  run_test("properties_never_write_past_size", properties_never_write_past_size);
  run_test("object_subtypes", object_subtypes);
  run_test("object_info", object_info);
  run_test("parameter_info", parameter_info);
  run_test("proc_address_finds_cavetrace_functions", proc_address_finds_cavetrace_functions);
  return test_summary();
}
