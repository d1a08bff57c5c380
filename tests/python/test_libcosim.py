"""The muscle FMUs under libcosim (libcosimpy) agree with fmpy on the same inputs.

libcosim runs in a subprocess (libcosim_worker.py): a crash there fails this
test instead of killing pytest. The worker drives `length` (and `activation`)
with an override manipulator (the values for step i set before the step) and
records `force` with a time-series observer; the parent replays the same
inputs through fmpy's FMU2Slave (set the inputs, then doStep(t_i, h)) and
compares the traces point by point, matched on the communication time.

Two input signals: a prescribed stretch-release cycle at constant activation,
run for HillMuscle1D (its length input the muscle's length) and for the
musculotendon units HillMusculotendon1D and HillMusculotendonFE (their length
input the path length: the cycle pulls the path above its declared start; the
FE unit on a 4 x 1 mesh, set as a start value in both importers, as
test_musculotendon.py runs it: its default mesh costs ~0.3 s a step), and the
length and activation command that the MuJoCo elbow (examples/arm_mujoco.py,
explicit scheme) fed HillMuscle1D in a coupled run.

Input timing is the same in both importers: a value set before step i (fmpy:
setReal; libcosim: the override manipulator, applied when the step commences)
holds over [t_i, t_i+1]; libcosim calls no fmi2SetRealInputDerivatives, so it
reproduces the zero-order-hold (explicit) coupling only. The one difference is
the clock: libcosim counts integer nanoseconds and passes
doStep(t_i = ns_i / 1e9, h = t_i+1 - t_i), where h is not always the double
the fmpy master passes (1e-3, or the arm's H); with libcosim's t_i and h,
fmpy is bit-identical to libcosim.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import elongation as el

REPO = Path(__file__).resolve().parents[2]
WORKER = Path(__file__).resolve().parent / "libcosim_worker.py"
STEP_NS = 1_000_000  # 1 ms, exact in libcosim's integer nanoseconds
N = 600
ACTIVATION = 1.0
MT_PATH = Path(os.environ.get("HILL_MUSCULOTENDON_FMU", REPO / "dist" / "HillMusculotendon1D.fmu"))
MT_FE_PATH = REPO / "dist" / "HillMusculotendonFE.fmu"
# The FE unit's mesh (Integer start values), as in test_musculotendon.py.
FE_MESH = (("n_axial", 4), ("n_radial", 1))


@dataclass(frozen=True)
class Case:
    """An FMU and its stretch-release cycle: the length input goes from the
    declared start up by 2 ``pull`` start and back, L_i = start (1 + pull (1 -
    cos(2 pi t_i / 0.5 s)))."""

    name: str
    fmu: Path
    start: float
    pull: float
    # Integer start values, set before initialization in both importers.
    integers: tuple = ()

    def lengths(self):
        h = STEP_NS * 1e-9
        return [self.start * (1.0 + self.pull * (1.0 - math.cos(2.0 * math.pi * i * h / 0.5))) for i in range(N)]


CASES = ("HillMuscle1D", "HillMusculotendon1D", "HillMusculotendonFE")


@pytest.fixture(scope="module", params=CASES)
def case(request, fmu_path):
    """HillMuscle1D: from L0 up to 20 % strain (start = L0). The units
    (HillMusculotendon1D, HillMusculotendonFE on FE_MESH): the path from the
    declared start (tendon slack length + L0) up by 0.2 L0 (L0 the fibres'
    rest length), the same pull on the fibres were the tendon rigid."""
    if request.param == "HillMuscle1D":
        return Case(request.param, fmu_path, el.L0, 0.1)
    path, integers = (MT_PATH, ()) if request.param == "HillMusculotendon1D" else (MT_FE_PATH, FE_MESH)
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs first with `scripts/build_fmus.sh`", pytrace=False)
    variables = el.load_fmu(path).variables
    start, L0 = float(variables["length"].start), float(variables["L0"].start)
    return Case(request.param, path, start, 0.1 * L0 / start, integers)


def run_worker(fmu_path, plan):
    """Run libcosim_worker.py on ``plan`` (see its docstring); its JSON result."""
    proc = subprocess.run([sys.executable, str(WORKER), str(fmu_path), json.dumps(plan)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, (
        f"libcosim worker failed with exit code {proc.returncode}\n--- stdout\n{proc.stdout[-4000:]}"
        f"\n--- stderr\n{proc.stderr[-4000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["ok"], "a libcosim call reported failure"
    return out


@pytest.fixture(scope="module")
def libcosim_run(case):
    plan = {"step_ns": STEP_NS, "activation": ACTIVATION.hex(), "lengths": [x.hex() for x in case.lengths()],
            "integers": dict(case.integers)}
    return run_worker(case.fmu, plan)


def libcosim_time(k):
    """libcosim's communication point k as a double: integer nanoseconds / 1e9."""
    return k * STEP_NS / 1e9


