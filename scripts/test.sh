#!/usr/bin/env bash
# Runs every test: formatting and lints, Rust unit and integration tests (including the
# header-up-to-date check), the C harness with and without sanitizers, the install test and,
# where Open MPI is installed, the MPI cluster tests (docs/testing.md).
set -euo pipefail
cd "$(dirname "$0")/.."

# Where Open MPI is installed, the lints and the Rust tests take the `mpi` feature too: the
# cluster stage then runs on the library this test build made instead of compiling it again.
target_dir=${CARGO_TARGET_DIR:-target}
case $target_dir in /*) ;; *) target_dir=$PWD/$target_dir ;; esac
features=()
if command -v mpirun >/dev/null && command -v mpicc >/dev/null; then
  features=(--features mpi)
  export CAVETRACE_MPI_LIBRARY=$target_dir/debug/deps/libcavetrace.so
fi
# The SDK-library test builds it in release, the build the C harness uses next.
export CAVETRACE_SDK_TEST_PROFILE=release

echo "== cargo fmt --check"
cargo fmt --check
echo "== cargo clippy ${features[*]}"
cargo clippy --all-targets "${features[@]}" --quiet -- -D warnings
# The traversal counters (a measuring build: docs/kernel.md) must keep compiling too.
echo "== cargo clippy --features kernel-counters"
cargo clippy --all-targets --features kernel-counters --quiet -- -D warnings
echo "== cargo test ${features[*]}"
mkdir -p "$target_dir"
cargo test "${features[@]}" --quiet 2>&1 | tee "$target_dir/cargo-test.log"
# The library must keep compiling for aarch64 (the x86 instruction-set paths are cfg'd out
# there); checked when the target's standard library is installed.
installed_targets=$(rustup target list --installed 2>/dev/null || true)
if grep -qx aarch64-unknown-linux-gnu <<<"$installed_targets"; then
  echo "== cargo check --target aarch64-unknown-linux-gnu"
  cargo check --quiet --lib --target aarch64-unknown-linux-gnu
else
  echo "== aarch64 check skipped: run 'rustup target add aarch64-unknown-linux-gnu' to include it"
fi
if [ -x capi-tests/run.sh ]; then
  echo "== C harness"
  capi-tests/run.sh
fi
if [ -x packaging/test-install.sh ]; then
  echo "== install and packaging (pkg-config, CMake)"
  packaging/test-install.sh
fi
# Rendering across MPI ranks (the `mpi` feature): skipped, saying so, without mpirun.
if [ -x cluster-tests/run.sh ]; then
  echo "== MPI cluster tests (mpirun -np 1/2/4)"
  cluster-tests/run.sh
fi
echo "all test stages passed"
