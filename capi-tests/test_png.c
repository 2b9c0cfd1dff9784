/* cavetraceWriteFramePNG and cavetraceWriteImagePNG: the files they write are well-formed PNGs
 * of the right size (chunk CRCs checked), and every bad argument is reported. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"

static uint32_t crc_table[256];

static uint32_t crc32_of(const unsigned char *bytes, size_t length) {
  if (!crc_table[1])
    for (uint32_t n = 0; n < 256; n++) {
      uint32_t c = n;
      for (int k = 0; k < 8; k++)
        c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      crc_table[n] = c;
    }
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < length; i++)
    c = crc_table[(c ^ bytes[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

static uint32_t big_endian(const unsigned char *p) {
  return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* Checks signature, chunk CRCs, IHDR (8-bit RGBA) and IEND; returns 1 when all hold and the
 * size is width×height. */
static int valid_png(const char *path, uint32_t width, uint32_t height) {
  FILE *file = fopen(path, "rb");
  if (!file)
    return 0;
  static unsigned char data[1 << 20];
  size_t size = fread(data, 1, sizeof data, file);
  fclose(file);
  static const unsigned char signature[8] = {137, 80, 78, 71, 13, 10, 26, 10};
  if (size < 8 || memcmp(data, signature, 8) != 0)
    return 0;
  size_t at = 8;
  int saw_header = 0, saw_data = 0;
  while (at + 12 <= size) {
    uint32_t length = big_endian(data + at);
    const unsigned char *type = data + at + 4;
    if (at + 12 + length > size)
      return 0;
    if (crc32_of(type, length + 4) != big_endian(type + 4 + length))
      return 0;
    if (memcmp(type, "IHDR", 4) == 0) {
      const unsigned char *h = type + 4;
      saw_header = big_endian(h) == width && big_endian(h + 4) == height && h[8] == 8 &&
                   h[9] == 6;
    }
    saw_data |= memcmp(type, "IDAT", 4) == 0;
    if (memcmp(type, "IEND", 4) == 0)
      return saw_header && saw_data && at + 12 == size;
    at += 12 + length;
  }
  return 0;
}

static char directory[] = "/tmp/cavetrace-png-XXXXXX";

static const char *path_of(const char *name) {
  static char path[256];
  snprintf(path, sizeof path, "%s/%s", directory, name);
  return path;
}

static void frame_channels_are_written(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIGeometry geometry = square_at(device, 0, 0, -3, 2);
  ANARISurface surface = matte_surface(device, geometry, 1, 0.5f, 0, 2);
  ANARIWorld world = world_of_surfaces(device, &surface, 1);
  float eye[3] = {0, 0, 0}, dir[3] = {0, 0, -1};
  ANARICamera camera = perspective_camera(device, eye, dir, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 40, 30, world, camera, renderer);
  render_and_wait(device, frame);
  const char *channels[] = {"channel.color", "channel.depth", "channel.objectId",
                            "channel.primitiveId"};
  for (int i = 0; i < 4; i++) {
    char name[64];
    snprintf(name, sizeof name, "%s.png", channels[i]);
    char path[256];
    snprintf(path, sizeof path, "%s", path_of(name));
    CHECK(cavetraceWriteFramePNG(device, frame, channels[i], path) == ANARI_STATUS_NO_ERROR);
    CHECK(valid_png(path, 40, 30));
  }
  /* The helper unmapped what it mapped: the application can map the channel itself. */
  CHECK(anariMapFrame(device, frame, "channel.color", NULL, NULL, NULL) != NULL);
  anariUnmapFrame(device, frame, "channel.color");
  CHECK(log_error_count() == 0);
  ANARIObject objects[] = {geometry, surface, world, camera, renderer, frame};
  for (size_t i = 0; i < 6; i++)
    anariRelease(device, objects[i]);
  close_device(library, device);
}