def fmpy_forces(case, h_of_step):
    """Force after each step i (at t_{i+1}) through fmpy's FMU2Slave with the
    same inputs: set length L_i and the activation, then doStep(t_i, h_i)."""
    from arm_pair import Unit

    force = {}
    unit = Unit(case.fmu, {}, "fmpy")
    try:
        L = case.lengths()
        vrs = [unit.vr["length"], unit.vr["activation"]]
        for name, value in case.integers:
            unit.slave.setInteger([unit.vr[name]], [value])
        unit.initialize(L[0], ACTIVATION)
        force[0] = unit.slave.getReal([unit.vr["force"]])[0]
        for i in range(N):
            unit.slave.setReal(vrs, [L[i], ACTIVATION])
            unit.slave.doStep(libcosim_time(i), h_of_step(i))
            force[i + 1] = unit.slave.getReal([unit.vr["force"]])[0]
    finally:
        unit.free()
    return force


@pytest.fixture(scope="module")
def fmpy_fixed_h(case):
    """fmpy with the nominal step h = 1e-3 s every step."""
    return fmpy_forces(case, lambda i: STEP_NS * 1e-9)


@pytest.fixture(scope="module")
def fmpy_libcosim_h(case):
    """fmpy with the step libcosim passes: the difference of its double time
    points, t_{i+1} - t_i, which differs from 1e-3 in the last bits."""
    return fmpy_forces(case, lambda i: libcosim_time(i + 1) - libcosim_time(i))


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


