/*
 * The environment and ambient occlusion in the default renderer, written to two PNG files:
 *   environment.png        a mirror, a rough gold and a glass sphere on a floor, lit by an
 *                          equirectangular sky (an hdri light with a sun) that is also seen
 *                          behind them, in their reflections and through the glass
 *   ambient_occlusion.png  spheres on a floor under the renderer's ambient light alone: contact
 *                          shadows where the spheres hide the sky from the floor
 *
 *   cc -std=c99 environment.c $(pkg-config --cflags --libs cavetrace) -lm -o environment
 *   ./environment [output directory]
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <cavetrace.h>

#include "example_support.h"

enum { SKY_WIDTH = 512, SKY_HEIGHT = 256 };

/* A sky: deep blue at the zenith to pale at the horizon, warm ground below, coloured stripes
 * low in the sky (so reflections are easy to read) and a small bright sun. Rows run from the
 * zenith (row 0) down; columns around the vertical axis. */
static ANARIArray2D sky_image(ANARIDevice device) {
  ANARIArray2D image =
      anariNewArray2D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, SKY_WIDTH, SKY_HEIGHT);
  float *texels = anariMapArray(device, image);
  const float pi = 3.14159265f;
  for (int row = 0; row < SKY_HEIGHT; row++)
    for (int column = 0; column < SKY_WIDTH; column++) {
      float theta = pi * (row + 0.5f) / SKY_HEIGHT;  /* from the zenith */
      float phi = 2 * pi * (column + 0.5f) / SKY_WIDTH;
      float elevation = pi / 2 - theta;
      float *t = texels + 3 * (row * SKY_WIDTH + column);
      if (elevation > 0) {
        float h = powf(1 - elevation / (pi / 2), 3);
        t[0] = 0.15f + 0.75f * h, t[1] = 0.3f + 0.6f * h, t[2] = 0.8f + 0.15f * h;
        /* Stripes of colour between 5 and 15 degrees up. */
        if (elevation > 0.09f && elevation < 0.26f) {
          int band = (int)(phi / (2 * pi) * 12);
          float colors[3][3] = {{0.9f, 0.2f, 0.15f}, {0.2f, 0.8f, 0.25f}, {0.95f, 0.8f, 0.2f}};
          if (band % 2 == 0)
            t[0] = colors[band / 2 % 3][0], t[1] = colors[band / 2 % 3][1],
            t[2] = colors[band / 2 % 3][2];
        }
      } else {
        float d = fminf(-elevation * 4, 1);
        t[0] = 0.35f - 0.15f * d, t[1] = 0.27f - 0.12f * d, t[2] = 0.2f - 0.1f * d;
      }
      /* The sun: about 3 degrees across, 40 degrees up. */
      float sun_theta = pi / 2 - 0.7f, sun_phi = 0.8f * pi;
      float cos_angle = cosf(theta) * cosf(sun_theta) +
                        sinf(theta) * sinf(sun_theta) * cosf(phi - sun_phi);
      if (cos_angle > cosf(0.027f))
        t[0] = 60, t[1] = 55, t[2] = 45;
    }
  anariUnmapArray(device, image);
  return image;
}

static ANARISurface sphere(ANARIDevice device, float x, float y, float z, float radius,
                           ANARIMaterial material) {
  float center[] = {x, y, z};
  ANARIArray1D centers = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 1);
  float *mapped = anariMapArray(device, centers);
  mapped[0] = center[0], mapped[1] = center[1], mapped[2] = center[2];
  anariUnmapArray(device, centers);
  ANARIGeometry geometry = anariNewGeometry(device, "sphere");
  anariSetParameter(device, geometry, "vertex.position", ANARI_ARRAY1D, &centers);
  anariSetParameter(device, geometry, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, geometry);
  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);
  anariRelease(device, centers);
  anariRelease(device, geometry);
  return surface;
}

static ANARISurface floor_surface(ANARIDevice device, ANARIMaterial material) {
  float corners[] = {-40, 0, -40, 40, 0, -40, 40, 0, 40, -40, 0, 40};
  uint32_t quad[] = {0, 1, 2, 3};
  ANARIArray1D positions = anariNewArray1D(device, corners, NULL, NULL, ANARI_FLOAT32_VEC3, 4);
  ANARIArray1D index = anariNewArray1D(device, quad, NULL, NULL, ANARI_UINT32_VEC4, 1);
  ANARIGeometry geometry = anariNewGeometry(device, "quad");
  anariSetParameter(device, geometry, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, geometry, "primitive.index", ANARI_ARRAY1D, &index);
  anariCommitParameters(device, geometry);
  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);
  anariRelease(device, positions);
  anariRelease(device, index);
  anariRelease(device, geometry);
  return surface;
}

static ANARIMaterial matte(ANARIDevice device, float r, float g, float b) {
  float color[] = {r, g, b};
  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, color);
  anariCommitParameters(device, material);
  return material;
}

static ANARIMaterial metal(ANARIDevice device, float r, float g, float b, float roughness) {
  float color[] = {r, g, b}, metallic = 1;
  ANARIMaterial material = anariNewMaterial(device, "physicallyBased");
  anariSetParameter(device, material, "baseColor", ANARI_FLOAT32_VEC3, color);
  anariSetParameter(device, material, "metallic", ANARI_FLOAT32, &metallic);
  anariSetParameter(device, material, "roughness", ANARI_FLOAT32, &roughness);
  anariCommitParameters(device, material);
  return material;
}

