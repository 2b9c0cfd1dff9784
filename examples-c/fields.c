/*
 * Scientific-visualization objects: on the left, three isosurfaces of one structured field
 * (wavy layers, one colour per isovalue through primitive.color); on the right, a volume over an
 * unstructured field of tetrahedra (a radial field, vertex-centred), rendered to a PNG file.
 *
 *   cc -std=c99 fields.c $(pkg-config --cflags --libs cavetrace) -lm -o fields
 *   ./fields [output.png]
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <cavetrace.h>

#include "example_support.h"

enum { GRID = 48, MESH = 13 };

/* Wavy layers: f = z + 0.25 sin(3x) cos(3y) over [-1, 1]^3 (x, y, z are grid coordinates). */
static ANARISpatialField layered_field(ANARIDevice device) {
  float *values = malloc(sizeof(float) * GRID * GRID * GRID);
  for (int k = 0; k < GRID; k++)
    for (int j = 0; j < GRID; j++)
      for (int i = 0; i < GRID; i++) {
        float x = -1 + 2.0f * i / (GRID - 1), y = -1 + 2.0f * j / (GRID - 1);
        float z = -1 + 2.0f * k / (GRID - 1);
        values[i + GRID * (j + GRID * k)] = z + 0.25f * sinf(3 * x) * cosf(3 * y);
      }
  ANARIArray3D data = anariNewArray3D(device, NULL, NULL, NULL, ANARI_FLOAT32, GRID, GRID, GRID);
  float *mapped = anariMapArray(device, data);
  for (int v = 0; v < GRID * GRID * GRID; v++)
    mapped[v] = values[v];
  anariUnmapArray(device, data);
  free(values);
  ANARISpatialField field = anariNewSpatialField(device, "structuredRegular");
  /* Placed at x in [-2.6, -0.6]; the field's own z axis points up (world y). */
  float origin[] = {-2.6f, -1, -1}, spacing[] = {2.0f / (GRID - 1), 2.0f / (GRID - 1),
                                                 2.0f / (GRID - 1)};
  anariSetParameter(device, field, "data", ANARI_ARRAY3D, &data);
  anariSetParameter(device, field, "origin", ANARI_FLOAT32_VEC3, origin);
  anariSetParameter(device, field, "spacing", ANARI_FLOAT32_VEC3, spacing);
  anariCommitParameters(device, field);
  anariRelease(device, data);
  return field;
}

/* A box of MESH^3 vertices split into six tetrahedra per cube, valued by the distance from a
 * point off the box's centre. */
static ANARISpatialField tetrahedra_field(ANARIDevice device) {
  const int n = MESH, cells = (MESH - 1) * (MESH - 1) * (MESH - 1);
  ANARIArray1D positions =
      anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, (uint64_t)n * n * n);
  ANARIArray1D values = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32,
                                        (uint64_t)n * n * n);
  ANARIArray1D index = anariNewArray1D(device, NULL, NULL, NULL, ANARI_UINT32,
                                       (uint64_t)cells * 6 * 4);
  ANARIArray1D types = anariNewArray1D(device, NULL, NULL, NULL, ANARI_UINT8,
                                       (uint64_t)cells * 6);
  float *p = anariMapArray(device, positions), *v = anariMapArray(device, values);
  for (int k = 0; k < n; k++)
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++) {
        float x = 0.6f + 2.0f * i / (n - 1), y = -1 + 2.0f * j / (n - 1);
        float z = -1 + 2.0f * k / (n - 1);
        int at = i + n * (j + n * k);
        p[3 * at] = x, p[3 * at + 1] = y, p[3 * at + 2] = z;
        float dx = x - 1.4f, dy = y - 0.2f, dz = z;
        v[at] = sqrtf(dx * dx + dy * dy + dz * dz);
      }
  anariUnmapArray(device, positions);
  anariUnmapArray(device, values);
  uint32_t *ix = anariMapArray(device, index);
  uint8_t *ty = anariMapArray(device, types);
  /* VTK hexahedron corner order, split along the diagonal 0-6 into six tetrahedra. */
  static const int pairs[6][2] = {{1, 2}, {2, 3}, {3, 7}, {7, 4}, {4, 5}, {5, 1}};
  int t = 0;
  for (int k = 0; k < n - 1; k++)
    for (int j = 0; j < n - 1; j++)
      for (int i = 0; i < n - 1; i++) {
        uint32_t c[8];
        for (int corner = 0; corner < 8; corner++) {
          int di = (corner == 1 || corner == 2 || corner == 5 || corner == 6);
          int dj = (corner == 2 || corner == 3 || corner == 6 || corner == 7);
          int dk = corner >= 4;
          c[corner] = (uint32_t)((i + di) + n * ((j + dj) + n * (k + dk)));
        }
        for (int s = 0; s < 6; s++, t++) {
          ix[4 * t] = c[0], ix[4 * t + 1] = c[pairs[s][0]];
          ix[4 * t + 2] = c[pairs[s][1]], ix[4 * t + 3] = c[6];
          ty[t] = 10; /* VTK_TETRA */
        }
      }
  anariUnmapArray(device, index);
  anariUnmapArray(device, types);
  ANARISpatialField field = anariNewSpatialField(device, "unstructured");
  anariSetParameter(device, field, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, field, "vertex.data", ANARI_ARRAY1D, &values);
  anariSetParameter(device, field, "index", ANARI_ARRAY1D, &index);
  anariSetParameter(device, field, "cell.type", ANARI_ARRAY1D, &types);
  anariCommitParameters(device, field);
  ANARIObject arrays[] = {positions, values, index, types};
  for (int a = 0; a < 4; a++)
    anariRelease(device, arrays[a]);
  return field;
}

