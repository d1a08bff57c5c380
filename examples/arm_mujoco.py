#!/usr/bin/env python3
"""A MuJoCo elbow driven by the HillMuscle1D FMU: co-simulation coupling schemes.

The model (MJCF inline below, ``ARM_XML``; written by this project)
--------------------------------------------------------------------
A planar elbow in the x-z plane: the upper arm is fixed (world geoms, elbow at
the origin, shoulder up at z = 0.30 m); the forearm (1.5 kg capsule, 0.28 m)
hangs on a hinge at the elbow (axis -y: a positive angle is flexion, 0 = arm
straight down) under gravity, with a 1.0 kg hand load at 0.30 m (about the
elbow: I = 0.127 kg m^2, gravity torque 5.0 N m at 90 deg). Joint damping
0.05 N m s, joint range [-0.1, 2.6] rad.

The elbow flexor is a spatial tendon ``flexor``: origin site on the upper arm
(0.025, 0, 0.28), insertion site on the forearm 0.04 m below the elbow
(0.015 m in front), wrapping over a cylinder of radius 0.02 m at the elbow
(side site in front), so that near full extension (angle < ~7 deg) the path
wraps around the elbow instead of passing through the joint (moment arm
stays 0.02 m there). MuJoCo computes its length: 0.3204 m at 0 deg,
0.2875 m at 60 deg, 0.2654 m at 90 deg, 0.2470 m at 120 deg (moment arm
-dL/dq: 0.020, 0.042, 0.041, 0.027 m).

The whole tendon path is the muscle (no series tendon): muscle length =
``ten_length``. A ``general`` actuator on the tendon with unit gain and no
bias applies ctrl as the tendon force; in MuJoCo a *positive* actuator force
on a tendon acts to *lengthen* it (generalized force = ten_J^T * force, and
ten_J = dL/dq < 0 for this flexor), so a muscle tension F (positive in the
FMU) is applied as ``ctrl = -F``. ``check_sign()`` verifies it numerically:
ctrl = -100 N (100 N of tension) gives a positive (flexing) elbow
acceleration.

Muscle sizing (the FMU's ``L0`` and ``area``)
--------------------------------------------
``L0 = 0.29 m`` (the path length at ~57 deg) and ``area = 5e-4 m^2``
(5 cm^2, brachialis-like; maximum isometric force sigma0 * area = 350 N, ~14
N m at the elbow vs 5.0 N m of gravity). Over the working range 0 .. 120 deg
the stretch L/L0 goes from 1.105 to 0.852 and the fibre stretch
lambda_f/lambda_opt (lambda_opt = 1.05) from 1.05 to 0.81: inside the
force-length support [0.6, 1.4] where f_lambda = 1 - 4 (1 - r)^2 >= 0.84
(``working_range()`` recomputes these numbers from the model; the tests
check the recorded fibre_stretch of the flex-and-hold runs).

Co-simulation loop (one communication step of size H = n * dt, dt the
MuJoCo step, 1 ms by default)
-------------------------------------------------------------------------
At a communication point t, ``mj_step1`` has been done: ``ten_length`` and
``ten_velocity`` are those of the state at t (after ``mj_step`` they would be
the pre-step values). The master reads L(t), dL/dt(t) and the elbow angle,
computes the activation command u (controller below), sets them into the FMU
through fmpy's ``FMU2Slave``, does ``doStep(t, H)``, and then runs n MuJoCo
steps (``ctrl`` set, ``mj_step2``, ``mj_step1``), ctrl = -force as the scheme
says:

``explicit``      zero-order hold: the FMU moves to L(t) (length input only),
                  its force F is applied unchanged over [t, t + H].
``derivative``    input derivatives: length L(t) and dL/dt(t) (order 1), so
                  the FMU step ends at L(t) + H dL/dt; its force at t + H is
                  applied over [t, t + H], linearly interpolated from the
                  force of the previous step.
``implicit``      linearly implicit: as ``derivative``, plus K = d force /
                  d length from ``fmi2GetDirectionalDerivative`` (the
                  stiffness of that step map); in each MuJoCo step the force
                  is F + K (L_now - L_set), with L_set = L(t) + H dL/dt the
                  length the FMU ended at and L_now the current tendon length
                  (read after mj_step1), so the muscle's stiffness acts at
                  the MuJoCo rate rather than once per communication step.
                  With an FMU that cannot interpolate inputs (or
                  ``input_derivatives=False``), ``derivative`` and
                  ``implicit`` set the length input L(t) + H dL/dt instead
                  (the same end length and rate).
``iterated``      Gauss-Seidel with rollback: the FMU state
                  (getFMUstate/setFMUstate) and mjData (mj_copyData) at t are
                  saved; the FMU is stepped to a guessed end length L*
                  (start: L(t) + H dL/dt), its force is applied over the
                  MuJoCo steps (linear from the previous force), the end
                  length L(t + H) replaces L*, both are rolled back, and
                  this repeats until |L(t + H) - L*| < 1e-9 m (max 20
                  iterations). The accurate reference.

Controller (activation command, evaluated at the communication points):
u = 0 until 0.05 s, a step u = 0.6 until the elbow passes 0.5 * target (or
0.35 s), then PD around a bias, u = clip(u_hold + kp (target - angle)
- kd angle_rate, 0, 1), target 90 deg (u_hold = 0.40, kp = 2.0 /rad,
kd = 0.4 s/rad).

Stability check (``stability``): a run is flagged unstable when its
oscillation energy grows — during the run, when three successive peaks of the
arm's kinetic energy each exceed the one before by 1.5x and the last is 4x
the first (and above 1 mJ); at the end, when the kinetic energy at the end of
the hold phase is > 4x that at its start — or when a value goes non-finite,
the FMU rejects a step, |force| exceeds 5x the maximum isometric force, or
the angle leaves [-0.5, 3.2] rad. The energy test comes first, so a
coupling instability is reported as what it is (the zero-order hold pumping
energy into the arm) before it blows up. The run stops at the first flag and
returns what it has, no exception.

Experiments (``EXPERIMENTS``): ``flex_hold`` (the controller above, 1 s),
``hold`` (open loop, constant command 0.4 at 90 deg with a 1 rad/s kick: the
same command for every step size) and ``hold_stiff`` (``hold`` with a 5 cm
fibre, L0 = 0.05 m, in series with a rigid tendon, ~5x stiffer; valid near
90 deg only) and ``passive_stiff`` (that fibre relaxed and stretched 25 % at
0 deg: a purely elastic muscle swinging the forearm, where the zero-order
hold pumps energy). ``--param alpha=100`` (any Real FMU parameter) applies
on top of an experiment. Measured results: docs/coupling.md.

The FE muscle (``--model fe``)
------------------------------
``--model fe`` runs ``dist/HillMuscleFE.fmu`` (the paper's fusiform
specimen meshed with tetrahedra, quasi-static FE per step, same inputs and
outputs as HillMuscle1D, Integer mesh parameters set with ``--mesh
NAME=VALUE``; its ``L0`` and ``area`` parameters scale the specimen to the
arm's muscle, as for the 1D model). An FE step costs ~1-20 ms, so the FE
communicates at a coarser rate than MuJoCo: by default H = ``FE_STEP`` =
10 ms, i.e. one FE step per 10 MuJoCo steps of 1 ms (100 Hz), with the
linearly implicit scheme (the FE's d force / d length from its converged
tangent acts at the MuJoCo rate in between; with the 1D muscle at that H
the angle error vs the iterated 1 ms reference is 0.06 deg in ``hold``,
and 2.7 deg in ``flex_hold``, where the controller sampled at 100 Hz
dominates). A scheme the FMU's capability flags do not allow (implicit
without providesDirectionalDerivative, iterated without
canGetAndSetFMUstate) is refused with a message; without
canInterpolateInputs the master sets the extrapolated length instead of
the derivative. When the FE FMU is absent the script says so and falls
back to HillMuscle1D at the same communication step.

The FMU's call trace (``--trace FILE``)
--------------------------------------
``--trace FILE`` (implicit scheme) writes what the master gave the FMU and got
back, one line per communication step, as CSV (``write_trace``): the header
comments name the parameters (``L0``, ``area``, mesh), the initial length and
activation and H; each row holds t, the length L(t), its derivative dL/dt,
the activation command u, the force after the step and d force / d length.
Per row the master called fmi2SetReal(length, activation = L, u),
fmi2SetRealInputDerivatives(length, order 1, dL/dt), fmi2DoStep(t, H),
fmi2GetReal(force), fmi2GetDirectionalDerivative(force; length; 1) and
fmi2GetReal(force, activation_level, fibre_stretch). The benchmark
``benches/fe_realtime.rs`` replays the committed trace of the default run
(``benches/data/arm_fe_implicit.csv``) open loop through the C ABI.

The antagonist pair (``--pair``)
--------------------------------
``--pair`` runs a second model on the same elbow: a flexor (biceps long
head) and an extensor (triceps long head), each a musculotendon FMU
(``HillMusculotendon1D``: path length in, tendon force out) on its own
spatial tendon, driven by a co-contraction pattern, with every scheme above,
and compared with MuJoCo's own muscles and with rigid tendons. The model,
the parameters and their sources, the pattern: ``arm_pair.py``.

Usage::

    python examples/arm_mujoco.py                      # all schemes, flex_hold, H = 1 ms, plot to docs/figures
    python examples/arm_mujoco.py --scheme implicit --step 0.02
    python examples/arm_mujoco.py --experiment hold_stiff --step 0.096 --t-end 2.0
    python examples/arm_mujoco.py --sweep --experiment hold --t-end 2.0   # stability limits, error vs wall time
    python examples/arm_mujoco.py --model fe           # HillMuscleFE, implicit, H = 10 ms
    python examples/arm_mujoco.py --model fe --scheme all --mesh n_axial=6 --mesh n_radial=1
    python examples/arm_mujoco.py --model fe --trace benches/data/arm_fe_implicit.csv   # record the FMU calls
    python examples/arm_mujoco.py --pair               # the antagonist pair: all schemes + comparison, H = 1 ms
    python examples/arm_mujoco.py --pair --sweep --steps-ms 1,4,16,32,64   # the pair's stability limits
"""

