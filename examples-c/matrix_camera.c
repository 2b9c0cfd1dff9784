/*
 * The "matrix" camera: hand cavetrace the OpenGL view and projection matrices a VR application
 * already has. The matrices are built here the way gluLookAt and glFrustum build them
 * (column-major, as glm and OpenGL store them); each eye of a head-mounted display gets its own
 * view (the eye offset) and its own asymmetric frustum.
 *
 *   cc -std=c99 matrix_camera.c $(pkg-config --cflags --libs cavetrace) -lm -o matrix_camera
 *   ./matrix_camera [output-folder]     → left.png, right.png
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <cavetrace.h>

#include "example_support.h"

/* ----- OpenGL matrix math (column-major: m[column * 4 + row]) ---------------------------- */

static void normalize(float v[3]) {
  float length = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  for (int i = 0; i < 3; i++)
    v[i] /= length;
}

static void cross(const float a[3], const float b[3], float out[3]) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

static float dot(const float a[3], const float b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* gluLookAt: the view matrix of an eye at `eye` looking at `center`. */
static void look_at(const float eye[3], const float center[3], const float up[3], float m[16]) {
  float f[3] = {center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]};
  normalize(f);
  float s[3], u[3];
  cross(f, up, s);
  normalize(s);
  cross(s, f, u);
  const float view[16] = {s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0,
                          s[2], u[2], -f[2], 0, -dot(s, eye), -dot(u, eye), dot(f, eye), 1};
  memcpy(m, view, sizeof view);
}

/* glFrustum: a perspective projection whose near plane spans [l,r]×[b,t] at distance n. */
static void frustum(float l, float r, float b, float t, float n, float f, float m[16]) {
  const float proj[16] = {2 * n / (r - l),       0, 0, 0, 0, 2 * n / (t - b), 0, 0,
                          (r + l) / (r - l), (t + b) / (t - b), -(f + n) / (f - n), -1,
                          0, 0, -2 * f * n / (f - n), 0};
  memcpy(m, proj, sizeof proj);
}

/* ----- a small scene --------------------------------------------------------------------- */

static ANARIObject make_scene(ANARIDevice device) {
  /* Floor: one quad, 6 m square at y = 0. */
  float floor_xyz[] = {-3, 0, 3, 3, 0, 3, 3, 0, -3, -3, 0, -3};
  ANARIArray1D floor_positions =
      anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 4);
  memcpy(anariMapArray(device, floor_positions), floor_xyz, sizeof floor_xyz);
  anariUnmapArray(device, floor_positions);
  ANARIGeometry floor = anariNewGeometry(device, "quad");
  anariSetParameter(device, floor, "vertex.position", ANARI_ARRAY1D, &floor_positions);
  anariCommitParameters(device, floor);

  /* Three spheres with per-sphere colours. */
  float centers[] = {-0.8f, 0.5f, -1, 0, 0.7f, -1.6f, 0.8f, 0.4f, -0.6f};
  float colors[] = {0.9f, 0.2f, 0.1f, 1, 0.2f, 0.8f, 0.3f, 1, 0.2f, 0.3f, 0.9f, 1};
  float radii[] = {0.4f, 0.6f, 0.35f};
  ANARIArray1D center_array = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  memcpy(anariMapArray(device, center_array), centers, sizeof centers);
  anariUnmapArray(device, center_array);
  ANARIArray1D color_array = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32_VEC4, 3);
  memcpy(anariMapArray(device, color_array), colors, sizeof colors);
  anariUnmapArray(device, color_array);
  ANARIArray1D radius_array = anariNewArray1D(device, NULL, NULL, NULL, ANARI_FLOAT32, 3);
  memcpy(anariMapArray(device, radius_array), radii, sizeof radii);
  anariUnmapArray(device, radius_array);
  ANARIGeometry spheres = anariNewGeometry(device, "sphere");
  anariSetParameter(device, spheres, "vertex.position", ANARI_ARRAY1D, &center_array);
  anariSetParameter(device, spheres, "vertex.color", ANARI_ARRAY1D, &color_array);
  anariSetParameter(device, spheres, "vertex.radius", ANARI_ARRAY1D, &radius_array);
  anariCommitParameters(device, spheres);

  ANARIMaterial grey = anariNewMaterial(device, "matte");
  anariCommitParameters(device, grey);
  ANARIMaterial colored = anariNewMaterial(device, "matte");
  anariSetParameter(device, colored, "color", ANARI_STRING, "color");
  anariCommitParameters(device, colored);

  ANARISurface surfaces[2] = {anariNewSurface(device), anariNewSurface(device)};
  anariSetParameter(device, surfaces[0], "geometry", ANARI_GEOMETRY, &floor);
  anariSetParameter(device, surfaces[0], "material", ANARI_MATERIAL, &grey);
  anariSetParameter(device, surfaces[1], "geometry", ANARI_GEOMETRY, &spheres);
  anariSetParameter(device, surfaces[1], "material", ANARI_MATERIAL, &colored);
  anariCommitParameters(device, surfaces[0]);
  anariCommitParameters(device, surfaces[1]);

  ANARILight light = anariNewLight(device, "directional");
  float direction[] = {-0.4f, -1, -0.3f};
  float irradiance = 1.8f;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);

  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D surface_array = anariNewArray1D(device, surfaces, NULL, NULL, ANARI_SURFACE, 2);
  ANARIArray1D light_array = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surface_array);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &light_array);
  anariCommitParameters(device, world);

  /* The world keeps what it uses; drop the application's references. */
  ANARIObject objects[] = {floor_positions, floor,       center_array, color_array,
                           radius_array,    spheres,     grey,         colored,
                           surfaces[0],     surfaces[1], light,        surface_array,
                           light_array};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  return world;
}

