#!/usr/bin/env python3
"""A CAVE's front wall in stereo, driven from Python through the ANARI C API (ctypes).

The scene: a cloud of spheres just in front of the wall, a floor, one light. The tracked head stands
half a metre left of the wall's centre; the offAxis camera renders both eyes side by side,
with the parallax channel, and the script writes the pair and prints the parallax range against
the comfort limit (0.03 x the head's distance to the wall).

    python3 examples-python/cave_wall.py [output.png] [wall resolution]

The ANARI calls go to one of two libraries:
- the Khronos front end, as an application written for any ANARI device does it: set
  ANARI_FRONT_END to the SDK's libanari.so; the front end then loads cavetrace's SDK library
  (libanari_library_cavetrace.so, from `cargo build --release`) from the loader's search path,
  so put target/release on LD_LIBRARY_PATH;
- otherwise cavetrace itself, which exports the same C API: CAVETRACE_LIBRARY (a path to
  libcavetrace.so), else target/release/libcavetrace.so of this checkout, else the loader's
  search path.
The image is read back with anariMapFrame and written by this script. Only the standard
library is used.
"""

import ctypes
import math
import os
import random
import struct
import sys
import zlib

# Values of the ANARI enums used here (include/cavetrace.h has them all).
ANARI_DATA_TYPE = 100
ANARI_STRING = 101
ANARI_ARRAY1D = 504
ANARI_CAMERA = 507
ANARI_GEOMETRY = 509
ANARI_LIGHT = 512
ANARI_MATERIAL = 513
ANARI_RENDERER = 514
ANARI_SURFACE = 515
ANARI_WORLD = 519
ANARI_UINT32_VEC2 = 1021
ANARI_FLOAT32 = 1068
ANARI_FLOAT32_VEC2 = 1069
ANARI_FLOAT32_VEC3 = 1070
ANARI_FLOAT32_VEC4 = 1071
ANARI_UFIXED8_RGBA_SRGB = 2003
ANARI_SEVERITY_ERROR = 2
ANARI_SEVERITY_WARNING = 3
ANARI_WAIT = 1

Handle = ctypes.c_void_p
StatusCallback = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, Handle, Handle, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_char_p
)


def load_library():
    front_end = os.environ.get("ANARI_FRONT_END")
    if front_end:
        return ctypes.CDLL(front_end)
    here = os.path.dirname(os.path.abspath(__file__))
    candidates = [
        os.environ.get("CAVETRACE_LIBRARY"),
        os.path.join(here, "..", "target", "release", "libcavetrace.so"),
        "libcavetrace.so.0",
    ]
    for path in candidates:
        if path and (os.path.exists(path) or not os.path.isabs(path)):
            try:
                return ctypes.CDLL(path)
            except OSError:
                continue
    sys.exit("libcavetrace.so not found: build it with `cargo build --release` or set CAVETRACE_LIBRARY")


