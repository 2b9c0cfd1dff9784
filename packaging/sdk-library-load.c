/* Loads an installed libanari_library_cavetrace.so the way the Khronos ANARI SDK front end
 * (libanari.so, SDK 0.14 - 0.17) does for ANARI_LIBRARY=cavetrace, without the SDK:
 * dlopen the file, call anari_library_cavetrace_new_library, drive the returned
 * anari::LibraryImpl object through its vtable, delete it through the vtable, dlclose.
 *
 * Usage: sdk-library-load <path of libanari_library_cavetrace.so>
 * Prints what it found; exits 0 only when every check holds. packaging/test-install.sh runs it.
 *
 * Slots (Itanium C++ ABI, in the SDK's declaration order): library 0 complete-object
 * destructor, 1 deleting destructor, 2 newDevice, 4 getDeviceExtensions, 5 getDeviceSubtypes;
 * device 40 deleting destructor. tests/sdk_interface.rs checks the full layout. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void (*StatusCallback)(const void *userData, void *device, void *source, int sourceType,
                               int severity, int code, const char *message);
typedef void *(*NewLibrary)(void *dlHandle, StatusCallback callback, const void *userData);
typedef const char **(*GetDeviceSubtypes)(void *library);
typedef const char **(*GetDeviceExtensions)(void *library, const char *deviceSubtype);
typedef void *(*NewDevice)(void *library, const char *subtype);
typedef void (*DeletingDestructor)(void *object);

enum { LIBRARY_DELETE = 1, LIBRARY_NEW_DEVICE = 2, LIBRARY_EXTENSIONS = 4, LIBRARY_SUBTYPES = 5 };
enum { DEVICE_DELETE = 40 };

static int failures = 0;
static int messages = 0;

static void check(int ok, const char *what) {
  printf("%s %s\n", ok ? "ok  " : "FAIL", what);
  if (!ok) failures++;
}

static void on_status(const void *userData, void *device, void *source, int sourceType,
                      int severity, int code, const char *message) {
  (void)userData, (void)device, (void)source, (void)sourceType, (void)code;
  printf("status (severity %d): %s\n", severity, message);
  messages++;
}

/* Slot `slot` of the vtable the object's first word points at. */
static void *slot(void *object, int slot) {
  void **vtable = *(void ***)object;
  return vtable[slot];
}

static int list_contains(const char **list, const char *wanted) {
  for (; list != NULL && *list != NULL; list++)
    if (strcmp(*list, wanted) == 0) return 1;
  return 0;
}

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s <libanari_library_cavetrace.so>\n", argv[0]);
    return 2;
  }
  void *handle = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
  if (handle == NULL) {
    printf("FAIL dlopen: %s\n", dlerror());
    return 1;
  }
  NewLibrary new_library;
  *(void **)&new_library = dlsym(handle, "anari_library_cavetrace_new_library");
  check(new_library != NULL, "anari_library_cavetrace_new_library is exported");
  if (new_library == NULL) return 1;

  /* The entry point must come from the file given, not from some other copy. */
  Dl_info info;
  char wanted[PATH_MAX], found[PATH_MAX];
  int same_file = dladdr(*(void **)&new_library, &info) != 0 && realpath(argv[1], wanted) &&
                  realpath(info.dli_fname, found) && strcmp(wanted, found) == 0;
  printf("entry point in %s\n", same_file ? found : "another file");
  check(same_file, "the entry point lies in the given file");

  void *library = new_library(handle, on_status, NULL);
  check(library != NULL, "new_library returns a library object");
  if (library == NULL) return 1;
  check(((void **)library)[1] == handle, "the library object keeps the dlopen handle at byte 8");

  const char **subtypes = ((GetDeviceSubtypes)slot(library, LIBRARY_SUBTYPES))(library);
  printf("device subtypes:");
  for (const char **s = subtypes; s != NULL && *s != NULL; s++) printf(" %s", *s);
  printf("\n");
  check(list_contains(subtypes, "default"), "getDeviceSubtypes (slot 5) lists \"default\"");

  const char **extensions =
      ((GetDeviceExtensions)slot(library, LIBRARY_EXTENSIONS))(library, "default");
  check(list_contains(extensions, "ANARI_KHR_GEOMETRY_TRIANGLE"),
        "getDeviceExtensions (slot 4) lists ANARI_KHR_GEOMETRY_TRIANGLE");

  void *device = ((NewDevice)slot(library, LIBRARY_NEW_DEVICE))(library, "default");
  check(device != NULL, "newDevice(\"default\") (slot 2) returns a device");
  if (device != NULL) ((DeletingDestructor)slot(device, DEVICE_DELETE))(device);

  ((DeletingDestructor)slot(library, LIBRARY_DELETE))(library);
  check(messages == 0, "no status messages");
  check(dlclose(handle) == 0, "dlclose");
  printf("%d failed\n", failures);
  return failures == 0 ? 0 : 1;
}
