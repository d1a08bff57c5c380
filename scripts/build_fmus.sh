#!/usr/bin/env bash
# Build the FMU of every shipped scene (fmu_build/scenes/*.toml) into dist/:
# per scene a release cdylib compiled for that scene, zipped with its model
# description. Arguments go to fmu_build (e.g. --scene FILE, --fmu ID).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo run --quiet --release -p fmu_build -- "$@"
