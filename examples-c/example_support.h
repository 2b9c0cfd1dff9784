/*
 * What the examples in this folder share (tutorial.c, the README's first program, spells every
 * step out instead). Included as "example_support.h", so an example builds with the same
 * command from any directory:
 *   print_status         the status callback: prints errors and warnings and counts the errors
 *                        in the int its user data points to
 *   perspective_camera   a committed perspective camera, y up
 *   render_to_png        renders a world into a new frame and writes its colour to a PNG file
 */
#ifndef CAVETRACE_EXAMPLE_SUPPORT_H
#define CAVETRACE_EXAMPLE_SUPPORT_H

#include <stdint.h>
#include <stdio.h>

#include <cavetrace.h>

static inline void print_status(const void *user_data, ANARIDevice device, ANARIObject source,
                                ANARIDataType source_type, ANARIStatusSeverity severity,
                                ANARIStatusCode code, const char *message) {
  (void)device, (void)source, (void)source_type, (void)code;
  if (severity <= ANARI_SEVERITY_ERROR)
    ++*(int *)user_data;
  if (severity <= ANARI_SEVERITY_WARNING)
    fprintf(stderr, "[cavetrace] %s\n", message);
}

/* A perspective camera at `eye` looking along `forward`, y up; `fovy` in radians, `aspect` the
 * frame's width / height. */
static inline ANARICamera perspective_camera(ANARIDevice device, const float eye[3],
                                             const float forward[3], float aspect, float fovy) {
  ANARICamera camera = anariNewCamera(device, "perspective");
  float up[] = {0, 1, 0};
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, eye);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, forward);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariSetParameter(device, camera, "fovy", ANARI_FLOAT32, &fovy);
  anariCommitParameters(device, camera);
  return camera;
}

/* Renders `world` through `camera` with `renderer` into a width × height sRGB frame, `frames`
 * frames accumulated (more than one: the frame's accumulation on), and writes the colour to
 * `path`. Returns cavetraceWriteFramePNG's status. */
static inline int render_to_png(ANARIDevice device, ANARIWorld world, ANARICamera camera,
                                ANARIRenderer renderer, uint32_t width, uint32_t height,
                                int frames, const char *path) {
  ANARIFrame frame = anariNewFrame(device);
  uint32_t size[] = {width, height};
  ANARIDataType color_type = ANARI_UFIXED8_RGBA_SRGB;
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(device, frame, "channel.color", ANARI_DATA_TYPE, &color_type);
  if (frames > 1) {
    uint8_t accumulate = 1; /* ANARI_BOOL is one byte */
    anariSetParameter(device, frame, "accumulation", ANARI_BOOL, &accumulate);
  }
  anariSetParameter(device, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(device, frame, "camera", ANARI_CAMERA, &camera);
  anariSetParameter(device, frame, "renderer", ANARI_RENDERER, &renderer);
  anariCommitParameters(device, frame);
  for (int f = 0; f < frames; f++) {
    anariRenderFrame(device, frame);
    anariFrameReady(device, frame, ANARI_WAIT);
  }
  int status = cavetraceWriteFramePNG(device, frame, "channel.color", path);
  if (status == ANARI_STATUS_NO_ERROR)
    printf("wrote %s\n", path);
  anariRelease(device, frame);
  return status;
}

#endif