from __future__ import annotations

import argparse
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from elongation import DEFAULT_FMU, Muscle  # noqa: E402

REPO = Path(__file__).resolve().parent.parent

ARM_XML = """
<mujoco model="elbow_flexor">
  <compiler angle="radian"/>
  <option timestep="0.001" gravity="0 0 -9.81" integrator="Euler"/>
  <worldbody>
    <geom name="upper_arm" type="capsule" fromto="0 0 0.30 0 0 0" size="0.03" contype="0" conaffinity="0"/>
    <site name="origin" pos="0.025 0 0.28" size="0.005"/>
    <geom name="elbow_wrap" type="cylinder" pos="0 0 0" zaxis="0 1 0" size="0.02 0.03" contype="0" conaffinity="0"/>
    <site name="elbow_side" pos="0.06 0 0" size="0.003"/>
    <body name="forearm" pos="0 0 0">
      <joint name="elbow" type="hinge" axis="0 -1 0" range="-0.1 2.6" limited="true" damping="0.05"/>
      <geom name="forearm" type="capsule" fromto="0 0 0 0 0 -0.28" size="0.025" mass="1.5" contype="0" conaffinity="0"/>
      <site name="insertion" pos="0.015 0 -0.04" size="0.005"/>
      <geom name="hand_load" type="sphere" pos="0 0 -0.30" size="0.04" mass="1.0" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <tendon>
    <spatial name="flexor" width="0.004">
      <site site="origin"/>
      <geom geom="elbow_wrap" sidesite="elbow_side"/>
      <site site="insertion"/>
    </spatial>
  </tendon>
  <actuator>
    <general name="muscle" tendon="flexor" gainprm="1" biasprm="0 0 0" ctrllimited="false"/>
  </actuator>
</mujoco>
"""

