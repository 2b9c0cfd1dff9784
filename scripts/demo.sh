#!/usr/bin/env bash
# Builds the library (release) and the C examples, then renders:
#   out/tutorial.png                       examples-c/tutorial.c
#   out/matrix_camera/{left,right}.png     examples-c/matrix_camera.c
#   out/cave/<head position>/…             examples-c/cave.c: every wall and eye with the offAxis
#                                          and the matrix camera, the unfolded CAVE, a red-cyan
#                                          anaglyph and a side-by-side pair of the front wall
# Usage: scripts/demo.sh [wall resolution (default 256)] [head positions (default 4)]
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
resolution=${1:-256}
steps=${2:-4}
target_dir=${CARGO_TARGET_DIR:-$root/target}
case $target_dir in /*) ;; *) target_dir=$root/$target_dir ;; esac

echo "== building libcavetrace.so (release)"
cargo build --release --quiet

# Link against the build tree: the soname is libcavetrace.so.0, so give it that name too.
bin=$target_dir/examples-c
mkdir -p "$bin/lib"
ln -sf "$target_dir/release/libcavetrace.so" "$bin/lib/libcavetrace.so"
ln -sf "$target_dir/release/libcavetrace.so" "$bin/lib/libcavetrace.so.0"
cflags=(-std=c99 -O2 -Wall -Wextra -I"$root/include")
echo "== building examples-c"
for example in tutorial matrix_camera cave; do
  "${CC:-cc}" "${cflags[@]}" "examples-c/$example.c" -o "$bin/$example" \
    -L"$bin/lib" -lcavetrace -Wl,-rpath,"$bin/lib" -lm
done

mkdir -p out/matrix_camera out/cave
echo "== tutorial"
"$bin/tutorial" out/tutorial.png
echo "== matrix camera (a headset's two eyes from OpenGL matrices)"
"$bin/matrix_camera" out/matrix_camera
echo "== CAVE: 5 walls × 2 eyes × offAxis and matrix cameras, $steps head positions"
"$bin/cave" out/cave "$resolution" "$steps"
echo "images in $root/out/"
