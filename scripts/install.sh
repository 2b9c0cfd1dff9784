#!/usr/bin/env bash
# Installs cavetrace for C and C++ applications:
#
#   <prefix>/lib/libcavetrace.so.<version>      the library (soname libcavetrace.so.<major>)
#   <prefix>/lib/libcavetrace.so.<major>        → libcavetrace.so.<version> (found at run time)
#   <prefix>/lib/libcavetrace.so                → libcavetrace.so.<major>   (found by -lcavetrace)
#   <prefix>/lib/libanari_library_cavetrace.so  the device library the Khronos ANARI SDK front end
#                                               dlopens for ANARI_LIBRARY=cavetrace (self-contained)
#   <prefix>/include/cavetrace.h
#   <prefix>/lib/pkgconfig/cavetrace.pc         pkg-config --cflags --libs cavetrace
#   <prefix>/lib/cmake/cavetrace/               find_package(cavetrace) → cavetrace::cavetrace
#
# Usage: scripts/install.sh [--prefix DIR] [--no-build]      (or PREFIX=DIR scripts/install.sh)
# The prefix defaults to /usr/local. Both libraries are built with `cargo build --release` (a
# no-op when they are up to date); --no-build installs the existing release build as it is.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
prefix=${PREFIX:-/usr/local}
build=1
while [ $# -gt 0 ]; do
  case $1 in
    --prefix) prefix=${2:?--prefix needs a directory}; shift 2 ;;
    --prefix=*) prefix=${1#--prefix=}; shift ;;
    PREFIX=*) prefix=${1#PREFIX=}; shift ;;
    --no-build) build=0; shift ;;
    -h | --help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "install.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
mkdir -p "$prefix"
prefix=$(cd "$prefix" && pwd)

version=$(sed -n 's/^version *= *"\([^"]*\)".*/\1/p' "$root/Cargo.toml" | head -n 1)
major=${version%%.*}
target_dir=${CARGO_TARGET_DIR:-$root/target}
case $target_dir in /*) ;; *) target_dir=$root/$target_dir ;; esac
library=$target_dir/release/libcavetrace.so
sdk_library=$target_dir/release/libanari_library_cavetrace.so

if [ "$build" = 1 ]; then
  (cd "$root" && cargo build --release --quiet)
fi
for file in "$library" "$sdk_library"; do
  [ -f "$file" ] || { echo "install.sh: $file is missing (build it first)" >&2; exit 1; }
done

# The sonames are set by build.rs and sdk-library/build.rs; what gets installed must agree.
check_soname() { # check_soname <library> <expected soname>
  local soname
  soname=$(objdump -p "$1" 2>/dev/null | awk '$1 == "SONAME" {print $2}')
  if [ -n "$soname" ] && [ "$soname" != "$2" ]; then
    echo "install.sh: $1 has soname '$soname', expected $2" >&2
    exit 1
  fi
}
check_soname "$library" "libcavetrace.so.$major"
check_soname "$sdk_library" libanari_library_cavetrace.so

lib=$prefix/lib
install -d "$lib" "$prefix/include" "$lib/pkgconfig" "$lib/cmake/cavetrace"
install -m 0755 "$library" "$lib/libcavetrace.so.$version"
ln -sfn "libcavetrace.so.$version" "$lib/libcavetrace.so.$major"
ln -sfn "libcavetrace.so.$major" "$lib/libcavetrace.so"
# The SDK front end dlopens exactly lib<name>.so, so this file is installed unversioned.
install -m 0755 "$sdk_library" "$lib/libanari_library_cavetrace.so"
install -m 0644 "$root/include/cavetrace.h" "$prefix/include/cavetrace.h"

# @PREFIX@ may hold characters special to sed; substitute with bash instead.
fill() { # fill <template> <output>
  local text
  text=$(<"$1")
  text=${text//@PREFIX@/$prefix}
  text=${text//@VERSION@/$version}
  text=${text//@SOVERSION@/$major}
  printf '%s\n' "$text" >"$2"
}
fill "$root/packaging/cavetrace.pc.in" "$lib/pkgconfig/cavetrace.pc"
fill "$root/packaging/cavetraceConfig.cmake.in" "$lib/cmake/cavetrace/cavetraceConfig.cmake"
fill "$root/packaging/cavetraceConfigVersion.cmake.in" \
  "$lib/cmake/cavetrace/cavetraceConfigVersion.cmake"

echo "installed cavetrace $version in $prefix"
