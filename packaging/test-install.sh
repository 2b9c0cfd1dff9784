#!/usr/bin/env bash
# Installs cavetrace into a temporary prefix with scripts/install.sh, checks the installed
# ANARI SDK device library (soname, dependencies, and packaging/sdk-library-load.c loading it as
# the SDK front end does), then builds examples-c/tutorial.c against that prefix twice — with
# pkg-config and with CMake's find_package(cavetrace) — and runs both programs. Prints one line
# per check and "N passed, M failed, K skipped"; exits non-zero when a check fails.
set -uo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/cavetrace-install.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix
passed=0
failed=0
skipped=0
# A tool that is missing is skipped on a developer's machine and a failure in CI (.ci/run
# installs it).
missing_tool() { # missing_tool <tool> <what it checks>
  if [ "${CI:-}" = true ]; then
    failed=$((failed + 1))
    echo "FAIL $2: $1 is not installed"
  else
    skipped=$((skipped + 1))
    echo "skip $2: $1 is not installed"
  fi
}
check() { # check <name> <command…>: runs the command quietly, shows its output on failure
  local name=$1
  shift
  if "$@" >"$work/out" 2>&1; then
    passed=$((passed + 1))
    echo "ok   $name"
  else
    failed=$((failed + 1))
    sed 's/^/  /' "$work/out"
    echo "FAIL $name"
  fi
}

check "install.sh --prefix" "$root/scripts/install.sh" --prefix "$prefix"
check "install.sh PREFIX=<dir with a space> --no-build" bash -c "
  PREFIX='$work/with space' '$root/scripts/install.sh' --no-build &&
  test -L '$work/with space/lib/libcavetrace.so' -a -f '$work/with space/include/cavetrace.h' &&
  grep -qF 'prefix=$work/with space' '$work/with space/lib/pkgconfig/cavetrace.pc'"
lib=$prefix/lib
version=$(sed -n 's/^version *= *"\([^"]*\)".*/\1/p' "$root/Cargo.toml" | head -n 1)
check "installed files" test -f "$lib/libcavetrace.so.$version" -a -L "$lib/libcavetrace.so.0" \
  -a -L "$lib/libcavetrace.so" -a -f "$prefix/include/cavetrace.h" \
  -a -f "$lib/pkgconfig/cavetrace.pc" -a -f "$lib/cmake/cavetrace/cavetraceConfig.cmake"
check "soname is libcavetrace.so.0" \
  bash -c "objdump -p '$lib/libcavetrace.so.$version' | grep -Eq 'SONAME +libcavetrace\.so\.0$'"

# The SDK device library: its own soname (not libcavetrace.so.0), self-contained (the Rust core is
# linked in; it needs neither libcavetrace nor the SDK's libanari), loadable as the SDK loads it.
sdk_library=$lib/libanari_library_cavetrace.so
check "libanari_library_cavetrace.so is installed" test -f "$sdk_library" -a ! -L "$sdk_library"
check "its soname is libanari_library_cavetrace.so" \
  bash -c "objdump -p '$sdk_library' | grep -Eq 'SONAME +libanari_library_cavetrace\.so$'"
check "it needs neither libcavetrace nor libanari, and its dependencies resolve" bash -c "
  objdump -p '$sdk_library' | awk '\$1 == \"NEEDED\" {print \$2}' >'$work/needed' &&
  grep -q '^libc\.so' '$work/needed' && ! grep -Eq '^lib(cavetrace|anari)' '$work/needed' &&
  ldd '$sdk_library' >'$work/ldd' && ! grep -q 'not found' '$work/ldd'"
check "sdk-library-load.c builds" ${CC:-cc} -std=c99 -Wall -Wextra -Werror \
  "$root/packaging/sdk-library-load.c" -o "$work/sdk-library-load" -ldl
check "the installed SDK library loads; its library object answers through the vtable" \
  "$work/sdk-library-load" "$sdk_library"