static void frame_helper_reports_bad_arguments(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  ANARIWorld world = anariNewWorld(device);
  float eye[3] = {0, 0, 0}, dir[3] = {0, 0, -1};
  ANARICamera camera = perspective_camera(device, eye, dir, 1.0f);
  ANARIRenderer renderer = albedo_renderer(device);
  ANARIFrame frame = new_frame(device, 8, 8, world, camera, renderer);
  render_and_wait(device, frame);
  CHECK(cavetraceWriteFramePNG(device, frame, "channel.albedo", path_of("a.png")) ==
        ANARI_STATUS_INVALID_OPERATION);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "cavetraceWriteFramePNG",
                 "channel.albedo", NULL));
  log_clear();
  CHECK(cavetraceWriteFramePNG(device, frame, "channel.color", NULL) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'path' is NULL", NULL));
  log_clear();
  CHECK(cavetraceWriteFramePNG(device, frame, NULL, path_of("b.png")) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'channel' is NULL", NULL));
  log_clear();
  CHECK(cavetraceWriteFramePNG(device, world, "channel.color", path_of("c.png")) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "not a frame", NULL));
  log_clear();
  CHECK(cavetraceWriteFramePNG(device, frame, "channel.color",
                               "/nonexistent-cavetrace-dir/x.png") ==
        ANARI_STATUS_INVALID_OPERATION);
  CHECK(log_find(ANARI_STATUS_INVALID_OPERATION, ANARI_SEVERITY_ERROR, "cannot create",
                 "/nonexistent-cavetrace-dir/x.png", NULL));
  log_clear();
  CHECK(cavetraceWriteFramePNG(NULL, frame, "channel.color", path_of("d.png")) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  /* no device: reported through the callback given to anariLoadLibrary (the only library) */
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "cavetraceWriteFramePNG",
                 "device handle is NULL", NULL));
  CHECK(status_log.count == 1);
  CHECK(access(path_of("a.png"), F_OK) != 0 && access(path_of("d.png"), F_OK) != 0);
  ANARIObject objects[] = {world, camera, renderer, frame};
  for (size_t i = 0; i < 4; i++)
    anariRelease(device, objects[i]);
  close_device(library, device);
}

static void application_pixels_are_written(void) {
  ANARILibrary library;
  ANARIDevice device = open_device(&library);
  unsigned char rgba[6 * 4 * 4];
  for (size_t i = 0; i < sizeof rgba; i++)
    rgba[i] = (unsigned char)(i * 7);
  CHECK(cavetraceWriteImagePNG(device, path_of("pixels.png"), 6, 4, ANARI_UFIXED8_RGBA_SRGB,
                               rgba) == ANARI_STATUS_NO_ERROR);
  CHECK(valid_png(path_of("pixels.png"), 6, 4));
  float depth[3] = {1, 2, INFINITY};
  CHECK(cavetraceWriteImagePNG(device, path_of("depth.png"), 3, 1, ANARI_FLOAT32, depth) ==
        ANARI_STATUS_NO_ERROR);
  CHECK(valid_png(path_of("depth.png"), 3, 1));
  CHECK(log_error_count() == 0);

  CHECK(cavetraceWriteImagePNG(device, path_of("x.png"), 6, 4, ANARI_FLOAT64_VEC4, rgba) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "cavetraceWriteImagePNG",
                 "ANARI_FLOAT64_VEC4", NULL));
  log_clear();
  CHECK(cavetraceWriteImagePNG(device, path_of("x.png"), 6, 4, ANARI_UFIXED8_RGBA_SRGB, NULL) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "'pixels' is NULL", NULL));
  log_clear();
  CHECK(cavetraceWriteImagePNG(device, path_of("x.png"), 0, 4, ANARI_UFIXED8_RGBA_SRGB, rgba) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_find(ANARI_STATUS_INVALID_ARGUMENT, ANARI_SEVERITY_ERROR, "empty", NULL));
  log_clear();
  CHECK(cavetraceWriteImagePNG(device, NULL, 6, 4, ANARI_UFIXED8_RGBA_SRGB, rgba) ==
        ANARI_STATUS_INVALID_ARGUMENT);
  CHECK(log_error_count() == 1);
  CHECK(access(path_of("x.png"), F_OK) != 0);
  close_device(library, device);
}

int main(void) {
  if (!mkdtemp(directory)) {
    perror("mkdtemp");
    return 1;
  }
  run_test("frame_channels_are_written", frame_channels_are_written);
  run_test("frame_helper_reports_bad_arguments", frame_helper_reports_bad_arguments);
  run_test("application_pixels_are_written", application_pixels_are_written);
  char command[300];
  snprintf(command, sizeof command, "rm -rf '%s'", directory);
  if (system(command) != 0)
    printf("  could not remove %s\n", directory);
  return test_summary();
}
