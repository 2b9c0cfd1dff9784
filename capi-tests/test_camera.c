/* Cameras through the C API: perspective (with imageRegion), orthographic, matrix and offAxis
 * scenes checked pixel by pixel against an analytic ray caster (object and primitive ids,
 * depth, window depth), stereo viewports, Listing 5 verbatim, the three off-axis strategies
 * agreeing, and the off-axis helper functions on known configurations. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

#define NO_ID 0xFFFFFFFFu
#define PI 3.14159265358979323846

/* ----- small linear algebra (doubles; matrices column-major like OpenGL) ----------------- */

static void sub3(const double a[3], const double b[3], double out[3]) {
  for (int i = 0; i < 3; i++)
    out[i] = a[i] - b[i];
}
static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void cross3(const double a[3], const double b[3], double out[3]) {
  double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  memcpy(out, c, sizeof c);
}
static double length3(const double a[3]) { return sqrt(dot3(a, a)); }
static void normalize3(double a[3]) {
  double l = length3(a);
  for (int i = 0; i < 3; i++)
    a[i] /= l;
}
static void to_double3(const float in[3], double out[3]) {
  for (int i = 0; i < 3; i++)
    out[i] = in[i];
}

/* out = a·b (4×4, column-major). */
static void mul4(const double a[16], const double b[16], double out[16]) {
  double r[16];
  for (int c = 0; c < 4; c++)
    for (int row = 0; row < 4; row++) {
      r[c * 4 + row] = 0;
      for (int k = 0; k < 4; k++)
        r[c * 4 + row] += a[k * 4 + row] * b[c * 4 + k];
    }
  memcpy(out, r, sizeof r);
}

static void transform4(const double m[16], const double v[4], double out[4]) {
  for (int row = 0; row < 4; row++)
    out[row] = m[row] * v[0] + m[4 + row] * v[1] + m[8 + row] * v[2] + m[12 + row] * v[3];
}

/* Gauss-Jordan inverse; returns 0 when singular. */
static int invert4(const double m[16], double out[16]) {
  double a[4][8];
  for (int row = 0; row < 4; row++)
    for (int c = 0; c < 4; c++) {
      a[row][c] = m[c * 4 + row];
      a[row][4 + c] = row == c;
    }
  for (int c = 0; c < 4; c++) {
    int pivot = c;
    for (int row = c + 1; row < 4; row++)
      if (fabs(a[row][c]) > fabs(a[pivot][c]))
        pivot = row;
    if (fabs(a[pivot][c]) < 1e-15)
      return 0;
    for (int k = 0; k < 8; k++) {
      double t = a[c][k];
      a[c][k] = a[pivot][k];
      a[pivot][k] = t;
    }
    double scale = a[c][c];
    for (int k = 0; k < 8; k++)
      a[c][k] /= scale;
    for (int row = 0; row < 4; row++)
      if (row != c) {
        double f = a[row][c];
        for (int k = 0; k < 8; k++)
          a[row][k] -= f * a[c][k];
      }
  }
  for (int row = 0; row < 4; row++)
    for (int c = 0; c < 4; c++)
      out[c * 4 + row] = a[row][4 + c];
  return 1;
}

static void to_double16(const float in[16], double out[16]) {
  for (int i = 0; i < 16; i++)
    out[i] = in[i];
}

/* gluLookAt and glFrustum, in float as an application would build them. */
static void look_at(const float eye[3], const float center[3], const float up[3], float m[16]) {
  double f[3] = {center[0] - eye[0], center[1] - eye[1], center[2] - eye[2]}, u0[3], s[3], u[3];
  double e[3];
  to_double3(up, u0);
  to_double3(eye, e);
  normalize3(f);
  cross3(f, u0, s);
  normalize3(s);
  cross3(s, f, u);
  const double v[16] = {s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
                        -dot3(s, e), -dot3(u, e), dot3(f, e), 1};
  for (int i = 0; i < 16; i++)
    m[i] = (float)v[i];
}

static void frustum(double l, double r, double b, double t, double n, double f, float m[16]) {
  const double p[16] = {2 * n / (r - l), 0, 0, 0, 0, 2 * n / (t - b), 0, 0,
                        (r + l) / (r - l), (t + b) / (t - b), -(f + n) / (f - n), -1,
                        0, 0, -2 * f * n / (f - n), 0};
  for (int i = 0; i < 16; i++)
    m[i] = (float)p[i];
}

/* ----- an analytic ray caster over quads ------------------------------------------------- */

/* A square (or parallelogram) c ± a ± b as two triangles (LL, LR, UR) and (LL, UR, UL),
 * primitive ids 0 and 1, in a surface with `id`. */
typedef struct {
  double center[3], a[3], b[3];
  uint32_t id;
  float rgb[3];
} Quad;

typedef struct {
  double origin[3], dir[3]; /* dir need not be unit length */
} Ray;

typedef struct {
  int quad;         /* -1: miss */
  uint32_t primitive;
  double point[3];
} Hit;

/* Ray-parallelogram intersection; local coordinates u, v in [-1, 1]. */
static Hit cast(const Quad *quads, int count, const Ray *ray) {
  Hit best = {-1, NO_ID, {0, 0, 0}};
  double best_t = INFINITY;
  for (int i = 0; i < count; i++) {
    const Quad *q = &quads[i];
    double n[3];
    cross3(q->a, q->b, n);
    double denom = dot3(n, ray->dir);
    if (fabs(denom) < 1e-12)
      continue;
    double to_center[3];
    sub3(q->center, ray->origin, to_center);
    double t = dot3(n, to_center) / denom;
    if (t <= 1e-9 || t >= best_t)
      continue;
    double p[3], rel[3];
    for (int k = 0; k < 3; k++)
      p[k] = ray->origin[k] + t * ray->dir[k];
    sub3(p, q->center, rel);
    double u = dot3(rel, q->a) / dot3(q->a, q->a), v = dot3(rel, q->b) / dot3(q->b, q->b);
    if (u < -1 || u > 1 || v < -1 || v > 1)
      continue;
    best_t = t;
    best.quad = i;
    best.primitive = u > v ? 0 : 1;
    memcpy(best.point, p, sizeof p);
  }
  return best;
}

