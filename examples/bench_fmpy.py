#!/usr/bin/env python3
"""Per-step cost of HillMuscle1D through fmpy's FMU2Slave.

Each step of the loop is one ``setReal`` (length and activation command), one
``doStep`` and one ``getReal`` (all nine outputs): the cost an fmpy master
pays per communication step, Python/ctypes overhead included. The input is a
stretch-and-release cycle with the activation on (u = 1): the length goes
L0 -> 1.2 L0 -> L0 as a cosine with a 1 s period, steps of 1e-4 s. The run is
repeated and the median is reported::

    python examples/bench_fmpy.py --steps 20000 --repeats 5

Prints a human line and a JSON line (``{"bench": "fmpy_step", ...}``).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from elongation import DEFAULT_FMU, L0, OUTPUT_NAMES, Muscle  # noqa: E402


def stretch_release(t, period=1.0, strain=0.2):
    """Length [m] of the stretch-and-release cycle at time t."""
    return L0 * (1.0 + 0.5 * strain * (1.0 - math.cos(2.0 * math.pi * t / period)))


def one_run(fmu, steps, h):
    """Time ``steps`` steps of set + doStep + get; returns seconds and the last force."""
    with Muscle(fmu) as m:
        m.initialize(length=L0, activation=1.0)
        slave = m.slave
        in_vrs = [m.vr["length"], m.vr["activation"]]
        out_vrs = [m.vr[n] for n in OUTPUT_NAMES]
        lengths = [stretch_release(i * h) for i in range(steps)]
        t0 = time.perf_counter()
        for i in range(steps):
            slave.setReal(in_vrs, [lengths[i], 1.0])
            slave.doStep(i * h, h)
            out = slave.getReal(out_vrs)
        elapsed = time.perf_counter() - t0
    return elapsed, out[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fmu", default=str(DEFAULT_FMU), help="path to HillMuscle1D.fmu (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=20000, help="steps per run (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=5, help="runs; the median is reported (default: %(default)s)")
    parser.add_argument("--step-size", type=float, default=1e-4, help="communication step [s] (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.steps < 1 or args.repeats < 1:
        parser.error("--steps and --repeats must be >= 1")

    times = []
    for _ in range(args.repeats):
        elapsed, force = one_run(args.fmu, args.steps, args.step_size)
        times.append(elapsed)
    per_step = [t / args.steps * 1e9 for t in times]
    median = statistics.median(per_step)
    print(f"fmpy FMU2Slave loop (setReal + doStep + getReal): {median:.0f} ns/step "
          f"(median of {args.repeats} runs of {args.steps} steps of {args.step_size:g} s; "
          f"min {min(per_step):.0f}, max {max(per_step):.0f}; last force {force:.6g} N)")
    print(json.dumps({
        "bench": "fmpy_step",
        "fmu": str(args.fmu),
        "steps": args.steps,
        "repeats": args.repeats,
        "step_size": args.step_size,
        "ns_per_step_median": median,
        "ns_per_step_min": min(per_step),
        "ns_per_step_max": max(per_step),
        "ns_per_step_all": per_step,
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