def test_libcosim_force_matches_fmpy(case, libcosim_run, fmpy_fixed_h):
    """The force trace under libcosim equals fmpy's (nominal h = 1e-3 s) on
    the same inputs to 1e-9 relative of the trace's scale at every
    communication point. Measured: HillMuscle1D max |dF| = 2.0e-12 N of
    171.7 N (1.2e-14 relative), bitwise equal at 387 of 600 points;
    HillMusculotendon1D 1.2e-11 N of 846.6 N (1.4e-14), bitwise equal at
    502 of 600; HillMusculotendonFE 1.3e-7 N of 810.3 N (1.6e-10), bitwise
    equal at 30 of 600: its FE Newton solve and the tendon's equilibrium stop
    within their tolerances (1e-10 and 1e-9 of F0 = 624 N, 7.7e-10 of the
    scale), so a change of h in the last bits can move the force that far,
    not by round-off only. libcosim passes h = t_{i+1} - t_i computed
    from its integer-nanosecond clock (see the next test), which is not
    always the double 1e-3."""
    idx, force = libcosim_force(libcosim_run)
    ours = np.array([fmpy_fixed_h[int(i)] for i in idx])
    scale = np.max(abs(ours))
    diff = abs(force - ours)
    worst = int(np.argmax(diff))
    print(f"{case.name}: libcosim vs fmpy (h = 1e-3): max |dF| = {diff.max():.3e} N "
          f"at t = {idx[worst] * STEP_NS * 1e-9:.3f} s, scale {scale:.3e} N, relative {diff.max() / scale:.3e}; "
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


def test_libcosim_sees_the_inputs_it_was_given(case, libcosim_run):
    """The length libcosim reports after step i is the override set before
    step i (the FMU's input convention, as fmpy applies it)."""
    times = np.array(libcosim_run["time_ns"])
    seen = np.array([float.fromhex(x) for x in libcosim_run["length"]])
    L = case.lengths()
    for t, s in zip(times, seen):
        i = int(t // STEP_NS)
        if i >= 1:
            assert s == L[i - 1], (t, s, L[i - 1])


# --------------------------------------------------------------------------
# The length signal of a coupled MuJoCo run, replayed under libcosim
# --------------------------------------------------------------------------

ARM_STEP_NS = 2_000_000  # the arm's communication step H = 2 ms (2 MuJoCo steps of 1 ms)
ARM_T_END = 0.6  # s: rest, the activation step at 0.05 s, the flexion, the switch to the PD law


@pytest.fixture(scope="module")
def arm(fmu_path):
    """A coupled flex-and-hold run of the elbow (explicit scheme: the FMU saw
    exactly the recorded length L(t_i) and command u_i before each step) and
    the same inputs run under libcosim."""
    import arm_mujoco as am

    H = ARM_STEP_NS * 1e-9
    r = am.run("flex_hold", "explicit", H, t_end=ARM_T_END, fmu=fmu_path)
    assert r.stable, r.reason
    n = len(r.t) - 1
    inputs = {"lengths": r.length[:n].copy(), "activations": r.command[:n].copy(),
              "params": dict(am.MUSCLE_PARAMS), "initial": {"length": float(r.length[0]), "activation": 0.0}}
    plan = {"step_ns": ARM_STEP_NS, "lengths": [float(x).hex() for x in inputs["lengths"]],
            "activations": [float(x).hex() for x in inputs["activations"]],
            "params": {k: float(v).hex() for k, v in inputs["params"].items()},
            "initial": {k: float(v).hex() for k, v in inputs["initial"].items()}}
    cosim = run_worker(fmu_path, plan)
    return r, inputs, cosim


def replay(fmu_path, inputs, t_of, h_of, lag=0):
    """fmpy FMU2Slave on the recorded inputs: before step i set length and
    command of step i - lag (clamped at 0), then doStep(t_of(i), h_of(i));
    the force after each step."""
    L, u = inputs["lengths"], inputs["activations"]
    out = np.empty(len(L))
    with el.Muscle(fmu_path, inputs["params"], name="replay") as m:
        m.initialize(**inputs["initial"])
        for i in range(len(L)):
            j = max(0, i - lag)
            m.set_inputs(length=L[j], activation=u[j])
            m.slave.doStep(t_of(i), h_of(i))
            out[i] = m.get("force")[0]
    return out


def test_libcosim_replays_the_coupled_arm_run(arm, fmu_path):
    """The length and activation signal of a coupled MuJoCo run, fed to the
    FMU by libcosim (override manipulator, time-series observer), gives the
    force the FMU produced inside the coupled run, to 1e-9 of the force scale
    at every communication point.

    Why 1e-9: the runs differ only in the double h (and t) libcosim derives
    from its nanosecond clock, ~1 ulp of t_i, i.e. ~1e-13 relative in h; the
    step map is smooth in h, so the force moves by the same order (measured:
    ~1e-14 relative). An input-timing mismatch of one step, the error a
    wrong convention would make, is checked below to be > 1e-4 of the scale,
    five orders above the tolerance. Measured: max |dF| = 1.5e-12 N of
    210.9 N (7e-15), bitwise equal at 159 of 300 points; the one-step lag
    gives 10.2 N (4.8e-2)."""
    r, inputs, cosim = arm
    n = len(inputs["lengths"])
    steps = np.array(cosim["step"])
    assert np.array_equal(steps, np.arange(1, n + 1))
    assert np.array_equal(np.array(cosim["time_ns"]), steps * ARM_STEP_NS)
    # the lengths libcosim reports are the arm's tendon lengths, step by step
    seen = np.array([float.fromhex(x) for x in cosim["length"]])
    assert np.array_equal(seen, inputs["lengths"])
    force = np.array([float.fromhex(x) for x in cosim["force"]])
    coupled = r.force[1:n + 1]
    scale = np.max(np.abs(coupled))
    diff = np.abs(force - coupled)
    H = ARM_STEP_NS * 1e-9
    lagged = replay(fmu_path, inputs, lambda i: i * H, lambda i: H, lag=1)
    lag_diff = np.max(np.abs(lagged - coupled))
    print(f"arm replay: libcosim vs coupled fmpy run max |dF| = {diff.max():.3e} N "
          f"({diff.max() / scale:.2e} of {scale:.1f} N), bitwise equal at {np.sum(diff == 0)} of {n}; "
          f"a one-step input lag would differ by {lag_diff:.3e} N ({lag_diff / scale:.2e})")
    assert scale > 50.0  # the muscle lifts the forearm: a real force
    assert np.ptp(inputs["lengths"]) > 0.02 and np.ptp(inputs["activations"]) > 0.3  # both inputs move
    assert diff.max() <= 1e-9 * scale
    assert lag_diff > 1e-4 * scale


def test_arm_replay_bitwise_with_matching_clocks(arm, fmu_path):
    """Given the same (t, h) per step, replays are bit-identical: fmpy with
    the arm master's clock (t_i = i H, h = H) reproduces the coupled run's
    force exactly (so the recorded inputs are what the FMU saw), and fmpy with
    libcosim's clock (t_i = ns_i / 1e9, h = t_i+1 - t_i) reproduces
    libcosim's."""
    r, inputs, cosim = arm
    n = len(inputs["lengths"])
    H = ARM_STEP_NS * 1e-9
    same_as_arm = replay(fmu_path, inputs, lambda i: i * H, lambda i: H)
    assert np.array_equal(same_as_arm, r.force[1:n + 1])
    t_ns = lambda i: i * ARM_STEP_NS / 1e9  # noqa: E731
    same_as_libcosim = replay(fmu_path, inputs, t_ns, lambda i: t_ns(i + 1) - t_ns(i))
    force = np.array([float.fromhex(x) for x in cosim["force"]])
    assert np.array_equal(same_as_libcosim, force), np.flatnonzero(same_as_libcosim != force)[:10]