lib = load_library()
for name, restype, argtypes in [
    ("anariLoadLibrary", Handle, [ctypes.c_char_p, StatusCallback, ctypes.c_void_p]),
    ("anariUnloadLibrary", None, [Handle]),
    ("anariNewDevice", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewArray1D", Handle, [Handle, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_uint64]),
    ("anariNewGeometry", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewMaterial", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewLight", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewCamera", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewRenderer", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewSurface", Handle, [Handle]),
    ("anariNewWorld", Handle, [Handle]),
    ("anariNewFrame", Handle, [Handle]),
    ("anariSetParameter", None, [Handle, Handle, ctypes.c_char_p, ctypes.c_int, ctypes.c_void_p]),
    ("anariCommitParameters", None, [Handle, Handle]),
    ("anariMapArray", ctypes.c_void_p, [Handle, Handle]),
    ("anariUnmapArray", None, [Handle, Handle]),
    ("anariRelease", None, [Handle, Handle]),
    ("anariRenderFrame", None, [Handle, Handle]),
    ("anariFrameReady", ctypes.c_int, [Handle, Handle, ctypes.c_int]),
    ("anariGetProperty", ctypes.c_int, [Handle, Handle, ctypes.c_char_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_int]),
    ("anariMapFrame", ctypes.c_void_p, [Handle, Handle, ctypes.c_char_p, ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_int)]),
    ("anariUnmapFrame", None, [Handle, Handle, ctypes.c_char_p]),
]:
    function = getattr(lib, name)
    function.restype = restype
    function.argtypes = argtypes

errors = []


@StatusCallback
def print_status(user_data, device, source, source_type, severity, code, message):
    if severity <= ANARI_SEVERITY_WARNING:
        print("[cavetrace]", message.decode(), file=sys.stderr)
    if severity <= ANARI_SEVERITY_ERROR:
        errors.append(message.decode())


class Device:
    """Thin helpers over the C calls: values are packed with ctypes, objects are handles."""

    def __init__(self):
        self.library = lib.anariLoadLibrary(b"cavetrace", print_status, None)
        self.handle = lib.anariNewDevice(self.library, b"default")
        if not self.handle:
            sys.exit("no cavetrace device")

    def set(self, obj, name, data_type, value):
        if data_type == ANARI_STRING:
            lib.anariSetParameter(self.handle, obj, name.encode(), data_type, ctypes.c_char_p(value.encode()))
        elif data_type in (ANARI_FLOAT32, ANARI_FLOAT32_VEC2, ANARI_FLOAT32_VEC3, ANARI_FLOAT32_VEC4):
            values = (ctypes.c_float * len(value))(*value) if isinstance(value, (list, tuple)) else ctypes.c_float(value)
            lib.anariSetParameter(self.handle, obj, name.encode(), data_type, ctypes.byref(values))
        elif data_type == ANARI_UINT32_VEC2:
            lib.anariSetParameter(self.handle, obj, name.encode(), data_type, ctypes.byref((ctypes.c_uint32 * 2)(*value)))
        elif data_type == ANARI_DATA_TYPE:
            lib.anariSetParameter(self.handle, obj, name.encode(), data_type, ctypes.byref(ctypes.c_int(value)))
        else:  # an object handle
            lib.anariSetParameter(self.handle, obj, name.encode(), data_type, ctypes.byref(Handle(value)))

    def commit(self, obj):
        lib.anariCommitParameters(self.handle, obj)
        return obj

    def release(self, *objects):
        for obj in objects:
            lib.anariRelease(self.handle, obj)

    def array(self, element_type, values):
        """A managed 1D array: made without memory, mapped, filled, unmapped. (Memory passed to
        anariNewArray1D without a deleter is shared, and would have to outlive the array.)"""
        if element_type in (ANARI_SURFACE, ANARI_LIGHT):
            data = (Handle * len(values))(*values)
        else:
            flat = [component for value in values for component in value]
            data = (ctypes.c_float * len(flat))(*flat)
        array = lib.anariNewArray1D(self.handle, None, None, None, element_type, len(values))
        ctypes.memmove(lib.anariMapArray(self.handle, array), data, ctypes.sizeof(data))
        lib.anariUnmapArray(self.handle, array)
        return array


def write_png(device, frame, path):
    """Writes the frame's UFIXED8_RGBA_SRGB colour channel as an 8-bit RGBA PNG (frames store
    rows bottom to top, PNG top to bottom). Returns whether it worked."""
    width, height, data_type = ctypes.c_uint32(), ctypes.c_uint32(), ctypes.c_int()
    pixels = lib.anariMapFrame(device.handle, frame, b"channel.color", ctypes.byref(width), ctypes.byref(height), ctypes.byref(data_type))
    if not pixels or data_type.value != ANARI_UFIXED8_RGBA_SRGB:
        return False
    w, h = width.value, height.value
    data = ctypes.string_at(pixels, 4 * w * h)
    lib.anariUnmapFrame(device.handle, frame, b"channel.color")
    rows = b"".join(b"\0" + data[4 * w * y:4 * w * (y + 1)] for y in reversed(range(h)))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)
    with open(path, "wb") as out:
        out.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    return True


def sphere_cloud(device, count=2000):
    random.seed(7)
    centres = []
    while len(centres) < count:
        p = [random.uniform(-1, 1) for _ in range(3)]
        if sum(c * c for c in p) <= 1:
            centres.append((-0.3 + 0.45 * p[0], 1.5 + 0.45 * p[1], -1.1 + 0.45 * p[2]))
    geometry = lib.anariNewGeometry(device.handle, b"sphere")
    positions = device.array(ANARI_FLOAT32_VEC3, centres)
    device.set(geometry, "vertex.position", ANARI_ARRAY1D, positions)
    device.set(geometry, "radius", ANARI_FLOAT32, 0.025)
    device.commit(geometry)
    material = lib.anariNewMaterial(device.handle, b"physicallyBased")
    device.set(material, "baseColor", ANARI_FLOAT32_VEC3, [0.9, 0.55, 0.2])
    device.set(material, "metallic", ANARI_FLOAT32, 0.0)
    device.commit(material)
    device.release(positions)
    return geometry, material


