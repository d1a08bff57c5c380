#!/usr/bin/env bash
# Builds the FMUs and runs the paper's passive and activated elongation through
# fmpy on default parameters: prints engineering stress at 5, 10, 15 and 20 %
# strain and writes plots to out/. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/build_fmus.sh
python examples/elongation.py --out out
