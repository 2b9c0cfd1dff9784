/* Rendering through the C API: asynchronous frames, a perspective scene checked pixel by pixel
 * against an analytic reference (colour, depth, primitive/object/instance ids), instances,
 * spheres, and the PNG helpers. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "harness.h"

#define NO_ID 0xFFFFFFFFu

static const float ORIGIN[3] = {0, 0, 0};
static const float FORWARD[3] = {0, 0, -1};

/* ----- asynchronous frames --------------------------------------------------------------- */

typedef struct {
  int calls;
  ANARIFrame frame;
  ANARIDevice device;
} CompletionRecord;

static void on_frame_done(const void *user, ANARIDevice device, ANARIFrame frame) {
  CompletionRecord *record = (CompletionRecord *)user;
  record->device = device;
  record->frame = frame;
  __atomic_add_fetch(&record->calls, 1, __ATOMIC_SEQ_CST);
}

static void sleep_ms(long milliseconds) {
  struct timespec pause = {milliseconds / 1000, (milliseconds % 1000) * 1000000};
  nanosleep(&pause, NULL);
}

/* Waits up to 10 s for `expected` completion calls; returns the count seen. */
static int wait_for_calls(CompletionRecord *record, int expected) {
  int calls = 0;
  for (int i = 0; i < 10000; i++) {
    calls = __atomic_load_n(&record->calls, __ATOMIC_SEQ_CST);
    if (calls >= expected)
      break;
    sleep_ms(1);
  }
  sleep_ms(10); /* a surplus call would show up now */
  return __atomic_load_n(&record->calls, __ATOMIC_SEQ_CST);
}

/* Many spheres seen with many samples per pixel: seconds of work, so that polling sees it
 * unfinished. */
static ANARIFrame heavy_frame(ANARIDevice device, ANARIWorld *world_out) {
  enum { N = 4096 };
  static float centers[N * 3];
  for (int i = 0; i < N; i++) {
    centers[3 * i + 0] = (float)(i % 64) / 16.0f - 2.0f;
    centers[3 * i + 1] = (float)(i / 64) / 16.0f - 2.0f;
    centers[3 * i + 2] = -4.0f - (float)(i % 7) * 0.1f;
  }
  ANARIGeometry spheres = anariNewGeometry(device, "sphere");
  ANARIArray1D positions = managed_array(device, ANARI_FLOAT32_VEC3, centers, N, 12);
  float radius = 0.05f;
  anariSetParameter(device, spheres, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, spheres, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, spheres);
  anariRelease(device, positions);
  ANARISurface surface = matte_surface(device, spheres, 0.5f, 0.5f, 0.5f, 0);
  anariRelease(device, spheres);
  *world_out = world_of_surfaces(device, &surface, 1);
  anariRelease(device, surface);
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  int32_t samples = 256;
  anariSetParameter(device, renderer, "pixelSamples", ANARI_INT32, &samples);
  anariCommitParameters(device, renderer);
  ANARIFrame frame = new_frame(device, 1024, 1024, *world_out, camera, renderer);
  anariRelease(device, camera);
  anariRelease(device, renderer);
  return frame;
}

