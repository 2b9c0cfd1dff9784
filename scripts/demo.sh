#!/usr/bin/env bash
# Builds the library (release) and the C examples, then renders (every file is listed at the end):
#   out/tutorial.png                       examples-c/tutorial.c: the first program of the README
#   out/matrix_camera/{left,right}.png     examples-c/matrix_camera.c: a headset's two eyes from
#                                          OpenGL view and projection matrices
#   out/cave/<head position>/              examples-c/cave.c: every wall and eye with the offAxis
#                                          and the matrix camera, the unfolded CAVE, a red-cyan
#                                          anaglyph and a side-by-side pair of the front wall
#   out/cave/viewers/                      two tracked people, each alone and in every viewerMode
#   out/cave/stereo/                       parallax (comfortable and too close), cyclopean and
#                                          per-eye lighting, interleaved stereo, a light field
#   out/cave/panorama/                     360° equirectangular (mono, omni-directional stereo) and
#                                          a tilted planetarium dome (fisheye, centred and tracked)
#   out/fields.png                         examples-c/fields.c: isosurfaces of a structured field
#                                          beside an unstructured (tetrahedra) volume
#   out/environment/                       examples-c/environment.c: an HDRI seen behind and in a
#                                          mirror, a rough gold and a glass sphere; ambient occlusion
#   out/lit_volume.png                     examples-c/lit_volume.c: a lit cloud casting its shadow
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
for example in tutorial matrix_camera cave fields environment lit_volume; do
  "${CC:-cc}" "${cflags[@]}" "examples-c/$example.c" -o "$bin/$example" \
    -L"$bin/lib" -lcavetrace -Wl,-rpath,"$bin/lib" -lm
done

# Only the demo's own outputs are replaced, so the list below is exactly what this run wrote.
rm -rf out/tutorial.png out/matrix_camera out/cave out/fields.png out/environment out/lit_volume.png
mkdir -p out/matrix_camera out/cave out/environment
echo "== tutorial"
"$bin/tutorial" out/tutorial.png
echo "== matrix camera (a headset's two eyes from OpenGL matrices)"
"$bin/matrix_camera" out/matrix_camera
echo "== CAVE: 5 walls × 2 eyes × offAxis and matrix cameras, $steps head positions"
"$bin/cave" out/cave "$resolution" "$steps"
echo "== isosurfaces and an unstructured volume"
"$bin/fields" out/fields.png
echo "== environment (hdri seen and reflected, glass, ambient occlusion)"
"$bin/environment" out/environment
echo "== lit volume"
"$bin/lit_volume" out/lit_volume.png

# Every folder and file written, folders with the same files on one line.
echo "== outputs in $root/out/"
echo "out/tutorial.png"
echo "out/fields.png"
echo "out/lit_volume.png"
declare -A folders_of
order=()
while IFS= read -r folder; do
  files=$(find "$folder" -maxdepth 1 -type f -printf '%f\n' | sort | tr '\n' ' ')
  [ -n "$files" ] || continue
  [ -n "${folders_of[$files]+set}" ] || order+=("$files")
  folders_of[$files]+="$folder/ "
done < <(find out/matrix_camera out/cave out/environment -type d | sort -V)
for files in "${order[@]}"; do
  count=$(wc -w <<<"$files")
  echo "${folders_of[$files]}($count files): $files" | fold -s -w 100 | sed '2,$s/^/    /'
done
