#!/usr/bin/env bash
# All tests: the Rust workspace (cargo test) and the Python suite through fmpy
# against freshly built FMUs.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
echo "== cargo test"
cargo test --workspace --release
echo "== building FMUs"
scripts/build_fmus.sh
echo "== pytest"
python -m pytest -q tests/python "$@"