static ANARIMaterial glass(ANARIDevice device) {
  float white[] = {1, 1, 1}, zero = 0, one = 1, ior = 1.5f;
  ANARIMaterial material = anariNewMaterial(device, "physicallyBased");
  anariSetParameter(device, material, "baseColor", ANARI_FLOAT32_VEC3, white);
  anariSetParameter(device, material, "metallic", ANARI_FLOAT32, &zero);
  anariSetParameter(device, material, "roughness", ANARI_FLOAT32, &zero);
  anariSetParameter(device, material, "transmission", ANARI_FLOAT32, &one);
  anariSetParameter(device, material, "ior", ANARI_FLOAT32, &ior);
  anariSetParameter(device, material, "thickness", ANARI_FLOAT32, &one);
  anariCommitParameters(device, material);
  return material;
}

/* Renders `world` from `eye` towards `target` with `renderer`, `frames` accumulated frames,
 * and writes the colour to `path`. */
static int render(ANARIDevice device, ANARIWorld world, ANARIRenderer renderer, const float eye[3],
                  const float forward[3], int frames, const char *path) {
  ANARICamera camera = perspective_camera(device, eye, forward, 16.0f / 9.0f, 0.7f);
  int status = render_to_png(device, world, camera, renderer, 800, 450, frames, path);
  anariRelease(device, camera);
  return status;
}

static ANARIWorld world_of(ANARIDevice device, ANARISurface *surfaces, uint64_t count,
                           ANARILight light) {
  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D surface_array =
      anariNewArray1D(device, surfaces, NULL, NULL, ANARI_SURFACE, count);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surface_array);
  anariRelease(device, surface_array);
  if (light) {
    ANARIArray1D lights = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
    anariSetParameter(device, world, "light", ANARI_ARRAY1D, &lights);
    anariRelease(device, lights);
  }
  anariCommitParameters(device, world);
  return world;
}

int main(int argc, char **argv) {
  const char *directory = argc > 1 ? argv[1] : ".";
  char path[4096];
  int errors = 0, status = ANARI_STATUS_NO_ERROR;
  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &errors);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;

  /* 1. The environment: an hdri light (visible by default) with y up. */
  ANARIArray2D sky = sky_image(device);
  ANARILight light = anariNewLight(device, "hdri");
  float up[] = {0, 1, 0}, direction[] = {0, 0, -1};
  anariSetParameter(device, light, "radiance", ANARI_ARRAY2D, &sky);
  anariSetParameter(device, light, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariCommitParameters(device, light);
  ANARIMaterial materials[] = {matte(device, 0.6f, 0.6f, 0.6f), metal(device, 0.95f, 0.95f, 0.95f, 0),
                               metal(device, 1.0f, 0.75f, 0.3f, 0.3f), glass(device)};
  ANARISurface surfaces[] = {floor_surface(device, materials[0]),
                             sphere(device, -2.2f, 1, 0, 1, materials[1]),
                             sphere(device, 0, 1, 0, 1, materials[2]),
                             sphere(device, 2.2f, 1, 0, 1, materials[3])};
  ANARIWorld world = world_of(device, surfaces, 4, light);
  ANARIRenderer renderer = anariNewRenderer(device, "default");
  int samples = 16;
  anariSetParameter(device, renderer, "pixelSamples", ANARI_INT32, &samples);
  anariCommitParameters(device, renderer);
  float eye[] = {0, 1.6f, 7.5f}, forward[] = {0, -0.12f, -1};
  snprintf(path, sizeof path, "%s/environment.png", directory);
  status |= render(device, world, renderer, eye, forward, 4, path);

  /* 2. Ambient light alone: spheres of several sizes on a floor. */
  ANARIMaterial colors[] = {matte(device, 0.8f, 0.8f, 0.8f), matte(device, 0.85f, 0.3f, 0.25f),
                            matte(device, 0.3f, 0.6f, 0.9f), matte(device, 0.95f, 0.8f, 0.3f)};
  ANARISurface field[8];
  field[0] = floor_surface(device, colors[0]);
  float spheres[7][3] = {{-3, 1, -1}, {-0.6f, 0.6f, 0.4f}, {0.9f, 0.35f, 1.2f}, {2.4f, 1.1f, -0.6f},
                         {0.3f, 0.25f, 2.4f}, {-1.8f, 0.4f, 1.7f}, {1.1f, 0.15f, 2.8f}};
  for (int s = 0; s < 7; s++)
    field[s + 1] = sphere(device, spheres[s][0], spheres[s][1], spheres[s][2], spheres[s][1],
                          colors[1 + s % 3]);
  ANARIWorld ambient_world = world_of(device, field, 8, NULL);
  ANARIRenderer ambient_renderer = anariNewRenderer(device, "default");
  float ambient = 1, background[] = {1, 1, 1, 1};
  samples = 32;
  anariSetParameter(device, ambient_renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  anariSetParameter(device, ambient_renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, ambient_renderer, "pixelSamples", ANARI_INT32, &samples);
  anariCommitParameters(device, ambient_renderer);
  float high_eye[] = {0, 4.5f, 8.5f}, down[] = {0, -0.5f, -1};
  snprintf(path, sizeof path, "%s/ambient_occlusion.png", directory);
  status |= render(device, ambient_world, ambient_renderer, high_eye, down, 4, path);

  for (int i = 0; i < 4; i++)
    anariRelease(device, surfaces[i]), anariRelease(device, materials[i]),
        anariRelease(device, colors[i]);
  for (int i = 0; i < 8; i++)
    anariRelease(device, field[i]);
  ANARIObject objects[] = {sky, light, world, renderer, ambient_world, ambient_renderer};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
