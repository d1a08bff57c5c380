#!/usr/bin/env bash
# All tests: the Rust workspace (cargo test) and the Python suite through fmpy
# against freshly built FMUs. The FMUs (release profile, one compile per
# scene, mostly on one core) are built while the workspace's tests compile and
# run (profile `suite`, Cargo.toml): the two use separate build directories,
# and side by side they take about half the wall time of one after the other.
# Arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
mkdir -p target
fmu_log=target/build_fmus.log
echo "== building FMUs (in the background; log in $fmu_log)"
set -m # its own process group, so that a failure below stops all of it
scripts/build_fmus.sh > "$fmu_log" 2>&1 &
fmu_pid=$!
set +m
trap 'kill -- -"$fmu_pid" 2>/dev/null || true' EXIT
echo "== cargo test"
cargo test --workspace --profile suite
echo "== waiting for the FMUs"
if ! wait "$fmu_pid"; then
  cat "$fmu_log"
  echo "building the FMUs failed" >&2
  exit 1
fi
trap - EXIT
grep '^wrote ' "$fmu_log" || true
echo "== pytest"
python -m pytest -q -n auto tests/python "$@"
