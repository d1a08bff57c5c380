#!/usr/bin/env python3
"""An antagonist musculotendon pair on the MuJoCo elbow of ``arm_mujoco.py``.

``python examples/arm_mujoco.py --pair`` runs it (the command line is in
``arm_mujoco.main``); this module holds the model, the co-contraction
pattern, the coupled loop for two FMU instances and the comparisons.

The model (MJCF ``pair_xml()``; written by this project)
---------------------------------------------------------
The elbow, forearm, hand load and hinge of ``arm_mujoco.ARM_XML`` (1.5 kg
forearm + 1.0 kg at 0.30 m, damping 0.05 N m s, range [-0.1, 2.6] rad,
positive = flexion), with two spatial tendons wrapping on the same 2 cm
cylinder at the elbow, on opposite sides:

``flexor`` (biceps brachii long head): origin 0.375 m above the elbow on the
arm's axis (the supraglenoid tubercle, the path over the humeral head lumped
into a via site in the bicipital groove at (0.035, 0, 0.29)), insertion on the
forearm 0.035 m below the elbow, 0.012 m in front (radial tuberosity).
``extensor`` (triceps brachii long head): origin (-0.025, 0, 0.26)
(infraglenoid tubercle, behind the humerus), insertion on the olecranon,
forearm frame (-0.02, 0, 0.005), wrapping over the back of the elbow. Path
lengths and moment arms (MuJoCo, ``path_table()``):

    angle   flexor L, arm       extensor L, arm
      0     0.4183 m, 20 mm     0.2550 m, 20 mm
     60     0.3890 m, 36 mm     0.2762 m, 20 mm
    120     0.3542 m, 23 mm     0.2971 m, 20 mm

Both paths stay above their tendon slack lengths (0.2723 m, 0.143 m); with the
tendons at slack, the flexor's fibre length / optimal is 1.26 at 0 deg, 1.01 at
60 deg, 0.71 at 120 deg; the extensor's (through its pennation) 0.86, 1.01,
1.17: the fibres sit near their optimal length mid-range.

Muscles (Holzbaur, Murray & Delp 2005, as in OpenSim's arm26 model); each an
instance of the musculotendon FMU (``HillMusculotendon1D`` by default; any FMU
with the same variables, e.g. the FE unit, through ``fmus=``), sized as its
scene does (fmu_build/scenes/musculotendon_1d.toml): L0 = l_opt / lambda_opt
(1.05), area = F0 / sigma0 (7e5 Pa):

    biceps long head: F0 624.3 N, l_opt 0.1157 m, L_TS 0.2723 m, pennation 0
      -> L0 0.1102 m, area 8.919e-4 m^2 (the FMU's defaults)
    triceps long head: F0 798.52 N, l_opt 0.134 m, L_TS 0.143 m, pennation
      0.209 rad -> L0 0.12762 m, area 1.14074e-3 m^2

tendon_strain_at_F0 0.04 (Thelen 2003) for both. Each FMU gets its path length
(and rate, as the single-muscle schemes do) and returns the tendon force F,
applied along its tendon as ctrl = -F on a unit-gain ``general`` actuator
(``arm_mujoco.check_sign``'s convention).

The co-contraction pattern (``CoContraction``)
----------------------------------------------
Commands u_flexor = c + d/2, u_extensor = c - d/2 (clipped to [0, 1]), with a
constant co-contraction level c = 0.3 and a difference d(t), piecewise linear
through (0, 0), (0.3, 0), (0.6, 0.3), (1.3, 0.3), (1.6, -0.05), (2.4, -0.05)
[s, 1]: hold, flexion ramp, hold, extension ramp, hold. The run starts at
45 deg at rest with both activations at c (``initial_activation``) and lasts
2.4 s. At the end of the holds the compliant units are at 37, 82 and 29 deg
(the other models: ``compare``). At rest at 45 deg with d = 0 the flexor
dominates (net torque +2.3 N m; it vanishes near d = -0.07), so gravity's
torque is balanced near d = 0.

Comparisons
-----------
``builtin``: MuJoCo's muscle model on the same tendons (``gaintype`` and
``biastype`` ``muscle``, what ``<muscle>`` expands to) with F0 and the length
mapping of each muscle: ``lengthrange`` the path's range over the joint range
and ``range`` = (lengthrange - L_TS) / l_opt, i.e. a rigid tendon of the slack
length and no pennation, vmax 10 l_opt/s (arm26's), the rest MuJoCo's
defaults; the activation is a first-order filter with tau = 1/S = 20 ms
(``filterexact``), the FMU's activation dynamics, instead of ``<muscle>``'s
activation-dependent time constants. ``rigid``: the FMUs with
``compliant_tendon = false``.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import arm_mujoco as am
from elongation import load_fmu, logger_callbacks, release_logger

REPO = Path(__file__).resolve().parent.parent
MT_FMU = REPO / "dist" / "HillMusculotendon1D.fmu"
SIGMA0 = 7.0e5
LAMBDA_OPT = 1.05


@dataclass(frozen=True)
class MuscleSpec:
    """One muscle of the pair (Holzbaur et al. 2005 / arm26 values) and its
    FMU parameters (module docstring: L0 = l_opt / lambda_opt, area = F0 / sigma0)."""

    name: str
    f0: float
    l_opt: float
    slack: float
    pennation: float
    eps0: float = 0.04

    @property
    def params(self):
        return {"L0": self.l_opt / LAMBDA_OPT, "area": self.f0 / SIGMA0, "tendon_slack_length": self.slack,
                "tendon_strain_at_F0": self.eps0, "pennation_angle": self.pennation}


FLEXOR = MuscleSpec("flexor", f0=624.3, l_opt=0.1157, slack=0.2723, pennation=0.0)
EXTENSOR = MuscleSpec("extensor", f0=798.52, l_opt=0.134, slack=0.143, pennation=0.209)
MUSCLES = (FLEXOR, EXTENSOR)

_GEOMETRY = """
    <geom name="upper_arm" type="capsule" fromto="0 0 0.30 0 0 0" size="0.03" contype="0" conaffinity="0"/>
    <site name="biceps_origin" pos="0 0 0.375" size="0.005"/>
    <site name="bicipital_groove" pos="0.035 0 0.29" size="0.004"/>
    <site name="triceps_origin" pos="-0.025 0 0.26" size="0.005"/>
    <geom name="elbow_wrap" type="cylinder" pos="0 0 0" zaxis="0 1 0" size="0.02 0.03" contype="0" conaffinity="0"/>
    <site name="elbow_front" pos="0.06 0 0" size="0.003"/>
    <site name="elbow_back" pos="-0.06 0 0" size="0.003"/>
    <body name="forearm" pos="0 0 0">
      <joint name="elbow" type="hinge" axis="0 -1 0" range="-0.1 2.6" limited="true" damping="0.05"/>
      <geom name="forearm" type="capsule" fromto="0 0 0 0 0 -0.28" size="0.025" mass="1.5" contype="0" conaffinity="0"/>
      <site name="biceps_insertion" pos="0.012 0 -0.035" size="0.005"/>
      <site name="triceps_insertion" pos="-0.02 0 0.005" size="0.005"/>
      <geom name="hand_load" type="sphere" pos="0 0 -0.30" size="0.04" mass="1.0" contype="0" conaffinity="0"/>
    </body>
