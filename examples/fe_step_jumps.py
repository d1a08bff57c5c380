#!/usr/bin/env python3
"""Cost of one large FE step: length jumps from rest in a single communication step.

Each case is a fresh ``HillMuscleFE`` instance initialized at rest (L0 = 5 cm,
u = 0), then one ``doStep`` of ``--h`` seconds to L0 (1 + jump), passive. It
prints the step's linear solves (the ``newton_iterations`` output: Newton
corrections of the step's attempts, failed continuation and substep tries
not counted), its wall time and the force, for each compressibility D::

    python examples/fe_step_jumps.py                       # D = 1e-9, jumps -5 % .. 5 %
    python examples/fe_step_jumps.py --D 1e-9,1e-7 --jumps 0.01,0.05
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import muscle_models as mm  # noqa: E402

L0 = 0.05


def jump(fmu, jump_fraction, h, params):
    with mm.Instance(fmu, params) as m:
        m.initialize(L0, 0.0, stop_time=h)
        s, vr = m.slave, m.vr
        s.setReal([vr["length"], vr["activation"]], [L0 * (1 + jump_fraction), 0.0])
        started = time.perf_counter()
        try:
            s.doStep(0.0, h)
            status = "ok"
        except Exception as exc:  # the FMU refused the step: report, go on
            status = f"refused ({exc})"
        wall = time.perf_counter() - started
        solves = s.getInteger([vr["newton_iterations"]])[0]
        force = s.getReal([vr["force"]])[0]
    return status, solves, wall, force


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fmu", default=str(mm.FMU_FE))
    parser.add_argument("--h", type=float, default=0.1, help="communication step [s]")
    parser.add_argument("--jumps", default="0.001,0.005,0.01,0.02,0.05,-0.02,-0.05")
    parser.add_argument("--D", default="1e-9", help="comma-separated compressibilities [1/Pa]")
    args = parser.parse_args(argv)
    print("| D [1/Pa] | jump | status | linear solves | wall [s] | force [N] |")
    print("|---|---|---|---|---|---|")
    for d in (float(v) for v in args.D.split(",")):
        for j in (float(v) for v in args.jumps.split(",")):
            status, solves, wall, force = jump(Path(args.fmu), j, args.h, {"D": d})
            print(f"| {d:g} | {100 * j:+g} % | {status} | {solves} | {wall:.3f} | {force:.4f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
