#!/usr/bin/env python3
"""Wall time of HillMuscleFE's initialization (default mesh) at rest and
pre-activated, through fmpy: docs/fe.md "Verification status".

    .venv/bin/python examples/fe_init_time.py [--runs 3]

Per case, the median and range of `runs` initializations (fmi2ExitInitializationMode
with the inputs and `initial_activation` set), each on a fresh instance.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from elongation import L0, Muscle

FMU = Path(__file__).resolve().parents[1] / "dist" / "HillMuscleFE.fmu"
CASES = [(1.0, 0.0), (1.0, 0.5), (1.0, 1.0), (1.1, 0.5)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    print("L/L0  initial_activation  median s  (min - max)  force N")
    for stretch, a0 in CASES:
        times, force = [], None
        for _ in range(args.runs):
            m = Muscle(FMU, {"initial_activation": a0})
            t = time.perf_counter()
            m.initialize(length=stretch * L0)
            times.append(time.perf_counter() - t)
            force = m.get("force")[0]
            m.free()
        print(f"{stretch:4.2f}  {a0:18.2f}  {statistics.median(times):8.2f}  "
              f"({min(times):.2f} - {max(times):.2f})  {force:.6g}")


if __name__ == "__main__":
    main()