int main(int argc, char **argv) {
  const char *folder = argc > 1 ? argv[1] : ".";
  int errors = 0;
  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &errors);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;
  ANARIWorld world = make_scene(device);

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[] = {0.55f, 0.65f, 0.8f, 1}, ambient = 0.5f;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  anariCommitParameters(device, renderer);

  const uint32_t width = 640, height = 720; /* one eye of a headset panel */
  const float ipd = 0.0635f, near = 0.05f, far = 100.0f;
  const float head[3] = {0, 1.6f, 1.5f}, target[3] = {0, 0.6f, -1}, up[3] = {0, 1, 0};
  /* A headset's per-eye field of view: tangents of the half-angles, wider to the outside. */
  const float inner = 0.9f, outer = 1.1f, lower = 1.1f, upper = 1.0f;

  ANARIFrame frame = anariNewFrame(device);
  uint32_t size[] = {width, height};
  ANARIDataType color_type = ANARI_UFIXED8_RGBA_SRGB;
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(device, frame, "channel.color", ANARI_DATA_TYPE, &color_type);
  anariSetParameter(device, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(device, frame, "renderer", ANARI_RENDERER, &renderer);

  const char *names[2] = {"left", "right"};
  int status = ANARI_STATUS_NO_ERROR;
  for (int eye_index = 0; eye_index < 2; eye_index++) {
    /* The eye sits half an IPD to the side of the head, looking the same way. */
    float forward[3] = {target[0] - head[0], target[1] - head[1], target[2] - head[2]};
    normalize(forward);
    float right[3];
    cross(forward, up, right);
    normalize(right);
    float side = eye_index == 0 ? -0.5f * ipd : 0.5f * ipd;
    float eye[3], center[3];
    for (int i = 0; i < 3; i++) {
      eye[i] = head[i] + side * right[i];
      center[i] = eye[i] + forward[i];
    }
    float view[16], proj[16];
    look_at(eye, center, up, view);
    float l = eye_index == 0 ? -outer : -inner, r = eye_index == 0 ? inner : outer;
    frustum(l * near, r * near, -lower * near, upper * near, near, far, proj);

    /* Listing 5: the matrix camera takes the application's matrices as they are. */
    ANARICamera cam = anariNewCamera(device, "matrix");
    anariSetParameter(device, cam, "view", ANARI_FLOAT32_MAT4, view);
    anariSetParameter(device, cam, "proj", ANARI_FLOAT32_MAT4, proj);
    anariCommitParameters(device, cam);

    anariSetParameter(device, frame, "camera", ANARI_CAMERA, &cam);
    anariCommitParameters(device, frame);
    anariRenderFrame(device, frame);
    anariFrameReady(device, frame, ANARI_WAIT);
    char path[512];
    snprintf(path, sizeof path, "%s/%s.png", folder, names[eye_index]);
    int written = cavetraceWriteFramePNG(device, frame, "channel.color", path);
    if (written == ANARI_STATUS_NO_ERROR)
      printf("wrote %s\n", path);
    else
      status = written;
    anariRelease(device, cam);
  }

  anariRelease(device, frame);
  anariRelease(device, renderer);
  anariRelease(device, world);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