"""

_TENDONS = """
    <spatial name="flexor" width="0.004">
      <site site="biceps_origin"/>
      <site site="bicipital_groove"/>
      <geom geom="elbow_wrap" sidesite="elbow_front"/>
      <site site="biceps_insertion"/>
    </spatial>
    <spatial name="extensor" width="0.004">
      <site site="triceps_origin"/>
      <geom geom="elbow_wrap" sidesite="elbow_back"/>
      <site site="triceps_insertion"/>
    </spatial>
"""

JOINT_RANGE = (-0.1, 2.6)
BUILTIN_VMAX = 10.0
"""Maximum shortening velocity of the built-in muscles [l_opt/s] (arm26's Thelen muscles)."""
ACTIVATION_TAU = 1.0 / 50.0
"""The FMU's activation time constant 1/S [s] (S = 50 /s), given to the built-in muscles."""


def pair_xml(actuators="fmu", lengthranges=None):
    """The MJCF of the pair. ``actuators="fmu"``: unit-gain ``general``
    actuators (ctrl = -tendon force); ``"builtin"``: MuJoCo's muscle model
    (module docstring) with ``lengthranges`` [(lo, hi)] per tendon (default
    ``path_range()``)."""
    if actuators == "fmu":
        acts = "".join(f'\n    <general name="{m.name}" tendon="{m.name}" gainprm="1" biasprm="0 0 0" '
                       f'ctrllimited="false"/>' for m in MUSCLES)
    elif actuators == "builtin":
        ranges = lengthranges or path_range()
        acts = ""
        for m, (lo, hi) in zip(MUSCLES, ranges):
            r0, r1 = (lo - m.slack) / m.l_opt, (hi - m.slack) / m.l_opt
            prm = f"{r0:.6f} {r1:.6f} {m.f0} 200 0.5 1.6 {BUILTIN_VMAX} 1.3 1.2"
            acts += (f'\n    <general name="{m.name}" tendon="{m.name}" dyntype="filterexact" '
                     f'dynprm="{ACTIVATION_TAU}" gaintype="muscle" biastype="muscle" gainprm="{prm}" '
                     f'biasprm="{prm}" lengthrange="{lo:.6f} {hi:.6f}" ctrllimited="true" ctrlrange="0 1"/>')
    else:
        raise ValueError("actuators must be 'fmu' or 'builtin'")
    return (f'<mujoco model="elbow_pair">\n  <compiler angle="radian"/>\n'
            f'  <option timestep="0.001" gravity="0 0 -9.81" integrator="Euler"/>\n'
            f"  <worldbody>{_GEOMETRY}  </worldbody>\n  <tendon>{_TENDONS}  </tendon>\n"
            f"  <actuator>{acts}\n  </actuator>\n</mujoco>\n")


def build_pair(dt=1e-3, actuators="fmu"):
    import mujoco

    model = mujoco.MjModel.from_xml_string(pair_xml(actuators))
    model.opt.timestep = dt
    return model


def _dLdq(data):
    """d ten_length / d elbow angle of both tendons (one dof)."""
    return np.asarray(data.ten_J, dtype=float).reshape(len(MUSCLES), -1)[:, 0].copy()


def path_table(angles_deg=(0.0, 60.0, 120.0)):
    """Rows (angle deg, [L_flexor, L_extensor], [moment arms], [fibre length /
    l_opt with the tendon at slack, through cos pennation]). Moment arm:
    -dL/dq for the flexor, +dL/dq for the extensor (both positive)."""
    import mujoco

    model = build_pair()
    data = mujoco.MjData(model)
    rows = []
    for deg in angles_deg:
        data.qpos[0] = np.radians(deg)
        mujoco.mj_forward(model, data)
        L = np.array(data.ten_length[:2])
        arms = _dLdq(data) * np.array([-1.0, 1.0])
        rel = []
        for m, ell in zip(MUSCLES, L):
            # fibre length l with l cos(alpha) = ell - L_TS, l sin(alpha) = L0 sin(alpha0)
            h = m.params["L0"] * np.sin(m.pennation)
            rel.append(np.hypot(ell - m.slack, h) / m.l_opt)
        rows.append((deg, L, arms, np.array(rel)))
    return rows


def path_range(n=261):
    """(min, max) of each tendon's length over the joint range."""
    import mujoco

    model = build_pair()
    data = mujoco.MjData(model)
    Ls = []
    for q in np.linspace(*JOINT_RANGE, n):
        data.qpos[0] = q
        mujoco.mj_forward(model, data)
        Ls.append(np.array(data.ten_length[:2]))
    Ls = np.array(Ls)
    return [(float(Ls[:, k].min()), float(Ls[:, k].max())) for k in range(len(MUSCLES))]


@dataclass
class CoContraction:
    """u_flexor = c + d/2, u_extensor = c - d/2, clipped to [0, 1]; d(t)
    piecewise linear through (times, diffs) (module docstring)."""

    level: float = 0.3
    times: tuple = (0.0, 0.3, 0.6, 1.3, 1.6, 2.4)
    diffs: tuple = (0.0, 0.0, 0.3, 0.3, -0.05, -0.05)

    def difference(self, t):
        return float(np.interp(t, self.times, self.diffs))

    def hold_start(self, t):
        """Start of the hold (d constant) that contains t; None on a ramp."""
        for k in range(len(self.times) - 1, -1, -1):
            if t >= self.times[k] - 1e-12:
                if k == len(self.times) - 1 or self.diffs[k] == self.diffs[k + 1]:
                    return self.times[k]
                return None
        return None

    def __call__(self, t):
        d = self.difference(t)
        return np.clip([self.level + 0.5 * d, self.level - 0.5 * d], 0.0, 1.0)


T_END = 2.4
ANGLE0 = np.radians(45.0)
OUT_NAMES = ("force", "activation_level", "fibre_length", "tendon_strain")


class Unit:
    """One musculotendon FMU instance through fmpy's FMU2Slave, by variable names."""

    def __init__(self, fmu, params, name):
        from fmpy.fmi2 import FMU2Slave

        self.loaded = load_fmu(fmu)
        md = self.loaded.model_description
        variables = self.loaded.variables
        self.vr = self.loaded.vr
        missing = sorted(set(params) - set(variables))
        if missing:
            raise ValueError(f"{Path(fmu).name} has no parameter(s) {missing}: cannot size the {name}")
        self.log = []
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=self.loaded.unzipdir,
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self._callbacks, self._log_key = logger_callbacks(self.log)
        self.slave.instantiate(callbacks=self._callbacks)
        for key, value in params.items():
            if variables[key].type == "Boolean":
                self.slave.setBoolean([self.vr[key]], [bool(value)])
            else:
                self.slave.setReal([self.vr[key]], [float(value)])
        self.out = [self.vr.get(n) for n in OUT_NAMES]

    def initialize(self, length, activation):
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.setReal([self.vr["length"], self.vr["activation"]], [float(length), float(activation)])
        self.slave.exitInitializationMode()

    def outputs(self):
        """force, activation_level, fibre_length, tendon_strain (nan when the FMU lacks one)."""
        vrs = [v for v in self.out if v is not None]
        vals = iter(self.slave.getReal(vrs))
        return [next(vals) if v is not None else float("nan") for v in self.out]

    def stiffness(self):
        return self.slave.getDirectionalDerivative([self.vr["force"]], [self.vr["length"]], [1.0])[0]

    def free(self):
        if self.slave is not None:
            try:
                self.slave.terminate()
            except Exception:
                pass
            self.slave.freeInstance()
            self.slave = None
            release_logger(self._log_key)


@dataclass
class PairResult:
    """A run sampled at the communication points; per-muscle arrays have
    columns (flexor, extensor). ``torque``: the muscles' net torque about the
    elbow, sum of -F dL/dq (positive flexes)."""

    scheme: str
    H: float
    t: np.ndarray
    angle: np.ndarray
    length: np.ndarray
    command: np.ndarray
    activation: np.ndarray
    force: np.ndarray
    fibre_length: np.ndarray
    tendon_strain: np.ndarray
    torque: np.ndarray
    kinetic: np.ndarray
    wall: float
    iterations: float = 1.0
    stable: bool = True
    reason: str = ""
    extra: dict = field(default_factory=dict)


def _new_record(n):
    two = ("length", "command", "activation", "force", "fibre_length", "tendon_strain", "stiffness")
    rec = {k: np.full((n, 2), np.nan) for k in two}
    rec.update({k: np.full(n, np.nan) for k in ("t", "angle", "torque", "kinetic")})
    return rec


def _result(scheme, H, rec, wall, **kw):
    keys = ("t", "angle", "length", "command", "activation", "force", "fibre_length", "tendon_strain", "torque",
            "kinetic")
    return PairResult(scheme, H, *(rec[k] for k in keys), wall=wall, **kw)


def _flag(rec, i, H, f_max, hold_start):
    """Per-step divergence check (``arm_mujoco._flag`` for two muscles). The
    kinetic energy's peaks are checked from ``hold_start`` (the index where
    the current hold of the pattern began; None on a ramp): the pattern's
    movements are peaks of their own, of any size."""
    vals = [rec["angle"][i], rec["kinetic"][i], *rec["length"][i], *rec["force"][i]]
    if not all(np.isfinite(vals)):
        return f"non-finite value at t = {i * H:.4g} s"
    growing = "" if hold_start is None else am._growing_peaks(rec["kinetic"][hold_start: i + 1])
    if growing:
        return f"kinetic energy grows from one oscillation to the next ({growing}) by t = {i * H:.4g} s"
    for k, m in enumerate(MUSCLES):
        if abs(rec["force"][i, k]) > 5 * f_max[k]:
            return f"|{m.name} force| = {abs(rec['force'][i, k]):.4g} N > 5 F_max at t = {i * H:.4g} s"
    if not -0.5 <= rec["angle"][i] <= 3.2:
        return f"angle {rec['angle'][i]:.4g} rad out of range at t = {i * H:.4g} s"
    return ""


def simulate_pair(scheme="implicit", H=1e-3, t_end=T_END, dt=1e-3, fmus=None, pattern=None, angle0=ANGLE0,
                  qvel0=0.0, params=None, tol=1e-9, max_iter=20, input_derivatives=None, gravity=True):
    """One coupled run of the pair with ``scheme`` (``arm_mujoco.SCHEMES``,
    each applied to both muscles as ``arm_mujoco.simulate`` applies it to
    one). ``fmus``: one FMU path for both or (flexor, extensor) (default
    ``MT_FMU``); ``params``: FMU parameters set on both on top of each
    muscle's (e.g. ``{"compliant_tendon": False}``), or a pair of dicts.
    Both units start at the command pattern(0) (``initial_activation``) in
    their static equilibrium at the initial path lengths. ``gravity=False``
    turns gravity off (the sign test)."""
    import mujoco

    if scheme not in am.SCHEMES:
        raise ValueError(f"scheme must be one of {am.SCHEMES}")
    fmus = fmus or MT_FMU
    fmus = (fmus, fmus) if isinstance(fmus, (str, Path)) else tuple(fmus)
    for fmu in fmus:
        why = am.unsupported(fmu, scheme)
        if why:
            raise ValueError(f"{Path(fmu).name}: {why}")
    derivs = (all(am.fmu_capabilities(f)["input_derivatives"] for f in fmus) if input_derivatives is None
              else bool(input_derivatives))
    extra_params = params if isinstance(params, (list, tuple)) else (params or {}, params or {})
    n_sub = int(round(H / dt))
    if n_sub < 1 or abs(n_sub * dt - H) > 1e-9 * H:
        raise ValueError(f"H = {H} must be a multiple of dt = {dt}")
    n_comm = int(round(t_end / H))
    pattern = pattern or CoContraction()
    model = build_pair(dt)
    if not gravity:
        model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    backup = mujoco.MjData(model)
    data.qpos[0], data.qvel[0] = angle0, qvel0
    mujoco.mj_forward(model, data)
    mujoco.mj_step1(model, data)
    rec = _new_record(n_comm + 1)
    u0 = pattern(0.0)
    units = []
    try:
        for k, m in enumerate(MUSCLES):
            p = {**m.params, "initial_activation": float(u0[k]), **extra_params[k]}
            units.append(Unit(fmus[k], p, f"pair_{m.name}_{scheme}"))
    except Exception:
        for u in units:
            u.free()
        raise
    f_max = [SIGMA0 * {**m.params, **extra_params[k]}["area"] for k, m in enumerate(MUSCLES)]
    stable, reason, iters_total, unconverged = True, "", 0, 0
    clock = _time.perf_counter
    wall0 = clock()
    out = np.zeros((2, 4))
    vr_in = [(u.vr["length"], u.vr["activation"]) for u in units]

    def lengths():
        return np.array(data.ten_length[:2], dtype=float)

    def rates():
        return np.array(data.ten_velocity[:2], dtype=float)

    def apply(F):
        data.ctrl[:2] = -F
        mujoco.mj_step2(model, data)
        mujoco.mj_step1(model, data)

    def step_units(t, L_in, u, dL=None):
        F = np.empty(2)
        for k, unit in enumerate(units):
            unit.slave.setReal(list(vr_in[k]), [float(L_in[k]), float(u[k])])
            if dL is not None:
                unit.slave.setRealInputDerivatives([vr_in[k][0]], [1], [float(dL[k])])
            unit.slave.doStep(t, H)
            F[k] = unit.slave.getReal([unit.vr["force"]])[0]
        return F

    def record(i):
        rec["t"][i] = i * H
        rec["angle"][i] = data.qpos[0]
        rec["length"][i] = lengths()
        rec["activation"][i], rec["force"][i] = out[:, 1], out[:, 0]
        rec["fibre_length"][i], rec["tendon_strain"][i] = out[:, 2], out[:, 3]
        rec["torque"][i] = -float(np.dot(out[:, 0], _dLdq(data)))
        rec["kinetic"][i] = am._kinetic(model, data)

    try:
        for k, unit in enumerate(units):
            unit.initialize(lengths()[k], u0[k])
            out[k] = unit.outputs()
        record(0)
        for i in range(n_comm):
            t = i * H
            L, dL = lengths(), rates()
            u = pattern(t)
            rec["command"][i] = u
            F_prev = out[:, 0].copy()
            if scheme == "explicit":
                F = step_units(t, L, u)
                for _ in range(n_sub):
                    apply(F)
            elif scheme in ("derivative", "implicit"):
                F = step_units(t, L, u, dL) if derivs else step_units(t, L + H * dL, u)
                K = np.array([unit.stiffness() for unit in units]) if scheme == "implicit" else np.zeros(2)
                rec["stiffness"][i + 1] = K
                for j in range(n_sub):
                    # deviation of each length at the end of this MuJoCo step from the FMU's path L + tau dL
                    dev = lengths() + dt * rates() - (L + (j + 1) * dt * dL)
                    apply(F_prev + (F - F_prev) * (j + 0.5) / n_sub + K * dev)
            else:  # iterated: Gauss-Seidel on both end lengths, FMUs and mjData rolled back
                states = [unit.slave.getFMUstate() for unit in units]
                mujoco.mj_copyData(backup, model, data)
                L_star = L + H * dL
                for it in range(max_iter):
                    if it:
                        for unit, s in zip(units, states):
                            unit.slave.setFMUstate(s)
                        mujoco.mj_copyData(data, model, backup)
                    F = step_units(t, L_star, u)
                    for j in range(n_sub):
                        apply(F_prev + (F - F_prev) * (j + 0.5) / n_sub)
                    L_end = lengths()
                    iters_total += 1
                    if np.max(np.abs(L_end - L_star)) < tol:
                        break
                    L_star = L_end
                else:
                    unconverged += 1
                for unit, s in zip(units, states):
                    unit.slave.freeFMUstate(s)
            for k, unit in enumerate(units):
                out[k] = unit.outputs()
            record(i + 1)
            rec["command"][i + 1] = u
            t0 = pattern.hold_start(t)
            bad = _flag(rec, i + 1, H, f_max, None if t0 is None else int(np.ceil(t0 / H - 1e-9)))
            if bad:
                stable, reason = False, bad
                break
    except Exception as exc:  # an FMU rejection (fmpy raises on discard/error) or MuJoCo trouble
        stable, reason = False, f"{type(exc).__name__}: {exc}"
        errors = [msg for unit in units for status, _, msg in unit.log if status >= 2]
        if errors:
            reason += f" (FMU: {errors[-1]})"
    finally:
        wall = clock() - wall0
        for unit in units:
            unit.free()
    if stable:
        bad = am._energy_growth(rec)
        if bad:
            stable, reason = False, bad
    n_done = int(np.sum(np.isfinite(rec["t"])))
    log = [(m.name, status, msg) for m, unit in zip(MUSCLES, units) for status, _, msg in unit.log if status >= 1]
    return _result(scheme, H, rec, wall, stable=stable, reason=reason,
                   iterations=iters_total / max(1, n_done - 1) if scheme == "iterated" else 1.0,
                   extra={"stiffness": rec["stiffness"], "unconverged_steps": unconverged, "fmu_log": log})


def simulate_builtin(t_end=T_END, dt=1e-3, pattern=None, angle0=ANGLE0, qvel0=0.0, H=1e-3):
    """The same arm and pattern with MuJoCo's own muscles (module docstring);
    the command is set every H (as the FMU runs see it), recorded every H.
    Activations start at pattern(0)."""
    import mujoco

    pattern = pattern or CoContraction()
    model = build_pair(dt, actuators="builtin")
    data = mujoco.MjData(model)
    data.qpos[0], data.qvel[0] = angle0, qvel0
    data.act[:2] = pattern(0.0)
    mujoco.mj_forward(model, data)
    n_sub = int(round(H / dt))
    n_comm = int(round(t_end / H))
    rec = _new_record(n_comm + 1)
    wall0 = _time.perf_counter()

    def record(i):
        rec["t"][i] = i * H
        rec["angle"][i] = data.qpos[0]
        rec["length"][i] = data.ten_length[:2]
        rec["activation"][i] = data.act[:2]
        rec["force"][i] = -np.asarray(data.actuator_force[:2])
        rec["torque"][i] = float(data.qfrc_actuator[0])
        rec["kinetic"][i] = am._kinetic(model, data)

    record(0)
    for i in range(n_comm):
        u = pattern(i * H)
        rec["command"][i] = u
        data.ctrl[:2] = u
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)  # forces and lengths of the state at t + H
        record(i + 1)
        rec["command"][i + 1] = u
    return _result("builtin", H, rec, _time.perf_counter() - wall0)