static ANARIWorld quad_world(ANARIDevice device, const Quad *quads, int count) {
  ANARISurface surfaces[32] = {NULL};
  for (int i = 0; i < count; i++) {
    const Quad *q = &quads[i];
    float v[4][3];
    const double signs[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int c = 0; c < 4; c++)
      for (int k = 0; k < 3; k++)
        v[c][k] = (float)(q->center[k] + signs[c][0] * q->a[k] + signs[c][1] * q->b[k]);
    float xyz[18];
    const int order[6] = {0, 1, 2, 0, 2, 3};
    for (int j = 0; j < 6; j++)
      memcpy(xyz + 3 * j, v[order[j]], sizeof v[0]);
    ANARIGeometry geometry = triangle_geometry(device, xyz, 6);
    surfaces[i] = matte_surface(device, geometry, q->rgb[0], q->rgb[1], q->rgb[2], q->id);
    anariRelease(device, geometry);
  }
  ANARIWorld world = world_of_surfaces(device, surfaces, (uint64_t)count);
  for (int i = 0; i < count; i++)
    anariRelease(device, surfaces[i]);
  return world;
}

/* The ray of a camera through normalized viewport coordinates (s, t), t from the bottom. */
typedef void (*RayFunction)(const void *camera, double s, double t, Ray *ray);

/* Where depth is measured from: the eye (NULL: the ray origin, as for parallel rays). */
typedef struct {
  RayFunction ray;
  const void *camera;
  const double *eye;
  const double *view_proj; /* for window depth (NULL: not checked) */
} Reference;

typedef struct {
  float *depth, *window_depth;
  uint32_t *primitive, *object;
  uint32_t width, height;
} Channels;

static Channels read_channels(ANARIDevice device, ANARIFrame frame, int with_window_depth) {
  Channels c;
  memset(&c, 0, sizeof c);
  c.depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, &c.width, &c.height);
  c.primitive = copy_channel(device, frame, "channel.primitiveId", ANARI_UINT32, 4, NULL, NULL);
  c.object = copy_channel(device, frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  if (with_window_depth)
    c.window_depth =
        copy_channel(device, frame, "channel.windowDepth", ANARI_FLOAT32, 4, NULL, NULL);
  return c;
}

static void free_channels(Channels *c) {
  free(c->depth), free(c->window_depth), free(c->primitive), free(c->object);
}

/* Compares the viewport (x0, y0, w, h) of a rendered frame with the reference, pixel by pixel.
 * Pixels whose centre and four points 0.35 pixel away do not all hit the same primitive are
 * skipped. Returns the number of pixels compared (0 on a missing channel). */
static int compare_viewport(const Channels *c, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h,
                            const Quad *quads, int count, const Reference *ref) {
  if (!c->depth || !c->primitive || !c->object)
    return 0;
  int compared = 0, bad = 0;
  for (uint32_t y = 0; y < h; y++)
    for (uint32_t x = 0; x < w; x++) {
      double s = (x + 0.5) / w, t = (y + 0.5) / h;
      Ray ray;
      ref->ray(ref->camera, s, t, &ray);
      Hit hit = cast(quads, count, &ray);
      int sure = 1;
      const double offsets[4][2] = {{0.35, 0}, {-0.35, 0}, {0, 0.35}, {0, -0.35}};
      for (int k = 0; k < 4 && sure; k++) {
        Ray near_ray;
        ref->ray(ref->camera, s + offsets[k][0] / w, t + offsets[k][1] / h, &near_ray);
        Hit other = cast(quads, count, &near_ray);
        sure = other.quad == hit.quad && other.primitive == hit.primitive;
      }
      if (!sure)
        continue;
      compared++;
      size_t i = (size_t)(y0 + y) * c->width + x0 + x;
      int ok;
      double expected_depth = INFINITY;
      if (hit.quad < 0) {
        ok = isinf(c->depth[i]) && c->object[i] == NO_ID && c->primitive[i] == NO_ID;
      } else {
        double from[3];
        if (ref->eye)
          sub3(hit.point, ref->eye, from);
        else
          sub3(hit.point, ray.origin, from);
        expected_depth = length3(from);
        ok = fabs(c->depth[i] - expected_depth) <= 1e-4 * expected_depth + 1e-5 &&
             c->object[i] == quads[hit.quad].id && c->primitive[i] == hit.primitive;
        if (ok && ref->view_proj && c->window_depth) {
          double p[4] = {hit.point[0], hit.point[1], hit.point[2], 1}, clip[4];
          transform4(ref->view_proj, p, clip);
          double window = 0.5 * clip[2] / clip[3] + 0.5;
          ok = fabs(c->window_depth[i] - window) < 2e-5;
          if (!ok && bad < 5)
            printf("  pixel (%u,%u): window depth %.7f, expected %.7f\n", x0 + x, y0 + y,
                   c->window_depth[i], window);
        }
      }
      if (!ok && bad++ < 5)
        printf("  pixel (%u,%u): expected quad %d primitive %u depth %.6f; got object %u "
               "primitive %u depth %.6f\n",
               x0 + x, y0 + y, hit.quad, hit.primitive, expected_depth, c->object[i],
               c->primitive[i], c->depth[i]);
    }
  CHECK(bad == 0);
  return compared;
}

/* Adds channel.windowDepth to a frame made by new_frame. */
static void enable_window_depth(ANARIDevice device, ANARIFrame frame) {
  ANARIDataType type = ANARI_FLOAT32;
  anariSetParameter(device, frame, "channel.windowDepth", ANARI_DATA_TYPE, &type);
  anariCommitParameters(device, frame);
}

