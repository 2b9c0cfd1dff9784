#!/usr/bin/env bash
# Rendering across MPI ranks (docs/cluster.md): builds the library with the `mpi` feature and
# runs the C and Python tests under mpirun with 1, 2 and 4 ranks, then the tests in which a rank
# is killed mid-frame and in which a rank's own render fails. Skips, saying why, when mpirun,
# mpicc or mpi4py is missing (.ci/run installs them). Closes with "total: N passed, M failed";
# exits non-zero on a failure.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
target_dir=${CARGO_TARGET_DIR:-$root/target}
case $target_dir in /*) ;; *) target_dir=$root/$target_dir ;; esac
build=$target_dir/cluster-tests

for tool in mpirun mpicc; do
  if ! command -v $tool >/dev/null; then
    echo "-- MPI tests skipped: no $tool (install openmpi-bin and libopenmpi-dev)"
    exit 0
  fi
done
# Root may run mpirun only when it says so; a 2-core machine runs 4 ranks oversubscribed.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun=(mpirun --oversubscribe --mca btl self,vader,tcp)

# CAVETRACE_MPI_LIBRARY: a libcavetrace.so already built with the mpi feature (scripts/test.sh
# passes the one its `cargo test --features mpi` made); otherwise one is built here.
library=${CAVETRACE_MPI_LIBRARY:-}
if [ -z "$library" ]; then
  echo "-- building libcavetrace.so with the mpi feature"
  (cd "$root" && cargo build --quiet --lib --features mpi)
  library=$target_dir/debug/libcavetrace.so
fi
symbols=$(nm -D "$library" 2>/dev/null || true)
if ! grep -q ' MPI_Init' <<<"$symbols"; then
  echo "FAIL $library is not built with the mpi feature (it does not call MPI_Init)"
  exit 1
fi
mkdir -p "$build/lib"
ln -sf "$library" "$build/lib/libcavetrace.so"
ln -sf "$library" "$build/lib/libcavetrace.so.0"
mpicc -std=c99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O1 -g -I"$root/include" \
  "$here/mpi_render.c" -L"$build/lib" -lcavetrace -Wl,-rpath,"$build/lib" -lm \
  -o "$build/mpi_render"

passed=0
failed=0
# run <name> <command…>: its output, and its "ok"/"FAIL" lines counted.
run() {
  local name=$1 log=$build/$1.log status=0
  shift
  timeout 120 "$@" >"$log" 2>&1 || status=$?
  grep -E '^(ok|FAIL)' "$log" || true
  local ok fail
  ok=$(grep -c '^ok' "$log" || true)
  fail=$(grep -c '^FAIL' "$log" || true)
  if [ "$status" -ne 0 ] && [ "$fail" -eq 0 ]; then
    echo "FAIL $name exited with status $status:"
    tail -20 "$log"
    fail=1
  fi
  passed=$((passed + ok))
  failed=$((failed + fail))
}

python_ok=1
if ! python3 -c "import mpi4py" 2>/dev/null; then
  python_ok=0
  echo "-- Python MPI tests skipped: no mpi4py (pip install mpi4py)"
fi
for ranks in 1 2 4; do
  run "c_$ranks" "${mpirun[@]}" -np $ranks "$build/mpi_render"
  if [ $python_ok = 1 ]; then
    run "python_$ranks" "${mpirun[@]}" -np $ranks -x CAVETRACE_LIBRARY="$build/lib/libcavetrace.so" \
      python3 "$here/mpi_render.py"
  fi
done
# mpirun ends every rank when one dies unless recovery is enabled; with it, the survivors
# must report the lost rank through the status callback within mpiTimeout and return.
# mpirun itself exits non-zero (a rank was killed): the two survivors' "ok" lines decide.
log=$build/kill.log
timeout 120 "${mpirun[@]}" --mca orte_enable_recovery 1 --mca orte_abort_on_non_zero_status 0 \
  -np 3 "$build/mpi_render" kill >"$log" 2>&1 || true
grep -E '^(ok|FAIL)' "$log" || true
if [ "$(grep -c '^ok' "$log" || true)" -eq 2 ]; then
  passed=$((passed + 1))
else
  echo "FAIL a rank killed mid-frame: the two other ranks did not both report it"
  tail -20 "$log"
  failed=$((failed + 1))
fi

# A rank whose own render fails (CAVETRACE_TEST_FAIL_RANK, a test-only trigger read by the
# device's cluster code): every rank, the failing one included, reports it and returns.
log=$build/fail.log
status=0
timeout 120 "${mpirun[@]}" -np 3 -x CAVETRACE_TEST_FAIL_RANK=2 "$build/mpi_render" fail \
  >"$log" 2>&1 || status=$?
grep -E '^(ok|FAIL)' "$log" || true
if [ "$(grep -c '^ok' "$log" || true)" -eq 3 ] && [ "$status" -eq 0 ]; then
  passed=$((passed + 1))
else
  echo "FAIL a rank whose render fails: not every rank reported it and returned (status $status)"
  tail -20 "$log"
  failed=$((failed + 1))
fi

echo "total: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