def floor(device):
    corners = [(-6, 0, 6), (6, 0, 6), (6, 0, -6), (-6, 0, -6)]
    geometry = lib.anariNewGeometry(device.handle, b"quad")
    positions = device.array(ANARI_FLOAT32_VEC3, corners)
    device.set(geometry, "vertex.position", ANARI_ARRAY1D, positions)
    device.commit(geometry)
    material = lib.anariNewMaterial(device.handle, b"matte")
    device.set(material, "color", ANARI_FLOAT32_VEC3, [0.3, 0.3, 0.35])
    device.commit(material)
    device.release(positions)
    return geometry, material


def main():
    output = sys.argv[1] if len(sys.argv) > 1 else "cave_wall.png"
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 256
    device = Device()

    surfaces = []
    parts = []
    for geometry, material in (sphere_cloud(device), floor(device)):
        surface = lib.anariNewSurface(device.handle)
        device.set(surface, "geometry", ANARI_GEOMETRY, geometry)
        device.set(surface, "material", ANARI_MATERIAL, material)
        surfaces.append(device.commit(surface))
        parts += [geometry, material]
    light = lib.anariNewLight(device.handle, b"directional")
    device.set(light, "direction", ANARI_FLOAT32_VEC3, [0.3, -1.0, -0.5])
    device.set(light, "irradiance", ANARI_FLOAT32, 2.5)
    device.commit(light)
    world = lib.anariNewWorld(device.handle)
    surface_array = device.array(ANARI_SURFACE, surfaces)
    light_array = device.array(ANARI_LIGHT, [light])
    device.set(world, "surface", ANARI_ARRAY1D, surface_array)
    device.set(world, "light", ANARI_ARRAY1D, light_array)
    device.commit(world)

    # The front wall of a 3 m CAVE (z = -1.5) and a tracked head in front of it.
    head = [-0.5, 1.7, 0.4]
    camera = lib.anariNewCamera(device.handle, b"offAxis")
    device.set(camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, [-1.5, 0.0, -1.5])
    device.set(camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, [1.5, 0.0, -1.5])
    device.set(camera, "screen.upperRight", ANARI_FLOAT32_VEC3, [1.5, 3.0, -1.5])
    device.set(camera, "position", ANARI_FLOAT32_VEC3, head)
    device.set(camera, "stereoMode", ANARI_STRING, "sideBySide")
    device.commit(camera)
    renderer = lib.anariNewRenderer(device.handle, b"default")
    device.set(renderer, "background", ANARI_FLOAT32_VEC4, [0.1, 0.14, 0.26, 1.0])
    device.set(renderer, "ambientRadiance", ANARI_FLOAT32, 0.4)
    device.commit(renderer)

    frame = lib.anariNewFrame(device.handle)
    device.set(frame, "size", ANARI_UINT32_VEC2, [2 * n, n])
    device.set(frame, "channel.color", ANARI_DATA_TYPE, ANARI_UFIXED8_RGBA_SRGB)
    device.set(frame, "channel.parallax", ANARI_DATA_TYPE, ANARI_FLOAT32)
    device.set(frame, "world", ANARI_WORLD, world)
    device.set(frame, "camera", ANARI_CAMERA, camera)
    device.set(frame, "renderer", ANARI_RENDERER, renderer)
    device.commit(frame)
    lib.anariRenderFrame(device.handle, frame)
    lib.anariFrameReady(device.handle, frame, ANARI_WAIT)

    duration = ctypes.c_float(0)
    lib.anariGetProperty(device.handle, frame, b"duration", ANARI_FLOAT32, ctypes.byref(duration), 4, ANARI_WAIT)
    parallax = (ctypes.c_float * 2)()
    lib.anariGetProperty(device.handle, frame, b"parallaxRange", ANARI_FLOAT32_VEC2, parallax, 8, ANARI_WAIT)
    written = write_png(device, frame, output)
    limit = 0.03 * (head[2] + 1.5)
    through = "the Khronos front end" if os.environ.get("ANARI_FRONT_END") else "cavetrace's C API"
    comfortable = -limit <= parallax[0] and parallax[1] <= limit
    print(f"wrote {output} through {through}: {2 * n}x{n} stereo pair in {1e3 * duration.value:.1f} ms; parallax "
          f"{1e3 * parallax[0]:.1f} to {1e3 * parallax[1]:.1f} mm, comfort limit ±{1e3 * limit:.1f} mm: "
          f"{'comfortable' if comfortable else 'NOT comfortable'}")

    device.release(frame, renderer, camera, world, surface_array, light_array, light, *surfaces, *parts)
    lib.anariRelease(device.handle, device.handle)
    lib.anariUnloadLibrary(device.library)
    if not written or errors or math.isnan(parallax[0]):
        sys.exit(1)


if __name__ == "__main__":
    main()
