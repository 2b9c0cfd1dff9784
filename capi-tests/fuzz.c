/*
 * fuzz: random call sequences over cavetrace's whole C API.
 *
 * Each sequence (one seed) opens a library and a device, then one or more threads make random
 * calls on a shared table of objects: valid calls mixed with live, released, NULL, wrong-kind
 * and foreign handles (addresses of memory this program owns), valid and invalid data types,
 * real and made-up parameter names, arrays of 0, 1, huge and overflowing shapes, map/unmap in
 * wrong orders, frames rendered, discarded and mapped while their objects are released. At the
 * end every object is released, the device and library too, and no device may remain live.
 *
 * Checked per call: a misuse the generator can classify (a NULL, released, foreign or wrong-kind
 * handle given to a valid device) must produce a status message on the calling thread.
 * Checked by the build: crashes, hangs (an alarm), sanitizer reports, leaks (LeakSanitizer).
 *
 * What it does not try, because the ANARI specification leaves it undefined and no device can
 * guard against it: pointers to freed or too-small memory passed as data (app_memory shorter
 * than the array it describes, a parameter value shorter than its type), wild pointers given as
 * strings or callbacks (a random function pointer as statusCallback or a deleter), writing
 * through a mapped pointer after the object was unmapped or released, and frames so large that
 * the machine cannot hold them (that is the limits test's job, not a random sequence's).
 *
 *   fuzz                          the CI set: fixed seeds, prints "N passed, M failed"
 *   fuzz --seed S [--threads N]   replays one sequence
 *   fuzz --soak SECONDS [--threads N]  random seeds until the time is up; prints a failing seed
 */
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cavetrace.h"

/* ----- random numbers (splitmix64) ------------------------------------------------------- */

typedef struct {
  uint64_t state;
} Rng;

