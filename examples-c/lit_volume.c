/*
 * A lit volume: a cloud (a structured field) over a floor, lit by a low sun. The default
 * renderer scatters the sun's light in the cloud (single scattering, shadow rays through the
 * cloud itself) and the cloud casts a soft-edged shadow on the floor: the floor receives the
 * sun's light attenuated by the cloud's transmittance. The sky's ambient light reaches the
 * cloud's inside through the cloud and past the floor (ambient occlusion). Written to a PNG
 * file.
 *
 *   cc -std=c99 lit_volume.c $(pkg-config --cflags --libs cavetrace) -lm -o lit_volume
 *   ./lit_volume [output.png]
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <cavetrace.h>

#include "example_support.h"

enum { GRID = 64 };

/* A lumpy cloud: three overlapping balls with a ripple, in the box [-1.5, 1.5] x [0.4, 1.9] x
 * [-1, 1]; values fall from 1 at the balls' centres to 0 outside them. */
static ANARISpatialField cloud_field(ANARIDevice device) {
  static const float balls[3][4] = {
      {-0.6f, 1.1f, 0.0f, 0.55f}, {0.3f, 1.25f, 0.1f, 0.6f}, {0.9f, 1.0f, -0.2f, 0.45f}};
  ANARIArray3D data = anariNewArray3D(device, NULL, NULL, NULL, ANARI_FLOAT32, GRID, GRID, GRID);
  float *v = anariMapArray(device, data);
  for (int k = 0; k < GRID; k++)
    for (int j = 0; j < GRID; j++)
      for (int i = 0; i < GRID; i++) {
        float x = -1.5f + 3.0f * i / (GRID - 1), y = 0.4f + 1.5f * j / (GRID - 1);
        float z = -1 + 2.0f * k / (GRID - 1);
        float value = 0;
        for (int b = 0; b < 3; b++) {
          float dx = x - balls[b][0], dy = y - balls[b][1], dz = z - balls[b][2];
          float d = sqrtf(dx * dx + dy * dy + dz * dz) / balls[b][3];
          value = fmaxf(value, 1 - d);
        }
        value += 0.08f * sinf(9 * x) * sinf(11 * y) * sinf(7 * z);
        v[i + GRID * (j + GRID * k)] = value;
      }
  anariUnmapArray(device, data);
  ANARISpatialField field = anariNewSpatialField(device, "structuredRegular");
  float origin[] = {-1.5f, 0.4f, -1};
  float spacing[] = {3.0f / (GRID - 1), 1.5f / (GRID - 1), 2.0f / (GRID - 1)};
  anariSetParameter(device, field, "data", ANARI_ARRAY3D, &data);
  anariSetParameter(device, field, "origin", ANARI_FLOAT32_VEC3, origin);
  anariSetParameter(device, field, "spacing", ANARI_FLOAT32_VEC3, spacing);
  anariCommitParameters(device, field);
  anariRelease(device, data);
  return field;
}

int main(int argc, char **argv) {
  const char *output = argc > 1 ? argv[1] : "lit_volume.png";
  int errors = 0;
  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &errors);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;

  /* The cloud: transparent below 0.05, white and denser towards the centres. */
  ANARISpatialField field = cloud_field(device);
  float opacity[] = {0.0f, 0.5f, 0.9f}, range[] = {0.05f, 0.6f}, unit = 0.1f;
  float white[] = {0.95f, 0.95f, 0.95f};
  ANARIArray1D opacity_array = anariNewArray1D(device, opacity, NULL, NULL, ANARI_FLOAT32, 3);
  ANARIVolume volume = anariNewVolume(device, "transferFunction1D");
  anariSetParameter(device, volume, "value", ANARI_SPATIAL_FIELD, &field);
  anariSetParameter(device, volume, "color", ANARI_FLOAT32_VEC3, white);
  anariSetParameter(device, volume, "opacity", ANARI_ARRAY1D, &opacity_array);
  anariSetParameter(device, volume, "valueRange", ANARI_FLOAT32_BOX1, range);
  anariSetParameter(device, volume, "unitDistance", ANARI_FLOAT32, &unit);
  anariCommitParameters(device, volume);

  /* A floor at y = 0. */
  float corners[] = {-6, 0, -6, 6, 0, -6, 6, 0, 6, -6, 0, 6};
  uint32_t triangles[] = {0, 2, 1, 0, 3, 2};
  ANARIArray1D positions = anariNewArray1D(device, corners, NULL, NULL, ANARI_FLOAT32_VEC3, 4);
  ANARIArray1D index = anariNewArray1D(device, triangles, NULL, NULL, ANARI_UINT32_VEC3, 2);
  ANARIGeometry floor_geometry = anariNewGeometry(device, "triangle");
  anariSetParameter(device, floor_geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, floor_geometry, "primitive.index", ANARI_ARRAY1D, &index);
  anariCommitParameters(device, floor_geometry);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  float sand[] = {0.8f, 0.7f, 0.55f};
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, sand);
  anariCommitParameters(device, material);
  ANARISurface floor_surface = anariNewSurface(device);
  anariSetParameter(device, floor_surface, "geometry", ANARI_GEOMETRY, &floor_geometry);
  anariSetParameter(device, floor_surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, floor_surface);

  /* A low sun from the left and behind: the shadow falls to the right, towards the viewer. */
  ANARILight light = anariNewLight(device, "directional");
  float direction[] = {0.9f, -1, 0.5f}, irradiance = 3.0f;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);

  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D volumes = anariNewArray1D(device, &volume, NULL, NULL, ANARI_VOLUME, 1);
  ANARIArray1D surfaces = anariNewArray1D(device, &floor_surface, NULL, NULL, ANARI_SURFACE, 1);
  ANARIArray1D lights = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
  anariSetParameter(device, world, "volume", ANARI_ARRAY1D, &volumes);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surfaces);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &lights);
  anariCommitParameters(device, world);

  float eye[] = {0.4f, 2.6f, 5.0f}, forward[] = {-0.1f, -0.45f, -1};
  ANARICamera camera = perspective_camera(device, eye, forward, 16.0f / 9.0f, 0.8f);

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[] = {0.35f, 0.5f, 0.75f, 1}, ambient = 0.25f;
  int samples = 16;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  anariSetParameter(device, renderer, "pixelSamples", ANARI_INT32, &samples);
  anariCommitParameters(device, renderer);

  int status = render_to_png(device, world, camera, renderer, 640, 360, 1, output);

  ANARIObject objects[] = {field,    opacity_array, volume,      positions, index,
                           floor_geometry, material, floor_surface, light, world,
                           volumes,  surfaces,      lights,      camera,    renderer};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
