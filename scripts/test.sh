#!/usr/bin/env bash
# Runs every test: formatting and lints, Rust unit and integration tests (including the
# header-up-to-date check), and the C harness with and without sanitizers.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --check
echo "== cargo clippy"
cargo clippy --all-targets --quiet -- -D warnings
echo "== cargo test"
cargo test --quiet 2>&1 | tee target/cargo-test.log
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