/* Three quads at different depths and angles, seen from around the origin looking down -z. */
static const Quad SCENE[4] = {
    {{-0.5, 0.3, -3}, {0.6, 0, 0}, {0, 0.5, 0}, 11, {1, 0, 0}},
    {{0.6, -0.2, -4}, {0.8, 0, 0.4}, {0, 0.7, 0}, 12, {0, 1, 0}},
    {{0.1, -0.1, -2.5}, {0.25, 0.1, 0}, {-0.1, 0.3, 0.2}, 13, {0, 0, 1}},
    {{0, 0, -8}, {3, 0, 0}, {0, 0.4, 0}, 14, {1, 1, 0}},
};

static void release_all(ANARIDevice device, ANARIObject *objects, size_t count) {
  for (size_t i = 0; i < count; i++)
    anariRelease(device, objects[i]);
}

/* ----- perspective ----------------------------------------------------------------------- */

typedef struct {
  double position[3], direction[3], up[3];
  double fovy, aspect, region[4];
} Perspective;

static void perspective_ray(const void *camera, double s, double t, Ray *ray) {
  const Perspective *p = camera;
  double u = p->region[0] + s * (p->region[2] - p->region[0]);
  double v = p->region[1] + t * (p->region[3] - p->region[1]);
  double dir[3], right[3], up[3];
  memcpy(dir, p->direction, sizeof dir);
  normalize3(dir);
  cross3(dir, p->up, right);
  normalize3(right);
  cross3(right, dir, up);
  double h = tan(p->fovy / 2);
  for (int k = 0; k < 3; k++) {
    ray->origin[k] = p->position[k];
    ray->dir[k] = dir[k] + (2 * u - 1) * h * p->aspect * right[k] + (2 * v - 1) * h * up[k];
  }
}

static void set_perspective(ANARIDevice device, ANARICamera camera, const Perspective *p) {
  float position[3], direction[3], up[3], region[4];
  for (int k = 0; k < 3; k++) {
    position[k] = (float)p->position[k];
    direction[k] = (float)p->direction[k];
    up[k] = (float)p->up[k];
  }
  for (int k = 0; k < 4; k++)
    region[k] = (float)p->region[k];
  float fovy = (float)p->fovy, aspect = (float)p->aspect;
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, position);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "fovy", ANARI_FLOAT32, &fovy);
  anariSetParameter(device, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariSetParameter(device, camera, "imageRegion", ANARI_FLOAT32_BOX2, region);
  anariCommitParameters(device, camera);
}