MUSCLE_PARAMS = {"L0": 0.29, "area": 5e-4}
FE_FMU = REPO / "dist" / "HillMuscleFE.fmu"
FE_STEP = 10e-3
"""Default communication step of the FE muscle [s]: 10 MuJoCo steps (module docstring)."""
MODELS = ("1d", "fe")
SIGMA0 = 7.0e5
LAMBDA_OPT = 1.05
F_MAX = SIGMA0 * MUSCLE_PARAMS["area"]
SCHEMES = ("explicit", "derivative", "implicit", "iterated")


@dataclass
class Replay:
    """An open-loop activation command: the command samples (t, u) of a
    reference run, linearly interpolated, so that every scheme and step sees
    the same command signal (``Replay.of(result)``)."""

    times: np.ndarray
    values: np.ndarray

    def __call__(self, t, angle=None, rate=None):
        return float(np.interp(t, self.times, self.values))

    @classmethod
    def of(cls, result):
        ok = np.isfinite(result.command)
        return cls(result.t[ok], result.command[ok])


@dataclass
class Controller:
    target: float = np.radians(90.0)
    t_on: float = 0.05
    u_step: float = 0.6
    t_pd_latest: float = 0.35
    u_hold: float = 0.40
    kp: float = 2.0
    kd: float = 0.4
    switch: float = 0.5
    pd: bool = False

    def __call__(self, t, angle, rate):
        if t < self.t_on - 1e-12:
            return 0.0
        if not self.pd and (angle >= self.switch * self.target or t >= self.t_pd_latest - 1e-12):
            self.pd = True
        if not self.pd:
            return self.u_step
        u = self.u_hold + self.kp * (self.target - angle) - self.kd * rate
        return float(min(1.0, max(0.0, u)))


def build_model(dt=1e-3):
    import mujoco

    model = mujoco.MjModel.from_xml_string(ARM_XML)
    model.opt.timestep = dt
    return model


def check_sign():
    """Elbow acceleration (no gravity, at rest, 45 deg) under 100 N of muscle
    tension applied as ctrl = -100: positive means flexion (tendon shortens)."""
    import mujoco

    model = build_model()
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    data.qpos[0] = np.radians(45.0)
    data.ctrl[0] = -100.0
    mujoco.mj_forward(model, data)
    return float(data.qacc[0]), _dLdq(model, data)


def _dLdq(model, data):
    """d ten_length / d elbow angle (the tendon Jacobian, dense or sparse)."""
    J = np.asarray(data.ten_J).ravel()
    return float(J[0]) if J.size >= model.nv else float("nan")


def working_range(angles_deg=(0.0, 60.0, 90.0, 120.0)):
    """(angle deg, tendon length, moment arm, L/L0, fibre stretch / lambda_opt
    in the incompressible approximation lambda_f = L/L0)."""
    import mujoco

    model = build_model()
    data = mujoco.MjData(model)
    rows = []
    for deg in angles_deg:
        data.qpos[0] = np.radians(deg)
        mujoco.mj_forward(model, data)
        L = float(data.ten_length[0])
        lam = L / MUSCLE_PARAMS["L0"]
        rows.append((deg, L, -_dLdq(model, data), lam, lam / LAMBDA_OPT))
    return rows


@dataclass
class Result:
    scheme: str
    H: float
    dt: float
    t: np.ndarray
    angle: np.ndarray
    length: np.ndarray
    command: np.ndarray
    activation: np.ndarray
    force: np.ndarray
    fibre_stretch: np.ndarray
    kinetic: np.ndarray
    wall: float
    iterations: float = 1.0
    stable: bool = True
    reason: str = ""
    extra: dict = field(default_factory=dict)


def fmu_capabilities(fmu):
    """The FMU's Co-Simulation capability flags that the schemes rely on."""
    from elongation import load_fmu

    cs = load_fmu(fmu).model_description.coSimulation
    return {"input_derivatives": bool(cs.canInterpolateInputs),
            "directional_derivatives": bool(cs.providesDirectionalDerivative),
            "state": bool(cs.canGetAndSetFMUstate)}


SCHEME_NEEDS = {"explicit": (), "derivative": (), "implicit": ("directional_derivatives",), "iterated": ("state",)}
"""What each scheme needs of the FMU. ``derivative`` and ``implicit`` use
input derivatives when the FMU can interpolate inputs and otherwise set the
extrapolated length (``simulate``)."""


def unsupported(fmu, scheme):
    """Why ``scheme`` cannot run with this FMU ("" when it can)."""
    caps = fmu_capabilities(fmu)
    flags = {"directional_derivatives": "providesDirectionalDerivative", "state": "canGetAndSetFMUstate"}
    missing = [flags[c] for c in SCHEME_NEEDS[scheme] if not caps[c]]
    return f"the {scheme} scheme needs {', '.join(missing)} = true in the FMU's modelDescription" if missing else ""


def _set_integer_parameters(muscle, values):
    """Set Integer parameters (the FE mesh resolution) by name."""
    variables = muscle.loaded.variables
    for name, value in (values or {}).items():
        v = variables.get(name)
        if v is None or v.type != "Integer" or v.causality != "parameter":
            ints = sorted(n for n, x in variables.items() if x.type == "Integer" and x.causality == "parameter")
            raise ValueError(f"{name} is not an Integer parameter of {muscle.loaded.path.name} (those: {ints})")
        muscle.slave.setInteger([v.valueReference], [int(value)])


