#!/usr/bin/env bash
# Build every FMU into dist/ (release cdylib per FMU, zipped with its model description).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo run --quiet --release -p fmu_build -- "$@"