static void perspective_with_image_region(void) {
  enum { W = 80, H = 50 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world = quad_world(device, SCENE, 4);
  Perspective p = {{0.4, 0.3, 0.5}, {-0.1, -0.05, -1}, {0.1, 1, 0}, 0.9, 1.7,
                   {0.1, 0.2, 0.85, 0.9}};
  ANARICamera camera = anariNewCamera(device, "perspective");
  set_perspective(device, camera, &p);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, W, H, world, camera, renderer);
  render_and_wait(device, frame);
  Channels c = read_channels(device, frame, 0);
  Reference ref = {perspective_ray, &p, p.position, NULL};
  CHECK(compare_viewport(&c, 0, 0, W, H, SCENE, 4, &ref) > W * H * 3 / 4);
  free_channels(&c);
  ANARIObject objects[] = {world, camera, renderer, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* ----- orthographic ---------------------------------------------------------------------- */

typedef struct {
  double position[3], direction[3], up[3], height, aspect;
} Orthographic;

static void orthographic_ray(const void *camera, double s, double t, Ray *ray) {
  const Orthographic *o = camera;
  double dir[3], right[3], up[3];
  memcpy(dir, o->direction, sizeof dir);
  normalize3(dir);
  cross3(dir, o->up, right);
  normalize3(right);
  cross3(right, dir, up);
  for (int k = 0; k < 3; k++) {
    ray->origin[k] = o->position[k] + (s - 0.5) * o->height * o->aspect * right[k] +
                     (t - 0.5) * o->height * up[k];
    ray->dir[k] = dir[k];
  }
}

static void orthographic_scene(void) {
  enum { W = 72, H = 48 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world = quad_world(device, SCENE, 4);
  Orthographic o = {{0.1, 0.05, 0}, {0.05, 0, -1}, {0, 1, 0}, 2.2, 1.5};
  ANARICamera camera = anariNewCamera(device, "orthographic");
  float position[3] = {0.1f, 0.05f, 0}, direction[3] = {0.05f, 0, -1}, up[3] = {0, 1, 0};
  float height = 2.2f, aspect = 1.5f;
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, position);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "height", ANARI_FLOAT32, &height);
  anariSetParameter(device, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariCommitParameters(device, camera);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, W, H, world, camera, renderer);
  render_and_wait(device, frame);
  Channels c = read_channels(device, frame, 0);
  Reference ref = {orthographic_ray, &o, NULL, NULL};
  CHECK(compare_viewport(&c, 0, 0, W, H, SCENE, 4, &ref) > W * H * 3 / 4);
  free_channels(&c);
  ANARIObject objects[] = {world, camera, renderer, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* ----- matrix ---------------------------------------------------------------------------- */

typedef struct {
  double inverse[16]; /* of proj·view */
  double eye[3];
} Unproject;

static void unproject_ray(const void *camera, double s, double t, Ray *ray) {
  const Unproject *u = camera;
  double near_ndc[4] = {2 * s - 1, 2 * t - 1, -1, 1}, far_ndc[4] = {2 * s - 1, 2 * t - 1, 1, 1};
  double a[4], b[4];
  transform4(u->inverse, near_ndc, a);
  transform4(u->inverse, far_ndc, b);
  for (int k = 0; k < 3; k++) {
    ray->origin[k] = u->eye[k];
    ray->dir[k] = b[k] / b[3] - a[k] / a[3];
  }
}

/* Fills an Unproject and proj·view from float matrices; the eye is view⁻¹·(0,0,0,1). */
static int unproject_from(const float view[16], const float proj[16], Unproject *u,
                          double view_proj[16]) {
  double v[16], p[16], v_inverse[16];
  to_double16(view, v);
  to_double16(proj, p);
  mul4(p, v, view_proj);
  if (!invert4(view_proj, u->inverse) || !invert4(v, v_inverse))
    return 0;
  memcpy(u->eye, v_inverse + 12, 3 * sizeof(double));
  return 1;
}

static void matrix_scene_with_window_depth(void) {
  enum { W = 64, H = 56 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world = quad_world(device, SCENE, 4);
  float eye[3] = {0.3f, 0.2f, 1}, center[3] = {0, 0, -3}, up[3] = {0, 1, 0};
  float view[16], proj[16];
  look_at(eye, center, up, view);
  frustum(-0.07, 0.04, -0.05, 0.045, 0.1, 20, proj);
  ANARICamera camera = anariNewCamera(device, "matrix");
  anariSetParameter(device, camera, "view", ANARI_FLOAT32_MAT4, view);
  anariSetParameter(device, camera, "proj", ANARI_FLOAT32_MAT4, proj);
  anariCommitParameters(device, camera);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, W, H, world, camera, renderer);
  enable_window_depth(device, frame);
  render_and_wait(device, frame);
  Channels c = read_channels(device, frame, 1);
  Unproject u;
  double view_proj[16];
  CHECK(unproject_from(view, proj, &u, view_proj));
  CHECK_NEAR(u.eye[0], 0.3, 1e-5);
  Reference ref = {unproject_ray, &u, u.eye, view_proj};
  CHECK(compare_viewport(&c, 0, 0, W, H, SCENE, 4, &ref) > W * H * 3 / 4);
  /* A miss has window depth 1 (the far plane), like a cleared OpenGL depth buffer. */
  CHECK(c.window_depth && c.window_depth[0] == 1.0f && isinf(c.depth[0]));
  free_channels(&c);
  ANARIObject objects[] = {world, camera, renderer, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* Listing 5 of the issue, verbatim: the application's matrices go to the matrix camera. */
static void listing_5_verbatim(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  const Quad red = {{0, 1.5, -2}, {0.5, 0, 0}, {0, 0.5, 0}, 42, {1, 0, 0}};
  ANARIWorld world = quad_world(device, &red, 1);
  ANARIRenderer renderer = albedo_renderer(device);
  /* A head at 1.6 m looking at the square 2 m ahead; a 90° × 90° symmetric frustum. */
  float eye[3] = {0, 1.6f, 0}, target[3] = {0, 1.6f, -1}, up_vector[3] = {0, 1, 0};
  float view[16], proj[16];
  look_at(eye, target, up_vector, view);
  frustum(-0.1, 0.1, -0.1, 0.1, 0.1, 100, proj);

  ANARICamera cam = anariNewCamera(device, "matrix");
  anariSetParameter(device, cam, "view", ANARI_FLOAT32_MAT4, view);
  anariSetParameter(device, cam, "proj", ANARI_FLOAT32_MAT4, proj);
  anariCommitParameters(device, cam);

  ANARIFrame frame = new_frame(device, 100, 100, world, cam, renderer);
  render_and_wait(device, frame);
  float *color = copy_channel(device, frame, "channel.color", ANARI_FLOAT32_VEC4, 16, NULL, NULL);
  float *depth = copy_channel(device, frame, "channel.depth", ANARI_FLOAT32, 4, NULL, NULL);
  uint32_t *ids = copy_channel(device, frame, "channel.objectId", ANARI_UINT32, 4, NULL, NULL);
  if (color && depth && ids) {
    /* The square spans y 1.0..2.0 at 2 m: NDC ±0.25 around (0, -0.05); pixels 37..62 wide. */
    const float *inside = pixel_color(color, 100, 50, 50);
    CHECK_NEAR(inside[0], 1.0, 0.01);
    CHECK_NEAR(inside[1], 0.0, 0.01);
    CHECK(pixel_id(ids, 100, 50, 50) == 42);
    double x = (50.5 / 100 * 2 - 1), y = (50.5 / 100 * 2 - 1); /* NDC of the pixel centre */
    CHECK_NEAR(pixel_depth(depth, 100, 50, 50), 2 * sqrt(1 + x * x + y * y), 1e-4);
    CHECK(pixel_id(ids, 100, 50, 30) == NO_ID); /* below the square */
    CHECK(pixel_id(ids, 100, 39, 50) == 42 && pixel_id(ids, 100, 36, 50) == NO_ID);
    CHECK(pixel_id(ids, 100, 61, 50) == 42 && pixel_id(ids, 100, 63, 50) == NO_ID);
    const float *corner = pixel_color(color, 100, 0, 0);
    CHECK(corner[0] == 0 && corner[1] == 0 && corner[2] == 0 && corner[3] == 1);
  }
  free(color), free(depth), free(ids);
  ANARIObject objects[] = {world, cam, renderer, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* ----- offAxis --------------------------------------------------------------------------- */

typedef struct {
  double lower_left[3], lower_right[3], upper_right[3], eye[3];
} Screen;

static void screen_ray(const void *camera, double s, double t, Ray *ray) {
  const Screen *sc = camera;
  for (int k = 0; k < 3; k++) {
    double p = sc->lower_left[k] + s * (sc->lower_right[k] - sc->lower_left[k]) +
               t * (sc->upper_right[k] - sc->lower_right[k]);
    ray->origin[k] = sc->eye[k];
    ray->dir[k] = p - sc->eye[k];
  }
}

/* The CAVE's front wall (3 m × 3 m at z = -1.5), a grid of 4×4 cells lying on it, and
 * scene quads behind it. */
static const float LL[3] = {-1.5f, 0, -1.5f}, LR[3] = {1.5f, 0, -1.5f}, UR[3] = {1.5f, 3, -1.5f};
static const float HEAD[3] = {0.35f, 1.72f, 0.4f};

static int wall_scene(Quad *quads) {
  int n = 0;
  for (int j = 0; j < 4; j++)
    for (int i = 0; i < 4; i++) {
      Quad q = {{-1.5 + 0.375 + 0.75 * i, 0.375 + 0.75 * j, -1.5},
                {0.375, 0, 0},
                {0, 0.375, 0},
                (uint32_t)(100 + j * 4 + i),
                {0.2f + 0.2f * (float)i, 0.2f + 0.2f * (float)j, 0.5f}};
      quads[n++] = q;
    }
  return n;
}

static Screen front_screen(const float eye[3]) {
  Screen s;
  to_double3(LL, s.lower_left);
  to_double3(LR, s.lower_right);
  to_double3(UR, s.upper_right);
  to_double3(eye, s.eye);
  return s;
}

static void set_off_axis(ANARIDevice device, ANARICamera camera, const float position[3],
                         const char *stereo_mode) {
  anariSetParameter(device, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, LL);
  anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, LR);
  anariSetParameter(device, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, UR);
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, position);
  anariSetParameter(device, camera, "stereoMode", ANARI_STRING, stereo_mode);
  float near = 0.05f, far = 50;
  anariSetParameter(device, camera, "near", ANARI_FLOAT32, &near);
  anariSetParameter(device, camera, "far", ANARI_FLOAT32, &far);
  anariCommitParameters(device, camera);
}

/* The ray through every pixel centre hits the screen at LL + s(LR−LL) + t(UR−LR). */
static void off_axis_rays_hit_the_screen_where_the_pixel_is(void) {
  enum { W = 96, H = 72 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  Quad grid[16];
  int n = wall_scene(grid);
  ANARIWorld world = quad_world(device, grid, n);
  ANARICamera camera = anariNewCamera(device, "offAxis");
  set_off_axis(device, camera, HEAD, "none");
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, W, H, world, camera, renderer);
  render_and_wait(device, frame);
  Channels c = read_channels(device, frame, 0);
  Screen screen = front_screen(HEAD);
  Reference ref = {screen_ray, &screen, screen.eye, NULL};
  CHECK(compare_viewport(&c, 0, 0, W, H, grid, n, &ref) > W * H / 2);
  free_channels(&c);
  ANARIObject objects[] = {world, camera, renderer, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* offAxis, matrix (cavetraceOffAxisMatrices) and perspective (cavetraceOffAxisPerspective)
 * render the same image of the same eye and screen, window depth included. */
static void three_strategies_render_the_same_image(void) {
  enum { W = 80, H = 60 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  Quad quads[20];
  int n = wall_scene(quads);
  quads[n++] = SCENE[0];
  quads[n++] = SCENE[1];
  for (int i = 16; i < n; i++)
    quads[i].center[2] -= 1.0; /* behind the wall */
  ANARIWorld world = quad_world(device, quads, n);
  ANARIRenderer renderer = albedo_renderer(device);

  ANARICamera off_axis = anariNewCamera(device, "offAxis");
  set_off_axis(device, off_axis, HEAD, "none");

  float view[16], proj[16];
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, HEAD, 0.05f, 50, view, proj) ==
        ANARI_STATUS_NO_ERROR);
  ANARICamera matrix = anariNewCamera(device, "matrix");
  anariSetParameter(device, matrix, "view", ANARI_FLOAT32_MAT4, view);
  anariSetParameter(device, matrix, "proj", ANARI_FLOAT32_MAT4, proj);
  anariCommitParameters(device, matrix);

  float position[3], direction[3], up[3], fovy = 0, aspect = 0, region[4];
  CHECK(cavetraceOffAxisPerspective(LL, LR, UR, HEAD, position, direction, up, &fovy, &aspect,
                                    region) == ANARI_STATUS_NO_ERROR);
  ANARICamera perspective = anariNewCamera(device, "perspective");
  anariSetParameter(device, perspective, "position", ANARI_FLOAT32_VEC3, position);
  anariSetParameter(device, perspective, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, perspective, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, perspective, "fovy", ANARI_FLOAT32, &fovy);
  anariSetParameter(device, perspective, "aspect", ANARI_FLOAT32, &aspect);
  anariSetParameter(device, perspective, "imageRegion", ANARI_FLOAT32_BOX2, region);
  float near = 0.05f, far = 50;
  anariSetParameter(device, perspective, "near", ANARI_FLOAT32, &near);
  anariSetParameter(device, perspective, "far", ANARI_FLOAT32, &far);
  anariCommitParameters(device, perspective);

  Screen screen = front_screen(HEAD);
  Unproject u;
  double view_proj[16];
  CHECK(unproject_from(view, proj, &u, view_proj));
  ANARICamera cameras[3] = {off_axis, matrix, perspective};
  const char *names[3] = {"offAxis", "matrix", "perspective"};
  Channels results[3];
  for (int k = 0; k < 3; k++) {
    ANARIFrame frame = new_frame(device, W, H, world, cameras[k], renderer);
    enable_window_depth(device, frame);
    render_and_wait(device, frame);
    results[k] = read_channels(device, frame, 1);
    anariRelease(device, frame);
    /* Each against the analytic screen rays, window depth against proj·view. */
    Reference ref = {screen_ray, &screen, screen.eye, view_proj};
    int compared = compare_viewport(&results[k], 0, 0, W, H, quads, n, &ref);
    if (compared < W * H / 2)
      printf("  %s: only %d pixels compared\n", names[k], compared);
    CHECK(compared >= W * H / 2);
  }
  /* And against each other, every pixel: same ids, depths within float precision. */
  int differing = 0;
  for (int k = 1; k < 3; k++)
    for (size_t i = 0; i < (size_t)W * H && results[0].depth && results[k].depth; i++) {
      float a = results[0].depth[i], b = results[k].depth[i];
      int same_id = results[0].primitive[i] == results[k].primitive[i] &&
                    results[0].object[i] == results[k].object[i];
      int same_depth = (isinf(a) && isinf(b)) || fabsf(a - b) <= 1e-4f * a;
      differing += !(same_id && same_depth);
    }
  /* Pixels exactly on a cell edge may fall either way; allow a handful. */
  CHECK(differing <= (W * H) / 200);
  for (int k = 0; k < 3; k++)
    free_channels(&results[k]);
  ANARIObject objects[] = {world, renderer, off_axis, matrix, perspective};
  release_all(device, objects, 5);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

/* sideBySide puts the left eye (head − IPD/2 · right) in the left half, topBottom in the upper
 * rows; each half is the eye's own off-axis image. */
static void stereo_modes_split_the_frame_by_eye(void) {
  enum { W = 64, H = 48 };
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  Quad grid[16];
  int n = wall_scene(grid);
  ANARIWorld world = quad_world(device, grid, n);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARICamera camera = anariNewCamera(device, "offAxis");
  float right[3] = {0.8f, 0, -0.6f}, ipd = 0.2f; /* a turned head; a wide IPD to see it */
  anariSetParameter(device, camera, "right", ANARI_FLOAT32_VEC3, right);
  anariSetParameter(device, camera, "interpupillaryDistance", ANARI_FLOAT32, &ipd);
  float eyes[2][3];
  for (int k = 0; k < 3; k++) {
    eyes[0][k] = HEAD[k] - 0.5f * ipd * right[k];
    eyes[1][k] = HEAD[k] + 0.5f * ipd * right[k];
  }
  Screen left = front_screen(eyes[0]), right_screen = front_screen(eyes[1]);
  Reference refs[2] = {{screen_ray, &left, left.eye, NULL},
                       {screen_ray, &right_screen, right_screen.eye, NULL}};

  set_off_axis(device, camera, HEAD, "sideBySide");
  ANARIFrame frame = new_frame(device, 2 * W, H, world, camera, renderer);
  render_and_wait(device, frame);
  Channels c = read_channels(device, frame, 0);
  CHECK(compare_viewport(&c, 0, 0, W, H, grid, n, &refs[0]) > W * H / 2);
  CHECK(compare_viewport(&c, W, 0, W, H, grid, n, &refs[1]) > W * H / 2);
  free_channels(&c);

  set_off_axis(device, camera, HEAD, "topBottom");
  uint32_t tall[2] = {W, 2 * H};
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, tall);
  anariCommitParameters(device, frame);
  render_and_wait(device, frame);
  c = read_channels(device, frame, 0);
  CHECK(compare_viewport(&c, 0, H, W, H, grid, n, &refs[0]) > W * H / 2);
  CHECK(compare_viewport(&c, 0, 0, W, H, grid, n, &refs[1]) > W * H / 2);
  free_channels(&c);

  /* "left" alone renders the left eye over the whole frame. */
  set_off_axis(device, camera, HEAD, "left");
  uint32_t single[2] = {W, H};
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, single);
  anariCommitParameters(device, frame);
  render_and_wait(device, frame);
  c = read_channels(device, frame, 0);
  CHECK(compare_viewport(&c, 0, 0, W, H, grid, n, &refs[0]) > W * H / 2);
  free_channels(&c);
  ANARIObject objects[] = {world, renderer, camera, frame};
  release_all(device, objects, 4);
  CHECK(log_error_count() == 0);
  close_device(library, device);
}

static void bad_camera_parameters_are_reported_at_commit(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARICamera camera = anariNewCamera(device, "offAxis");
  anariCommitParameters(device, camera); /* no screen at all */
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "offAxis",
                 "screen.lowerLeft", NULL));
  log_clear();
  /* A degenerate screen: lowerRight equals lowerLeft. */
  anariSetParameter(device, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, LL);
  anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, LL);
  anariSetParameter(device, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, UR);
  anariCommitParameters(device, camera);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "offAxis", "screen",
                 NULL));
  log_clear();
  anariSetParameter(device, camera, "stereoMode", ANARI_STRING, "both");
  anariSetParameter(device, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, LR);
  anariCommitParameters(device, camera);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "stereoMode", "both",
                 NULL));
  log_clear();
  /* A camera that failed its commit renders only the background, and says so. */
  const Quad red = {{0, 1.5, -3}, {1, 0, 0}, {0, 1, 0}, 1, {1, 0, 0}};
  ANARIWorld world = quad_world(device, &red, 1);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 8, 8, world, camera, renderer);
  render_and_wait(device, frame);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "camera", NULL));
  ANARICamera perspective = anariNewCamera(device, "perspective");
  float fovy = -1;
  anariSetParameter(device, perspective, "fovy", ANARI_FLOAT32, &fovy);
  log_clear();
  anariCommitParameters(device, perspective);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "perspective", "fovy",
                 NULL));
  ANARIObject objects[] = {camera, perspective, world, renderer, frame};
  release_all(device, objects, 5);
  close_device(library, device);
}

