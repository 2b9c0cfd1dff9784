/*
 * A five-sided CAVE (front, left, right, floor, ceiling; 3 m cube) with a tracked head walking a
 * short path. For every head position, both eyes of every wall are rendered twice:
 *
 *   - with the "offAxis" camera: the wall's corners, the tracked head position and its right
 *     vector; stereoMode "sideBySide" renders both eyes into one frame;
 *   - with the "matrix" camera: per eye, the view and projection matrices an OpenGL CAVE
 *     renderer would use, from cavetraceOffAxisMatrices.
 *
 * Both show the same picture up to the last bits of their rays: the program prints, per head
 * position, how many pixels differ and why (one 8-bit rounding step; a silhouette where the two
 * rays hit different things; a shadow or reflection ray from the same hit grazing an edge), and
 * the time each camera took. The scene follows Zellmann and Amstutz's demo: a cloud of 10,000
 * spheres coloured by their distance from the cloud's centre (a per-vertex attribute through an
 * image1D sampler), a floor with a grid, a mirror sphere (physicallyBased, metallic 1,
 * roughness 0), and a ring of twelve coloured lanterns under the ceiling.
 *
 * Output, per head position k, in <folder>/k/: <wall>_<eye>_offAxis.png and
 * <wall>_<eye>_matrix.png for the five walls and two eyes, unfolded_<eye>.png (the CAVE opened
 * out as a cross), front_anaglyph.png (red-cyan) and front_stereo_pair.png (side by side).
 *
 * With a frame-time budget in milliseconds (ANARI_CAVETRACE_FRAME_BUDGET), the front wall's
 * stereo pair is also rendered as a head-tracked application would: one budgeted render per
 * head position (printed: its time and the fraction of pixels traced; written:
 * front_budget_pair.png), then, with the head still at the last position, renders until the
 * image is complete.
 *
 * Then two tracked viewers share the CAVE (ANARI_CAVETRACE_CAMERA_MULTI_VIEWER): A stands left
 * and looks at the front wall, B stands right and looks into the corner of the front and right
 * walls; their cones overlap on the front wall's right half. Written to <folder>/viewers/:
 * unfolded_A_alone.png and unfolded_B_alone.png (one tracked viewer, as before),
 * unfolded_perPixel.png, unfolded_tiles.png and unfolded_zones.png (both viewers, one file per
 * viewerMode), and unfolded_weights.png: each pixel's viewer weights in false colour (red A,
 * green B, grey where neither viewer's cone reaches and the heads' mean is used).
 *
 * Last, stereo on the front wall, written to <folder>/stereo/ (the head 2.7 m from the wall):
 *   - the time of a side-by-side pair against one eye (printed);
 *   - the parallax (ANARI_CAVETRACE_FRAME_CHANNEL_PARALLAX) in false colour, blue in front of
 *     the wall, green behind it, red beyond the comfort limit of 0.03 × the head's distance to
 *     the wall: front_parallax_comfortable.png from this head (all within the limit) and
 *     front_parallax_too_close.png from a head 1.8 m from the wall, where the sphere cloud
 *     comes within half a metre of the eyes (printed: the range and the share beyond);
 *   - a mirror on the wall reflecting white bars behind the viewer, lit per eye and from the
 *     point between the eyes (ANARI_CAVETRACE_RENDERER_STEREO_LIGHTING), through a 1 m window
 *     around the mirror: mirror_perEye_pair.png, mirror_cyclopean_pair.png,
 *     mirror_perEye_anaglyph.png, mirror_cyclopean_anaglyph.png and
 *     mirror_difference_pair.png (the difference, four times brighter). Per eye the bars stand
 *     at different places in the two eyes (the reflection lies far behind the mirror: red and
 *     cyan bars in the anaglyph); cyclopean they stand at the same place (the reflection lies
 *     on the mirror: grey bars);
 *   - the front wall for passive 3D displays and red-cyan glasses
 *     (ANARI_CAVETRACE_STEREO_INTERLEAVED): front_rowInterleaved.png, front_checkerboard.png,
 *     front_anaglyph.png; and as a light-field display would show it (lightField camera,
 *     sample calibration, 45 views): front_hologram.png, and the same display's 9×5 quilt:
 *     front_quilt.png.
 *
 * Then the whole scene around the CAVE's centre, written to <folder>/panorama/: a 360°
 * equirectangular image (omnidirectional camera), its omni-directional stereo pair for 360°
 * video, and a tilted planetarium dome (fisheye camera) from its centre and from a tracked head
 * (see panoramas()).
 *
 *   cc -std=c99 cave.c $(pkg-config --cflags --libs cavetrace) -lm -o cave
 *   ./cave [folder (default out/cave)] [wall resolution (default 256)] [head positions (4)]
 *          [budget in ms (default 0: none)]
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include <cavetrace.h>

#include "example_support.h"

#define WALLS 5
#define EYES 2
#define IPD 0.0635f
#define NEAR 0.05f
#define FAR 100.0f

/* ----- the CAVE -------------------------------------------------------------------------- */

/* CAVE space: meters, floor centre at the origin, x right, y up, the front wall at z = -1.5.
 * Each screen's lower-left, lower-right and upper-right corners as seen from inside. */
typedef struct {
  const char *name;
  float lower_left[3], lower_right[3], upper_right[3];
  int cell_x, cell_y; /* where the wall goes in the unfolded cross (cells from the bottom) */
} Wall;

static const Wall WALL[WALLS] = {
    {"front", {-1.5f, 0, -1.5f}, {1.5f, 0, -1.5f}, {1.5f, 3, -1.5f}, 1, 1},
    {"left", {-1.5f, 0, 1.5f}, {-1.5f, 0, -1.5f}, {-1.5f, 3, -1.5f}, 0, 1},
    {"right", {1.5f, 0, -1.5f}, {1.5f, 0, 1.5f}, {1.5f, 3, 1.5f}, 2, 1},
    {"floor", {-1.5f, 0, 1.5f}, {1.5f, 0, 1.5f}, {1.5f, 0, -1.5f}, 1, 0},
    {"ceiling", {-1.5f, 3, -1.5f}, {1.5f, 3, -1.5f}, {1.5f, 3, 1.5f}, 1, 2},
};

static const char *EYE_NAME[EYES] = {"left", "right"};

/* Where the matrix and the offAxis images of one head position differ. Both cameras make the
 * same rays from different numbers (the offAxis camera from the corners and the head in double
 * precision, the matrix camera from single-precision matrices), so ray origins and directions
 * differ in their last bits. Most pixels come out identical; a few shading values round to the
 * neighbouring 8-bit step; rarely, a ray passes so close to an edge that one camera's ray hits
 * it and the other's does not. That edge is either on the camera ray itself (a silhouette: the
 * two pixels see different things) or on a shadow or reflection ray from the same surface
 * point (the depths agree, the shading does not). */
typedef struct {
  size_t pixels, rounding, silhouette, secondary;
  int largest, largest_wall, largest_eye;
  uint32_t largest_x, largest_y;
  int largest_is_silhouette;
} Comparison;

/* ----- status and small utilities -------------------------------------------------------- */

static int error_count;

static double seconds_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* mkdir -p: creates every missing folder of `path`; returns 0 on success. */
static int make_folders(const char *path) {
  char partial[1024];
  size_t length = strlen(path);
  if (length >= sizeof partial)
    return -1;
  for (size_t i = 1; i <= length; i++)
    if (path[i] == '/' || path[i] == '\0') {
      memcpy(partial, path, i);
      partial[i] = '\0';
      if (mkdir(partial, 0755) != 0 && errno != EEXIST)
        return -1;
    }
  return 0;
}

static uint32_t random_state = 0x12345678u;

/* xorshift32 in [0, 1): the same cloud on every run. */
static float random_unit(void) {
  random_state ^= random_state << 13;
  random_state ^= random_state >> 17;
  random_state ^= random_state << 5;
  return (float)(random_state >> 8) / 16777216.0f;
}