def _kinetic(model, data):
    import mujoco

    mujoco.mj_energyVel(model, data)
    return float(data.energy[1])


def simulate(scheme="implicit", H=1e-3, t_end=1.0, dt=1e-3, fmu=DEFAULT_FMU, angle0=0.0,
             controller=None, tol=1e-9, max_iter=20, record_stiffness=False, params=None, slack=0.0, qvel0=0.0,
             mesh=None, input_derivatives=None, trace=None):
    """One coupled run; returns a ``Result`` sampled at the communication points.

    ``params`` overrides the FMU parameters (default ``MUSCLE_PARAMS``);
    ``slack`` is the length of a rigid series tendon: muscle length =
    tendon path length - slack (default 0, the path is all muscle);
    ``mesh``: Integer parameters by name (the FE FMU's mesh resolution).
    ``input_derivatives`` (default: when the FMU can interpolate inputs):
    whether the derivative and implicit schemes pass dL/dt through
    ``setRealInputDerivatives``; without, the master sets the extrapolated
    length L(t) + H dL/dt as the input, the same end length (the FMU moves
    linearly to its length input over a step either way).
    ``extra["stiffness"]`` holds the K of the implicit scheme (or, with
    ``record_stiffness``, of any scheme).
    ``extra`` holds the time spent in ``doStep`` (``fmu_wall``) and the
    number of ``doStep`` calls (``fmu_steps``).
    ``trace`` (a list, implicit scheme with input derivatives): each
    communication step's (t, L, dL/dt, u, force, d force / d length) is
    appended to it (``write_trace``)."""
    import mujoco

    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}")
    why = unsupported(fmu, scheme)
    if why:
        raise ValueError(f"{Path(fmu).name}: {why}")
    derivs = fmu_capabilities(fmu)["input_derivatives"] if input_derivatives is None else bool(input_derivatives)
    n_sub = int(round(H / dt))
    if n_sub < 1 or abs(n_sub * dt - H) > 1e-9 * H:
        raise ValueError(f"H = {H} must be a multiple of dt = {dt}")
    n_comm = int(round(t_end / H))
    ctrl_law = controller or Controller()
    model = build_model(dt)
    data = mujoco.MjData(model)
    backup = mujoco.MjData(model)
    data.qpos[0] = angle0
    data.qvel[0] = qvel0
    mujoco.mj_forward(model, data)
    mujoco.mj_step1(model, data)

    rec = {k: np.full(n_comm + 1, np.nan) for k in
           ("t", "angle", "length", "command", "activation", "force", "fibre_stretch", "kinetic",
            "stiffness")}
    all_params = {**MUSCLE_PARAMS, **(params or {})}
    from elongation import load_fmu

    missing = sorted(set(all_params) - set(load_fmu(fmu).variables))
    if missing:
        raise ValueError(f"{Path(fmu).name} has no parameter(s) {missing}: cannot size the muscle for the arm")
    muscle = Muscle(fmu, all_params, name=f"arm_{scheme}")
    try:
        _set_integer_parameters(muscle, mesh)
    except Exception:
        muscle.free()
        raise
    f_max = SIGMA0 * {**MUSCLE_PARAMS, **(params or {})}["area"]
    vr = muscle.vr
    vr_force, vr_len, vr_act = vr["force"], vr["length"], vr["activation"]
    out_vrs = [vr["force"], vr["activation_level"], vr["fibre_stretch"]]
    stable, reason, iters_total, unconverged = True, "", 0, 0
    fmu_wall, fmu_steps = 0.0, 0
    clock = _time.perf_counter
    wall0 = clock()
    try:
        L = float(data.ten_length[0]) - slack
        muscle.initialize(length=L, activation=0.0)
        F_prev, a, lf = muscle.slave.getReal(out_vrs)

        def record(i):
            rec["t"][i] = i * H
            rec["angle"][i] = data.qpos[0]
            rec["length"][i] = data.ten_length[0] - slack
            rec["activation"][i] = a
            rec["force"][i] = F_prev
            rec["fibre_stretch"][i] = lf
            rec["kinetic"][i] = _kinetic(model, data)

        record(0)
        slave = muscle.slave
        for i in range(n_comm):
            t = i * H
            L = float(data.ten_length[0]) - slack
            dL = float(data.ten_velocity[0])
            u = ctrl_law(t, float(data.qpos[0]), float(data.qvel[0]))
            rec["command"][i] = u
            if scheme == "explicit":
                slave.setReal([vr_len, vr_act], [L, u])
                c0 = clock()
                slave.doStep(t, H)
                fmu_wall += clock() - c0
                fmu_steps += 1
                F = slave.getReal([vr_force])[0]
                for _ in range(n_sub):
                    data.ctrl[0] = -F
                    mujoco.mj_step2(model, data)
                    mujoco.mj_step1(model, data)
            elif scheme in ("derivative", "implicit"):
                if derivs:
                    slave.setReal([vr_len, vr_act], [L, u])
                    slave.setRealInputDerivatives([vr_len], [1], [dL])
                else:  # the same end length, extrapolated by the master
                    slave.setReal([vr_len, vr_act], [L + H * dL, u])
                c0 = clock()
                slave.doStep(t, H)
                fmu_wall += clock() - c0
                fmu_steps += 1
                F = slave.getReal([vr_force])[0]
                if scheme == "derivative":
                    for j in range(n_sub):
                        data.ctrl[0] = -(F_prev + (F - F_prev) * (j + 0.5) / n_sub)
                        mujoco.mj_step2(model, data)
                        mujoco.mj_step1(model, data)
                else:
                    K = slave.getDirectionalDerivative([vr_force], [vr_len], [1.0])[0]
                    rec["stiffness"][i + 1] = K
                    if trace is not None:
                        trace.append((t, L, dL, u, F, K))
                    for j in range(n_sub):
                        # deviation of the length at the end of this MuJoCo step (predicted
                        # with the current velocity) from the FMU's straight path L + tau dL
                        dev = data.ten_length[0] - slack + dt * data.ten_velocity[0] - (L + (j + 1) * dt * dL)
                        data.ctrl[0] = -(F_prev + (F - F_prev) * (j + 0.5) / n_sub + K * dev)
                        mujoco.mj_step2(model, data)
                        mujoco.mj_step1(model, data)
            else:  # iterated
                state = slave.getFMUstate()
                mujoco.mj_copyData(backup, model, data)
                L_star = L + H * dL
                for k in range(max_iter):
                    if k:
                        slave.setFMUstate(state)
                        mujoco.mj_copyData(data, model, backup)
                    slave.setReal([vr_len, vr_act], [L_star, u])
                    c0 = clock()
                    slave.doStep(t, H)
                    fmu_wall += clock() - c0
                    fmu_steps += 1
                    F = slave.getReal([vr_force])[0]
                    for j in range(n_sub):
                        data.ctrl[0] = -(F_prev + (F - F_prev) * (j + 0.5) / n_sub)
                        mujoco.mj_step2(model, data)
                        mujoco.mj_step1(model, data)
                    L_end = float(data.ten_length[0]) - slack
                    iters_total += 1
                    if abs(L_end - L_star) < tol:
                        break
                    L_star = L_end
                else:
                    unconverged += 1
                slave.freeFMUstate(state)
            F_prev, a, lf = slave.getReal(out_vrs)
            if record_stiffness and scheme != "implicit":
                rec["stiffness"][i + 1] = slave.getDirectionalDerivative([vr_force], [vr_len], [1.0])[0]
            record(i + 1)
            rec["command"][i + 1] = u
            bad = _flag(rec, i + 1, H, f_max)
            if bad:
                stable, reason = False, bad
                break
    except Exception as exc:  # an FMU rejection (fmpy raises on discard/error) or MuJoCo trouble
        stable, reason = False, f"{type(exc).__name__}: {exc}"
        errors = [msg for status, _, msg in muscle.log if status >= 2]
        if errors:
            reason += f" (FMU: {errors[-1]})"
    finally:
        wall = clock() - wall0
        muscle.free()
    if stable:
        bad = _energy_growth(rec)
        if bad:
            stable, reason = False, bad
    n_done = int(np.sum(np.isfinite(rec["t"])))
    return Result(scheme, H, dt, *(rec[k] for k in ("t", "angle", "length", "command", "activation", "force",
                                                    "fibre_stretch", "kinetic")),
                  wall=wall, iterations=iters_total / max(1, n_done - 1) if scheme == "iterated" else 1.0,
                  stable=stable, reason=reason, extra={"stiffness": rec["stiffness"], "unconverged_steps": unconverged,
                                                       "fmu_wall": fmu_wall, "fmu_steps": fmu_steps})