# --------------------------------------------------------------------------
# Comparison, sweep, figure
# --------------------------------------------------------------------------

def max_diff(a, b, key="angle"):
    """Max |a.key - b.key| over the common communication points (b
    interpolated on a's times); per column for two-column records."""
    ok = np.isfinite(a.t)
    x, y = getattr(a, key)[ok], getattr(b, key)
    if y.ndim == 1:
        return float(np.max(np.abs(x - np.interp(a.t[ok], b.t, y))))
    return np.array([np.max(np.abs(x[:, k] - np.interp(a.t[ok], b.t, y[:, k]))) for k in range(y.shape[1])])


def at(result, t, key="angle"):
    """The value of ``key`` at time t (linear between communication points)."""
    y = getattr(result, key)
    if y.ndim == 1:
        return float(np.interp(t, result.t, y))
    return np.array([np.interp(t, result.t, y[:, k]) for k in range(y.shape[1])])


HOLD_TIMES = (0.3, 1.3, 2.4)
"""Ends of the three holds of ``CoContraction`` (d = 0, 0.3, -0.05) [s]."""


def compare(H=1e-3, fmus=None, scheme="implicit", t_end=T_END):
    """The compliant FMUs, the rigid-tendon FMUs and MuJoCo's muscles on the
    pattern; a dict of runs and printed numbers."""
    runs = {"compliant": simulate_pair(scheme, H, t_end=t_end, fmus=fmus),
            "rigid": simulate_pair(scheme, H, t_end=t_end, fmus=fmus, params={"compliant_tendon": False}),
            "builtin": simulate_builtin(t_end=t_end, H=H)}
    print(f"\n### Co-contraction pattern, {scheme} at H = {1e3 * H:g} ms\n")
    times = " / ".join(f"{t:g}" for t in HOLD_TIMES)
    print(f"| run | stable | angle at {times} s [deg] | peak angle [deg] | forces (flexor, extensor) at {times} s [N] "
          "| max angle / force diff vs compliant [deg / N] |")
    print("|---|---|---|---|---|---|")
    ref = runs["compliant"]
    for name, r in runs.items():
        a = " / ".join(f"{np.degrees(at(r, t)):.2f}" for t in HOLD_TIMES)
        f = " / ".join("{:.0f}, {:.0f}".format(*at(r, t, "force")) for t in HOLD_TIMES)
        da = np.degrees(max_diff(r, ref)) if r is not ref else 0.0
        df = np.max(max_diff(r, ref, "force")) if r is not ref else 0.0
        print(f"| {name} | {'yes' if r.stable else 'no: ' + r.reason} | {a} | {np.degrees(np.nanmax(r.angle)):.2f} "
              f"| {f} | {da:.2f} / {df:.1f} |")
    return runs