/* ----- the off-axis helper functions ----------------------------------------------------- */

static void off_axis_matrices_of_a_centred_eye_are_gl_frustum(void) {
  const float ll[3] = {-1, -1, -1}, lr[3] = {1, -1, -1}, ur[3] = {1, 1, -1}, eye[3] = {0, 0, 0};
  float view[16], proj[16];
  CHECK(cavetraceOffAxisMatrices(ll, lr, ur, eye, 0.5f, 10, view, proj) ==
        ANARI_STATUS_NO_ERROR);
  for (int i = 0; i < 16; i++)
    CHECK_NEAR(view[i], i % 5 == 0 ? 1 : 0, 1e-6); /* identity */
  /* glFrustum(-0.5, 0.5, -0.5, 0.5, 0.5, 10). */
  const double expected[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -10.5 / 9.5, -1, 0, 0, -10 / 9.5, 0};
  for (int i = 0; i < 16; i++)
    CHECK_NEAR(proj[i], expected[i], 1e-6);
}

/* proj·view maps the corners to the NDC corners, the eye to the origin, near/far to ∓1. */
static void check_off_axis_matrices(const float ll[3], const float lr[3], const float ur[3],
                                    const float eye[3], float near, float far) {
  float view[16], proj[16];
  CHECK(cavetraceOffAxisMatrices(ll, lr, ur, eye, near, far, view, proj) ==
        ANARI_STATUS_NO_ERROR);
  double v[16], p[16], pv[16];
  to_double16(view, v);
  to_double16(proj, p);
  mul4(p, v, pv);
  const float *corners[3] = {ll, lr, ur};
  const double ndc[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (int c = 0; c < 4; c++) {
    double x[4] = {0, 0, 0, 1}, clip[4];
    for (int k = 0; k < 3; k++)
      x[k] = c < 3 ? corners[c][k] : ll[k] + (ur[k] - lr[k]); /* upper left */
    transform4(pv, x, clip);
    CHECK_NEAR(clip[0] / clip[3], ndc[c][0], 1e-5);
    CHECK_NEAR(clip[1] / clip[3], ndc[c][1], 1e-5);
  }
  double e[4] = {eye[0], eye[1], eye[2], 1}, in_view[4];
  transform4(v, e, in_view);
  CHECK_NEAR(in_view[0], 0, 1e-5);
  CHECK_NEAR(in_view[1], 0, 1e-5);
  CHECK_NEAR(in_view[2], 0, 1e-5);
  /* Points at distance near and far in front of the eye, perpendicular to the screen. */
  double a[3], b[3], normal[3], l[3], r[3], u[3];
  to_double3(ll, l), to_double3(lr, r), to_double3(ur, u);
  sub3(r, l, a), sub3(u, r, b);
  cross3(a, b, normal); /* towards the viewer */
  normalize3(normal);
  const double distances[2] = {near, far}, expected_z[2] = {-1, 1};
  for (int k = 0; k < 2; k++) {
    double x[4] = {eye[0] - distances[k] * normal[0], eye[1] - distances[k] * normal[1],
                   eye[2] - distances[k] * normal[2], 1},
           clip[4];
    transform4(pv, x, clip);
    CHECK_NEAR(clip[2] / clip[3], expected_z[k], 1e-4);
  }
}

static void off_axis_matrices_of_cave_walls(void) {
  const float head[3] = {0.4f, 1.7f, 0.3f};
  check_off_axis_matrices(LL, LR, UR, head, 0.05f, 100); /* front */
  const float left[3][3] = {{-1.5f, 0, 1.5f}, {-1.5f, 0, -1.5f}, {-1.5f, 3, -1.5f}};
  check_off_axis_matrices(left[0], left[1], left[2], head, 0.1f, 20);
  const float floor_wall[3][3] = {{-1.5f, 0, 1.5f}, {1.5f, 0, 1.5f}, {1.5f, 0, -1.5f}};
  check_off_axis_matrices(floor_wall[0], floor_wall[1], floor_wall[2], head, 0.1f, 20);
  const float ceiling[3][3] = {{-1.5f, 3, -1.5f}, {1.5f, 3, -1.5f}, {1.5f, 3, 1.5f}};
  check_off_axis_matrices(ceiling[0], ceiling[1], ceiling[2], head, 0.1f, 20);
  /* The left wall's view maps its normal (+x, into the CAVE) to +z (towards the viewer). */
  float view[16], proj[16];
  CHECK(cavetraceOffAxisMatrices(left[0], left[1], left[2], head, 0.1f, 20, view, proj) == 0);
  CHECK_NEAR(view[0 * 4 + 2], 1, 1e-6); /* row 2 · x axis */
}

static void off_axis_perspective_of_a_centred_eye(void) {
  const float ll[3] = {-1, -1, -1}, lr[3] = {1, -1, -1}, ur[3] = {1, 1, -1}, eye[3] = {0, 0, 0};
  float position[3], direction[3], up[3], fovy, aspect, region[4];
  CHECK(cavetraceOffAxisPerspective(ll, lr, ur, eye, position, direction, up, &fovy, &aspect,
                                    region) == ANARI_STATUS_NO_ERROR);
  const float expected_direction[3] = {0, 0, -1}, expected_up[3] = {0, 1, 0};
  for (int k = 0; k < 3; k++) {
    CHECK_NEAR(position[k], 0, 1e-6);
    CHECK_NEAR(direction[k], expected_direction[k], 1e-6);
    CHECK_NEAR(up[k], expected_up[k], 1e-6);
  }
  CHECK_NEAR(fovy, PI / 2, 1e-6);
  CHECK_NEAR(aspect, 1, 1e-6);
  const double full[4] = {0, 0, 1, 1};
  for (int k = 0; k < 4; k++)
    CHECK_NEAR(region[k], full[k], 1e-6);
}

/* An off-centre eye: the fitted camera's rays (imageRegion applied) meet the screen exactly
 * where the pixel is. */
static void off_axis_perspective_rays_meet_the_screen(void) {
  const float eye[3] = {0.6f, 2.1f, -0.4f};
  float position[3], direction[3], up[3], fovy, aspect, region[4];
  CHECK(cavetraceOffAxisPerspective(LL, LR, UR, eye, position, direction, up, &fovy, &aspect,
                                    region) == ANARI_STATUS_NO_ERROR);
  for (int k = 0; k < 4; k++)
    CHECK(region[k] >= 0 && region[k] <= 1);
  CHECK(region[0] < region[2] && region[1] < region[3]);
  Perspective p;
  to_double3(position, p.position);
  to_double3(direction, p.direction);
  to_double3(up, p.up);
  p.fovy = fovy, p.aspect = aspect;
  for (int k = 0; k < 4; k++)
    p.region[k] = region[k];
  Screen screen = front_screen(eye);
  for (int i = 0; i <= 4; i++)
    for (int j = 0; j <= 4; j++) {
      double s = i / 4.0, t = j / 4.0;
      Ray fitted, exact;
      perspective_ray(&p, s, t, &fitted);
      screen_ray(&screen, s, t, &exact);
      normalize3(fitted.dir);
      normalize3(exact.dir);
      for (int k = 0; k < 3; k++)
        CHECK_NEAR(fitted.dir[k], exact.dir[k], 2e-5);
    }
}

static void perspective_from_matrices_inverts_both_constructions(void) {
  /* From cavetraceOffAxisMatrices: the same camera as cavetraceOffAxisPerspective. */
  const float eye[3] = {-0.3f, 1.5f, 0.8f};
  float view[16], proj[16];
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, eye, 0.1f, 30, view, proj) == 0);
  float a[15], b[15]; /* position, direction, up, fovy, aspect, imageRegion */
  CHECK(cavetracePerspectiveFromMatrices(view, proj, a, a + 3, a + 6, a + 9, a + 10, a + 11) ==
        0);
  CHECK(cavetraceOffAxisPerspective(LL, LR, UR, eye, b, b + 3, b + 6, b + 9, b + 10, b + 11) ==
        0);
  for (int k = 0; k < 15; k++)
    CHECK_NEAR(a[k], b[k], 1e-4);
  /* gluLookAt + a symmetric glFrustum: position, forward, fovy and aspect come back. */
  const float from[3] = {1, 2, 3}, to[3] = {1, 2, 2}, up_vector[3] = {0, 1, 0};
  look_at(from, to, up_vector, view);
  double fovy = 0.7, aspect = 1.5, n = 0.2;
  double top = n * tan(fovy / 2);
  frustum(-top * aspect, top * aspect, -top, top, n, 50, proj);
  float position[3], direction[3], up[3], out_fovy, out_aspect, region[4];
  CHECK(cavetracePerspectiveFromMatrices(view, proj, position, direction, up, &out_fovy,
                                         &out_aspect, region) == ANARI_STATUS_NO_ERROR);
  const float forward[3] = {0, 0, -1};
  for (int k = 0; k < 3; k++) {
    CHECK_NEAR(position[k], from[k], 1e-4);
    CHECK_NEAR(direction[k], forward[k], 1e-5);
    CHECK_NEAR(up[k], up_vector[k], 1e-5);
  }
  CHECK_NEAR(out_fovy, fovy, 1e-5);
  CHECK_NEAR(out_aspect, aspect, 1e-5);
  const double full[4] = {0, 0, 1, 1};
  for (int k = 0; k < 4; k++)
    CHECK_NEAR(region[k], full[k], 1e-5);
}

