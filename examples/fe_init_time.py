#!/usr/bin/env python3
"""Wall time of HillMuscleFE's initialization (default mesh) at rest and
pre-activated, through fmpy: docs/fe.md "Verification status".

    .venv/bin/python examples/fe_init_time.py [--runs 3] [--fmu A.fmu --fmu B.fmu ...]

Per case, the median and range of `runs` initializations (fmi2ExitInitializationMode
with the inputs and `initial_activation` set), each on a fresh instance. With
several `--fmu` (e.g. a build of an earlier commit beside dist/HillMuscleFE.fmu)
the runs alternate between them, and each FMU's median is also given as a
ratio to the first FMU's. `newton` is the `newton_iterations` output after the
initialization: the linear solves of its converged stages.
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
    ap.add_argument("--fmu", type=Path, action="append",
                    help="FMU to time (repeatable; default dist/HillMuscleFE.fmu)")
    args = ap.parse_args()
    fmus = args.fmu or [FMU]
    print("fmu  L/L0  initial_activation  median s  (min - max)  / first  force N  newton")
    for stretch, a0 in CASES:
        times = {f: [] for f in fmus}
        force, newton = {}, {}
        for _ in range(args.runs):
            for fmu in fmus:
                m = Muscle(fmu, {"initial_activation": a0})
                t = time.perf_counter()
                m.initialize(length=stretch * L0)
                times[fmu].append(time.perf_counter() - t)
                force[fmu] = m.get("force")[0]
                newton[fmu] = m.slave.getInteger([m.vr["newton_iterations"]])[0]
                m.free()
        first = statistics.median(times[fmus[0]])
        for i, fmu in enumerate(fmus):
            ts = times[fmu]
            med = statistics.median(ts)
            print(f"{i:3d}  {stretch:4.2f}  {a0:18.2f}  {med:8.2f}  "
                  f"({min(ts):.2f} - {max(ts):.2f})  {med / first:6.2f}  {force[fmu]:.10g}  {newton[fmu]}")


if __name__ == "__main__":
    main()