TRACE_COLUMNS = ("t", "length", "der_length", "activation", "force", "dforce_dlength")
"""The columns of a call trace (module docstring, ``--trace``)."""


def write_trace(path, rows, params, mesh, length0, H):
    """Write the call trace ``rows`` of ``simulate(..., trace=rows)`` as CSV
    (module docstring, ``--trace``): header comments with the FMU's Real
    and Integer parameters, the initial inputs and H, then one row per
    communication step at full precision."""
    lines = ["# HillMuscleFE calls of examples/arm_mujoco.py, implicit scheme (module docstring, --trace)",
             "# per row: fmi2SetReal(length, activation), fmi2SetRealInputDerivatives(length, 1, der_length),",
             "# fmi2DoStep(t, H), fmi2GetReal(force), fmi2GetDirectionalDerivative(force; length; 1),",
             "# fmi2GetReal(force, activation_level, fibre_stretch)",
             f"# H = {H!r}",
             f"# initial length = {float(length0)!r}",
             "# initial activation = 0.0"]
    lines += [f"# parameter {k} = {float(v)!r}" for k, v in params.items()]
    lines += [f"# integer {k} = {int(v)}" for k, v in (mesh or {}).items()]
    lines.append(",".join(TRACE_COLUMNS))
    lines += [",".join(repr(float(x)) for x in row) for row in rows]
    Path(path).write_text("\n".join(lines) + "\n")


def _flag(rec, i, H, f_max):
    """Per-step divergence check (see the module docstring)."""
    vals = [rec[k][i] for k in ("angle", "length", "force", "kinetic")]
    if not all(np.isfinite(vals)):
        return f"non-finite value at t = {i * H:.4g} s"
    growing = _growing_peaks(rec["kinetic"][: i + 1])
    if growing:
        return f"kinetic energy grows from one oscillation to the next ({growing}) by t = {i * H:.4g} s"
    if abs(rec["force"][i]) > 5 * f_max:
        return f"|force| = {abs(rec['force'][i]):.4g} N > 5 F_max at t = {i * H:.4g} s"
    if not -0.5 <= rec["angle"][i] <= 3.2:
        return f"angle {rec['angle'][i]:.4g} rad out of range at t = {i * H:.4g} s"
    return ""


def _growing_peaks(ke, factor=1.5, overall=4.0, floor=1e-3):
    """The last three peaks of the kinetic energy (interior local maxima, and
    the last sample when it exceeds the one before), as text, when each
    exceeds the one before by ``factor``, the last is ``overall`` times the
    first and above ``floor`` J; else "". """
    ke = np.asarray(ke, dtype=float)
    if ke.size < 3:
        return ""
    inner = np.flatnonzero((ke[1:-1] > ke[:-2]) & (ke[1:-1] >= ke[2:])) + 1
    peaks = list(ke[inner])
    if ke[-1] > ke[-2]:
        peaks.append(ke[-1])
    if len(peaks) < 3:
        return ""
    a, b, c = peaks[-3:]
    if b > factor * a and c > factor * b and c > overall * a and c > floor:
        return f"peaks {a:.3g}, {b:.3g}, {c:.3g} J"
    return ""