/* A managed array filled with a copy of `data`. */
static ANARIArray1D array_of(ANARIDevice device, ANARIDataType type, const void *data,
                             uint64_t count, size_t element_size) {
  ANARIArray1D array = anariNewArray1D(device, NULL, NULL, NULL, type, count);
  void *memory = anariMapArray(device, array);
  if (memory)
    memcpy(memory, data, (size_t)count * element_size);
  anariUnmapArray(device, array);
  return array;
}

static ANARISurface surface_of(ANARIDevice device, ANARIGeometry geometry,
                               ANARIMaterial material) {
  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);
  anariRelease(device, geometry);
  anariRelease(device, material);
  return surface;
}

static ANARIMaterial matte(ANARIDevice device, float r, float g, float b) {
  ANARIMaterial material = anariNewMaterial(device, "matte");
  float color[3] = {r, g, b};
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, color);
  anariCommitParameters(device, material);
  return material;
}

/* ----- the scene ------------------------------------------------------------------------- */

/* 10,000 spheres in a ball, coloured through a colour map by distance from the centre. */
static ANARISurface sphere_cloud(ANARIDevice device) {
  enum { COUNT = 10000 };
  const float center[3] = {0, 1.5f, -1.1f}, radius = 0.9f;
  float *positions = malloc(sizeof(float) * 3 * COUNT);
  float *distance = malloc(sizeof(float) * COUNT);
  for (int i = 0; i < COUNT; i++) {
    float p[3], d2;
    do {
      for (int k = 0; k < 3; k++)
        p[k] = 2 * random_unit() - 1;
      d2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    } while (d2 > 1);
    for (int k = 0; k < 3; k++)
      positions[3 * i + k] = center[k] + radius * p[k];
    distance[i] = sqrtf(d2); /* 0 at the centre, 1 at the rim */
  }
  ANARIGeometry spheres = anariNewGeometry(device, "sphere");
  ANARIArray1D position_array = array_of(device, ANARI_FLOAT32_VEC3, positions, COUNT, 12);
  ANARIArray1D distance_array = array_of(device, ANARI_FLOAT32, distance, COUNT, 4);
  float sphere_radius = 0.014f;
  anariSetParameter(device, spheres, "vertex.position", ANARI_ARRAY1D, &position_array);
  anariSetParameter(device, spheres, "vertex.attribute0", ANARI_ARRAY1D, &distance_array);
  anariSetParameter(device, spheres, "radius", ANARI_FLOAT32, &sphere_radius);
  anariCommitParameters(device, spheres);
  anariRelease(device, position_array);
  anariRelease(device, distance_array);
  free(positions);
  free(distance);

  /* Hot at the centre, cool at the rim. */
  const float colormap[5][3] = {
      {1.0f, 0.95f, 0.4f}, {1.0f, 0.5f, 0.1f}, {0.85f, 0.1f, 0.3f},
      {0.4f, 0.1f, 0.6f},  {0.1f, 0.2f, 0.7f}};
  ANARIArray1D image = array_of(device, ANARI_FLOAT32_VEC3, colormap, 5, 12);
  ANARISampler sampler = anariNewSampler(device, "image1D");
  anariSetParameter(device, sampler, "image", ANARI_ARRAY1D, &image);
  anariSetParameter(device, sampler, "inAttribute", ANARI_STRING, "attribute0");
  anariSetParameter(device, sampler, "filter", ANARI_STRING, "linear");
  anariSetParameter(device, sampler, "wrapMode", ANARI_STRING, "clampToEdge");
  anariCommitParameters(device, sampler);
  anariRelease(device, image);

  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariSetParameter(device, material, "color", ANARI_SAMPLER, &sampler);
  anariCommitParameters(device, material);
  anariRelease(device, sampler);
  return surface_of(device, spheres, material);
}

/* A 12 m square floor at y = 0 (it continues beyond the CAVE's walls). */
static ANARISurface floor_plane(ANARIDevice device) {
  const float corners[4][3] = {{-6, 0, 6}, {6, 0, 6}, {6, 0, -6}, {-6, 0, -6}};
  ANARIGeometry quad = anariNewGeometry(device, "quad");
  ANARIArray1D positions = array_of(device, ANARI_FLOAT32_VEC3, corners, 4, 12);
  anariSetParameter(device, quad, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, quad);
  anariRelease(device, positions);
  return surface_of(device, quad, matte(device, 0.22f, 0.22f, 0.25f));
}

/* Grid lines every 0.5 m on the floor, as thin cylinders. */
static ANARISurface floor_grid(ANARIDevice device) {
  enum { LINES = 25 };
  float ends[2 * LINES][2][3];
  for (int i = 0; i < LINES; i++) {
    float at = -6 + 0.5f * (float)i;
    const float along_x[2][3] = {{-6, 0.004f, at}, {6, 0.004f, at}};
    const float along_z[2][3] = {{at, 0.004f, -6}, {at, 0.004f, 6}};
    memcpy(ends[i], along_x, sizeof along_x);
    memcpy(ends[LINES + i], along_z, sizeof along_z);
  }
  ANARIGeometry cylinders = anariNewGeometry(device, "cylinder");
  ANARIArray1D positions = array_of(device, ANARI_FLOAT32_VEC3, ends, 4 * LINES, 12);
  float radius = 0.006f;
  anariSetParameter(device, cylinders, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, cylinders, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, cylinders);
  anariRelease(device, positions);
  return surface_of(device, cylinders, matte(device, 0.75f, 0.75f, 0.8f));
}

/* A metal sphere: roughness 0 is a mirror; more blends its reflection with a diffuse look. */
static ANARISurface metal_sphere(ANARIDevice device, const float center[3], float radius,
                                 const float base[3], float roughness) {
  ANARIGeometry sphere = anariNewGeometry(device, "sphere");
  ANARIArray1D position = array_of(device, ANARI_FLOAT32_VEC3, center, 1, 12);
  anariSetParameter(device, sphere, "vertex.position", ANARI_ARRAY1D, &position);
  anariSetParameter(device, sphere, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, sphere);
  anariRelease(device, position);
  ANARIMaterial metal = anariNewMaterial(device, "physicallyBased");
  float metallic = 1;
  anariSetParameter(device, metal, "baseColor", ANARI_FLOAT32_VEC3, base);
  anariSetParameter(device, metal, "metallic", ANARI_FLOAT32, &metallic);
  anariSetParameter(device, metal, "roughness", ANARI_FLOAT32, &roughness);
  anariCommitParameters(device, metal);
  return surface_of(device, sphere, metal);
}

/* Twelve lanterns in a ring under the ceiling, coloured round the colour wheel, so the ceiling
 * shows something and the unfolded CAVE shows which way round it is (red towards the front
 * wall, then yellow, green, cyan, blue and magenta counter-clockwise seen from above). */
static ANARISurface lantern_ring(ANARIDevice device) {
  enum { COUNT = 12 };
  float positions[COUNT][3], colors[COUNT][3];
  for (int i = 0; i < COUNT; i++) {
    float angle = 6.2831853f * (float)i / COUNT; /* 0: straight towards the front wall */
    positions[i][0] = -1.05f * sinf(angle);
    positions[i][1] = 2.7f;
    positions[i][2] = -0.2f - 1.05f * cosf(angle);
    float hue = 6 * (float)i / COUNT; /* red, yellow, green, cyan, blue, magenta */
    for (int k = 0; k < 3; k++) {
      float h = fmodf(hue + 4 * (float)k, 6); /* distance round the wheel from this primary */
      float d = fminf(h, 6 - h);
      colors[i][k] = 0.1f + 0.85f * fmaxf(0, fminf(1, 2 - d));
    }
  }
  ANARIGeometry spheres = anariNewGeometry(device, "sphere");
  ANARIArray1D position_array = array_of(device, ANARI_FLOAT32_VEC3, positions, COUNT, 12);
  ANARIArray1D color_array = array_of(device, ANARI_FLOAT32_VEC3, colors, COUNT, 12);
  float radius = 0.11f;
  anariSetParameter(device, spheres, "vertex.position", ANARI_ARRAY1D, &position_array);
  anariSetParameter(device, spheres, "vertex.color", ANARI_ARRAY1D, &color_array);
  anariSetParameter(device, spheres, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, spheres);
  anariRelease(device, position_array);
  anariRelease(device, color_array);
  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariSetParameter(device, material, "color", ANARI_STRING, "color");
  anariCommitParameters(device, material);
  return surface_of(device, spheres, material);
}