static void poll_then_discard(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world;
  ANARIFrame frame = heavy_frame(device, &world);
  anariRenderFrame(device, frame);
  /* anariRenderFrame returned at once: the render is still going. */
  CHECK(anariFrameReady(device, frame, ANARI_NO_WAIT) == 0);
  anariDiscardFrame(device, frame);
  CHECK(anariFrameReady(device, frame, ANARI_WAIT) == 1);
  CHECK(anariFrameReady(device, frame, ANARI_NO_WAIT) == 1);
  /* The frame stays usable: a small render afterwards completes normally. */
  uint32_t small[2] = {8, 8};
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, small);
  anariCommitParameters(device, frame);
  render_and_wait(device, frame);
  uint32_t w = 0, h = 0;
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, &w, &h);
  CHECK(w == 8 && h == 8);
  free(depth);
  anariRelease(device, world);
  anariRelease(device, frame);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void poll_until_ready(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry geometry = square_at(device, 0, 0, -2, 2);
  ANARISurface surface = matte_surface(device, geometry, 1, 1, 1, 5);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 64, 64, world, camera, renderer);
  CompletionRecord record = {0, NULL, NULL};
  ANARIFrameCompletionCallback callback = on_frame_done;
  anariSetParameter(device, frame, "frameCompletionCallback", ANARI_FRAME_COMPLETION_CALLBACK,
                    &callback);
  void *user = &record;
  anariSetParameter(device, frame, "frameCompletionCallbackUserData", ANARI_VOID_POINTER, user);
  anariCommitParameters(device, frame);
  anariRenderFrame(device, frame);
  int polls = 0;
  while (!anariFrameReady(device, frame, ANARI_NO_WAIT) && polls < 60000) {
    sleep_ms(1);
    polls++;
  }
  CHECK(polls < 60000);
  uint32_t *ids = copy_channel(device, frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  CHECK(ids && pixel_id(ids, 64, 32, 32) == 5);
  free(ids);
  /* Two renders back to back: the second waits for the first. */
  anariRenderFrame(device, frame);
  anariRenderFrame(device, frame);
  CHECK(anariFrameReady(device, frame, ANARI_WAIT) == 1);
  /* The callback runs on a render thread once per render, possibly just after the frame became
   * ready (the device does not order the two), so wait for it a bounded time. */
  CHECK(wait_for_calls(&record, 3) == 3);
  CHECK(record.frame == frame && record.device == device);
  ANARIObject objects[] = {geometry, surface, world, camera, renderer, frame};
  for (size_t i = 0; i < 6; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void device_release_during_a_render_is_safe(void) {
  int threads_before = thread_count();
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world;
  ANARIFrame frame = heavy_frame(device, &world);
  anariRenderFrame(device, frame);
  CHECK(thread_count() > threads_before); /* the render threads run */
  anariRelease(device, world);
  anariRelease(device, frame);
  close_device(library, device); /* stops the render and joins the threads */
  CHECK(thread_count_settled(threads_before) == threads_before);
  CHECK(log_error_count() == 0);
}

/* ----- a perspective scene checked against an analytic reference ------------------------- */

typedef struct {
  float x, y, z, side; /* an axis-aligned square facing +z */
  float rgb[3];
  uint32_t id;
} Square;

typedef enum { MISS, HIT, UNSURE } Expectation;

/* What the ray from the origin along dir hits among the squares; UNSURE within `margin` (in
 * meters at the hit distance, scaled by t) of any edge or of a triangle's diagonal. */
static Expectation reference_hit(const Square *squares, int count, const float dir[3],
                                 float margin, int *which, int *triangle, float *distance) {
  float best = INFINITY;
  Expectation result = MISS;
  for (int i = 0; i < count; i++) {
    const Square *s = &squares[i];
    float t = s->z / dir[2];
    if (t <= 0)
      continue;
    float px = dir[0] * t, py = dir[1] * t, h = s->side / 2, m = margin * t;
    float u = px - (s->x - h), v = py - (s->y - h); /* from the lower-left corner */
    int inside = u > m && u < s->side - m && v > m && v < s->side - m;
    int near_edge = u > -m && u < s->side + m && v > -m && v < s->side + m && !inside;
    int near_diagonal = fabsf(u - v) < 2 * m;
    if (t >= best)
      continue;
    if (near_edge || (inside && near_diagonal)) {
      result = UNSURE;
      best = t;
    } else if (inside) {
      result = HIT;
      best = t;
      *which = i;
      *triangle = u > v ? 0 : 1; /* (LL, LR, UR) below the diagonal, then (LL, UR, UL) */
      *distance = t * sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    }
  }
  return result;
}

static void perspective_scene_matches_reference(void) {
  enum { W = 96, H = 64 };
  const Square squares[3] = {
      {-0.6f, 0.0f, -3.0f, 1.0f, {1, 0, 0}, 7},
      {0.4f, 0.2f, -5.0f, 3.0f, {0, 1, 0}, 9},
      {0.8f, -0.6f, -2.5f, 0.5f, {0.2f, 0.3f, 1.0f}, 11},
  };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry geometries[3];
  ANARISurface surfaces[3];
  for (int i = 0; i < 3; i++) {
    const Square *s = &squares[i];
    geometries[i] = square_at(device, s->x, s->y, s->z, s->side);
    surfaces[i] = matte_surface(device, geometries[i], s->rgb[0], s->rgb[1], s->rgb[2], s->id);
  }
  ANARIWorld world = world_of_surfaces(device, surfaces, 3);
  const float fovy = 0.9f;
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, fovy);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, W, H, world, camera, renderer);
  render_and_wait(device, frame);
  uint32_t w = 0, h = 0;
  float *color = copy_channel(device, frame, "channel.color", ANARI_FLOAT32_VEC4, 16, &w, &h);
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  uint32_t *prim = copy_channel(device, frame, "channel.primitiveId", ANARI_UINT32, 4, NULL, NULL);
  uint32_t *object = copy_channel(device, frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  uint32_t *instance =
      copy_channel(device, frame, "channel.instanceId", ANARI_UINT32, 4, NULL, NULL);
  CHECK(w == W && h == H);
  if (color && depth && prim && object && instance && w == W && h == H) {
    float tan_half = tanf(fovy / 2), aspect = (float)W / H;
    float pixel = 2 * tan_half / H; /* one pixel at unit distance */
    int checked = 0, hits = 0, misses = 0, bad = 0;
    for (uint32_t y = 0; y < H; y++) {
      for (uint32_t x = 0; x < W; x++) {
        float dir[3] = {(2 * (x + 0.5f) / W - 1) * tan_half * aspect,
                        (2 * (y + 0.5f) / H - 1) * tan_half, -1};
        int which = -1, triangle = -1;
        float distance = 0;
        Expectation e = reference_hit(squares, 3, dir, pixel, &which, &triangle, &distance);
        if (e == UNSURE)
          continue;
        checked++;
        const float *c = pixel_color(color, W, x, y);
        float d = pixel_depth(depth, W, x, y);
        int ok;
        if (e == MISS) {
          misses++;
          ok = isinf(d) && pixel_id(object, W, x, y) == NO_ID &&
               pixel_id(prim, W, x, y) == NO_ID && pixel_id(instance, W, x, y) == NO_ID &&
               c[0] == 0 && c[1] == 0 && c[2] == 0 && c[3] == 1;
        } else {
          hits++;
          const Square *s = &squares[which];
          ok = fabsf(d - distance) < 1e-4f * distance &&
               pixel_id(object, W, x, y) == s->id &&
               pixel_id(prim, W, x, y) == (uint32_t)triangle &&
               fabsf(c[0] - s->rgb[0]) < 0.01f && fabsf(c[1] - s->rgb[1]) < 0.01f &&
               fabsf(c[2] - s->rgb[2]) < 0.01f && c[3] == 1;
        }
        if (!ok && bad++ < 5)
          printf("  pixel (%u,%u): expected %s square %d triangle %d depth %g; got object %u "
                 "primitive %u depth %g colour (%g %g %g %g)\n",
                 x, y, e == HIT ? "hit of" : "miss", which, triangle, distance,
                 pixel_id(object, W, x, y), pixel_id(prim, W, x, y), d, c[0], c[1], c[2], c[3]);
      }
    }
    CHECK(bad == 0);
    /* The reference decided most pixels, and the scene has both. */
    CHECK(checked > W * H * 3 / 4);
    CHECK(hits > 500 && misses > 500);
  }
  free(color), free(depth), free(prim), free(object), free(instance);
  for (int i = 0; i < 3; i++) {
    anariRelease(device, geometries[i]);
    anariRelease(device, surfaces[i]);
  }
  ANARIObject objects[] = {world, camera, renderer, frame};
  for (size_t i = 0; i < 4; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void instances_move_groups_and_carry_ids(void) {
  enum { S = 32 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry geometry = square_at(device, 0, 0, 0, 2);
  ANARISurface surface = matte_surface(device, geometry, 1, 1, 0, 21);
  ANARIGroup group = anariNewGroup(device);
  ANARIArray1D surfaces = object_array(device, ANARI_SURFACE, &surface, 1);
  anariSetParameter(device, group, "surface", ANARI_ARRAY1D, &surfaces);
  anariCommitParameters(device, group);
  /* Two instances of the group: 3 m away on the left, 6 m away on the right. */
  ANARIInstance instances[2];
  const float offsets[2][3] = {{-1.5f, 0, -3}, {1.5f, 0, -6}};
  for (int i = 0; i < 2; i++) {
    instances[i] = anariNewInstance(device, "transform");
    float m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                   offsets[i][0], offsets[i][1], offsets[i][2], 1};
    uint32_t id = 100 + (uint32_t)i;
    anariSetParameter(device, instances[i], "group", ANARI_GROUP, &group);
    anariSetParameter(device, instances[i], "transform", ANARI_FLOAT32_MAT4, m);
    anariSetParameter(device, instances[i], "id", ANARI_UINT32, &id);
    anariCommitParameters(device, instances[i]);
  }
  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D instance_array = object_array(device, ANARI_INSTANCE, instances, 2);
  anariSetParameter(device, world, "instance", ANARI_ARRAY1D, &instance_array);
  anariCommitParameters(device, world);
  float bounds[6];
  CHECK(anariGetProperty(device, world, "bounds", ANARI_FLOAT32_BOX3, bounds, sizeof bounds,
                         ANARI_WAIT));
  CHECK_NEAR(bounds[0], -2.5, 1e-5);
  CHECK_NEAR(bounds[3], 2.5, 1e-5);
  CHECK_NEAR(bounds[2], -6, 1e-5);
  CHECK_NEAR(bounds[5], -3, 1e-5);
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, 1.5f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, S, S, world, camera, renderer);
  render_and_wait(device, frame);
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  uint32_t *instance = copy_channel(device, frame, "channel.instanceId", ANARI_UINT32, 4, NULL, NULL);
  uint32_t *object = copy_channel(device, frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  if (depth && instance && object) {
    /* Pixel centres whose rays meet each instance's centre line at y = 0. */
    float tan_half = tanf(0.75f);
    for (int i = 0; i < 2; i++) {
      float s = offsets[i][0] / -offsets[i][2] / tan_half; /* NDC x of the square's centre */
      uint32_t x = (uint32_t)((s + 1) / 2 * S);
      float sx = (2 * (x + 0.5f) / S - 1) * tan_half, sy = (2 * (S / 2 + 0.5f) / S - 1) * tan_half;
      float expected = -offsets[i][2] * sqrtf(sx * sx + sy * sy + 1);
      CHECK(pixel_id(instance, S, x, S / 2) == 100 + (uint32_t)i);
      CHECK(pixel_id(object, S, x, S / 2) == 21);
      CHECK_NEAR(pixel_depth(depth, S, x, S / 2), expected, 1e-3 * expected);
    }
    CHECK(pixel_id(instance, S, S / 2, S / 2) == NO_ID); /* the gap between them */
  }
  free(depth), free(instance), free(object);
  ANARIObject objects[] = {geometry, surface, group, surfaces, instances[0], instances[1],
                           world, instance_array, camera, renderer, frame};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void spheres_report_depth_and_primitive_index(void) {
  enum { S = 33 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const float centers[9] = {-100, 0, -5, 0, 0, -5, 100, 0, -5}; /* only index 1 is in view */
  const float radii[3] = {1, 1.5f, 1};
  ANARIGeometry spheres = anariNewGeometry(device, "sphere");
  ANARIArray1D positions = managed_array(device, ANARI_FLOAT32_VEC3, centers, 3, 12);
  ANARIArray1D radius = managed_array(device, ANARI_FLOAT32, radii, 3, 4);
  anariSetParameter(device, spheres, "vertex.position", ANARI_ARRAY1D, &positions);
  anariSetParameter(device, spheres, "vertex.radius", ANARI_ARRAY1D, &radius);
  anariCommitParameters(device, spheres);
  ANARISurface surface = matte_surface(device, spheres, 1, 1, 1, 4);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, S, S, world, camera, renderer);
  render_and_wait(device, frame);
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  uint32_t *prim = copy_channel(device, frame, "channel.primitiveId", ANARI_UINT32, 4, NULL, NULL);
  if (depth && prim) {
    CHECK_NEAR(pixel_depth(depth, S, S / 2, S / 2), 3.5, 1e-4); /* centre pixel, odd size */
    CHECK(pixel_id(prim, S, S / 2, S / 2) == 1);
    CHECK(isinf(pixel_depth(depth, S, 0, 0)));
    CHECK(pixel_id(prim, S, 0, 0) == NO_ID);
  }
  free(depth), free(prim);
  ANARIObject objects[] = {spheres, positions, radius, surface, world, camera, renderer, frame};
  for (size_t i = 0; i < 8; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* A frame with a budget, rendered again and again without a change, refines to exactly the
 * image rendered without one; `progress` tells how far it got. */
static void budgeted_frame_refines_to_the_full_image(void) {
  enum { W = 61, H = 47 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry near_square = square_at(device, -0.4f, 0.1f, -3, 0.8f);
  ANARIGeometry far_square = square_at(device, 0.3f, -0.2f, -6, 2.5f);
  ANARISurface surfaces[2] = {matte_surface(device, near_square, 1, 0.2f, 0.1f, 1),
                              matte_surface(device, far_square, 0.1f, 0.5f, 1, 2)};
  ANARIWorld world = world_of_surfaces(device, surfaces, 2);
  ANARICamera camera = perspective_camera(device, ORIGIN, FORWARD, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame full = new_frame(device, W, H, world, camera, renderer);
  ANARIFrame budgeted = new_frame(device, W, H, world, camera, renderer);
  float budget = 0.005f;
  uint32_t pixels_per_render = 100;
  anariSetParameter(device, budgeted, "budget", ANARI_FLOAT32, &budget);
  anariSetParameter(device, budgeted, "budgetPixels", ANARI_UINT32, &pixels_per_render);
  anariCommitParameters(device, budgeted);
  render_and_wait(device, full);
  float progress = 0, first_progress = 0;
  int renders = 0;
  while (progress < 1 && renders < 100) {
    render_and_wait(device, budgeted);
    CHECK(anariGetProperty(device, budgeted, "progress", ANARI_FLOAT32, &progress,
                           sizeof progress, ANARI_WAIT) == 1);
    if (renders++ == 0)
      first_progress = progress;
  }
  CHECK(first_progress > 0 && first_progress < 0.25f);
  CHECK(progress == 1);
  CHECK(renders > 3);
  const char *channels[] = {"channel.color", "channel.depth", "channel.primitiveId",
                            "channel.objectId"};
  const ANARIDataType types[] = {ANARI_FLOAT32_VEC4, ANARI_FLOAT32, ANARI_UINT32, ANARI_UINT32};
  const size_t sizes[] = {16, 4, 4, 4};
  for (int c = 0; c < 4; c++) {
    void *a = copy_channel(device, full, channels[c], types[c], sizes[c], NULL, NULL);
    void *b = copy_channel(device, budgeted, channels[c], types[c], sizes[c], NULL, NULL);
    CHECK(a && b && memcmp(a, b, sizes[c] * W * H) == 0);
    free(a), free(b);
  }
  ANARIObject objects[] = {near_square, far_square, surfaces[0], surfaces[1], world,
                           camera,      renderer,   full,        budgeted};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

int main(void) {
  run_test("poll_then_discard", poll_then_discard);
  run_test("poll_until_ready", poll_until_ready);
  run_test("device_release_during_a_render_is_safe", device_release_during_a_render_is_safe);
  run_test("perspective_scene_matches_reference", perspective_scene_matches_reference);
  run_test("instances_move_groups_and_carry_ids", instances_move_groups_and_carry_ids);
  run_test("spheres_report_depth_and_primitive_index", spheres_report_depth_and_primitive_index);
  run_test("budgeted_frame_refines_to_the_full_image", budgeted_frame_refines_to_the_full_image);
  return test_summary();
}