static void helpers_refuse_bad_input_and_write_nothing(void) {
  const float eye[3] = {0, 1.7f, 0};
  float view[16], proj[16], out[15];
  for (int i = 0; i < 16; i++)
    view[i] = proj[i] = -7;
  CHECK(cavetraceOffAxisMatrices(NULL, LR, UR, eye, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, eye, 0.1f, 10, NULL, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisMatrices(LL, LL, UR, eye, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT); /* zero width */
  CHECK(cavetraceOffAxisMatrices(LL, LR, LR, eye, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT); /* zero height */
  const float on_screen[3] = {0, 1, -1.5f}, behind[3] = {0, 1, -2};
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, on_screen, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, behind, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, eye, 0, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, eye, 1, 0.5f, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  const float not_a_number[3] = {NAN, 0, 0};
  CHECK(cavetraceOffAxisMatrices(LL, LR, UR, not_a_number, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  const float skewed[3] = {1.0f, 3, -1.0f}; /* not a right angle at lowerRight */
  CHECK(cavetraceOffAxisMatrices(LL, LR, skewed, eye, 0.1f, 10, view, proj) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  int untouched = 1;
  for (int i = 0; i < 16; i++)
    untouched = untouched && view[i] == -7 && proj[i] == -7;
  CHECK(untouched);

  for (int i = 0; i < 15; i++)
    out[i] = -7;
  CHECK(cavetraceOffAxisPerspective(LL, LR, UR, behind, out, out + 3, out + 6, out + 9,
                                    out + 10, out + 11) == ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetraceOffAxisPerspective(LL, LR, UR, eye, out, NULL, out + 6, out + 9, out + 10,
                                    out + 11) == ANARI_STATUS_INVALID_ARGUMENT);
  /* Orthographic and singular matrices have no eye. */
  float ortho[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -0.2f, 0, 0, 0, -1, 1};
  float identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  float zero[16] = {0};
  CHECK(cavetracePerspectiveFromMatrices(identity, ortho, out, out + 3, out + 6, out + 9,
                                         out + 10, out + 11) == ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetracePerspectiveFromMatrices(zero, ortho, out, out + 3, out + 6, out + 9, out + 10,
                                         out + 11) == ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(cavetracePerspectiveFromMatrices(NULL, ortho, out, out + 3, out + 6, out + 9, out + 10,
                                         out + 11) == ANARI_STATUS_INVALID_ARGUMENT);
  untouched = 1;
  for (int i = 0; i < 15; i++)
    untouched = untouched && out[i] == -7;
  CHECK(untouched);
}

int main(void) {
  run_test("perspective_with_image_region", perspective_with_image_region);
  run_test("orthographic_scene", orthographic_scene);
  run_test("matrix_scene_with_window_depth", matrix_scene_with_window_depth);
  run_test("listing_5_verbatim", listing_5_verbatim);
  run_test("off_axis_rays_hit_the_screen_where_the_pixel_is",
           off_axis_rays_hit_the_screen_where_the_pixel_is);
  run_test("three_strategies_render_the_same_image", three_strategies_render_the_same_image);
  run_test("stereo_modes_split_the_frame_by_eye", stereo_modes_split_the_frame_by_eye);
  run_test("bad_camera_parameters_are_reported_at_commit",
           bad_camera_parameters_are_reported_at_commit);
  run_test("off_axis_matrices_of_a_centred_eye_are_gl_frustum",
           off_axis_matrices_of_a_centred_eye_are_gl_frustum);
  run_test("off_axis_matrices_of_cave_walls", off_axis_matrices_of_cave_walls);
  run_test("off_axis_perspective_of_a_centred_eye", off_axis_perspective_of_a_centred_eye);
  run_test("off_axis_perspective_rays_meet_the_screen",
           off_axis_perspective_rays_meet_the_screen);
  run_test("perspective_from_matrices_inverts_both_constructions",
           perspective_from_matrices_inverts_both_constructions);
  run_test("helpers_refuse_bad_input_and_write_nothing",
           helpers_refuse_bad_input_and_write_nothing);
  return test_summary();
}
