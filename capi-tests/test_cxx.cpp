// The header used from C++17: handles in RAII wrappers, a lambda as status callback, a triangle
// rendered and read back, and an error reported with its code.
#include <cavetrace.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

int passed = 0, failed = 0, failures = 0;

void check(bool ok, const char *what, int line) {
  if (!ok) {
    ++failures;
    std::printf("  test_cxx.cpp:%d: check failed: %s\n", line, what);
  }
}
#define CHECK(condition) check((condition), #condition, __LINE__)

template <typename Test> void run(const char *name, Test test) {
  failures = 0;
  test();
  if (failures == 0) {
    ++passed;
    std::printf("ok   %s\n", name);
  } else {
    ++failed;
    std::printf("FAIL %s\n", name);
  }
}

struct Message {
  int severity;
  int code;
  std::string text;
};

// One reference to an ANARI object, released when the wrapper goes.
class Handle {
public:
  Handle(ANARIDevice device, ANARIObject object) : device_(device), object_(object) {}
  Handle(const Handle &) = delete;
  Handle &operator=(const Handle &) = delete;
  ~Handle() {
    if (object_)
      anariRelease(device_, object_);
  }
  ANARIObject get() const { return object_; }

private:
  ANARIDevice device_;
  ANARIObject object_;
};

class Device {
public:
  Device() {
    library_ = anariLoadLibrary(
        "cavetrace",
        [](const void *user, ANARIDevice, ANARIObject, ANARIDataType, ANARIStatusSeverity severity,
           ANARIStatusCode code, const char *message) {
          auto *log = static_cast<std::vector<Message> *>(const_cast<void *>(user));
          log->push_back({severity, code, message});
        },
        &messages);
    device_ = anariNewDevice(library_, "default");
  }
  Device(const Device &) = delete;
  Device &operator=(const Device &) = delete;
  ~Device() {
    anariRelease(device_, device_);
    anariUnloadLibrary(library_);
  }
  ANARIDevice get() const { return device_; }
  std::vector<Message> messages;

private:
  ANARILibrary library_ = nullptr;
  ANARIDevice device_ = nullptr;
};

template <typename T> void set(ANARIDevice d, ANARIObject o, const char *name, int type, const T &v) {
  anariSetParameter(d, o, name, type, &v);
}

void triangle_renders_and_reads_back() {
  Device device;
  ANARIDevice d = device.get();
  CHECK(d != nullptr);
  const std::array<float, 9> vertices = {-1, -1, -3, 1, -1, -3, 0, 1, -3};
  Handle positions(d, anariNewArray1D(d, nullptr, nullptr, nullptr, ANARI_FLOAT32_VEC3, 3));
  if (void *memory = anariMapArray(d, positions.get())) {
    std::memcpy(memory, vertices.data(), sizeof vertices);
  }
  anariUnmapArray(d, positions.get());
  Handle geometry(d, anariNewGeometry(d, "triangle"));
  set(d, geometry.get(), "vertex.position", ANARI_ARRAY1D, positions.get());
  anariCommitParameters(d, geometry.get());
  Handle material(d, anariNewMaterial(d, "matte"));
  set(d, material.get(), "color", ANARI_FLOAT32_VEC3, std::array<float, 3>{0, 0, 1});
  anariCommitParameters(d, material.get());
  Handle surface(d, anariNewSurface(d));
  set(d, surface.get(), "geometry", ANARI_GEOMETRY, geometry.get());
  set(d, surface.get(), "material", ANARI_MATERIAL, material.get());
  anariCommitParameters(d, surface.get());
  Handle surfaces(d, anariNewArray1D(d, nullptr, nullptr, nullptr, ANARI_SURFACE, 1));
  if (auto *slot = static_cast<ANARIObject *>(anariMapArray(d, surfaces.get()))) {
    slot[0] = surface.get();
  }
  anariUnmapArray(d, surfaces.get());
  Handle world(d, anariNewWorld(d));
  set(d, world.get(), "surface", ANARI_ARRAY1D, surfaces.get());
  anariCommitParameters(d, world.get());
  Handle camera(d, anariNewCamera(d, "perspective"));
  set(d, camera.get(), "position", ANARI_FLOAT32_VEC3, std::array<float, 3>{0, 0, 0});
  anariCommitParameters(d, camera.get());
  Handle renderer(d, anariNewRenderer(d, "default"));
  set(d, renderer.get(), "ambientRadiance", ANARI_FLOAT32, 1.0f);
  anariCommitParameters(d, renderer.get());
  Handle frame(d, anariNewFrame(d));
  set(d, frame.get(), "size", ANARI_UINT32_VEC2, std::array<uint32_t, 2>{32, 32});
  set(d, frame.get(), "channel.color", ANARI_DATA_TYPE, ANARIDataType{ANARI_FLOAT32_VEC4});
  set(d, frame.get(), "channel.depth", ANARI_DATA_TYPE, ANARIDataType{ANARI_FLOAT32});
  set(d, frame.get(), "world", ANARI_WORLD, world.get());
  set(d, frame.get(), "camera", ANARI_CAMERA, camera.get());
  set(d, frame.get(), "renderer", ANARI_RENDERER, renderer.get());
  anariCommitParameters(d, frame.get());
  anariRenderFrame(d, frame.get());
  CHECK(anariFrameReady(d, frame.get(), ANARI_WAIT) == 1);
  uint32_t width = 0, height = 0;
  ANARIDataType type = ANARI_UNKNOWN;
  const auto *color = static_cast<const float *>(
      anariMapFrame(d, frame.get(), "channel.color", &width, &height, &type));
  CHECK(color != nullptr && width == 32 && height == 32 && type == ANARI_FLOAT32_VEC4);
  if (color) {
    const float *centre = color + 4 * (16 * 32 + 16);
    CHECK(std::fabs(centre[2] - 1.0f) < 0.01f && centre[0] == 0.0f);
    CHECK(color[0] == 0.0f && color[3] == 1.0f); // bottom-left corner: background
  }
  anariUnmapFrame(d, frame.get(), "channel.color");
  const auto *depth = static_cast<const float *>(
      anariMapFrame(d, frame.get(), "channel.depth", nullptr, nullptr, nullptr));
  CHECK(depth != nullptr && std::isinf(depth[0]));
  if (depth) {
    float x = (2 * 16.5f / 32 - 1) * std::tan(0.5f * 1.0471975512f);
    CHECK(std::fabs(depth[16 * 32 + 16] - 3.0f * std::sqrt(1 + 2 * x * x)) < 1e-3f);
  }
  anariUnmapFrame(d, frame.get(), "channel.depth");
  for (const Message &m : device.messages) {
    CHECK(m.severity > ANARI_SEVERITY_ERROR);
  }
}

void errors_arrive_with_their_codes() {
  Device device;
  ANARIDevice d = device.get();
  Handle material(d, anariNewMaterial(d, "matte"));
  set(d, material.get(), "color", ANARI_FLOAT32, 0.5f);
  bool found = false;
  for (const Message &m : device.messages) {
    found |= m.code == ANARI_STATUS_INVALID_ARGUMENT && m.severity == ANARI_SEVERITY_ERROR &&
             m.text.find("'color'") != std::string::npos;
  }
  CHECK(found);
}

} // namespace

int main() {
  run("triangle_renders_and_reads_back", triangle_renders_and_reads_back);
  run("errors_arrive_with_their_codes", errors_arrive_with_their_codes);
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