def sweep_pair(steps_ms, t_end=T_END, fmus=None):
    """Every scheme at every step on the pattern: stable?, max angle error vs
    the iterated scheme at H = 1 ms, wall time. Prints a markdown table and
    the largest stable step per scheme."""
    reference = simulate_pair("iterated", 1e-3, t_end=t_end, fmus=fmus)
    rows = []
    print(f"\n### Pair, co-contraction pattern (t_end = {t_end:g} s, reference: iterated at H = 1 ms)\n")
    print("| scheme | H [ms] | stable | max angle error [deg] | wall [ms] | iterations/step | unconverged steps |")
    print("|---|---|---|---|---|---|---|")
    for scheme in am.SCHEMES:
        for h in steps_ms:
            r = simulate_pair(scheme, h * 1e-3, t_end=t_end, fmus=fmus)
            err = max_diff(r, reference) if r.stable else float("inf")
            rows.append((scheme, h, r.stable, err, r.wall, r.iterations, r.extra["unconverged_steps"], r.reason))
            status = "yes" if r.stable else f"**no**: {r.reason}"
            print(f"| {scheme} | {h:g} | {status} | {np.degrees(err):.3g} | {1e3 * r.wall:.1f} | {r.iterations:.2f} "
                  f"| {r.extra['unconverged_steps'] if scheme == 'iterated' else ''} |", flush=True)
    print()
    for scheme in am.SCHEMES:
        best = None
        for row in (x for x in rows if x[0] == scheme):
            if not row[2] or row[6]:
                break
            best = row[1]
        print(f"largest stable step (pair, {scheme}): {best if best is None else format(best, 'g')} ms")
    return reference, rows


