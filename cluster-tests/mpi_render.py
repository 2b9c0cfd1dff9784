#!/usr/bin/env python3
"""Rendering across MPI ranks from Python: mpi4py for MPI, ctypes for the ANARI C API.

    mpirun -np 4 python3 cluster-tests/mpi_render.py

Object k of the scene (a floor mesh, a sphere whose shadow falls on the floor, a mirror, an
instanced mesh, three spheres) belongs to rank k mod N. Rank 0 renders the whole scene alone
(its frame's communicator is MPI_COMM_SELF) and compares with the frame every rank rendered
together: 'dataParallel' ids and depth bit for bit, colour within 1/255; 'replicated' (every
rank holds the whole scene) every channel byte for byte. The ranks' 'pixelsTraced' add up to the
frame's pixels. The library: CAVETRACE_LIBRARY, else target/debug/libcavetrace.so (built with
`cargo build --features mpi`). Prints "ok   name" / "FAIL name" on rank 0; exits 1 on a failure.
"""

import ctypes
import os
import struct
import sys

from mpi4py import MPI

ANARI_DATA_TYPE = 100
ANARI_STRING = 101
ANARI_VOID_POINTER = 102
ANARI_STATUS_CALLBACK = 202
ANARI_ARRAY1D = 504
ANARI_CAMERA = 507
ANARI_GEOMETRY = 509
ANARI_GROUP = 510
ANARI_INSTANCE = 511
ANARI_LIGHT = 512
ANARI_MATERIAL = 513
ANARI_RENDERER = 514
ANARI_SURFACE = 515
ANARI_WORLD = 519
ANARI_UINT32 = 1020
ANARI_UINT32_VEC2 = 1021
ANARI_UINT32_VEC3 = 1022
ANARI_UINT64 = 1028
ANARI_FLOAT32 = 1068
ANARI_FLOAT32_VEC3 = 1070
ANARI_FLOAT32_VEC4 = 1071
ANARI_FLOAT32_MAT4 = 2014
ANARI_UFIXED8_RGBA_SRGB = 2003
ANARI_SEVERITY_ERROR = 2
ANARI_WAIT = 1

WIDTH, HEIGHT = 80, 60
CHANNELS = [
    ("channel.color", ANARI_UFIXED8_RGBA_SRGB),
    ("channel.depth", ANARI_FLOAT32),
    ("channel.primitiveId", ANARI_UINT32),
    ("channel.objectId", ANARI_UINT32),
    ("channel.instanceId", ANARI_UINT32),
]

Handle = ctypes.c_void_p
StatusCallback = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, Handle, Handle, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_char_p
)

