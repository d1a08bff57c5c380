"""HillMuscle1D under libcosim (libcosimpy) agrees with fmpy on the same inputs.

libcosim runs in a subprocess (libcosim_worker.py): a crash there fails this
test instead of killing pytest. The worker drives `length` with an override
manipulator (value for step i set before the step) and records `force` with a
time-series observer; the parent replays the same inputs through fmpy's
FMU2Slave (set the inputs, then doStep(t_i, h)) and compares the traces point
by point, matched on the communication time.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import elongation as el

WORKER = Path(__file__).resolve().parent / "libcosim_worker.py"
STEP_NS = 1_000_000  # 1 ms, exact in libcosim's integer nanoseconds
N = 600
ACTIVATION = 1.0


def lengths():
    """A stretch-release cycle (period 0.5 s, up to 20 % strain) at t_i = i h."""
    h = STEP_NS * 1e-9
    return [el.L0 * (1.0 + 0.1 * (1.0 - math.cos(2.0 * math.pi * i * h / 0.5))) for i in range(N)]


@pytest.fixture(scope="module")
def libcosim_run(fmu_path):
    plan = {"step_ns": STEP_NS, "activation": ACTIVATION.hex(), "lengths": [x.hex() for x in lengths()]}
    proc = subprocess.run([sys.executable, str(WORKER), str(fmu_path), json.dumps(plan)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, (
        f"libcosim worker failed with exit code {proc.returncode}\n--- stdout\n{proc.stdout[-4000:]}"
        f"\n--- stderr\n{proc.stderr[-4000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["ok"], "a libcosim call reported failure"
    return out


def libcosim_time(k):
    """libcosim's communication point k as a double: integer nanoseconds / 1e9."""
    return k * STEP_NS / 1e9


def fmpy_forces(fmu_path, h_of_step):
    """Force after each step i (at t_{i+1}) through fmpy's FMU2Slave with the
    same inputs: set length L_i and the activation, then doStep(t_i, h_i)."""
    force = {}
    with el.Muscle(fmu_path, name="fmpy") as m:
        L = lengths()
        m.initialize(length=L[0], activation=ACTIVATION)
        force[0] = m.outputs()["force"]
        for i in range(N):
            m.set_inputs(length=L[i], activation=ACTIVATION)
            m.slave.doStep(libcosim_time(i), h_of_step(i))
            force[i + 1] = m.outputs()["force"]
    return force


@pytest.fixture(scope="module")
def fmpy_fixed_h(fmu_path):
    """fmpy with the nominal step h = 1e-3 s every step."""
    return fmpy_forces(fmu_path, lambda i: STEP_NS * 1e-9)


@pytest.fixture(scope="module")
def fmpy_libcosim_h(fmu_path):
    """fmpy with the step libcosim passes: the difference of its double time
    points, t_{i+1} - t_i, which differs from 1e-3 in the last bits."""
    return fmpy_forces(fmu_path, lambda i: libcosim_time(i + 1) - libcosim_time(i))


def libcosim_force(run):
    times = np.array(run["time_ns"])
    return times // STEP_NS, np.array([float.fromhex(x) for x in run["force"]])


def test_libcosim_runs_all_steps(libcosim_run):
    """libcosim took all N steps and observed the force after each of them."""
    steps = np.array(libcosim_run["step"])
    times = np.array(libcosim_run["time_ns"])
    assert len(libcosim_run["force"]) == N
    assert np.array_equal(steps, np.arange(1, N + 1))
    assert np.array_equal(times, steps * STEP_NS)


def test_libcosim_force_matches_fmpy(libcosim_run, fmpy_fixed_h):
    """The force trace under libcosim equals fmpy's (nominal h = 1e-3 s) on
    the same inputs to 1e-9 relative of the trace's scale at every
    communication point. Measured: max |dF| = 2.0e-12 N of 245 N (8e-15
    relative), bitwise equal at 514 of 600 points: libcosim passes
    h = t_{i+1} - t_i computed from its integer-nanosecond clock (see the
    next test), which is not always the double 1e-3."""
    idx, force = libcosim_force(libcosim_run)
    ours = np.array([fmpy_fixed_h[int(i)] for i in idx])
    scale = np.max(abs(ours))
    diff = abs(force - ours)
    worst = int(np.argmax(diff))
    print(f"libcosim vs fmpy (h = 1e-3): max |dF| = {diff.max():.3e} N at t = {idx[worst] * STEP_NS * 1e-9:.3f} s, "
          f"scale {scale:.3e} N, relative {diff.max() / scale:.3e}; "
          f"bitwise equal at {np.sum(diff == 0)} of {diff.size} points")
    assert scale > 10.0  # the activated muscle carries a real force
    assert diff.max() <= 1e-9 * scale


def test_libcosim_is_bitwise_fmpy_with_its_step_sizes(libcosim_run, fmpy_libcosim_h):
    """Given libcosim's exact communication points (ns / 1e9) and step sizes
    (t_{i+1} - t_i), fmpy reproduces libcosim's force trace bit for bit: both
    importers apply the inputs the same way (set before the step, held over
    it), and the FMU is deterministic."""
    idx, force = libcosim_force(libcosim_run)
    ours = np.array([fmpy_libcosim_h[int(i)] for i in idx])
    assert np.array_equal(force, ours), np.flatnonzero(force != ours)[:10]


def test_libcosim_sees_the_inputs_it_was_given(libcosim_run):
    """The length libcosim reports after step i is the override set before
    step i (the FMU's input convention, as fmpy applies it)."""
    times = np.array(libcosim_run["time_ns"])
    seen = np.array([float.fromhex(x) for x in libcosim_run["length"]])
    L = lengths()
    for t, s in zip(times, seen):
        i = int(t // STEP_NS)
        if i >= 1:
            assert s == L[i - 1], (t, s, L[i - 1])