static ANARISurface mirror_sphere(ANARIDevice device) {
  const float center[3] = {0.85f, 0.55f, -0.7f}, base[3] = {0.95f, 0.95f, 0.95f};
  return metal_sphere(device, center, 0.45f, base, 0);
}

/* A world of `count` surfaces (released here) and one directional light. */
static ANARIWorld world_of(ANARIDevice device, ANARISurface *surfaces, int count) {
  ANARILight light = anariNewLight(device, "directional");
  float direction[3] = {0.3f, -1, -0.5f}, irradiance = 2.5f;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);
  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D surface_array =
      array_of(device, ANARI_SURFACE, surfaces, (uint64_t)count, sizeof(ANARIObject));
  ANARIArray1D light_array = array_of(device, ANARI_LIGHT, &light, 1, sizeof(ANARIObject));
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surface_array);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &light_array);
  anariCommitParameters(device, world);
  for (int i = 0; i < count; i++)
    anariRelease(device, surfaces[i]);
  anariRelease(device, light);
  anariRelease(device, surface_array);
  anariRelease(device, light_array);
  return world;
}

static ANARIWorld make_world(ANARIDevice device) {
  ANARISurface surfaces[5] = {sphere_cloud(device), floor_plane(device), floor_grid(device),
                              mirror_sphere(device), lantern_ring(device)};
  return world_of(device, surfaces, 5);
}

/* A flat mirror hung on the front wall (5 cm in front of it, 0.8 m square, its centre at eye
 * height) facing into the CAVE, and behind the viewer, 1.8 m beyond the head, a dark board
 * with white vertical bars for the mirror to show; the floor and its grid. */
static ANARIWorld mirror_world(ANARIDevice device) {
  const float mirror_corners[4][3] = {
      {-0.4f, 1.1f, -1.45f}, {0.4f, 1.1f, -1.45f}, {0.4f, 1.9f, -1.45f}, {-0.4f, 1.9f, -1.45f}};
  ANARIGeometry mirror = anariNewGeometry(device, "quad");
  ANARIArray1D positions = array_of(device, ANARI_FLOAT32_VEC3, mirror_corners, 4, 12);
  anariSetParameter(device, mirror, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, mirror);
  anariRelease(device, positions);
  ANARIMaterial silver = anariNewMaterial(device, "physicallyBased");
  float base[3] = {0.92f, 0.92f, 0.92f}, metallic = 1, roughness = 0;
  anariSetParameter(device, silver, "baseColor", ANARI_FLOAT32_VEC3, base);
  anariSetParameter(device, silver, "metallic", ANARI_FLOAT32, &metallic);
  anariSetParameter(device, silver, "roughness", ANARI_FLOAT32, &roughness);
  anariCommitParameters(device, silver);

  /* The board faces the mirror (−z); the bars, 10 cm wide every 30 cm, 1 cm in front of it. */
  enum { BARS = 11 };
  const float board_corners[4][3] = {
      {1.8f, 0.0f, 3.0f}, {-1.8f, 0.0f, 3.0f}, {-1.8f, 2.8f, 3.0f}, {1.8f, 2.8f, 3.0f}};
  float bar_corners[4 * BARS][3];
  for (int i = 0; i < BARS; i++) {
    float x = -1.5f + 0.3f * (float)i;
    const float corners[4][3] = {
        {x + 0.1f, 0.1f, 2.99f}, {x, 0.1f, 2.99f}, {x, 2.7f, 2.99f}, {x + 0.1f, 2.7f, 2.99f}};
    memcpy(bar_corners[4 * i], corners, sizeof corners);
  }
  ANARIGeometry board = anariNewGeometry(device, "quad");
  positions = array_of(device, ANARI_FLOAT32_VEC3, board_corners, 4, 12);
  anariSetParameter(device, board, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, board);
  anariRelease(device, positions);
  ANARIGeometry bars = anariNewGeometry(device, "quad");
  positions = array_of(device, ANARI_FLOAT32_VEC3, bar_corners, 4 * BARS, 12);
  anariSetParameter(device, bars, "vertex.position", ANARI_ARRAY1D, &positions);
  anariCommitParameters(device, bars);
  anariRelease(device, positions);

  ANARISurface surfaces[5] = {floor_plane(device), floor_grid(device),
                              surface_of(device, mirror, silver),
                              surface_of(device, board, matte(device, 0.05f, 0.05f, 0.08f)),
                              surface_of(device, bars, matte(device, 1.0f, 1.0f, 1.0f))};
  return world_of(device, surfaces, 5);
}

/* ----- images ---------------------------------------------------------------------------- */

typedef unsigned char Rgba[4];

/* Copies a w×h block of a frame's sRGB colour channel starting at column x0. */
static void copy_block(const unsigned char *frame, uint32_t frame_width, uint32_t x0,
                       uint32_t w, uint32_t h, unsigned char *out) {
  for (uint32_t y = 0; y < h; y++)
    memcpy(out + 4 * (size_t)y * w, frame + 4 * ((size_t)y * frame_width + x0), 4 * (size_t)w);
}

/* Adds one wall and eye to a comparison: colours (RGBA), depths and primitive ids of the
 * matrix image (m_*) and the offAxis image (o_*), n×n pixels each. */
static void compare_images(Comparison *c, int wall, int eye, uint32_t n,
                           const unsigned char *m_rgba, const float *m_depth,
                           const uint32_t *m_id, const unsigned char *o_rgba,
                           const float *o_depth, const uint32_t *o_id) {
  for (size_t i = 0; i < (size_t)n * n; i++) {
    int d = 0;
    for (int k = 0; k < 3; k++) {
      int channel = abs((int)m_rgba[4 * i + k] - (int)o_rgba[4 * i + k]);
      d = channel > d ? channel : d;
    }
    c->pixels++;
    if (d == 0)
      continue;
    /* The same hit: the same primitive at the same distance (to float precision). */
    int same_hit = m_id[i] == o_id[i] &&
                   (m_depth[i] == o_depth[i] ||
                    fabsf(m_depth[i] - o_depth[i]) <= 1e-4f * fabsf(m_depth[i]));
    if (d == 1)
      c->rounding++;
    else if (same_hit)
      c->secondary++;
    else
      c->silhouette++;
    if (d > c->largest) {
      c->largest = d, c->largest_wall = wall, c->largest_eye = eye;
      c->largest_x = (uint32_t)(i % n), c->largest_y = (uint32_t)(i / n);
      c->largest_is_silhouette = !same_hit;
    }
  }
}

/* Copies a w×h block of a frame's FLOAT32 or UINT32 channel starting at column x0. */
static void copy_block32(const void *frame, uint32_t frame_width, uint32_t x0, uint32_t w,
                         uint32_t h, void *out) {
  for (uint32_t y = 0; y < h; y++)
    memcpy((char *)out + 4 * (size_t)y * w,
           (const char *)frame + 4 * ((size_t)y * frame_width + x0), 4 * (size_t)w);
}

static int write_png(ANARIDevice device, const char *folder, const char *name, uint32_t w,
                     uint32_t h, const unsigned char *rgba) {
  char path[2048];
  snprintf(path, sizeof path, "%s/%s", folder, name);
  return cavetraceWriteImagePNG(device, path, w, h, ANARI_UFIXED8_RGBA_SRGB, rgba) ==
         ANARI_STATUS_NO_ERROR;
}

