/*
 * The smallest complete cavetrace program: two triangles lit by one directional light, rendered
 * once and written to a PNG file.
 *
 *   cc -std=c99 tutorial.c $(pkg-config --cflags --libs cavetrace) -o tutorial
 *   ./tutorial [output.png]
 */
#include <stdio.h>

#include <cavetrace.h>

/* Every error, warning and note of the device arrives here. */
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

  /* Geometry: two triangles (a quad), vertex colours interpolated across them. */
  float positions[] = {-1, -1, -3, 1, -1, -3, 1, 1, -3, -1, 1, -3};
  float colors[] = {1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 1, 1, 1, 0, 1};
  uint32_t indices[] = {0, 1, 2, 0, 2, 3};
  /* Arrays with a NULL deleter share the application's memory, which must outlive them. */
  ANARIArray1D position_array =
      anariNewArray1D(device, positions, NULL, NULL, ANARI_FLOAT32_VEC3, 4);
  ANARIArray1D color_array = anariNewArray1D(device, colors, NULL, NULL, ANARI_FLOAT32_VEC4, 4);
  ANARIArray1D index_array = anariNewArray1D(device, indices, NULL, NULL, ANARI_UINT32_VEC3, 2);
  ANARIGeometry geometry = anariNewGeometry(device, "triangle");
  anariSetParameter(device, geometry, "vertex.position", ANARI_ARRAY1D, &position_array);
  anariSetParameter(device, geometry, "vertex.color", ANARI_ARRAY1D, &color_array);
  anariSetParameter(device, geometry, "primitive.index", ANARI_ARRAY1D, &index_array);
  anariCommitParameters(device, geometry);

  /* A matte material coloured by the geometry's "color" attribute. */
  ANARIMaterial material = anariNewMaterial(device, "matte");
  anariSetParameter(device, material, "color", ANARI_STRING, "color");
  anariCommitParameters(device, material);

  ANARISurface surface = anariNewSurface(device);
  anariSetParameter(device, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(device, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(device, surface);

  /* One light, shining from behind the viewer's left shoulder. */
  ANARILight light = anariNewLight(device, "directional");
  float direction[] = {0.3f, -0.3f, -1};
  float irradiance = 3;
  anariSetParameter(device, light, "direction", ANARI_FLOAT32_VEC3, direction);
  anariSetParameter(device, light, "irradiance", ANARI_FLOAT32, &irradiance);
  anariCommitParameters(device, light);

  /* The world holds the surface and the light. */
  ANARIWorld world = anariNewWorld(device);
  ANARIArray1D surfaces = anariNewArray1D(device, &surface, NULL, NULL, ANARI_SURFACE, 1);
  ANARIArray1D lights = anariNewArray1D(device, &light, NULL, NULL, ANARI_LIGHT, 1);
  anariSetParameter(device, world, "surface", ANARI_ARRAY1D, &surfaces);
  anariSetParameter(device, world, "light", ANARI_ARRAY1D, &lights);
  anariCommitParameters(device, world);

  /* A perspective camera at the origin looking down -z. */
  ANARICamera camera = anariNewCamera(device, "perspective");
  float eye[] = {0, 0, 0}, forward[] = {0, 0, -1}, up[] = {0, 1, 0};
  float aspect = 640.0f / 480.0f;
  anariSetParameter(device, camera, "position", ANARI_FLOAT32_VEC3, eye);
  anariSetParameter(device, camera, "direction", ANARI_FLOAT32_VEC3, forward);
  anariSetParameter(device, camera, "up", ANARI_FLOAT32_VEC3, up);
  anariSetParameter(device, camera, "aspect", ANARI_FLOAT32, &aspect);
  anariCommitParameters(device, camera);

  ANARIRenderer renderer = anariNewRenderer(device, "default");
  float background[] = {0.1f, 0.1f, 0.15f, 1};
  anariSetParameter(device, renderer, "background", ANARI_FLOAT32_VEC4, background);
  anariCommitParameters(device, renderer);

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
  ANARIObject objects[] = {position_array, color_array, index_array, geometry, material,
                           surface,        light,       surfaces,    lights,   world,
                           camera,         renderer,    frame};
  for (size_t i = 0; i < sizeof objects / sizeof objects[0]; i++)
    anariRelease(device, objects[i]);
  anariRelease(device, device);
  anariUnloadLibrary(library);
  return status == ANARI_STATUS_NO_ERROR && errors == 0 ? 0 : 1;
}