def _energy_growth(rec):
    """Oscillation energy growth in the hold phase (the last half of the run)."""
    t, ke = rec["t"], rec["kinetic"]
    T = np.nanmax(t)
    first = ke[(t >= 0.5 * T) & (t < 0.625 * T)]
    last = ke[t >= 0.875 * T]
    if first.size and last.size and np.max(last) > 4 * max(np.max(first), 1e-6):
        return f"kinetic energy grows in the hold phase ({np.max(first):.3g} J -> {np.max(last):.3g} J)"
    return ""


def stability(result):
    """(stable, reason) of a run."""
    return result.stable, result.reason


def error_vs(result, reference):
    """Max |angle - angle_ref| [rad] at the result's communication points
    (reference interpolated) over the whole run; inf if unstable."""
    if not result.stable:
        return float("inf")
    ok = np.isfinite(result.t)
    ref = np.interp(result.t[ok], reference.t, reference.angle)
    return float(np.max(np.abs(result.angle[ok] - ref)))


def force_error_vs(result, reference):
    if not result.stable:
        return float("inf")
    ok = np.isfinite(result.t)
    ref = np.interp(result.t[ok], reference.t, reference.force)
    return float(np.max(np.abs(result.force[ok] - ref)))


# --------------------------------------------------------------------------
# Experiments
# --------------------------------------------------------------------------

L_AT_90 = 0.26542
"""Tendon path length at 90 deg [m] (``working_range``)."""
STIFF_L0 = 0.05
STIFF_SLACK = L_AT_90 - 0.95 * STIFF_L0
"""The stiff variant: the paper's 5 cm muscle in series with a rigid tendon of
this length, so that the fibre stretch is 0.95 at 90 deg (valid for a hold
near 90 deg only: at 0 deg L/L0 would be 2.05, outside the support)."""
U_HOLD = 0.4
L_AT_0 = 0.32036
"""Tendon path length at 0 deg (arm hanging) [m] (``working_range``)."""
PASSIVE_STRETCH = 1.25
PASSIVE_SLACK = L_AT_0 - PASSIVE_STRETCH * STIFF_L0
"""The passive variant: the 5 cm fibre + rigid tendon of this length, so that
the relaxed muscle is stretched by 25 % when the arm hangs straight."""

EXPERIMENTS = ("flex_hold", "hold", "hold_stiff", "passive_stiff")
"""``flex_hold``: from the hanging arm, the step-then-PD controller (1 s).
``hold``: open loop, constant command 0.4 (initial_activation 0.4, isometric
start), elbow at 90 deg with an initial 1 rad/s flexion kick; every step size
sees the same command, so differences are the coupling's.
``hold_stiff``: ``hold`` with the stiff variant (L0 = 0.05 m + rigid tendon):
a 5.8x shorter fibre, ~5x the stiffness d force/d length.
``passive_stiff``: the relaxed muscle (command 0, activation 0) as a
spring: the 5 cm fibre + rigid tendon stretched 25 % at 0 deg
(``PASSIVE_SLACK``); released from the hanging arm at rest, its passive
tension (matrix + PE, up to ~320 N) swings the forearm up to ~31 deg and
back against gravity. With no active fibre force the CE's force-velocity
damping is absent (SEE and CE carry nothing): the muscle is purely elastic,
the only damping the hinge's."""


def experiment_kwargs(experiment):
    """Keyword arguments of ``simulate`` for a named experiment (the
    controller is a fresh object per call: it has state)."""
    if experiment == "flex_hold":
        return {"controller": Controller()}
    hold = {"controller": Replay(np.array([0.0]), np.array([U_HOLD])), "angle0": np.radians(90.0), "qvel0": 1.0}
    if experiment == "hold":
        return {**hold, "params": {"initial_activation": U_HOLD}}
    if experiment == "hold_stiff":
        return {**hold, "params": {"initial_activation": U_HOLD, "L0": STIFF_L0}, "slack": STIFF_SLACK}
    if experiment == "passive_stiff":
        return {"controller": Replay(np.array([0.0]), np.array([0.0])), "angle0": 0.0, "qvel0": 0.0,
                "params": {"initial_activation": 0.0, "L0": STIFF_L0}, "slack": PASSIVE_SLACK}
    raise ValueError(f"experiment must be one of {EXPERIMENTS}")


def run(experiment, scheme, H, overrides=None, **kw):
    """``simulate`` on a named experiment; ``overrides`` are FMU parameters
    set on top of the experiment's (e.g. ``{"alpha": 100.0}``)."""
    args = {**experiment_kwargs(experiment), **kw}
    if overrides:
        args["params"] = {**args.get("params", {}), **overrides}
    return simulate(scheme, H, **args)


def largest_stable_step(experiment, scheme, steps, **kw):
    """The largest H in ``steps`` (ascending) below which every step tried ran
    stably, and the list of (H, stable, reason)."""
    table, best = [], None
    for H in steps:
        r = run(experiment, scheme, H, **kw)
        table.append((H, r.stable, r.reason))
        if r.stable and all(st for _, st, _ in table):
            best = H
    return best, table


# --------------------------------------------------------------------------
# Plots, sweep, command line
# --------------------------------------------------------------------------

