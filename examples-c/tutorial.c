/*
 * The first cavetrace program: one sphere lit by one directional light, rendered once and
 * written to a PNG file. Built from this checkout (see the README, "A first program"):
 *
 *   cargo build --release
 *   ln -sf libcavetrace.so target/release/libcavetrace.so.0
 *   cc -std=c99 examples-c/tutorial.c -Iinclude -Ltarget/release -lcavetrace \
 *      -Wl,-rpath,"$PWD/target/release" -o tutorial
 *   mkdir -p out && ./tutorial out/tutorial.png
 */
#include <stdio.h>

#include <cavetrace.h>

/* Every error, warning and note of the device arrives here, with the object it concerns. */
static void print_status(const void *user_data, ANARIDevice device, ANARIObject source,
                         ANARIDataType source_type, ANARIStatusSeverity severity,
                         ANARIStatusCode code, const char *message) {
  (void)device, (void)source, (void)source_type, (void)code;
  int *errors = (int *)user_data;
  if (severity <= ANARI_SEVERITY_ERROR)
    ++*errors;
  if (severity <= ANARI_SEVERITY_WARNING)
    fprintf(stderr, "[cavetrace] %s\n", message);
}

int main(int argc, char **argv) {
  const char *output = argc > 1 ? argv[1] : "tutorial.png";
  int errors = 0;

  ANARILibrary library = anariLoadLibrary("cavetrace", print_status, &errors);
  ANARIDevice device = anariNewDevice(library, "default");
  if (!device)
    return 1;

  /* Geometry: one sphere of radius 1 at (0, 0, -4). Positions are an array, one per sphere;
   * with a NULL deleter the array uses the application's memory, which must outlive it. */
  float centers[] = {0, 0, -4};
  float radius = 1;
  ANARIArray1D center_array = anariNewArray1D(device, centers, NULL, NULL, ANARI_FLOAT32_VEC3, 1);
  ANARIGeometry sphere = anariNewGeometry(device, "sphere");
  anariSetParameter(device, sphere, "vertex.position", ANARI_ARRAY1D, &center_array);
  anariSetParameter(device, sphere, "radius", ANARI_FLOAT32, &radius);
  anariCommitParameters(device, sphere);

  ANARIMaterial material = anariNewMaterial(device, "matte");
  float orange[] = {0.9f, 0.45f, 0.1f};
  anariSetParameter(device, material, "color", ANARI_FLOAT32_VEC3, orange);
  anariCommitParameters(device, material);

  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &sphere);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);

  /* The default renderer shows only what light reaches: without a light and without ambient
   * light every surface is black. */
  ANARILight light = anariNewLight(device, "directional");
  float direction[] = {1, -1, -1}, irradiance = 3;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);

  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D surfaces = anariNewArray1D(device, &surface, NULL, NULL, ANARI_SURFACE, 1);
  ANARIArray1D lights = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surfaces);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &lights);
  anariCommitParameters(device, world);

  /* A perspective camera at the origin looking down -z; aspect = the frame's width / height. */
  ANARICamera camera = anariNewCamera(device, "perspective");
  float eye[] = {0, 0, 0}, forward[] = {0, 0, -1}, up[] = {0, 1, 0};
  float aspect = 640.0f / 480.0f, fovy = 0.8f; /* radians */
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, eye);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, forward);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariSetParameter(device, camera, "fovy", ANARI_FLOAT32, &fovy);
  anariCommitParameters(device, camera);

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[] = {0.1f, 0.1f, 0.15f, 1}, ambient = 0.3f;
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariSetParameter(device, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
  anariCommitParameters(device, renderer);

  /* The frame ties it together: its size, the channels to render, world, camera, renderer. */
  ANARIFrame frame = anariNewFrame(device);
  uint32_t size[] = {640, 480};
  ANARIDataType color_type = ANARI_UFIXED8_RGBA_SRGB;
  anariSetParameter(device, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(device, frame, "channel.color", ANARI_DATA_TYPE, &color_type);
  anariSetParameter(device, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(device, frame, "camera", ANARI_CAMERA, &camera);
  anariSetParameter(device, frame, "renderer", ANARI_RENDERER, &renderer);
  anariCommitParameters(device, frame);

  /* Rendering is asynchronous: anariRenderFrame returns at once, anariFrameReady waits. */
  anariRenderFrame(device, frame);
  anariFrameReady(device, frame, ANARI_WAIT);
  int status = cavetraceWriteFramePNG(device, frame, "channel.color", output);
  if (status == ANARI_STATUS_NO_ERROR)
    printf("wrote %s\n", output);

  /* Release what we created; objects still used by others live on until they are not. */
  ANARIObject objects[] = {center_array, sphere, material, surface, light,    surfaces,
                           lights,       world,  camera,   renderer, frame};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
