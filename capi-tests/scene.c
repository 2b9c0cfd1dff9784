/* The device and scene helpers of harness.h (they call the library). */
#include "harness.h"

#include <stdlib.h>
#include <string.h>

/* ----- devices and scenes ---------------------------------------------------------------- */

ANARIDevice open_device(ANARILibrary *library) {
  *library = anariLoadLibrary("cavetrace", record_status, &status_log);
  CHECK(*library != NULL);
  ANARIDevice device = anariNewDevice(*library, "default");
  CHECK(device != NULL);
  return device;
}

void close_device(ANARILibrary library, ANARIDevice device) {
  anariRelease(device, device);
  anariUnloadLibrary(library);
}

ANARIArray1D managed_array(ANARIDevice device, ANARIDataType type, const void *data,
                           uint64_t count, size_t element_size) {
  ANARIArray1D array = anariNewArray1D(device, NULL, NULL, NULL, type, count);
  void *memory = anariMapArray(device, array);
  CHECK(memory != NULL);
  if (memory)
    memcpy(memory, data, (size_t)count * element_size);
  anariUnmapArray(device, array);
  return array;
}

ANARIArray1D object_array(ANARIDevice device, ANARIDataType type, const ANARIObject *objects,
                          uint64_t count) {
  return managed_array(device, type, objects, count, sizeof(ANARIObject));
}

ANARIGeometry triangle_geometry(ANARIDevice device, const float *xyz, uint64_t vertex_count) {
  ANARIGeometry geometry = anariNewGeometry(device, "triangle");
  ANARIArray1D positions =
      managed_array(device, ANARI_FLOAT32_VEC3, xyz, vertex_count, 3 * sizeof(float));
  anariSetParameter(device, geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, geometry);
  anariRelease(device, positions);
  return geometry;
}

ANARIGeometry square_at(ANARIDevice device, float x, float y, float z, float side) {
  float h = side / 2;
  float xyz[18] = {x - h, y - h, z, x + h, y - h, z, x + h, y + h, z,
                   x - h, y - h, z, x + h, y + h, z, x - h, y + h, z};
  return triangle_geometry(device, xyz, 6);
}

ANARISurface matte_surface(ANARIDevice device, ANARIGeometry geometry, float r, float g, float b,
                           uint32_t id) {
  ANARIMaterial material = anariNewMaterial(device, "matte");
  float color[3] = {r, g, b};
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, color);
  anariCommitParameters(device, material);
  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariSetParameter(device, surface, "id", ANARI_UINT32, &id);
  anariCommitParameters(device, surface);
  anariRelease(device, material);
  return surface;
}

ANARIWorld world_of_surfaces(ANARIDevice device, const ANARISurface *surfaces, uint64_t count) {
  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D array = object_array(device, ANARI_SURFACE, surfaces, count);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &array);
  anariCommitParameters(device, world);
  anariRelease(device, array);
  return world;
}

ANARICamera perspective_camera(ANARIDevice device, const float eye[3], const float dir[3],
                               float fovy) {
  ANARICamera camera = anariNewCamera(device, "perspective");
  float up[3] = {0, 1, 0};
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, eye);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, dir);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "fovy", ANARI_FLOAT32, &fovy);
  anariCommitParameters(device, camera);
  return camera;
}

ANARIRenderer albedo_renderer(ANARIDevice device) {
  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[4] = {0, 0, 0, 1};
  /* Ambient radiance 1 from every direction, unoccluded (ambientOcclusionDistance 0): a matte
   * surface shows exactly its albedo. */
  float one = 1.0f, no_occlusion = 0.0f;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &one);
  anariSetParameter(device, renderer, "ambientOcclusionDistance", ANARI_FLOAT32, &no_occlusion);
  anariCommitParameters(device, renderer);
  return renderer;
}

ANARIFrame new_frame(ANARIDevice device, uint32_t width, uint32_t height, ANARIWorld world,
                     ANARICamera camera, ANARIRenderer renderer) {
  ANARIFrame frame = anariNewFrame(device);
  uint32_t size[2] = {width, height};
  ANARIDataType color = ANARI_FLOAT32_VEC4, scalar = ANARI_FLOAT32, id = ANARI_UINT32;
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(device, frame, "channel.color", ANARI_DATA_TYPE, &color);
  anariSetParameter(device, frame, "channel.depth", ANARI_DATA_TYPE, &scalar);
  anariSetParameter(device, frame, "channel.primitiveId", ANARI_DATA_TYPE, &id);
  anariSetParameter(device, frame, "channel.objectId", ANARI_DATA_TYPE, &id);
  anariSetParameter(device, frame, "channel.instanceId", ANARI_DATA_TYPE, &id);
  anariSetParameter(device, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(device, frame, "camera", ANARI_CAMERA, &camera);
  anariSetParameter(device, frame, "renderer", ANARI_RENDERER, &renderer);
  anariCommitParameters(device, frame);
  return frame;
}

void render_and_wait(ANARIDevice device, ANARIFrame frame) {
  anariRenderFrame(device, frame);
  anariFrameReady(device, frame, ANARI_WAIT);
}

void *copy_channel(ANARIDevice device, ANARIFrame frame, const char *channel,
                   ANARIDataType expected_type, size_t element_size, uint32_t *width,
                   uint32_t *height) {
  uint32_t w = 0, h = 0;
  ANARIDataType type = ANARI_UNKNOWN;
  const void *pixels = anariMapFrame(device, frame, channel, &w, &h, &type);
  void *copy = NULL;
  if (pixels && type == expected_type) {
    copy = malloc((size_t)w * h * element_size);
    if (copy)
      memcpy(copy, pixels, (size_t)w * h * element_size);
  }
  if (pixels)
    anariUnmapFrame(device, frame, channel);
  CHECK(copy != NULL);
  if (width)
    *width = w;
  if (height)
    *height = h;
  return copy;
}

float pixel_depth(const float *depth, uint32_t width, uint32_t x, uint32_t y) {
  return depth[(size_t)y * width + x];
}

uint32_t pixel_id(const uint32_t *ids, uint32_t width, uint32_t x, uint32_t y) {
  return ids[(size_t)y * width + x];
}

const float *pixel_color(const float *rgba, uint32_t width, uint32_t x, uint32_t y) {
  return rgba + 4 * ((size_t)y * width + x);
}