/* The CAVE opened out as a cross (rows bottom to top, like ANARI frames). */
static void unfold(unsigned char *const walls[WALLS], uint32_t n, unsigned char *out) {
  memset(out, 0, 4 * (size_t)9 * n * n);
  for (size_t i = 3; i < 4 * (size_t)9 * n * n; i += 4)
    out[i] = 255;
  for (int w = 0; w < WALLS; w++)
    for (uint32_t y = 0; y < n; y++)
      memcpy(out + 4 * ((size_t)(WALL[w].cell_y * n + y) * 3 * n + (size_t)WALL[w].cell_x * n),
             walls[w] + 4 * (size_t)y * n, 4 * (size_t)n);
}

/* Red from the left eye, green and blue from the right. */
static void anaglyph(const unsigned char *left, const unsigned char *right, size_t pixels,
                     unsigned char *out) {
  for (size_t i = 0; i < pixels; i++) {
    out[4 * i + 0] = left[4 * i + 0];
    out[4 * i + 1] = right[4 * i + 1];
    out[4 * i + 2] = right[4 * i + 2];
    out[4 * i + 3] = 255;
  }
}

/* ----- two viewers ----------------------------------------------------------------------- */

/* Head, gaze target and right vector of the two viewers. */
static const float VIEWER_HEAD[2][3] = {{-0.5f, 1.70f, 0.3f}, {0.6f, 1.60f, -0.2f}};
static const float VIEWER_TARGET[2][3] = {{-0.5f, 1.4f, -1.5f}, {1.5f, 1.3f, -1.4f}};
static const float VIEWER_RIGHT[2][3] = {{1, 0, 0}, {0.8f, 0, -0.6f}};
#define VIEWER_CUTOFF 0.785398f /* π/4, the default viewerCutoffAngle */

/* Viewer i's linear weight at screen point p: 1 − a/c inside its cone, with a the angle between
 * its gaze and the direction to p (the device's definition, written out). */
static float viewer_weight(int i, const float p[3]) {
  float gaze[3], to[3], dot = 0, gaze_length = 0, to_length = 0;
  for (int k = 0; k < 3; k++) {
    gaze[k] = VIEWER_TARGET[i][k] - VIEWER_HEAD[i][k];
    to[k] = p[k] - VIEWER_HEAD[i][k];
    dot += gaze[k] * to[k];
    gaze_length += gaze[k] * gaze[k];
    to_length += to[k] * to[k];
  }
  float angle = acosf(fmaxf(-1, fminf(1, dot / sqrtf(gaze_length * to_length))));
  return fmaxf(0, 1 - angle / VIEWER_CUTOFF);
}

/* False colour of the normalised weights over a wall's n×n pixel centres. */
static void weight_image(const Wall *wall, uint32_t n, unsigned char *out) {
  for (uint32_t y = 0; y < n; y++)
    for (uint32_t x = 0; x < n; x++) {
      float s = ((float)x + 0.5f) / (float)n, t = ((float)y + 0.5f) / (float)n, p[3];
      for (int k = 0; k < 3; k++)
        p[k] = wall->lower_left[k] + s * (wall->lower_right[k] - wall->lower_left[k]) +
               t * (wall->upper_right[k] - wall->lower_right[k]);
      float a = viewer_weight(0, p), b = viewer_weight(1, p), sum = a + b;
      unsigned char *rgba = out + 4 * ((size_t)y * n + x);
      rgba[0] = (unsigned char)(sum > 0 ? 255 * a / sum : 90);
      rgba[1] = (unsigned char)(sum > 0 ? 255 * b / sum : 90);
      rgba[2] = (unsigned char)(sum > 0 ? 0 : 90);
      rgba[3] = 255;
    }
}

/* Sets both viewers on an offAxis camera. */
static void set_two_viewers(ANARIDevice device, ANARICamera camera, const char *mode) {
  float gaze[2][3];
  for (int i = 0; i < 2; i++)
    for (int k = 0; k < 3; k++)
      gaze[i][k] = VIEWER_TARGET[i][k] - VIEWER_HEAD[i][k];
  ANARIArray1D arrays[3] = {
      array_of(device, ANARI_FLOAT32_VEC3, VIEWER_HEAD, 2, 3 * sizeof(float)),
      array_of(device, ANARI_FLOAT32_VEC3, gaze, 2, 3 * sizeof(float)),
      array_of(device, ANARI_FLOAT32_VEC3, VIEWER_RIGHT, 2, 3 * sizeof(float))};
  const char *names[3] = {"viewer.position", "viewer.direction", "viewer.right"};
  for (int i = 0; i < 3; i++) {
    anariSetParameter(device, camera, names[i], ANARI_ARRAY1D, &arrays[i]);
    anariRelease(device, arrays[i]);
  }
  anariSetParameter(device, camera, "viewerMode", ANARI_STRING, mode);
}

/* ----- stereo ---------------------------------------------------------------------------- */

/* False colour of screen parallax p (meters) against the comfort limit: blue in front of the
 * screen, grey on it, green behind, brighter towards the limit; red beyond ±limit; black where
 * nothing was hit (NaN). */
static size_t parallax_image(const float *parallax, size_t pixels, float limit,
                             unsigned char *out) {
  size_t beyond = 0;
  for (size_t i = 0; i < pixels; i++) {
    float p = parallax[i];
    unsigned char *o = out + 4 * i;
    o[3] = 255;
    if (isnan(p)) {
      o[0] = o[1] = o[2] = 0;
    } else if (fabsf(p) > limit) {
      o[0] = 255, o[1] = 40, o[2] = 40;
      beyond++;
    } else {
      float a = fabsf(p) / limit;
      unsigned char grey = (unsigned char)(110 * (1 - a));
      o[0] = grey;
      o[1] = (unsigned char)(grey + (p > 0 ? 145 * a : 0));
      o[2] = (unsigned char)(grey + (p < 0 ? 145 * a : 0));
    }
  }
  return beyond;
}

/* Sets the front wall's corners, `head` and `right` on an offAxis camera in `stereo` mode. */
static void front_wall_camera(ANARIDevice device, ANARICamera camera, const float head[3],
                              const float right[3], const char *stereo) {
  anariSetParameter(device, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, WALL[0].lower_left);
  anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3,
                    WALL[0].lower_right);
  anariSetParameter(device, camera, "screen.upperRight", ANARI_FLOAT32_VEC3,
                    WALL[0].upper_right);
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, head);
  anariSetParameter(device, camera, "right", ANARI_FLOAT32_VEC3, right);
  anariSetParameter(device, camera, "stereoMode", ANARI_STRING, stereo);
  anariCommitParameters(device, camera);
}

/* Like front_wall_camera, for the 1 m square window of the front wall around the mirror. */
static void window_camera(ANARIDevice device, ANARICamera camera, const float head[3],
                          const float right[3], const char *stereo) {
  const float lower_left[3] = {-0.5f, 1.0f, -1.5f}, lower_right[3] = {0.5f, 1.0f, -1.5f},
              upper_right[3] = {0.5f, 2.0f, -1.5f};
  anariSetParameter(device, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, lower_left);
  anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, lower_right);
  anariSetParameter(device, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, upper_right);
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, head);
  anariSetParameter(device, camera, "right", ANARI_FLOAT32_VEC3, right);
  anariSetParameter(device, camera, "stereoMode", ANARI_STRING, stereo);
  anariCommitParameters(device, camera);
}