static uint64_t next_u64(Rng *rng) {
  uint64_t z = (rng->state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
static uint32_t below(Rng *rng, uint32_t n) { return (uint32_t)(next_u64(rng) % n); }
static int chance(Rng *rng, uint32_t percent) { return below(rng, 100) < percent; }
#define PICK(rng, table) (table)[below((rng), (uint32_t)(sizeof(table) / sizeof((table)[0])))]

/* ----- status messages --------------------------------------------------------------------- */

static _Atomic uint64_t messages_total;
static _Atomic uint64_t calls_total;
static _Thread_local uint64_t messages_here; /* messages reported on this thread */

static void on_status(const void *user, ANARIDevice device, ANARIObject source,
                      ANARIDataType source_type, ANARIStatusSeverity severity,
                      ANARIStatusCode code, const char *message) {
  (void)user, (void)device, (void)source, (void)source_type, (void)severity, (void)code;
  /* The message must be a readable string: touch all of it. */
  volatile size_t length = strlen(message);
  (void)length;
  messages_here++;
  atomic_fetch_add(&messages_total, 1);
}

static _Atomic uint64_t deleter_calls;
static void count_deleter(const void *user, const void *memory) {
  (void)user, (void)memory;
  atomic_fetch_add(&deleter_calls, 1);
}

/* ----- the shared object table ------------------------------------------------------------- */

#define SLOTS 48
#define DEAD 64

typedef struct {
  ANARIObject handle;
  ANARIDataType kind;
} Slot;

typedef struct {
  ANARILibrary library;
  ANARIDevice device;
  pthread_mutex_t lock; /* guards the tables, never held across an API call */
  Slot slots[SLOTS];
  ANARIObject dead[DEAD]; /* released handles, for misuse */
  int dead_count;
  int threads;
  uint32_t calls_per_thread;
  uint64_t seed;
  _Atomic int failures;
  /* Foreign handles: addresses of memory this program owns, never objects. */
  uint64_t foreign[4];
  /* app_memory for arrays: lives until the device is released. */
  unsigned char *app_memory;
} Sequence;

#define APP_MEMORY_BYTES 4096

static const ANARIDataType object_kinds[] = {
    ANARI_LIGHT,   ANARI_CAMERA,   ANARI_GEOMETRY, ANARI_SPATIAL_FIELD, ANARI_VOLUME,
    ANARI_SURFACE, ANARI_MATERIAL, ANARI_SAMPLER,  ANARI_GROUP,         ANARI_INSTANCE,
    ANARI_WORLD,   ANARI_FRAME,    ANARI_RENDERER, ANARI_ARRAY1D,       ANARI_ARRAY2D,
    ANARI_ARRAY3D};

/* Released handles join the misuse list only after their release has returned: before, another
 * thread could still find them live. */
static void mark_released(Sequence *s, ANARIObject handle) {
  pthread_mutex_lock(&s->lock);
  if (s->dead_count < DEAD)
    s->dead[s->dead_count++] = handle;
  pthread_mutex_unlock(&s->lock);
}

static void put(Sequence *s, Rng *rng, ANARIObject handle, ANARIDataType kind) {
  if (!handle)
    return;
  ANARIObject evicted = NULL;
  pthread_mutex_lock(&s->lock);
  Slot *slot = &s->slots[below(rng, SLOTS)];
  evicted = slot->handle;
  slot->handle = handle;
  slot->kind = kind;
  pthread_mutex_unlock(&s->lock);
  if (evicted) {
    anariRelease(s->device, evicted);
    mark_released(s, evicted);
  }
}

/* Takes a live object out of the table (the caller then owns its reference), or NULL. */
static Slot take(Sequence *s, Rng *rng) {
  pthread_mutex_lock(&s->lock);
  Slot *slot = &s->slots[below(rng, SLOTS)];
  Slot taken = *slot;
  slot->handle = NULL;
  pthread_mutex_unlock(&s->lock);
  return taken;
}

/* A live object of the table (it may be released by another thread meanwhile: then it is a
 * released handle, which the device must report just the same). */
static Slot peek(Sequence *s, Rng *rng) {
  pthread_mutex_lock(&s->lock);
  Slot found = s->slots[below(rng, SLOTS)];
  pthread_mutex_unlock(&s->lock);
  return found;
}

static Slot peek_kind(Sequence *s, Rng *rng, ANARIDataType kind) {
  pthread_mutex_lock(&s->lock);
  Slot found = {NULL, 0};
  uint32_t start = below(rng, SLOTS);
  for (uint32_t i = 0; i < SLOTS; i++) {
    Slot *slot = &s->slots[(start + i) % SLOTS];
    if (slot->handle && slot->kind == kind) {
      found = *slot;
      break;
    }
  }
  pthread_mutex_unlock(&s->lock);
  return found;
}

typedef enum { HANDLE_LIVE, HANDLE_NULL, HANDLE_RELEASED, HANDLE_FOREIGN } HandleClass;

/* Some handle: live most of the time, else NULL, released or foreign. *bad is set when the
 * handle is certainly not a live object (so a call on it must be reported). */
static ANARIObject any_handle(Sequence *s, Rng *rng, int *bad, ANARIDataType *kind) {
  *bad = 0;
  *kind = ANARI_OBJECT;
  uint32_t roll = below(rng, 100);
  if (roll < 70) {
    Slot slot = peek(s, rng);
    if (slot.handle) {
      *kind = slot.kind;
      return slot.handle;
    }
  }
  *bad = 1;
  if (roll < 80)
    return NULL;
  if (roll < 90) {
    pthread_mutex_lock(&s->lock);
    ANARIObject dead = s->dead_count ? s->dead[below(rng, (uint32_t)s->dead_count)] : NULL;
    pthread_mutex_unlock(&s->lock);
    return dead;
  }
  return (ANARIObject)&s->foreign[below(rng, 4)];
}

/* ----- random values ------------------------------------------------------------------------ */

static const char *const names[] = {
    "position",     "direction",   "up",          "fovy",          "aspect",
    "imageRegion",  "near",        "far",         "vertex.position", "vertex.color",
    "vertex.normal", "primitive.index", "primitive.color", "geometry",   "material",
    "surface",      "instance",    "light",       "world",         "camera",
    "renderer",     "size",        "channel.color", "channel.depth", "channel.primitiveId",
    "color",        "opacity",     "intensity",   "irradiance",    "radius",
    "transform",    "group",       "background",  "ambientRadiance", "pixelSamples",
    "image",        "inAttribute", "filter",      "wrapMode1",     "id",
    "name",         "numThreads2", "field",       "isovalue",      "data",
    "index",        "cell.index",  "cell.type",   "vertex.data",   "cell.data",
    "",             "??",          "vertex.position.x",
    "a very long name that no object has, to see the message quote it in full........"};

static const char *const subtypes[] = {"default", "perspective", "orthographic", "omnidirectional",
                                       "triangle", "quad", "sphere", "cylinder", "cone", "curve",
                                       "matte", "physicallyBased", "directional", "point", "spot",
                                       "image1D", "image2D", "image3D", "transform", "primitive",
                                       "ambientOcclusion", "debug", "isosurface",
                                       "structuredRegular", "unstructured", "nope", ""};

static const char *const channels[] = {"channel.color", "channel.depth", "channel.primitiveId",
                                       "channel.objectId", "channel.instanceId", "color", "", "x"};

/* Element types with their sizes; object types are handles. */
static const struct {
  ANARIDataType type;
  uint32_t size;
} element_types[] = {
    {ANARI_FLOAT32, 4},      {ANARI_FLOAT32_VEC2, 8},  {ANARI_FLOAT32_VEC3, 12},
    {ANARI_FLOAT32_VEC4, 16}, {ANARI_UINT32, 4},        {ANARI_UINT32_VEC2, 8},
    {ANARI_UINT32_VEC3, 12},  {ANARI_INT32, 4},         {ANARI_UFIXED8_VEC4, 4},
    {ANARI_UFIXED8, 1},       {ANARI_FLOAT32_MAT4, 64}, {ANARI_BOOL, 1},
    {ANARI_SURFACE, 8},       {ANARI_INSTANCE, 8},      {ANARI_LIGHT, 8},
    {ANARI_GEOMETRY, 8},      {ANARI_OBJECT, 8}};

static ANARIDataType random_type(Rng *rng, uint32_t *size) {
  uint32_t roll = below(rng, 100);
  if (roll < 80) {
    uint32_t i = below(rng, sizeof(element_types) / sizeof(element_types[0]));
    *size = element_types[i].size;
    return element_types[i].type;
  }
  *size = 0;
  if (roll < 90)
    return PICK(rng, object_kinds);
  static const ANARIDataType odd[] = {ANARI_UNKNOWN, ANARI_STRING, ANARI_DATA_TYPE, 9999,
                                      0x7fffffff, ANARI_UFIXED8_RGBA_SRGB, ANARI_DEVICE,
                                      ANARI_LIBRARY, ANARI_VOID_POINTER};
  return PICK(rng, odd);
}

/* n1·n2·n3, or UINT64_MAX when the product overflows. */
static uint64_t product(uint64_t n1, uint64_t n2, uint64_t n3) {
  if ((n2 && n1 > UINT64_MAX / n2))
    return UINT64_MAX;
  uint64_t n12 = n1 * n2;
  if (n3 && n12 > UINT64_MAX / n3)
    return UINT64_MAX;
  return n12 * n3;
}

static uint64_t random_count(Rng *rng) {
  static const uint64_t counts[] = {0, 1, 1, 2, 3, 4, 7, 16, 100, 1ull << 40, UINT64_MAX / 3,
                                    UINT64_MAX};
  return PICK(rng, counts);
}

/* Fills the value buffer for anariSetParameter with something of `type`. Pointer-like types
 * get only pointers that are valid for them (see the header comment). */
static const void *parameter_value(Sequence *s, Rng *rng, ANARIDataType type, uint64_t *value,
                                   const char **string) {
  for (int i = 0; i < 16; i++)
    value[i] = next_u64(rng);
  if (chance(rng, 20)) { /* floats in a sane range, sometimes NaN or infinite */
    float *f = (float *)value;
    for (int i = 0; i < 32; i++)
      f[i] = chance(rng, 5) ? (float)(i % 2 ? 1.0 / 0.0 : 0.0 / 0.0)
                            : (float)below(rng, 2000) / 100.0f - 10.0f;
  }
  switch (type) {
  case ANARI_STRING:
    *string = PICK(rng, subtypes);
    return string;
  case ANARI_STATUS_CALLBACK: {
    static ANARIStatusCallback callback = on_status;
    return chance(rng, 50) ? (const void *)&callback : NULL;
  }
  case ANARI_FUNCTION_POINTER:
  case ANARI_MEMORY_DELETER:
  case ANARI_FRAME_COMPLETION_CALLBACK:
  case ANARI_STRING_LIST:
  case ANARI_DATA_TYPE_LIST:
  case ANARI_PARAMETER_LIST:
  case ANARI_VOID_POINTER:
    value[0] = 0; /* a NULL pointer: anything else would be a wild one */
    return value;
  default:
    break;
  }
  for (int i = 0; i < 16; i++) /* object types read a handle */
    if (chance(rng, 50)) {
      int bad;
      ANARIDataType kind;
      value[i] = (uint64_t)(uintptr_t)any_handle(s, rng, &bad, &kind);
    }
  return chance(rng, 3) ? NULL : value;
}

/* ----- checks -------------------------------------------------------------------------------- */

static void fail(Sequence *s, const char *what, const char *function, HandleClass how) {
  static const char *const how_names[] = {"live", "NULL", "released", "foreign"};
  fprintf(stderr, "fuzz seed %llu: %s: %s (%s handle)\n", (unsigned long long)s->seed, function,
          what, how_names[how]);
  atomic_fetch_add(&s->failures, 1);
}

/* A call on a handle that is certainly not a live object must be reported. */
#define EXPECT_REPORTED(s, bad, function, call)                                                 \
  do {                                                                                          \
    uint64_t before_ = messages_here;                                                           \
    call;                                                                                       \
    if ((bad) && messages_here == before_)                                                      \
      fail((s), "misuse not reported", (function), HANDLE_RELEASED);                            \
  } while (0)

/* ----- operations ---------------------------------------------------------------------------- */

static ANARIObject new_object(Sequence *s, Rng *rng, ANARIDataType kind) {
  ANARIDevice d = s->device;
  const char *subtype = PICK(rng, subtypes);
  switch (kind) {
  case ANARI_LIGHT: return anariNewLight(d, subtype);
  case ANARI_CAMERA: return anariNewCamera(d, subtype);
  case ANARI_GEOMETRY: return anariNewGeometry(d, subtype);
  case ANARI_SPATIAL_FIELD: return anariNewSpatialField(d, subtype);
  case ANARI_VOLUME: return anariNewVolume(d, subtype);
  case ANARI_SURFACE: return anariNewSurface(d);
  case ANARI_MATERIAL: return anariNewMaterial(d, subtype);
  case ANARI_SAMPLER: return anariNewSampler(d, subtype);
  case ANARI_GROUP: return anariNewGroup(d);
  case ANARI_INSTANCE: return anariNewInstance(d, subtype);
  case ANARI_WORLD: return anariNewWorld(d);
  case ANARI_FRAME: return anariNewFrame(d);
  case ANARI_RENDERER: return anariNewRenderer(d, subtype);
  default: {
    static const char *const type_names[] = {"light", "camera", "geometry", "world", "frame",
                                             "renderer", "sampler", "bogus", ""};
    return anariNewObject(d, PICK(rng, type_names), subtype);
  }
  }
}

static ANARIArray new_array(Sequence *s, Rng *rng, ANARIDataType *kind) {
  uint32_t size;
  ANARIDataType type = random_type(rng, &size);
  uint64_t n1 = random_count(rng), n2 = 1, n3 = 1;
  int dims = 1 + (int)below(rng, 3);
  if (dims > 1)
    n2 = random_count(rng);
  if (dims > 2)
    n3 = random_count(rng);
  /* app_memory only when it certainly holds the whole array (else it would be undefined). */
  const void *memory = NULL;
  if (size && chance(rng, 50)) {
    if (product(n1, n2, n3) <= APP_MEMORY_BYTES / size)
      memory = s->app_memory;
  }
  ANARIMemoryDeleter deleter = memory && chance(rng, 50) ? count_deleter : NULL;
  *kind = dims == 1 ? ANARI_ARRAY1D : dims == 2 ? ANARI_ARRAY2D : ANARI_ARRAY3D;
  if (dims == 1)
    return anariNewArray1D(s->device, memory, deleter, NULL, type, n1);
  if (dims == 2)
    return anariNewArray2D(s->device, memory, deleter, NULL, type, n1, n2);
  return anariNewArray3D(s->device, memory, deleter, NULL, type, n1, n2, n3);
}

/* A small valid scene, so that renders trace real geometry. */
static void new_scene(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  float xyz[9] = {-1, -1, 3, 1, -1, 3, 0, 1, 3};
  ANARIArray1D vertices = anariNewArray1D(d, NULL, NULL, NULL, ANARI_FLOAT32_VEC3, 3);
  float *mapped = anariMapArray(d, vertices);
  if (mapped)
    memcpy(mapped, xyz, sizeof xyz);
  anariUnmapArray(d, vertices);
  ANARIGeometry geometry = anariNewGeometry(d, "triangle");
  anariSetParameter(d, geometry, "vertex.position", ANARI_ARRAY1D, &vertices);
  anariCommitParameters(d, geometry);
  ANARIMaterial material = anariNewMaterial(d, "matte");
  anariCommitParameters(d, material);
  ANARISurface surface = anariNewSurface(d);
  anariSetParameter(d, surface, "geometry", ANARI_GEOMETRY, &geometry);
  anariSetParameter(d, surface, "material", ANARI_MATERIAL, &material);
  anariCommitParameters(d, surface);
  ANARIArray1D surfaces = anariNewArray1D(d, NULL, NULL, NULL, ANARI_SURFACE, 1);
  ANARISurface *slot = anariMapArray(d, surfaces);
  if (slot)
    *slot = surface;
  anariUnmapArray(d, surfaces);
  ANARIWorld world = anariNewWorld(d);
  anariSetParameter(d, world, "surface", ANARI_ARRAY1D, &surfaces);
  anariCommitParameters(d, world);
  ANARICamera camera = anariNewCamera(d, "perspective");
  anariCommitParameters(d, camera);
  ANARIRenderer renderer = anariNewRenderer(d, "default");
  anariCommitParameters(d, renderer);
  ANARIFrame frame = anariNewFrame(d);
  uint32_t size[2] = {1 + below(rng, 24), 1 + below(rng, 24)};
  ANARIDataType color = ANARI_FLOAT32_VEC4, depth = ANARI_FLOAT32;
  anariSetParameter(d, frame, "size", ANARI_UINT32_VEC2, size);
  anariSetParameter(d, frame, "channel.color", ANARI_DATA_TYPE, &color);
  anariSetParameter(d, frame, "channel.depth", ANARI_DATA_TYPE, &depth);
  anariSetParameter(d, frame, "world", ANARI_WORLD, &world);
  anariSetParameter(d, frame, "camera", ANARI_CAMERA, &camera);
  anariSetParameter(d, frame, "renderer", ANARI_RENDERER, &renderer);
  anariCommitParameters(d, frame);
  put(s, rng, vertices, ANARI_ARRAY1D);
  put(s, rng, geometry, ANARI_GEOMETRY);
  put(s, rng, material, ANARI_MATERIAL);
  put(s, rng, surface, ANARI_SURFACE);
  put(s, rng, surfaces, ANARI_ARRAY1D);
  put(s, rng, world, ANARI_WORLD);
  put(s, rng, camera, ANARI_CAMERA);
  put(s, rng, renderer, ANARI_RENDERER);
  put(s, rng, frame, ANARI_FRAME);
}

static uint32_t pixel_bytes(ANARIDataType type) {
  switch (type) {
  case ANARI_FLOAT32_VEC4: return 16;
  case ANARI_FLOAT32_VEC3: return 12;
  case ANARI_FLOAT32:
  case ANARI_UINT32:
  case ANARI_UFIXED8_VEC4:
  case ANARI_UFIXED8_RGBA_SRGB: return 4;
  default: return 0;
  }
}

static void frame_op(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  int bad = 0;
  ANARIDataType kind = ANARI_FRAME;
  ANARIObject frame;
  if (chance(rng, 75)) {
    frame = peek_kind(s, rng, ANARI_FRAME).handle;
    if (!frame)
      frame = any_handle(s, rng, &bad, &kind);
  } else {
    frame = any_handle(s, rng, &bad, &kind);
  }
  /* A live object of another kind is a wrong-kind handle. */
  int wrong = bad || (kind != ANARI_FRAME && kind != ANARI_OBJECT); /* OBJECT: unknown */
  const char *channel = PICK(rng, channels);
  switch (below(rng, 7)) {
  case 0:
    EXPECT_REPORTED(s, wrong, "anariRenderFrame", anariRenderFrame(d, frame));
    break;
  case 1:
    EXPECT_REPORTED(s, wrong, "anariFrameReady",
                    anariFrameReady(d, frame, chance(rng, 50) ? ANARI_WAIT : ANARI_NO_WAIT));
    break;
  case 2:
    EXPECT_REPORTED(s, wrong, "anariDiscardFrame", anariDiscardFrame(d, frame));
    break;
  case 3: {
    uint32_t width = 0, height = 0;
    ANARIDataType type = ANARI_UNKNOWN;
    const void *pixels;
    EXPECT_REPORTED(s, wrong, "anariMapFrame",
                    pixels = anariMapFrame(d, frame, channel, &width, &height, &type));
    /* Reading is defined only while no other thread may release the frame. */
    if (pixels && s->threads == 1) {
      size_t bytes = (size_t)width * height * pixel_bytes(type);
      volatile unsigned char sum = 0;
      for (size_t i = 0; i < bytes; i++)
        sum = (unsigned char)(sum + ((const unsigned char *)pixels)[i]);
    }
    if (chance(rng, 80))
      anariUnmapFrame(d, frame, channel);
    break;
  }
  case 4:
    EXPECT_REPORTED(s, wrong, "anariUnmapFrame", anariUnmapFrame(d, frame, channel));
    break;
  case 5:
    cavetraceWriteFramePNG(d, frame, channel,
                           chance(rng, 50) ? "/dev/null" : "/nonexistent/dir/x.png");
    break;
  default: {
    uint32_t size[2] = {below(rng, 40), below(rng, 40)};
    anariSetParameter(d, frame, "size", ANARI_UINT32_VEC2, size);
    anariCommitParameters(d, frame);
    anariRenderFrame(d, frame);
    break;
  }
  }
}

static void array_op(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  int bad = 0;
  ANARIDataType kind = ANARI_ARRAY1D;
  ANARIObject array = peek_kind(s, rng, (ANARIDataType)PICK(rng, ((ANARIDataType[]){
                                                             ANARI_ARRAY1D, ANARI_ARRAY2D,
                                                             ANARI_ARRAY3D})))
                          .handle;
  if (!array || chance(rng, 30))
    array = any_handle(s, rng, &bad, &kind);
  else
    kind = ANARI_ARRAY1D;
  int wrong = bad || !(kind == ANARI_ARRAY1D || kind == ANARI_ARRAY2D ||
                       kind == ANARI_ARRAY3D || kind == ANARI_OBJECT);
  switch (below(rng, 3)) {
  case 0: {
    void *mapped;
    EXPECT_REPORTED(s, wrong, "anariMapArray", mapped = anariMapArray(d, array));
    (void)mapped; /* its size is not known here: not written */
    if (chance(rng, 70))
      anariUnmapArray(d, array);
    break;
  }
  case 1:
    EXPECT_REPORTED(s, wrong, "anariUnmapArray", anariUnmapArray(d, array));
    break;
  default: {
    ANARIDataType array_kind = ANARI_ARRAY1D;
    ANARIArray created = new_array(s, rng, &array_kind);
    put(s, rng, created, array_kind);
    break;
  }
  }
}

static void parameter_op(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  int bad;
  ANARIDataType kind;
  ANARIObject object = any_handle(s, rng, &bad, &kind);
  if (chance(rng, 3)) { /* the device itself, but never its thread count */
    object = (ANARIObject)d;
    bad = 0;
  }
  const char *name = PICK(rng, names);
  uint64_t value[16];
  const char *string = NULL;
  uint32_t size;
  ANARIDataType type = random_type(rng, &size);
  if (chance(rng, 10)) {
    static const ANARIDataType pointers[] = {ANARI_STRING, ANARI_STATUS_CALLBACK,
                                             ANARI_VOID_POINTER, ANARI_FUNCTION_POINTER,
                                             ANARI_DATA_TYPE, ANARI_UINT32_VEC2};
    type = PICK(rng, pointers);
  }
  uint64_t element_stride = 0;
  switch (below(rng, 8)) {
  case 0:
  case 1:
  case 2:
    EXPECT_REPORTED(s, bad, "anariSetParameter",
                    anariSetParameter(d, object, name, type,
                                      parameter_value(s, rng, type, value, &string)));
    break;
  case 3:
    EXPECT_REPORTED(s, bad, "anariUnsetParameter", anariUnsetParameter(d, object, name));
    break;
  case 4:
    EXPECT_REPORTED(s, bad, "anariUnsetAllParameters", anariUnsetAllParameters(d, object));
    break;
  case 5:
    EXPECT_REPORTED(s, bad, "anariCommitParameters", anariCommitParameters(d, object));
    break;
  case 6: {
    void *mapped;
    int dims = 1 + (int)below(rng, 3);
    uint64_t n1 = random_count(rng), n2 = random_count(rng), n3 = random_count(rng);
    if (dims == 1)
      mapped = anariMapParameterArray1D(d, object, name, type, n1, &element_stride);
    else if (dims == 2)
      mapped = anariMapParameterArray2D(d, object, name, type, n1, n2, &element_stride);
    else
      mapped = anariMapParameterArray3D(d, object, name, type, n1, n2, n3,
                                        chance(rng, 20) ? NULL : &element_stride);
    /* Writing is defined while this thread alone holds the object: one element only. */
    uint64_t elements = product(n1, dims > 1 ? n2 : 1, dims > 2 ? n3 : 1);
    if (mapped && s->threads == 1 && size && elements > 0 && size <= 8 &&
        !(type >= ANARI_OBJECT && type < 1000))
      memset(mapped, 0, size);
    if (chance(rng, 70))
      anariUnmapParameterArray(d, object, name);
    break;
  }
  default:
    anariUnmapParameterArray(d, object, name); /* often without a map */
    break;
  }
}

static void query_op(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  uint32_t size;
  ANARIDataType type = random_type(rng, &size);
  switch (below(rng, 6)) {
  case 0: {
    const char **list = anariGetObjectSubtypes(d, PICK(rng, object_kinds));
    for (int i = 0; list && list[i]; i++)
      (void)strlen(list[i]);
    break;
  }
  case 1: {
    static const char *const infos[] = {"description", "parameter", "channel", "extension",
                                        "sourceExtension", "nope"};
    (void)anariGetObjectInfo(d, PICK(rng, object_kinds), PICK(rng, subtypes), PICK(rng, infos),
                             type);
    break;
  }
  case 2: {
    static const char *const infos[] = {"description", "required", "default", "minimum",
                                        "maximum", "value", "sourceExtension", "elementType",
                                        "nope"};
    (void)anariGetParameterInfo(d, PICK(rng, object_kinds), PICK(rng, subtypes),
                                PICK(rng, names), type, PICK(rng, infos), type);
    break;
  }
  case 3: {
    int bad;
    ANARIDataType kind;
    ANARIObject object = chance(rng, 20) ? (ANARIObject)d : any_handle(s, rng, &bad, &kind);
    static const char *const properties[] = {"version", "bounds", "duration", "progress",
                                             "extension", "geometryMaxIndex", "nope"};
    unsigned char memory[256];
    uint64_t bytes = chance(rng, 80) ? size : below(rng, 256);
    (void)anariGetProperty(d, object, PICK(rng, properties), type, memory,
                           bytes > sizeof memory ? sizeof memory : bytes,
                           chance(rng, 30) ? ANARI_WAIT : ANARI_NO_WAIT);
    break;
  }
  case 4: {
    static const char *const procs[] = {"anariNewWorld", "anariRenderFrame", "nope", ""};
    (void)anariDeviceGetProcAddress(d, PICK(rng, procs));
    break;
  }
  default: {
    /* cavetrace's own functions: NULLs, NaNs, degenerate walls. */
    float in[4][3], out[64];
    float *value = (float *)in;
    for (int i = 0; i < 12; i++)
      value[i] = chance(rng, 5) ? 0.0f / 0.0f : (float)below(rng, 5) - 2.0f;
    float *maybe = chance(rng, 10) ? NULL : out;
    (void)cavetraceOffAxisMatrices(in[0], in[1], in[2], chance(rng, 10) ? NULL : in[3], 0.1f,
                                   100.0f, maybe, out + 16);
    (void)cavetraceOffAxisPerspective(in[0], in[1], in[2], in[3], out, out + 3, out + 6,
                                      maybe, out + 10, out + 11);
    (void)cavetracePerspectiveFromMatrices(out, out + 16, out + 32, out + 35, out + 38, maybe,
                                           out + 42, out + 43);
    static float pixels[8 * 8 * 4];
    (void)cavetraceWriteImagePNG(d, chance(rng, 50) ? "/dev/null" : "/nonexistent/y.png",
                                 below(rng, 9), below(rng, 9),
                                 PICK(rng, ((ANARIDataType[]){ANARI_FLOAT32_VEC4,
                                                              ANARI_UFIXED8_VEC4, 1234})),
                                 chance(rng, 10) ? NULL : pixels);
    break;
  }
  }
}

static void object_op(Sequence *s, Rng *rng) {
  ANARIDevice d = s->device;
  switch (below(rng, 6)) {
  case 0:
  case 1: {
    ANARIDataType kind = PICK(rng, object_kinds);
    if (kind == ANARI_ARRAY1D || kind == ANARI_ARRAY2D || kind == ANARI_ARRAY3D)
      kind = ANARI_OBJECT; /* anariNewObject */
    put(s, rng, new_object(s, rng, kind), kind);
    break;
  }
  case 2: {
    Slot slot = take(s, rng);
    if (slot.handle) {
      anariRelease(d, slot.handle);
      mark_released(s, slot.handle);
    }
    break;
  }
  case 3: {
    int bad;
    ANARIDataType kind;
    ANARIObject object = any_handle(s, rng, &bad, &kind);
    if (bad) {
      EXPECT_REPORTED(s, 1, "anariRelease", anariRelease(d, object));
      EXPECT_REPORTED(s, 1, "anariRetain", anariRetain(d, object));
    } else {
      /* Balanced: the table keeps owning one reference. The object may have been released
       * by another thread meanwhile; then both calls are reported, and balanced still. */
      anariRetain(d, object);
      anariRelease(d, object);
    }
    break;
  }
  default:
    new_scene(s, rng);
    break;
  }
}

static void library_op(Sequence *s, Rng *rng) {
  static const char *const modules[] = {"default", "nope", ""};
  switch (below(rng, 5)) {
  case 0: {
    const char **list = anariGetDeviceSubtypes(s->library);
    for (int i = 0; list && list[i]; i++)
      (void)strlen(list[i]);
    break;
  }
  case 1: {
    const char **list = anariGetDeviceExtensions(s->library, PICK(rng, modules));
    for (int i = 0; list && list[i]; i++)
      (void)strlen(list[i]);
    break;
  }
  case 2:
    anariLoadModule(s->library, PICK(rng, modules));
    anariUnloadModule(s->library, PICK(rng, modules));
    break;
  case 3: {
    /* A second device, used a little and released. */
    ANARIStatusCallback callback = on_status;
    uint32_t threads = 1 + below(rng, 2);
    ANARIParameterValue init[] = {{"statusCallback", ANARI_STATUS_CALLBACK, &callback},
                                  {"numThreads", ANARI_UINT32, &threads},
                                  {NULL, ANARI_UNKNOWN, NULL}};
    ANARIDevice other = anariNewInitializedDevice(s->library, PICK(rng, modules), init);
    if (other) {
      /* An object of this device given to the other one is a foreign handle. */
      ANARIWorld world = anariNewWorld(other);
      Slot slot = peek(s, rng);
      if (slot.handle)
        EXPECT_REPORTED(s, 1, "anariCommitParameters (other device)",
                        anariCommitParameters(other, slot.handle));
      anariRelease(other, world);
      anariRelease(other, other);
    }
    break;
  }
  default: {
    ANARIDevice device = anariNewDevice(s->library, "default");
    anariRelease(device, device);
    break;
  }
  }
}

/* ----- a sequence --------------------------------------------------------------------------- */

typedef struct {
  Sequence *sequence;
  uint64_t seed;
} Worker;

static void *work(void *argument) {
  Worker *worker = argument;
  Sequence *s = worker->sequence;
  Rng rng = {worker->seed};
  for (uint32_t i = 0; i < s->calls_per_thread; i++) {
    switch (below(&rng, 10)) {
    case 0:
    case 1: parameter_op(s, &rng); break;
    case 2:
    case 3: object_op(s, &rng); break;
    case 4: array_op(s, &rng); break;
    case 5:
    case 6: frame_op(s, &rng); break;
    case 7: query_op(s, &rng); break;
    case 8: parameter_op(s, &rng); break;
    default:
      if (chance(&rng, 20))
        library_op(s, &rng);
      else
        frame_op(s, &rng);
      break;
    }
    atomic_fetch_add(&calls_total, 1);
  }
  return NULL;
}

static volatile sig_atomic_t alarm_seed_low, alarm_seed_high;

static void on_alarm(int signal) {
  (void)signal;
  char text[96];
  uint64_t seed = ((uint64_t)(uint32_t)alarm_seed_high << 32) | (uint32_t)alarm_seed_low;
  int n = snprintf(text, sizeof text, "fuzz seed %llu: hung (alarm)\n", (unsigned long long)seed);
  if (write(2, text, (size_t)n) < 0)
    _exit(3);
  _exit(3);
}

/* Runs one sequence; returns the number of failures. */
static int run_sequence(uint64_t seed, int threads, uint32_t calls_per_thread) {
  alarm_seed_low = (sig_atomic_t)(uint32_t)seed;
  alarm_seed_high = (sig_atomic_t)(uint32_t)(seed >> 32);
  alarm(60);
  uint64_t devices_before = cavetraceLiveDeviceCount();
  Sequence *s = calloc(1, sizeof *s);
  s->seed = seed;
  s->threads = threads;
  s->calls_per_thread = calls_per_thread;
  s->app_memory = calloc(1, APP_MEMORY_BYTES);
  pthread_mutex_init(&s->lock, NULL);
  s->library = anariLoadLibrary("cavetrace", on_status, NULL);
  s->device = anariNewDevice(s->library, "default");
  if (!s->device) {
    fprintf(stderr, "fuzz seed %llu: no device\n", (unsigned long long)seed);
    return 1;
  }
  uint32_t render_threads = 2;
  anariSetParameter(s->device, s->device, "numThreads", ANARI_UINT32, &render_threads);
  anariCommitParameters(s->device, s->device);

  pthread_t ids[16];
  Worker workers[16];
  for (int t = 0; t < threads; t++) {
    workers[t].sequence = s;
    workers[t].seed = seed * 0x100000001b3ull + (uint64_t)t * 0x9e3779b97f4a7c15ull + 1;
    pthread_create(&ids[t], NULL, work, &workers[t]);
  }
  for (int t = 0; t < threads; t++)
    pthread_join(ids[t], NULL);

  for (int i = 0; i < SLOTS; i++)
    if (s->slots[i].handle)
      anariRelease(s->device, s->slots[i].handle);
  anariRelease(s->device, s->device);
  anariUnloadLibrary(s->library);
  int failures = atomic_load(&s->failures);
  if (cavetraceLiveDeviceCount() != devices_before) {
    fprintf(stderr, "fuzz seed %llu: %llu devices live after release (before: %llu)\n",
            (unsigned long long)seed, (unsigned long long)cavetraceLiveDeviceCount(),
            (unsigned long long)devices_before);
    failures++;
  }
  pthread_mutex_destroy(&s->lock);
  free(s->app_memory);
  free(s);
  alarm(0);
  return failures;
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
  signal(SIGALRM, on_alarm);
  long long seed = -1;
  double soak = 0;
  int threads = 0;
  uint32_t calls = 300;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!strcmp(argv[i], "--seed"))
      seed = atoll(argv[i + 1]);
    else if (!strcmp(argv[i], "--soak"))
      soak = atof(argv[i + 1]);
    else if (!strcmp(argv[i], "--threads"))
      threads = atoi(argv[i + 1]);
    else if (!strcmp(argv[i], "--calls"))
      calls = (uint32_t)atoi(argv[i + 1]);
    else {
      fprintf(stderr, "usage: fuzz [--seed S | --soak SECONDS] [--threads N] [--calls N]\n");
      return 2;
    }
  }
  if (threads < 0 || threads > 16) {
    fprintf(stderr, "--threads: 1 to 16\n");
    return 2;
  }
  double start = now();
  int failed = 0, passed = 0;
  uint64_t sequences = 0;
  if (seed >= 0) {
    int f = run_sequence((uint64_t)seed, threads ? threads : 1, calls);
    sequences = 1;
    failed += f != 0;
    passed += f == 0;
  } else if (soak > 0) {
    uint64_t base = (uint64_t)time(NULL) * 1000003u + (uint64_t)getpid();
    while (now() - start < soak) {
      uint64_t this_seed = base + sequences;
      int t = threads ? threads : 1 + (int)(this_seed % 4);
      int f = run_sequence(this_seed, t, calls);
      sequences++;
      if (f) {
        failed++;
        fprintf(stderr, "replay: fuzz --seed %llu --threads %d --calls %u\n",
                (unsigned long long)this_seed, t, calls);
        break;
      }
      passed++;
    }
  } else {
    /* The CI set: fixed seeds, one to four threads. */
    for (uint64_t i = 1; i <= 48; i++) {
      int t = threads ? threads : 1 + (int)(i % 4);
      int f = run_sequence(i, t, calls);
      sequences++;
      if (f)
        fprintf(stderr, "replay: fuzz --seed %llu --threads %d --calls %u\n",
                (unsigned long long)i, t, calls);
      failed += f != 0;
      passed += f == 0;
    }
  }
  double seconds = now() - start;
  printf("fuzz: %llu sequences, %llu operations, %llu status messages, %llu deleter calls in %.1f s "
         "(%.1f sequences/s)\n",
         (unsigned long long)sequences, (unsigned long long)atomic_load(&calls_total),
         (unsigned long long)atomic_load(&messages_total),
         (unsigned long long)atomic_load(&deleter_calls), seconds,
         seconds > 0 ? (double)sequences / seconds : 0.0);
  printf("%d passed, %d failed\n", passed, failed);
  return failed ? 1 : 0;
}