here = os.path.dirname(os.path.abspath(__file__))
lib = ctypes.CDLL(
    os.environ.get("CAVETRACE_LIBRARY") or os.path.join(here, "..", "target", "debug", "libcavetrace.so")
)
for name, restype, argtypes in [
    ("anariLoadLibrary", Handle, [ctypes.c_char_p, ctypes.c_void_p, ctypes.c_void_p]),
    ("anariNewDevice", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewArray1D", Handle, [Handle, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_uint64]),
    ("anariNewGeometry", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewMaterial", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewLight", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewCamera", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewRenderer", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewInstance", Handle, [Handle, ctypes.c_char_p]),
    ("anariNewGroup", Handle, [Handle]),
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

comm = MPI.COMM_WORLD
rank, ranks = comm.Get_rank(), comm.Get_size()
errors = []


@StatusCallback
def on_status(user_data, device, source, source_type, severity, code, message):
    if severity <= ANARI_SEVERITY_ERROR:
        errors.append(message.decode())


library = lib.anariLoadLibrary(b"cavetrace", None, None)
d = lib.anariNewDevice(library, b"default")
lib.anariSetParameter(d, d, b"statusCallback", ANARI_STATUS_CALLBACK, ctypes.byref(ctypes.cast(on_status, ctypes.c_void_p)))
lib.anariCommitParameters(d, d)


def setp(obj, name, data_type, value):
    name = name.encode()
    if data_type == ANARI_STRING:
        lib.anariSetParameter(d, obj, name, data_type, ctypes.c_char_p(value.encode()))
    elif data_type == ANARI_VOID_POINTER:
        lib.anariSetParameter(d, obj, name, data_type, ctypes.c_void_p(value))
    elif data_type in (ANARI_FLOAT32, ANARI_FLOAT32_VEC3, ANARI_FLOAT32_VEC4, ANARI_FLOAT32_MAT4):
        values = value if isinstance(value, (list, tuple)) else [value]
        lib.anariSetParameter(d, obj, name, data_type, ctypes.byref((ctypes.c_float * len(values))(*values)))
    elif data_type in (ANARI_UINT32, ANARI_UINT32_VEC2, ANARI_DATA_TYPE):
        values = value if isinstance(value, (list, tuple)) else [value]
        lib.anariSetParameter(d, obj, name, data_type, ctypes.byref((ctypes.c_uint32 * len(values))(*values)))
    else:
        lib.anariSetParameter(d, obj, name, data_type, ctypes.byref(Handle(value)))


def array(element_type, fmt, values, count):
    a = lib.anariNewArray1D(d, None, None, None, element_type, count)
    data = struct.pack(fmt, *values)
    ctypes.memmove(lib.anariMapArray(d, a), data, len(data))
    lib.anariUnmapArray(d, a)
    return a


def handles(element_type, objects):
    return array(element_type, "%dP" % len(objects), objects, len(objects))


def mesh(xyz, index):
    g = lib.anariNewGeometry(d, b"triangle")
    setp(g, "vertex.position", ANARI_ARRAY1D, array(ANARI_FLOAT32_VEC3, "%df" % len(xyz), xyz, len(xyz) // 3))
    setp(g, "primitive.index", ANARI_ARRAY1D, array(ANARI_UINT32_VEC3, "%dI" % len(index), index, len(index) // 3))
    lib.anariCommitParameters(d, g)
    return g


def spheres(centers, radius):
    g = lib.anariNewGeometry(d, b"sphere")
    setp(g, "vertex.position", ANARI_ARRAY1D, array(ANARI_FLOAT32_VEC3, "%df" % len(centers), centers, len(centers) // 3))
    setp(g, "radius", ANARI_FLOAT32, radius)
    lib.anariCommitParameters(d, g)
    return g


def material(color, metal=False):
    m = lib.anariNewMaterial(d, b"physicallyBased" if metal else b"matte")
    if metal:
        setp(m, "baseColor", ANARI_FLOAT32_VEC3, color)
        setp(m, "metallic", ANARI_FLOAT32, 1.0)
        setp(m, "roughness", ANARI_FLOAT32, 0.0)
    else:
        setp(m, "color", ANARI_FLOAT32_VEC3, color)
    lib.anariCommitParameters(d, m)
    return m


def surface(geometry, mat, ident):
    s = lib.anariNewSurface(d)
    setp(s, "geometry", ANARI_GEOMETRY, geometry)
    setp(s, "material", ANARI_MATERIAL, mat)
    setp(s, "id", ANARI_UINT32, ident)
    lib.anariCommitParameters(d, s)
    return s


QUAD = [0, 1, 2, 0, 2, 3]
OBJECTS = [
    lambda: surface(mesh([-4, 0, -4, 4, 0, -4, 4, 0, 4, -4, 0, 4], QUAD), material([0.8, 0.8, 0.75]), 30),
    lambda: surface(spheres([-0.3, 0.8, 0.2], 0.5), material([0.9, 0.3, 0.1]), 31),
    lambda: surface(mesh([-2.5, 0.1, -1.6, 2.5, 0.1, -1.6, 2.5, 2.4, -1.9, -2.5, 2.4, -1.9], QUAD), material([0.9, 0.9, 0.9], True), 32),
    lambda: surface(mesh([0, 0, 0, 0.7, 0, 0, 0, 0.7, 0, 0, 0, 0.7], [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]), material([0.2, 0.8, 0.3]), 33),
    lambda: surface(spheres([1.0, 0.3, 1.0, 1.5, 0.3, 0.4, -1.4, 0.4, 1.2], 0.3), material([0.2, 0.3, 0.9]), 34),
]
INSTANCED = 3


def world_of(mine):
    world = lib.anariNewWorld(d)
    direct = []
    for k, make in enumerate(OBJECTS):
        if not mine[k]:
            continue
        s = make()
        if k != INSTANCED:
            direct.append(s)
            continue
        group = lib.anariNewGroup(d)
        setp(group, "surface", ANARI_ARRAY1D, handles(ANARI_SURFACE, [s]))
        lib.anariCommitParameters(d, group)
        instance = lib.anariNewInstance(d, b"transform")
        setp(instance, "group", ANARI_GROUP, group)
        setp(instance, "transform", ANARI_FLOAT32_MAT4, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.9, 0.0, -0.4, 1])
        setp(instance, "id", ANARI_UINT32, 40)
        lib.anariCommitParameters(d, instance)
        setp(world, "instance", ANARI_ARRAY1D, handles(ANARI_INSTANCE, [instance]))
    if direct:
        setp(world, "surface", ANARI_ARRAY1D, handles(ANARI_SURFACE, direct))
    light = lib.anariNewLight(d, b"directional")
    setp(light, "direction", ANARI_FLOAT32_VEC3, [0.3, -1.0, -0.2])
    setp(light, "irradiance", ANARI_FLOAT32, 2.5)
    lib.anariCommitParameters(d, light)
    setp(world, "light", ANARI_ARRAY1D, handles(ANARI_LIGHT, [light]))
    lib.anariCommitParameters(d, world)
    return world


camera = lib.anariNewCamera(d, b"perspective")
setp(camera, "position", ANARI_FLOAT32_VEC3, [0.4, 1.7, 4.5])
setp(camera, "direction", ANARI_FLOAT32_VEC3, [-0.1, -0.3, -1.0])
setp(camera, "up", ANARI_FLOAT32_VEC3, [0, 1, 0])
setp(camera, "aspect", ANARI_FLOAT32, WIDTH / HEIGHT)
lib.anariCommitParameters(d, camera)


def renderer_of(subtype):
    r = lib.anariNewRenderer(d, subtype.encode())
    setp(r, "background", ANARI_FLOAT32_VEC4, [0.1, 0.1, 0.25, 1.0])
    setp(r, "ambientRadiance", ANARI_FLOAT32, 0.3)
    lib.anariCommitParameters(d, r)
    return r


def render(world, renderer, communicator, mode, renders=1):
    """Every channel's bytes and this rank's pixelsTraced."""
    frame = lib.anariNewFrame(d)
    setp(frame, "size", ANARI_UINT32_VEC2, [WIDTH, HEIGHT])
    setp(frame, "world", ANARI_WORLD, world)
    setp(frame, "camera", ANARI_CAMERA, camera)
    setp(frame, "renderer", ANARI_RENDERER, renderer)
    for name, data_type in CHANNELS:
        setp(frame, name, ANARI_DATA_TYPE, data_type)
    # The MPI_Comm handle itself is the parameter's value (Open MPI's handles are pointers).
    setp(frame, "mpiCommunicator", ANARI_VOID_POINTER, MPI._handleof(communicator))
    setp(frame, "mpiMode", ANARI_STRING, mode)
    setp(frame, "mpiTimeout", ANARI_FLOAT32, 20.0)
    lib.anariCommitParameters(d, frame)
    for _ in range(renders):
        lib.anariRenderFrame(d, frame)
        lib.anariFrameReady(d, frame, ANARI_WAIT)
    images = []
    for name, _ in CHANNELS:
        w, h, t = ctypes.c_uint32(), ctypes.c_uint32(), ctypes.c_int()
        pointer = lib.anariMapFrame(d, frame, name.encode(), ctypes.byref(w), ctypes.byref(h), ctypes.byref(t))
        images.append(ctypes.string_at(pointer, WIDTH * HEIGHT * 4) if pointer and w.value == WIDTH else b"")
        lib.anariUnmapFrame(d, frame, name.encode())
    traced = ctypes.c_uint64()
    lib.anariGetProperty(d, frame, b"pixelsTraced", ANARI_UINT64, ctypes.byref(traced), 8, ANARI_WAIT)
    lib.anariRelease(d, frame)
    return images, traced.value


def differences(got, alone, tolerance):
    """The first difference and how many values differ."""
    first, count = None, 0
    for (name, _), a, b in zip(CHANNELS, got, alone):
        if len(a) != len(b):
            return "%s missing" % name, 1
        for i in range(0, len(a), 4):
            x, y = a[i : i + 4], b[i : i + 4]
            if x == y:
                continue
            if name == "channel.color" and all(abs(p - q) <= tolerance for p, q in zip(x, y)):
                continue
            count += 1
            if first is None:
                first = "%s at (%d, %d): %s, alone %s" % (name, (i // 4) % WIDTH, (i // 4) // WIDTH, x.hex(), y.hex())
    return first, count


failures = 0
everything = [True] * len(OBJECTS)
mine = [k % ranks == rank for k in range(len(OBJECTS))]
for mode, subtype, tolerance in [
    ("dataParallel", "default", 1),
    ("dataParallel", "fast", 1),
    ("replicated", "default", 0),
]:
    name = "python: %s, %s renderer, %d ranks: rank 0 = one device" % (mode, subtype, ranks)
    renderer = renderer_of(subtype)
    del errors[:]
    world = world_of(everything if mode == "replicated" else mine)
    got, traced = render(world, renderer, MPI.COMM_WORLD, mode, 2 if mode == "replicated" else 1)
    total = comm.allreduce(traced, op=MPI.SUM)
    detail = "; ".join(errors[:1])
    if rank == 0:
        alone, _ = render(world_of(everything), renderer, MPI.COMM_SELF, mode)
        first, count = differences(got, alone, tolerance)
        seen = set(struct.unpack("%dI" % (WIDTH * HEIGHT), alone[3])) if len(alone[3]) == WIDTH * HEIGHT * 4 else set()
        if len(seen) < len(OBJECTS) + 1:
            detail = "the whole scene shows %d object ids (background included), not %d" % (len(seen), len(OBJECTS) + 1)
        elif count:
            detail = "%s (%d values differ)" % (first, count)
        elif total != WIDTH * HEIGHT:
            detail = "pixelsTraced adds up to %d, not %d" % (total, WIDTH * HEIGHT)
    ok = comm.allreduce(0 if detail else 1, op=MPI.MIN)
    detail = comm.bcast(detail, root=0) or detail
    if rank == 0:
        print("%s %s%s" % ("ok  " if ok else "FAIL", name, "" if ok else ": " + detail), flush=True)
    failures += 0 if ok else 1

if rank == 0:
    print("%d ranks: %d failed" % (ranks, failures))
sys.exit(1 if failures else 0)