def plot_runs(results, path, title=""):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(7, 9), sharex=True)
    for r in results:
        lab = f"{r.scheme}, H = {1e3 * r.H:g} ms" + ("" if r.stable else " (unstable)")
        ax[0].plot(r.t, np.degrees(r.angle), label=lab)
        ax[1].plot(r.t, 1e3 * r.length, label=lab)
        ax[2].plot(r.t, r.activation, label=lab)
        ax[2].plot(r.t, r.command, ":", color=ax[2].lines[-1].get_color())
        ax[3].plot(r.t, r.force, label=lab)
    stable = [r for r in results if r.stable]
    if stable and len(stable) < len(results):  # keep the axes on the stable runs; diverged ones leave the plot
        for k, get in enumerate((lambda r: np.degrees(r.angle), lambda r: 1e3 * r.length, None, lambda r: r.force)):
            if get is None:
                continue
            lo = min(np.nanmin(get(r)) for r in stable)
            hi = max(np.nanmax(get(r)) for r in stable)
            pad = 0.5 * (hi - lo) + 1e-9
            ax[k].set_ylim(lo - pad, hi + pad)
    ax[0].set_ylabel("elbow angle [deg]")
    ax[1].set_ylabel("muscle length [mm]")
    ax[2].set_ylabel("activation (dotted: command)")
    ax[3].set_ylabel("force [N]")
    ax[3].set_xlabel("time [s]")
    ax[0].legend(fontsize=7)
    if title:
        ax[0].set_title(title)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


SWEEP_STEPS_MS = (1, 2, 4, 8, 16, 32, 48, 64, 80, 96, 112, 128, 160, 192, 256)


def sweep(experiment, steps_ms=SWEEP_STEPS_MS, t_end=2.0, out=None, overrides=None):
    """Every scheme at every step: stable?, max angle and force error vs the
    iterated scheme at H = 1 ms, wall time. Prints a markdown table.
    ``overrides``: FMU parameters on top of the experiment's."""
    reference = run(experiment, "iterated", 1e-3, t_end=t_end, overrides=overrides)
    rows = []
    print(f"\n### {experiment}{f' {overrides}' if overrides else ''} (t_end = {t_end:g} s, "
          f"reference: iterated at H = 1 ms)\n")
    print("| scheme | H [ms] | stable | max angle error [deg] | max force error [N] | wall [ms] | iterations/step "
          "| unconverged steps |")
    print("|---|---|---|---|---|---|---|---|")
    for scheme in SCHEMES:
        for h in steps_ms:
            r = run(experiment, scheme, h * 1e-3, t_end=t_end, overrides=overrides)
            row = (scheme, h, r.stable, error_vs(r, reference), force_error_vs(r, reference), r.wall,
                   r.iterations, r.reason)
            row = row + (r.extra["unconverged_steps"],)
            rows.append(row)
            status = "yes" if r.stable else f"**no**: {r.reason}"
            print(f"| {scheme} | {h:g} | {status} | {np.degrees(row[3]):.3g} | {row[4]:.3g} | {1e3 * r.wall:.1f} "
                  f"| {r.iterations:.2f} | {r.extra['unconverged_steps'] if scheme == 'iterated' else ''} |", flush=True)
    print()
    for scheme in SCHEMES:
        rs = [r for r in rows if r[0] == scheme]
        best = None
        for r in rs:
            if not r[2] or r[8]:  # unstable, or (iterated) a step whose iteration did not converge
                break
            best = r[1]
        print(f"largest stable step ({experiment}, {scheme}): {best if best is None else format(best, 'g')} ms"
              + (" (stable and every step's iteration converged)" if scheme == "iterated" else ""))
    if out is not None:
        _plot_work_precision(rows, out, f"{experiment}, {t_end:g} s simulated")
    return reference, rows


def _plot_work_precision(rows, path, title=""):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for scheme in SCHEMES:
        rs = [r for r in rows if r[0] == scheme and r[2] and r[3] > 0]
        if not rs:
            continue
        ax[0].loglog([r[1] for r in rs], [np.degrees(r[3]) for r in rs], "o-", label=scheme)
        ax[1].loglog([1e3 * r[5] for r in rs], [np.degrees(r[3]) for r in rs], "o-", label=scheme)
    ax[0].set_xlabel("communication step H [ms]")
    ax[1].set_xlabel("wall time [ms]")
    if title:
        fig.suptitle(title)
    for a in ax:
        a.set_ylabel("max |angle - reference| [deg]")
        a.grid(alpha=0.3, which="both")
        a.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _real_arg(text):
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: {value!r} is not a number") from None


def _mesh_arg(text):
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: {value!r} is not an integer") from None