def plot_comparison(runs, path, title=""):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(7, 10), sharex=True)
    for name, r in runs.items():
        line = ax[0].plot(r.t, np.degrees(r.angle), label=name)[0]
        c = line.get_color()
        ax[1].plot(r.t, r.force[:, 0], color=c, label=f"{name}, flexor")
        ax[1].plot(r.t, r.force[:, 1], "--", color=c, label=f"{name}, extensor")
        ax[2].plot(r.t, r.torque, color=c, label=name)
        ax[3].plot(r.t, r.activation[:, 0], color=c)
        ax[3].plot(r.t, r.activation[:, 1], "--", color=c)
    first = next(iter(runs.values()))
    ax[3].plot(first.t, first.command[:, 0] - first.command[:, 1], ":", color="k", label="command difference d")
    ax[0].set_ylabel("elbow angle [deg]")
    ax[1].set_ylabel("tendon force [N]\n(solid flexor, dashed extensor)")
    ax[2].set_ylabel("net muscle torque [N m]")
    ax[3].set_ylabel("activation\n(solid flexor, dashed extensor)")
    ax[3].set_xlabel("time [s]")
    ax[0].legend(fontsize=7)
    ax[1].legend(fontsize=6, ncol=2)
    ax[3].legend(fontsize=7)
    if title:
        ax[0].set_title(title)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_schemes(results, path, title=""):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for r in results:
        lab = f"{r.scheme}, H = {1e3 * r.H:g} ms" + ("" if r.stable else " (unstable)")
        line = ax[0].plot(r.t, np.degrees(r.angle), label=lab)[0]
        ax[1].plot(r.t, r.force[:, 0], color=line.get_color(), label=lab)
        ax[1].plot(r.t, r.force[:, 1], "--", color=line.get_color())
    ax[0].set_ylabel("elbow angle [deg]")
    ax[1].set_ylabel("tendon force [N]\n(solid flexor, dashed extensor)")
    ax[1].set_xlabel("time [s]")
    ax[0].legend(fontsize=7)
    if title:
        ax[0].set_title(title)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(scheme="all", step=1e-3, fmus=None, out=REPO / "docs" / "figures", sweep_steps_ms=None, t_end=T_END):
    """``arm_mujoco.py --pair``: the path table, every scheme (or one), the
    comparison with the rigid tendon and MuJoCo's muscles, the figures; with
    ``sweep_steps_ms`` the stability sweep instead."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = sorted({load_fmu(f).model_description.modelName for f in
                    ((fmus or MT_FMU,) if isinstance(fmus or MT_FMU, (str, Path)) else fmus)})
    print(f"pair: {', '.join(names)}; pattern {CoContraction()}")
    for deg, L, arms, rel in path_table():
        print(f"  {deg:5.0f} deg: L = {L[0]:.4f} / {L[1]:.4f} m, moment arm {1e3 * arms[0]:.1f} / "
              f"{1e3 * arms[1]:.1f} mm, fibre/l_opt at slack tendon {rel[0]:.3f} / {rel[1]:.3f} (flexor / extensor)")
    if sweep_steps_ms:
        sweep_pair(sweep_steps_ms, t_end=t_end, fmus=fmus)
        return 0
    schemes = am.SCHEMES if scheme == "all" else (scheme,)
    results = []
    for s in schemes:
        r = simulate_pair(s, step, t_end=t_end, fmus=fmus)
        results.append(r)
        angles = " / ".join(f"{np.degrees(at(r, t)):.2f}" for t in HOLD_TIMES)
        print(f"{s:10s} H = {step:g} s: stable={r.stable} {r.reason} angle at "
              f"{' / '.join(f'{t:g}' for t in HOLD_TIMES)} s: {angles} deg, wall {1e3 * r.wall:.1f} ms")
    fname = out / f"arm_pair_{scheme}_H{1e3 * step:g}ms.png"
    plot_schemes(results, fname, f"Antagonist pair ({', '.join(names)}), H = {1e3 * step:g} ms")
    print(f"wrote {fname}")
    runs = compare(step, fmus=fmus, scheme="implicit" if scheme == "all" else scheme, t_end=t_end)
    fname = out / f"arm_pair_compare_H{1e3 * step:g}ms.png"
    plot_comparison(runs, fname, "Co-contraction: compliant vs rigid tendon vs MuJoCo muscles")
    print(f"wrote {fname}")
    return 0