int main(int argc, char **argv) {
  const char *output = argc > 1 ? argv[1] : "fields.png";
  int errors = 0;
  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &errors);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;

  /* Three isosurfaces of the layered field, one colour each (primitive id = isovalue index). */
  ANARISpatialField layers = layered_field(device);
  float isovalues[] = {-0.5f, 0.0f, 0.5f};
  float colors[] = {0.9f, 0.3f, 0.2f, 0.95f, 0.8f, 0.3f, 0.3f, 0.6f, 0.95f};
  ANARIArray1D isovalue_array = anariNewArray1D(device, isovalues, NULL, NULL, ANARI_FLOAT32, 3);
  ANARIArray1D color_array = anariNewArray1D(device, colors, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  ANARIGeometry isosurface = anariNewGeometry(device, "isosurface");
  anariSetParameter(device, isosurface, "field", ANARI_SPATIAL_FIELD, &layers);
  anariSetParameter(device, isosurface, "isovalue", ANARI_ARRAY1D, &isovalue_array);
  anariSetParameter(device, isosurface, "primitive.color", ANARI_ARRAY1D, &color_array);
  anariCommitParameters(device, isosurface);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariSetParameter(device, material, "color", ANARI_STRING, "color");
  anariCommitParameters(device, material);
  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &isosurface);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);
  /* The field's z runs up: turn the group so that it does. */
  ANARIGroup group = anariNewGroup(device);
  ANARIArray1D surfaces = anariNewArray1D(device, &surface, NULL, NULL, ANARI_SURFACE, 1);
  anariSetParameter(device, group, "surface", ANARI_ARRAY1D, &surfaces);
  anariCommitParameters(device, group);
  ANARIInstance instance = anariNewInstance(device, "transform");
  float turn[16] = {1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};
  anariSetParameter(device, instance, "group", ANARI_GROUP, &group);
  anariSetParameter(device, instance, "transform", ANARI_FLOAT32_MAT4, turn);
  anariCommitParameters(device, instance);

  /* The unstructured volume: near values opaque yellow, far ones faint blue. */
  ANARISpatialField tetrahedra = tetrahedra_field(device);
  float ramp[] = {1.0f, 0.85f, 0.2f, 0.9f, 0.3f, 0.2f, 0.2f, 0.4f, 1.0f};
  float opacity[] = {0.9f, 0.35f, 0.0f};
  float range[] = {0.0f, 1.2f}, unit = 0.25f;
  ANARIArray1D ramp_array = anariNewArray1D(device, ramp, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  ANARIArray1D opacity_array = anariNewArray1D(device, opacity, NULL, NULL, ANARI_FLOAT32, 3);
  ANARIVolume volume = anariNewVolume(device, "transferFunction1D");
  anariSetParameter(device, volume, "value", ANARI_SPATIAL_FIELD, &tetrahedra);
  anariSetParameter(device, volume, "color", ANARI_ARRAY1D, &ramp_array);
  anariSetParameter(device, volume, "opacity", ANARI_ARRAY1D, &opacity_array);
  anariSetParameter(device, volume, "valueRange", ANARI_FLOAT32_BOX1, range);
  anariSetParameter(device, volume, "unitDistance", ANARI_FLOAT32, &unit);
  anariCommitParameters(device, volume);

  ANARILight light = anariNewLight(device, "directional");
  float direction[] = {-0.4f, -1, -0.6f}, irradiance = 2.5f;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);

  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D instances = anariNewArray1D(device, &instance, NULL, NULL, ANARI_INSTANCE, 1);
  ANARIArray1D volumes = anariNewArray1D(device, &volume, NULL, NULL, ANARI_VOLUME, 1);
  ANARIArray1D lights = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
  anariSetParameter(device, world, "instance", ANARI_ARRAY1D, &instances);
  anariSetParameter(device, world, "volume", ANARI_ARRAY1D, &volumes);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &lights);
  anariCommitParameters(device, world);

  float eye[] = {0, 1.9f, 5.2f}, forward[] = {0, -0.36f, -1};
  ANARICamera camera = perspective_camera(device, eye, forward, 16.0f / 9.0f, 0.75f);

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[] = {0.08f, 0.08f, 0.1f, 1}, ambient = 0.4f;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  /* Ambient occlusion takes one ray per pixel sample: enough samples that the shadows between
   * the sheets settle instead of speckling (more samples, smoother; each costs a pass). */
  int32_t samples = 4;
  anariSetParameter(device, renderer, "pixelSamples", ANARI_INT32, &samples);
  anariCommitParameters(device, renderer);

  int status = render_to_png(device, world, camera, renderer, 800, 450, 1, output);

  ANARIObject objects[] = {layers,     isovalue_array, color_array, isosurface, material,
                           surface,    group,          surfaces,    instance,   tetrahedra,
                           ramp_array, opacity_array,  volume,      light,      world,
                           instances,  volumes,        lights,      camera,     renderer};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