def resolve_model(model, fmu=None, out=sys.stderr):
    """(model, fmu path) to run. ``--model fe`` without ``--fmu`` uses
    ``FE_FMU``; when that file is absent it says so on ``out`` and falls back
    to HillMuscle1D. An explicit ``--fmu`` that does not exist is an error."""
    if fmu is not None:
        if not Path(fmu).is_file():
            raise FileNotFoundError(f"{fmu} not found (build the FMUs with scripts/build_fmus.sh)")
        return model, Path(fmu)
    if model == "fe" and not FE_FMU.is_file():
        print(f"--model fe: {FE_FMU} not found (the FE muscle FMU; build it with "
              f"scripts/build_fmus.sh). Falling back to HillMuscle1D ({DEFAULT_FMU}) "
              f"at the same communication step.", file=out)
        return "1d", DEFAULT_FMU
    return model, (FE_FMU if model == "fe" else DEFAULT_FMU)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scheme", choices=SCHEMES + ("all",), default=None,
                   help="default: all (1d), implicit (fe)")
    p.add_argument("--step", type=float, default=None,
                   help=f"communication step H [s] (default: 1e-3 for 1d, FE_STEP = {FE_STEP:g} for fe)")
    p.add_argument("--t-end", type=float, default=None, help="simulated time [s] (default 1.0; --pair: 2.4)")
    p.add_argument("--model", choices=MODELS, default="1d")
    p.add_argument("--fmu", default=None, help="FMU path (default: dist/HillMuscle1D.fmu or dist/HillMuscleFE.fmu)")
    p.add_argument("--mesh", type=_mesh_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="Integer parameter of the FMU (FE mesh resolution), repeatable")
    p.add_argument("--experiment", choices=EXPERIMENTS, default="flex_hold")
    p.add_argument("--param", type=_real_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="Real FMU parameter on top of the experiment's (e.g. alpha=100), repeatable")
    p.add_argument("--steps-ms", default=None, help="--sweep: comma-separated communication steps [ms]")
    p.add_argument("--sweep", action="store_true", help="stability limits and error vs wall time")
    p.add_argument("--out", default=str(REPO / "docs" / "figures"))
    p.add_argument("--trace", default=None, metavar="FILE",
                   help="implicit scheme: write the FMU's call trace as CSV (module docstring)")
    p.add_argument("--pair", action="store_true",
                   help="the antagonist musculotendon pair (arm_pair.py); --fmu: the musculotendon FMU")
    args = p.parse_args(argv)
    if args.pair:
        import arm_pair

        steps_ms = tuple(float(x) for x in args.steps_ms.split(",")) if args.steps_ms else SWEEP_STEPS_MS
        return arm_pair.main(scheme=args.scheme or "all", step=args.step or 1e-3, fmus=args.fmu,
                             out=args.out, sweep_steps_ms=steps_ms if args.sweep else None,
                             t_end=args.t_end or arm_pair.T_END)
    if args.t_end is None:
        args.t_end = 1.0
    requested = args.model
    step = args.step if args.step is not None else (FE_STEP if requested == "fe" else 1e-3)
    scheme = args.scheme or ("implicit" if requested == "fe" else "all")
    try:
        model, fmu = resolve_model(requested, args.fmu)
    except FileNotFoundError as exc:
        p.error(str(exc))
    mesh = dict(args.mesh)
    if mesh and model != "fe":
        print(f"--mesh {mesh} ignored: the 1D model has no mesh", file=sys.stderr)
        mesh = {}
    from elongation import load_fmu

    name = load_fmu(fmu).model_description.modelName
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    qacc, J = check_sign()
    print(f"sign check: 100 N tension (ctrl = -100) -> elbow acceleration {qacc:+.3f} rad/s^2 (dL/dq = {J:.4f} m)")
    for deg, L, r, lam, rel in working_range():
        print(f"  {deg:5.0f} deg: L = {L:.4f} m, moment arm {1e3 * r:.1f} mm, L/L0 = {lam:.3f}, "
              f"lambda_f/lambda_opt ~ {rel:.3f}")
    print(f"muscle: {name} ({fmu}), communication step H = {1e3 * step:g} ms = {step / 1e-3:g} MuJoCo steps of 1 ms"
          + (f", mesh {mesh}" if mesh else ""))
    if args.sweep:
        if model != "1d":
            p.error("--sweep runs the 1D model only")
        steps_ms = tuple(float(x) for x in args.steps_ms.split(",")) if args.steps_ms else SWEEP_STEPS_MS
        tag = "".join(f"_{k}{v:g}" for k, v in args.param)
        sweep(args.experiment, steps_ms=steps_ms, t_end=args.t_end, overrides=dict(args.param) or None,
              out=out / f"arm_{args.experiment}{tag}_work_precision.png")
        return 0
    schemes = SCHEMES if scheme == "all" else (scheme,)
    if args.trace and schemes != ("implicit",):
        p.error("--trace records the implicit scheme: use it with --scheme implicit")
    trace = [] if args.trace else None
    results = []
    for s in schemes:
        why = unsupported(fmu, s)
        if why:
            print(f"{s:10s} skipped: {why}")
            continue
        try:
            r = run(args.experiment, s, step, t_end=args.t_end, fmu=fmu, mesh=mesh,
                    overrides=dict(args.param) or None, trace=trace)
        except ValueError as exc:
            p.error(str(exc))
        results.append(r)
        finite = np.flatnonzero(np.isfinite(r.angle))
        if finite.size == 0:  # stopped before its first sample (e.g. refused at initialization)
            print(f"{s:10s} H = {step:g} s: stable={r.stable} {r.reason} (no sample recorded)")
            continue
        last = int(finite[-1])
        fmu_ms = 1e3 * r.extra["fmu_wall"] / max(1, r.extra["fmu_steps"])
        print(f"{s:10s} H = {step:g} s: stable={r.stable} {r.reason} angle at t = {r.t[last]:.3g} s: "
              f"{np.degrees(r.angle[last]):.3f} deg, force {r.force[last]:.2f} N, fibre stretch "
              f"[{np.nanmin(r.fibre_stretch):.3f}, {np.nanmax(r.fibre_stretch):.3f}] wall {1e3 * r.wall:.1f} ms "
              f"({r.extra['fmu_steps']} FMU steps, {fmu_ms:.3f} ms each)")
    if not results:
        print("no scheme could run with this FMU", file=sys.stderr)
        return 1
    if trace is not None:
        params = {**MUSCLE_PARAMS, **experiment_kwargs(args.experiment).get("params", {}), **dict(args.param)}
        length0 = results[0].length[0]
        write_trace(args.trace, trace, params, mesh, length0, step)
        print(f"wrote {args.trace} ({len(trace)} steps)")
    tag = "" if model == "1d" else "_fe"
    fname = f"arm{tag}_{args.experiment}_{scheme}_H{1e3 * step:g}ms.png"
    plot_runs(results, out / fname, f"{name} on a MuJoCo elbow ({args.experiment}), H = {1e3 * step:g} ms")
    print(f"wrote {out / fname}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