static int compare_doubles(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* ----- rendering ------------------------------------------------------------------------- */

static ANARIFrame color_frame(ANARIDevice device, uint32_t width, uint32_t height,
                              ANARIWorld world, ANARIRenderer renderer) {
  ANARIFrame frame = anariNewFrame(device);
  uint32_t size[2] = {width, height};
  ANARIDataType color = ANARI_UFIXED8_RGBA_SRGB;
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(device, frame, "channel.color", ANARI_DATA_TYPE, &color);
  anariSetParameter(device, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(device, frame, "renderer", ANARI_RENDERER, &renderer);
  return frame; /* committed by render(), once it has a camera */
}

/* Renders `frame` through `camera` and copies its colour into out (NULL: no copy). Returns the
 * wall-clock seconds the render took. */
static double render(ANARIDevice device, ANARIFrame frame, ANARICamera camera,
                     unsigned char *out, size_t bytes) {
  anariSetParameter(device, frame, "camera", ANARI_CAMERA, &camera);
  anariCommitParameters(device, frame);
  double start = seconds_now();
  anariRenderFrame(device, frame);
  anariFrameReady(device, frame, ANARI_WAIT);
  double elapsed = seconds_now() - start;
  const void *pixels = anariMapFrame(device, frame, "channel.color", NULL, NULL, NULL);
  if (pixels && out)
    memcpy(out, pixels, bytes);
  anariUnmapFrame(device, frame, "channel.color");
  return elapsed;
}

/* Renders a budgeted frame without committing it (a commit would restart its refinement);
 * returns the wall-clock seconds and writes the fraction of pixels traced. */
static double render_budgeted(ANARIDevice device, ANARIFrame frame, float *progress) {
  double start = seconds_now();
  anariRenderFrame(device, frame);
  anariFrameReady(device, frame, ANARI_WAIT);
  double elapsed = seconds_now() - start;
  *progress = 0;
  anariGetProperty(device, frame, "progress", ANARI_FLOAT32, progress, sizeof *progress,
                   ANARI_WAIT);
  return elapsed;
}

/* ----- panoramas ------------------------------------------------------------------------- */

/* Renders `camera` into a new width×height frame and writes it to <folder>/<name>; returns 1 on
 * success and prints the render time. */
static int render_panorama(ANARIDevice device, ANARIWorld world, ANARIRenderer renderer,
                           ANARICamera camera, uint32_t width, uint32_t height,
                           const char *folder, const char *name) {
  ANARIFrame frame = color_frame(device, width, height, world, renderer);
  double seconds = render(device, frame, camera, NULL, 0);
  char path[2048];
  snprintf(path, sizeof path, "%s/%s", folder, name);
  int ok = cavetraceWriteFramePNG(device, frame, "channel.color", path) == ANARI_STATUS_NO_ERROR;
  printf("panorama: %s %u×%u in %.1f ms\n", name, width, height, 1e3 * seconds);
  anariRelease(device, frame);
  return ok;
}

/* The CAVE's scene all around one point, written to <folder>/: equirectangular.png (the
 * omnidirectional camera, ANARI_KHR_CAMERA_OMNIDIRECTIONAL: 360° × 180°, the front wall's
 * direction in the middle), equirectangular_ods.png (360° stereo video's layout: omni-directional
 * stereo, left eye on top), dome.png (the fisheye camera, ANARI_CAVETRACE_CAMERA_FISHEYE: a
 * 4 m planetarium dome over the CAVE's centre, tilted 30° towards the front wall, 180° field of
 * view, seen from its centre; outside the image circle the renderer's background) and
 * dome_tracked.png (the same dome from a tracked head 0.7 m right of and 0.9 m behind the centre:
 * every pixel still shows its point of the dome). */
static int panoramas(ANARIDevice device, ANARIWorld world, ANARIRenderer renderer,
                     const char *folder, uint32_t n) {
  int ok = 1;
  const float eye[3] = {0, 1.6f, 0.3f}, front[3] = {0, 0, -1}, up[3] = {0, 1, 0};
  ANARICamera omni = anariNewCamera(device, "omnidirectional");
  anariSetParameter(device, omni, "position", ANARI_FLOAT32_VEC3, eye);
  anariSetParameter(device, omni, "direction", ANARI_FLOAT32_VEC3, front);
  anariSetParameter(device, omni, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, omni, "layout", ANARI_STRING, "equirectangular");
  anariCommitParameters(device, omni);
  ok &= render_panorama(device, world, renderer, omni, 2 * n, n, folder, "equirectangular.png");
  float ipd = IPD;
  anariSetParameter(device, omni, "stereoMode", ANARI_STRING, "topBottom");
  anariSetParameter(device, omni, "interpupillaryDistance", ANARI_FLOAT32, &ipd);
  anariCommitParameters(device, omni);
  ok &= render_panorama(device, world, renderer, omni, 2 * n, 2 * n, folder,
                        "equirectangular_ods.png");
  anariRelease(device, omni);

  const float center[3] = {0, 1.2f, 0.3f}, radius = 4, tilt = 0.5236f, fov = 3.14159265f;
  ANARICamera dome = anariNewCamera(device, "fisheye");
  anariSetParameter(device, dome, "dome.center", ANARI_FLOAT32_VEC3, center);
  anariSetParameter(device, dome, "dome.radius", ANARI_FLOAT32, &radius);
  anariSetParameter(device, dome, "dome.tilt", ANARI_FLOAT32, &tilt);
  anariSetParameter(device, dome, "fov", ANARI_FLOAT32, &fov);
  anariSetParameter(device, dome, "position", ANARI_FLOAT32_VEC3, center);
  anariCommitParameters(device, dome);
  ok &= render_panorama(device, world, renderer, dome, n, n, folder, "dome.png");
  const float head[3] = {0.7f, 1.6f, 1.2f};
  anariSetParameter(device, dome, "position", ANARI_FLOAT32_VEC3, head);
  anariCommitParameters(device, dome);
  ok &= render_panorama(device, world, renderer, dome, n, n, folder, "dome_tracked.png");
  anariRelease(device, dome);
  return ok;
}


int main(int argc, char **argv) {
  const char *folder = argc > 1 ? argv[1] : "out/cave";
  const uint32_t n = argc > 2 ? (uint32_t)atoi(argv[2]) : 256;
  const int steps = argc > 3 ? atoi(argv[3]) : 4;
  const float budget_ms = argc > 4 ? (float)atof(argv[4]) : 0;
  if (n < 8 || n > 4096 || steps < 1 || steps > 100 || !(budget_ms >= 0 && budget_ms <= 1000)) {
    fprintf(stderr,
            "usage: %s [folder] [wall resolution 8..4096] [head positions 1..100] "
            "[budget 0..1000 ms]\n",
            argv[0]);
    return 2;
  }

  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &error_count);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;
  double start = seconds_now();
  ANARIWorld world = make_world(device);
  printf("scene: 10,000-sphere cloud, floor grid, mirror sphere (%.0f ms to build)\n",
         1e3 * (seconds_now() - start));

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[4] = {0.10f, 0.14f, 0.26f, 1}, ambient = 0.5f;
  /* One sample per pixel: ambient occlusion would be per-pixel noise here (and would make the
   * matrix and offAxis images differ by their noise), so the ambient light stays unoccluded;
   * out/environment/ambient_occlusion.png shows it converged. */
  float no_occlusion = 0.f;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  anariSetParameter(device, renderer, "ambientOcclusionDistance", ANARI_FLOAT32, &no_occlusion);
  /* The matrix camera sees one eye at a time, so the offAxis pair it is compared with is lit
   * per eye too (the default, cyclopean, is shown at the end). */
  anariSetParameter(device, renderer, "stereoLighting", ANARI_STRING, "perEye");
  anariCommitParameters(device, renderer);

  ANARIFrame pair_frame = color_frame(device, 2 * n, n, world, renderer);
  ANARIFrame eye_frame = color_frame(device, n, n, world, renderer);
  ANARICamera off_axis = anariNewCamera(device, "offAxis");
  ANARICamera matrix = anariNewCamera(device, "matrix");
  /* The front wall's stereo pair under a frame-time budget, with a camera of its own. */
  ANARIFrame budget_frame = color_frame(device, 2 * n, n, world, renderer);
  ANARICamera budget_camera = anariNewCamera(device, "offAxis");
  if (budget_ms > 0) {
    float budget = budget_ms / 1000;
    anariSetParameter(device, budget_frame, "budget", ANARI_FLOAT32, &budget);
    anariSetParameter(device, budget_frame, "camera", ANARI_CAMERA, &budget_camera);
    anariSetParameter(device, budget_camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3,
                      WALL[0].lower_left);
    anariSetParameter(device, budget_camera, "screen.lowerRight", ANARI_FLOAT32_VEC3,
                      WALL[0].lower_right);
    anariSetParameter(device, budget_camera, "screen.upperRight", ANARI_FLOAT32_VEC3,
                      WALL[0].upper_right);
    anariSetParameter(device, budget_camera, "stereoMode", ANARI_STRING, "sideBySide");
    anariCommitParameters(device, budget_frame);
  }

  const size_t wall_bytes = 4 * (size_t)n * n;
  unsigned char *pair = malloc(2 * wall_bytes);
  unsigned char *composite = malloc(9 * wall_bytes);
  unsigned char *matrix_image = malloc(wall_bytes);
  unsigned char *walls[EYES][WALLS];
  for (int e = 0; e < EYES; e++)
    for (int w = 0; w < WALLS; w++)
      walls[e][w] = malloc(wall_bytes);
  /* Depths and primitive ids say why a matrix and an offAxis pixel differ. */
  float *off_axis_depth[EYES], *matrix_depth = malloc(wall_bytes);
  uint32_t *off_axis_id[EYES], *matrix_id = malloc(wall_bytes);
  for (int e = 0; e < EYES; e++)
    off_axis_depth[e] = malloc(wall_bytes), off_axis_id[e] = malloc(wall_bytes);
  ANARIDataType f32 = ANARI_FLOAT32, u32 = ANARI_UINT32;
  ANARIFrame compared_frames[2] = {pair_frame, eye_frame};
  for (int f = 0; f < 2; f++) {
    anariSetParameter(device, compared_frames[f], "channel.depth", ANARI_DATA_TYPE, &f32);
    anariSetParameter(device, compared_frames[f], "channel.primitiveId", ANARI_DATA_TYPE, &u32);
  }

  int ok = 1;
  for (int step = 0; step < steps; step++) {
    /* The tracked head walks from the back left towards the front right, turning right. */
    float s = steps > 1 ? (float)step / (float)(steps - 1) : 0;
    float head[3] = {-0.4f + 0.8f * s, 1.70f - 0.05f * s, 0.7f - 0.9f * s};
    float yaw = 0.25f - 0.55f * s; /* radians, positive turns left */
    float right[3] = {cosf(yaw), 0, -sinf(yaw)};
    char step_folder[1024];
    snprintf(step_folder, sizeof step_folder, "%s/%d", folder, step);
    if (make_folders(step_folder) != 0) {
      perror(step_folder);
      return 1;
    }

    double off_axis_seconds = 0, matrix_seconds = 0;
    Comparison comparison = {0};
    for (int w = 0; w < WALLS; w++) {
      /* offAxis: corners, head and its right vector; both eyes side by side in one frame. */
      anariSetParameter(device, off_axis, "screen.lowerLeft", ANARI_FLOAT32_VEC3,
                        WALL[w].lower_left);
      anariSetParameter(device, off_axis, "screen.lowerRight", ANARI_FLOAT32_VEC3,
                        WALL[w].lower_right);
      anariSetParameter(device, off_axis, "screen.upperRight", ANARI_FLOAT32_VEC3,
                        WALL[w].upper_right);
      anariSetParameter(device, off_axis, "position", ANARI_FLOAT32_VEC3, head);
      anariSetParameter(device, off_axis, "right", ANARI_FLOAT32_VEC3, right);
      float ipd = IPD;
      anariSetParameter(device, off_axis, "interpupillaryDistance", ANARI_FLOAT32, &ipd);
      anariSetParameter(device, off_axis, "stereoMode", ANARI_STRING, "sideBySide");
      /* The same clipping planes as the matrices below, so both cameras see the same. */
      float near = NEAR, far = FAR;
      anariSetParameter(device, off_axis, "near", ANARI_FLOAT32, &near);
      anariSetParameter(device, off_axis, "far", ANARI_FLOAT32, &far);
      anariCommitParameters(device, off_axis);
      off_axis_seconds += render(device, pair_frame, off_axis, pair, 2 * wall_bytes);
      const void *depth = anariMapFrame(device, pair_frame, "channel.depth", NULL, NULL, NULL);
      const void *ids = anariMapFrame(device, pair_frame, "channel.primitiveId", NULL, NULL, NULL);
      for (int e = 0; e < EYES; e++) {
        copy_block(pair, 2 * n, e * n, n, n, walls[e][w]);
        if (depth && ids) {
          copy_block32(depth, 2 * n, e * n, n, n, off_axis_depth[e]);
          copy_block32(ids, 2 * n, e * n, n, n, off_axis_id[e]);
        }
      }
      anariUnmapFrame(device, pair_frame, "channel.depth");
      anariUnmapFrame(device, pair_frame, "channel.primitiveId");
      ok &= depth && ids;
      if (w == 0) {
        char path[2048];
        snprintf(path, sizeof path, "%s/front_stereo_pair.png", step_folder);
        ok &= cavetraceWriteFramePNG(device, pair_frame, "channel.color", path) ==
              ANARI_STATUS_NO_ERROR;
      }

      /* matrix: what an OpenGL CAVE renderer would load for each eye. */
      for (int e = 0; e < EYES; e++) {
        float eye[3], view[16], proj[16];
        float side = e == 0 ? -0.5f * IPD : 0.5f * IPD;
        for (int k = 0; k < 3; k++)
          eye[k] = head[k] + side * right[k];
        if (cavetraceOffAxisMatrices(WALL[w].lower_left, WALL[w].lower_right,
                                     WALL[w].upper_right, eye, NEAR, FAR, view, proj) !=
            ANARI_STATUS_NO_ERROR) {
          fprintf(stderr, "no off-axis frustum for the %s wall\n", WALL[w].name);
          ok = 0;
          continue;
        }
        anariSetParameter(device, matrix, "view", ANARI_FLOAT32_MAT4, view);
        anariSetParameter(device, matrix, "proj", ANARI_FLOAT32_MAT4, proj);
        anariCommitParameters(device, matrix);
        matrix_seconds += render(device, eye_frame, matrix, matrix_image, wall_bytes);
        depth = anariMapFrame(device, eye_frame, "channel.depth", NULL, NULL, NULL);
        ids = anariMapFrame(device, eye_frame, "channel.primitiveId", NULL, NULL, NULL);
        if (depth && ids) {
          memcpy(matrix_depth, depth, wall_bytes);
          memcpy(matrix_id, ids, wall_bytes);
          compare_images(&comparison, w, e, n, matrix_image, matrix_depth, matrix_id,
                         walls[e][w], off_axis_depth[e], off_axis_id[e]);
        }
        anariUnmapFrame(device, eye_frame, "channel.depth");
        anariUnmapFrame(device, eye_frame, "channel.primitiveId");
        ok &= depth && ids;
        char name[64];
        snprintf(name, sizeof name, "%s_%s_offAxis.png", WALL[w].name, EYE_NAME[e]);
        ok &= write_png(device, step_folder, name, n, n, walls[e][w]);
        snprintf(name, sizeof name, "%s_%s_matrix.png", WALL[w].name, EYE_NAME[e]);
        ok &= write_png(device, step_folder, name, n, n, matrix_image);
      }
    }
    for (int e = 0; e < EYES; e++) {
      char name[64];
      snprintf(name, sizeof name, "unfolded_%s.png", EYE_NAME[e]);
      unfold(walls[e], n, composite);
      ok &= write_png(device, step_folder, name, 3 * n, 3 * n, composite);
    }
    anaglyph(walls[0][0], walls[1][0], (size_t)n * n, composite);
    ok &= write_png(device, step_folder, "front_anaglyph.png", n, n, composite);
    if (budget_ms > 0) {
      /* As a tracked application does every frame: the newest head pose, one render. */
      anariSetParameter(device, budget_camera, "position", ANARI_FLOAT32_VEC3, head);
      anariSetParameter(device, budget_camera, "right", ANARI_FLOAT32_VEC3, right);
      anariCommitParameters(device, budget_camera);
      float progress;
      double seconds = render_budgeted(device, budget_frame, &progress);
      printf("head %d, budget %.0f ms: front wall pair (%u×%u) in %.1f ms, %.1f %% of the "
             "pixels traced\n",
             step, budget_ms, 2 * n, n, 1e3 * seconds, 100.0 * progress);
      char path[2048];
      snprintf(path, sizeof path, "%s/front_budget_pair.png", step_folder);
      ok &= cavetraceWriteFramePNG(device, budget_frame, "channel.color", path) ==
            ANARI_STATUS_NO_ERROR;
    }
    printf("head %d at (%.2f, %.2f, %.2f): 5 walls × 2 eyes of %u×%u in %.0f ms with offAxis "
           "(%.1f ms per wall, both eyes), %.0f ms with matrix\n",
           step, head[0], head[1], head[2], n, n, 1e3 * off_axis_seconds,
           1e3 * off_axis_seconds / WALLS, 1e3 * matrix_seconds);
    printf("  matrix vs offAxis: %zu of %zu pixels differ: %zu by one 8-bit step (rounding), "
           "%zu on a silhouette (the two rays hit different things), %zu where a shadow or "
           "reflection ray grazes an edge (same hit, different light)",
           comparison.rounding + comparison.silhouette + comparison.secondary,
           comparison.pixels, comparison.rounding, comparison.silhouette,
           comparison.secondary);
    if (comparison.largest > 1)
      printf("; largest %d/255 (%s) on the %s wall, %s eye, pixel (%u, %u) counted from the "
             "bottom left",
             comparison.largest, comparison.largest_is_silhouette ? "silhouette" : "same hit, grazing secondary ray",
             WALL[comparison.largest_wall].name, EYE_NAME[comparison.largest_eye],
             comparison.largest_x, comparison.largest_y);
    printf("\n");
  }
  for (int f = 0; f < 2; f++) {
    anariUnsetParameter(device, compared_frames[f], "channel.depth");
    anariUnsetParameter(device, compared_frames[f], "channel.primitiveId");
  }
  if (budget_ms > 0) {
    /* The head stands still: keep rendering to refine until the image is complete. */
    float progress = 0;
    int renders = 0;
    double seconds = 0;
    while (progress < 1 && renders < 1000) {
      seconds += render_budgeted(device, budget_frame, &progress);
      renders++;
    }
    printf("head still: the front wall pair is complete after %d more renders (%.0f ms)\n",
           renders, 1e3 * seconds);
    ok &= progress == 1;
  }
  printf("images in %s/<head position>/\n", folder);

  /* Two viewers: each alone (the camera's own position), then both in every viewerMode. */
  char viewers_folder[1024];
  snprintf(viewers_folder, sizeof viewers_folder, "%s/viewers", folder);
  if (make_folders(viewers_folder) != 0) {
    perror(viewers_folder);
    return 1;
  }
  const char *cases[] = {"A_alone", "B_alone", "perPixel", "tiles", "zones"};
  for (int c = 0; c < 5; c++) {
    ANARICamera camera = anariNewCamera(device, "offAxis");
    double seconds = 0;
    for (int w = 0; w < WALLS; w++) {
      anariSetParameter(device, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3,
                        WALL[w].lower_left);
      anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3,
                        WALL[w].lower_right);
      anariSetParameter(device, camera, "screen.upperRight", ANARI_FLOAT32_VEC3,
                        WALL[w].upper_right);
      if (c < 2)
        anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, VIEWER_HEAD[c]);
      else
        set_two_viewers(device, camera, cases[c]);
      anariCommitParameters(device, camera);
      seconds += render(device, eye_frame, camera, walls[0][w], wall_bytes);
    }
    char name[64];
    snprintf(name, sizeof name, "unfolded_%s.png", cases[c]);
    unfold(walls[0], n, composite);
    ok &= write_png(device, viewers_folder, name, 3 * n, 3 * n, composite);
    printf("viewers %s: 5 walls of %u×%u in %.0f ms\n", cases[c], n, n, 1e3 * seconds);
    anariRelease(device, camera);
  }
  for (int w = 0; w < WALLS; w++)
    weight_image(&WALL[w], n, walls[0][w]);
  unfold(walls[0], n, composite);
  ok &= write_png(device, viewers_folder, "unfolded_weights.png", 3 * n, 3 * n, composite);
  printf("two viewers' images in %s/\n", viewers_folder);

  /* Stereo: what a pair costs against one eye, where the parallax is, cyclopean lighting. */
  char stereo_folder[1024];
  snprintf(stereo_folder, sizeof stereo_folder, "%s/stereo", folder);
  if (make_folders(stereo_folder) != 0) {
    perror(stereo_folder);
    return 1;
  }
  {
    /* The tracked head near the CAVE's open back, 2.7 m from the front wall: everything the
     * front wall shows lies within the comfort limit. */
    const float head[3] = {0.1f, 1.65f, 1.2f}, right[3] = {1, 0, 0};
    ANARICamera mono_camera = anariNewCamera(device, "offAxis");
    ANARICamera pair_camera = anariNewCamera(device, "offAxis");
    front_wall_camera(device, mono_camera, head, right, "none");
    front_wall_camera(device, pair_camera, head, right, "sideBySide");
    enum { RUNS = 5 };
    double mono_seconds[RUNS], pair_seconds[RUNS];
    for (int r = 0; r < RUNS; r++) {
      mono_seconds[r] = render(device, eye_frame, mono_camera, NULL, 0);
      pair_seconds[r] = render(device, pair_frame, pair_camera, NULL, 0);
    }
    qsort(mono_seconds, RUNS, sizeof(double), compare_doubles);
    qsort(pair_seconds, RUNS, sizeof(double), compare_doubles);
    printf("stereo: front wall %u×%u, one eye %.1f ms, both eyes side by side %.1f ms (%.2f× "
           "one eye; medians of %d)\n",
           n, n, 1e3 * mono_seconds[RUNS / 2], 1e3 * pair_seconds[RUNS / 2],
           pair_seconds[RUNS / 2] / mono_seconds[RUNS / 2], RUNS);

    /* Parallax of the pair against the comfort limit, from the head above and from a head
     * 0.9 m nearer the wall, where the sphere cloud comes within half a metre of the eyes. */
    const float near_head[3] = {0.1f, 1.65f, 0.3f};
    const float *heads[2] = {head, near_head};
    const char *parallax_names[2] = {"front_parallax_comfortable.png",
                                     "front_parallax_too_close.png"};
    ANARICamera parallax_camera = anariNewCamera(device, "offAxis");
    anariSetParameter(device, pair_frame, "channel.parallax", ANARI_DATA_TYPE, &f32);
    for (int h = 0; h < 2; h++) {
      front_wall_camera(device, parallax_camera, heads[h], right, "sideBySide");
      render(device, pair_frame, parallax_camera, NULL, 0);
      float distance = heads[h][2] - WALL[0].lower_left[2], limit = 0.03f * distance;
      float range[2] = {0, 0};
      anariGetProperty(device, pair_frame, "parallaxRange", ANARI_FLOAT32_VEC2, range,
                       sizeof range, ANARI_WAIT);
      const float *parallax =
          anariMapFrame(device, pair_frame, "channel.parallax", NULL, NULL, NULL);
      size_t beyond = 0;
      if (parallax) {
        beyond = parallax_image(parallax, 2 * (size_t)n * n, limit, pair);
        ok &= write_png(device, stereo_folder, parallax_names[h], 2 * n, n, pair);
      } else {
        ok = 0;
      }
      anariUnmapFrame(device, pair_frame, "channel.parallax");
      printf("stereo: head %.1f m from the front wall: parallax from %.1f to %.1f mm, comfort "
             "limit ±%.1f mm: %s",
             distance, 1e3 * range[0], 1e3 * range[1], 1e3 * limit,
             beyond == 0 ? "comfortable" : "NOT comfortable");
      if (beyond > 0)
        printf(", %.1f %% of the pixels beyond it (red)",
               100.0 * (double)beyond / (2.0 * n * n));
      printf(" (%s)\n", parallax_names[h]);
    }
    anariUnsetParameter(device, pair_frame, "channel.parallax");
    anariRelease(device, parallax_camera);

    /* Cyclopean lighting: a mirror hung on the front wall reflects a board with white bars
     * behind the viewer. Lit per eye, each eye sees the reflection from its own position, so
     * it has its own depth far behind the mirror; lit from the point between the eyes, both
     * eyes see the same reflection at each point of the mirror, so it lies on the mirror's
     * surface. Rendered through a 1 m window of the front wall around the mirror, so the
     * shift shows. */
    ANARIWorld mirror = mirror_world(device);
    ANARIRenderer lit = anariNewRenderer(device, "default");
    anariSetParameter(device, lit, "background", ANARI_FLOAT32_VEC4, background);
    anariSetParameter(device, lit, "ambientRadiance", ANARI_FLOAT32, &ambient);
    anariSetParameter(device, lit, "ambientOcclusionDistance", ANARI_FLOAT32, &no_occlusion);
    ANARIFrame mirror_frame = color_frame(device, 2 * n, n, mirror, lit);
    ANARIFrame mirror_anaglyph_frame = color_frame(device, n, n, mirror, lit);
    ANARICamera window_pair = anariNewCamera(device, "offAxis");
    ANARICamera window_anaglyph = anariNewCamera(device, "offAxis");
    window_camera(device, window_pair, head, right, "sideBySide");
    window_camera(device, window_anaglyph, head, right, "anaglyph");
    const char *lightings[2] = {"perEye", "cyclopean"};
    unsigned char *lit_pairs[2] = {pair, composite};
    for (int l = 0; l < 2; l++) {
      anariSetParameter(device, lit, "stereoLighting", ANARI_STRING, lightings[l]);
      anariCommitParameters(device, lit);
      render(device, mirror_frame, window_pair, lit_pairs[l], 2 * wall_bytes);
      char name[64];
      snprintf(name, sizeof name, "mirror_%s_pair.png", lightings[l]);
      ok &= write_png(device, stereo_folder, name, 2 * n, n, lit_pairs[l]);
      render(device, mirror_anaglyph_frame, window_anaglyph, NULL, 0);
      char path[2048];
      snprintf(path, sizeof path, "%s/mirror_%s_anaglyph.png", stereo_folder, lightings[l]);
      ok &= cavetraceWriteFramePNG(device, mirror_anaglyph_frame, "channel.color", path) ==
            ANARI_STATUS_NO_ERROR;
    }
    /* Where the two pairs differ, four times brighter. */
    size_t differing = 0;
    int largest = 0;
    for (size_t i = 0; i < 2 * (size_t)n * n; i++) {
      for (int k = 0; k < 3; k++) {
        int d = abs((int)pair[4 * i + k] - (int)composite[4 * i + k]);
        largest = d > largest ? d : largest;
        pair[4 * i + k] = (unsigned char)(4 * d > 255 ? 255 : 4 * d);
      }
      differing += pair[4 * i] || pair[4 * i + 1] || pair[4 * i + 2];
      pair[4 * i + 3] = 255;
    }
    ok &= write_png(device, stereo_folder, "mirror_difference_pair.png", 2 * n, n, pair);
    printf("stereo: mirror lit per eye and cyclopean: %zu of %u pixels differ, largest %d/255 "
           "(mirror_difference_pair.png)\n",
           differing, 2 * n * n, largest);
    anariRelease(device, window_pair);
    anariRelease(device, window_anaglyph);
    anariRelease(device, mirror_anaglyph_frame);
    /* Passive 3D displays and red-cyan glasses: the front wall, one frame of one eye's size. */
    const char *interleaved[3] = {"rowInterleaved", "checkerboard", "anaglyph"};
    ANARICamera shared_camera = anariNewCamera(device, "offAxis");
    for (int m = 0; m < 3; m++) {
      front_wall_camera(device, shared_camera, head, right, interleaved[m]);
      render(device, eye_frame, shared_camera, NULL, 0);
      char name[64];
      snprintf(name, sizeof name, "front_%s.png", interleaved[m]);
      char path[2048];
      snprintf(path, sizeof path, "%s/%s", stereo_folder, name);
      ok &= cavetraceWriteFramePNG(device, eye_frame, "channel.color", path) ==
            ANARI_STATUS_NO_ERROR;
    }
    anariRelease(device, shared_camera);

    /* A light-field display in the front wall's place (sample calibration, 45 views): one ray
     * per subpixel, written as the panel shows it (ANARI_CAVETRACE_CAMERA_LIGHT_FIELD). */
    ANARICamera hologram = anariNewCamera(device, "lightField");
    anariSetParameter(device, hologram, "screen.lowerLeft", ANARI_FLOAT32_VEC3,
                      WALL[0].lower_left);
    anariSetParameter(device, hologram, "screen.lowerRight", ANARI_FLOAT32_VEC3,
                      WALL[0].lower_right);
    anariSetParameter(device, hologram, "screen.upperRight", ANARI_FLOAT32_VEC3,
                      WALL[0].upper_right);
    uint32_t views = 45;
    anariSetParameter(device, hologram, "views", ANARI_UINT32, &views);
    anariCommitParameters(device, hologram);
    ANARIFrame hologram_frame = color_frame(device, n, n, world, renderer);
    double hologram_seconds = render(device, hologram_frame, hologram, NULL, 0);
    char hologram_path[2048];
    snprintf(hologram_path, sizeof hologram_path, "%s/front_hologram.png", stereo_folder);
    ok &= cavetraceWriteFramePNG(device, hologram_frame, "channel.color", hologram_path) ==
          ANARI_STATUS_NO_ERROR;
    printf("light field: front wall %u×%u, one ray per subpixel, in %.1f ms\n", n, n,
           1e3 * hologram_seconds);
    /* The same display's quilt for drivers that interleave one themselves: 9 × 5 whole views,
     * view 0 (leftmost eye) at the bottom left, rows bottom to top. */
    uint32_t quilt[2] = {9, 5};
    anariSetParameter(device, hologram, "quilt", ANARI_UINT32_VEC2, quilt);
    anariCommitParameters(device, hologram);
    double quilt_seconds = render(device, hologram_frame, hologram, NULL, 0);
    snprintf(hologram_path, sizeof hologram_path, "%s/front_quilt.png", stereo_folder);
    ok &= cavetraceWriteFramePNG(device, hologram_frame, "channel.color", hologram_path) ==
          ANARI_STATUS_NO_ERROR;
    printf("light field: its quilt of 9×5 views in one %u×%u frame, in %.1f ms\n", n, n,
           1e3 * quilt_seconds);
    anariRelease(device, hologram_frame);
    anariRelease(device, hologram);
    printf("stereo images in %s/\n", stereo_folder);
    ANARIObject stereo_objects[] = {mono_camera, pair_camera, mirror, lit, mirror_frame};
    for (size_t i = 0; i < sizeof stereo_objects / sizeof stereo_objects[0]; i++)
      anariRelease(device, stereo_objects[i]);
  }

  char panorama_folder[1024];
  snprintf(panorama_folder, sizeof panorama_folder, "%s/panorama", folder);
  if (make_folders(panorama_folder) != 0) {
    fprintf(stderr, "cannot create %s\n", panorama_folder);
    ok = 0;
  } else {
    ok &= panoramas(device, world, renderer, panorama_folder, n);
  }

  for (int e = 0; e < EYES; e++)
    for (int w = 0; w < WALLS; w++)
      free(walls[e][w]);
  for (int e = 0; e < EYES; e++)
    free(off_axis_depth[e]), free(off_axis_id[e]);
  free(pair), free(composite), free(matrix_image), free(matrix_depth), free(matrix_id);
  ANARIObject objects[] = {off_axis,     matrix,        pair_frame, eye_frame,
                           budget_frame, budget_camera, renderer,   world};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return ok && error_count == 0 ? 0 : 1;
}
