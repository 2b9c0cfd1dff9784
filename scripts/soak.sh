#!/usr/bin/env bash
# Soak figures: builds capi-tests/soak.c and capi-tests/fuzz.c against the release library and
# prints resident memory, frames per second and messages of 10,000 frames whose scenes are
# created, changed and released every frame from 4 threads, then the fuzzer's throughput.
#
#   scripts/soak.sh                  SOAK_FRAMES=400 scripts/soak.sh   (a quick run)
#   FUZZ_SECONDS=60 scripts/soak.sh  (how long the fuzzer soaks; default 20)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
target_dir=${CARGO_TARGET_DIR:-$root/target}
case $target_dir in /*) ;; *) target_dir=$root/$target_dir ;; esac
build=$target_dir/soak
cc=${CC:-cc}
(cd "$root" && cargo build --release --quiet)
mkdir -p "$build/lib"
ln -sf "$target_dir/release/libcavetrace.so" "$build/lib/libcavetrace.so"
ln -sf "$target_dir/release/libcavetrace.so" "$build/lib/libcavetrace.so.0"
for program in soak fuzz; do
  "$cc" -std=c11 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O2 -g -I"$root/include" \
    -o "$build/$program" "$root/capi-tests/$program.c" -L"$build/lib" -lcavetrace \
    -Wl,-rpath,"$build/lib" -lm -lpthread
done
"$build/soak"
"$build/fuzz" --soak "${FUZZ_SECONDS:-20}" 2>/dev/null | head -n 1