# With a build of the Khronos ANARI SDK (ANARI_SDK_BUILD=<dir holding anariInfo and libanari.so>),
# the SDK's own front end loads the installed library too. The SDK is not a CI tool.
if [ -n "${ANARI_SDK_BUILD:-}" ]; then
  check "anariInfo -l cavetrace (Khronos front end) lists the installed device" bash -c "
    ANARI_LIBRARY=cavetrace LD_LIBRARY_PATH='$lib:$ANARI_SDK_BUILD' \
      '$ANARI_SDK_BUILD/anariInfo' -l cavetrace >'$work/anariInfo' 2>&1 &&
    grep -q 'default' '$work/anariInfo' && grep -q 'ANARI_KHR_GEOMETRY_TRIANGLE' '$work/anariInfo'"
  if command -v python3 >/dev/null; then
    check "examples-python/cave_wall.py renders through the Khronos front end (libanari)" bash -c "
      ANARI_FRONT_END='$ANARI_SDK_BUILD/libanari.so' LD_LIBRARY_PATH='$lib:$ANARI_SDK_BUILD' \
        python3 '$root/examples-python/cave_wall.py' '$work/cave_wall.png' 32 >'$work/python' 2>&1 &&
      grep -q 'through the Khronos front end' '$work/python'"
  fi
else
  skipped=$((skipped + 1))
  echo "skip anariInfo -l cavetrace: set ANARI_SDK_BUILD to a Khronos ANARI SDK build"
fi

# pkg-config: flags from the .pc file, an rpath to the installed libdir.
if command -v pkg-config >/dev/null; then
  export PKG_CONFIG_PATH="$lib/pkgconfig"
  check "pkg-config --modversion" test "$(pkg-config --modversion cavetrace)" = "$version"
  pc_build() {
    # shellcheck disable=SC2046 # pkg-config's output is meant to be split into words
    ${CC:-cc} -std=c99 -Wall -Wextra -Werror "$root/examples-c/tutorial.c" \
      -o "$work/tutorial-pkgconfig" $(pkg-config --cflags --libs cavetrace) \
      -Wl,-rpath,"$(pkg-config --variable=libdir cavetrace)"
  }
  check "tutorial.c builds with pkg-config" pc_build
  check "the pkg-config build loads the installed library" \
    bash -c "ldd '$work/tutorial-pkgconfig' | grep -F 'libcavetrace.so.0 => $lib/libcavetrace.so.0'"
  check "the pkg-config build runs and writes its image" \
    bash -c "'$work/tutorial-pkgconfig' '$work/pkgconfig.png' && test -s '$work/pkgconfig.png'"
else
  missing_tool pkg-config "the pkg-config build"
fi

# CMake: find_package(cavetrace) and the imported target cavetrace::cavetrace.
if command -v cmake >/dev/null; then
  mkdir -p "$work/cmake-project"
  cat >"$work/cmake-project/CMakeLists.txt" <<EOF
cmake_minimum_required(VERSION 3.16)
project(cavetrace_tutorial C)
find_package(cavetrace 0.1 REQUIRED)
add_executable(tutorial "$root/examples-c/tutorial.c")
set_property(TARGET tutorial PROPERTY C_STANDARD 99)
target_compile_options(tutorial PRIVATE -Wall -Wextra -Werror)
target_link_libraries(tutorial PRIVATE cavetrace::cavetrace)
EOF
  check "cmake configures with find_package(cavetrace 0.1)" \
    cmake -S "$work/cmake-project" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$prefix"
  check "find_package(cavetrace 1.0) is refused as incompatible" bash -c "
    mkdir -p '$work/cmake-v1' && sed 's/cavetrace 0.1 REQUIRED/cavetrace 1.0 REQUIRED/' \
      '$work/cmake-project/CMakeLists.txt' >'$work/cmake-v1/CMakeLists.txt' &&
    ! cmake -S '$work/cmake-v1' -B '$work/cmake-v1/build' -DCMAKE_PREFIX_PATH='$prefix' \
      >'$work/v1.log' 2>&1 && grep -q 'compatible with requested version' '$work/v1.log'"
  check "tutorial.c builds with CMake" cmake --build "$work/cmake-build"
  check "the CMake build runs and writes its image" \
    bash -c "'$work/cmake-build/tutorial' '$work/cmake.png' && test -s '$work/cmake.png'"
else
  missing_tool cmake "the CMake build"
fi

echo "$passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
