"""The musculotendon units HillMusculotendon1D and HillMusculotendonFE
(dist/<id>.fmu) through fmpy, as an importer sees them; every test runs on both.

The FE unit runs on a 4 x 1 mesh (n_axial, n_radial) with 10 ms communication
steps where a test follows the protocol (the same inputs at every tenth
millisecond), and fewer steps elsewhere, to stay fast.

- After every step the outputs satisfy the unit's equilibrium (MODEL_NOTES
  "Musculotendon unit"): force = F_T(tendon_strain) and force = F_M cos(pennation)
  with F_M = stress * area, to the unit's equilibrium tolerance: 1e-10 F0 (1D),
  1e-9 F0 (FE, ten times the FE solve's force tolerance).
- A rigid tendon without pennation is the plain muscle at length path - L_TS,
  bit for bit: HillMuscle1D, resp. HillMuscleFE on the same mesh.
- fmi2GetDirectionalDerivative of the outputs with respect to both inputs
  against finite differences of the step map (FMU states); ``stiffness`` is
  d force / d length.
- FMU states: save/restore and serialize/deserialize continue bit for bit.
- Bad values of the unit's parameters: fmi2Error with the standard message,
  the instance then running as a twin that never saw them.
- A slack tendon carries nothing; a path jump in one step is solved.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
H = 1e-3
OUTPUTS = ["force", "stress", "fibre_length", "tendon_strain", "pennation",
           "activation_level", "stiffness"]
# Per unit: the plain muscle it equals with a rigid tendon and no pennation,
# the mesh of its FE muscle (and of that plain one), the equilibrium's
# tolerance relative to F0, the protocol's stride (communication step
# stride * H, the protocol sampled at every stride-th millisecond) and the
# steps of the derivative test (a check at every tenth).
CASES = {
    "HillMusculotendon1D": {"plain": "HillMuscle1D", "mesh": {}, "rtol": 1e-10, "stride": 1,
                            "dd_steps": 40},
    "HillMusculotendonFE": {"plain": "HillMuscleFE", "mesh": {"n_axial": 4, "n_radial": 1},
                            "rtol": 1e-9, "stride": 10, "dd_steps": 20},
}


def fmu_path(fmu_id: str) -> Path:
    path = REPO / "dist" / f"{fmu_id}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs first with `scripts/build_fmus.sh`",
                    pytrace=False)
    return path


class Unit:
    """One instance of an FMU, parameters set before initialization, addressed by names."""

    def __init__(self, fmu_id="HillMusculotendon1D", reals=None, bools=None, ints=None,
                 activation=0.0, length=None, name="mt", initialize=True, h=H):
        from elongation import logger_callbacks
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.id, self.h = fmu_id, h
        self.md = read_model_description(str(fmu_path(fmu_id)))
        self.dir = extract(str(fmu_path(fmu_id)))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.vr = {n: v.valueReference for n, v in self.vars.items()}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.log = []
        self._callbacks, self._log_key = logger_callbacks(self.log)
        self.fmu.instantiate(callbacks=self._callbacks)
        for k, v in (reals or {}).items():
            self.fmu.setReal([self.vr[k]], [v])
        for k, v in (bools or {}).items():
            self.fmu.setBoolean([self.vr[k]], [v])
        for k, v in (ints or {}).items():
            self.fmu.setInteger([self.vr[k]], [v])
        self.t = 0.0
        if initialize:
            self.initialize(activation, length)

    def start(self, name):
        return float(self.vars[name].start)

    def initialize(self, activation, length):
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.set(activation=activation, length=self.start("length") if length is None else length)
        self.fmu.exitInitializationMode()

    def set(self, **values):
        self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, *names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, activation, length, h=None):
        h = self.h if h is None else h
        self.set(activation=activation, length=length)
        self.fmu.doStep(self.t, h)
        self.t += h

    def dd(self, unknown, known):
        return self.fmu.getDirectionalDerivative([self.vr[unknown]], [self.vr[known]], [1.0])[0]

    def close(self):
        from elongation import release_logger

        self.fmu.freeInstance()
        release_logger(self._log_key)
        shutil.rmtree(self.dir, ignore_errors=True)


@pytest.fixture(params=sorted(CASES))
def unit(request):
    """Factory of instances of the unit under test (or, with ``fmu_id``, of
    its plain muscle), on the case's mesh and communication step."""
    case = CASES[request.param]
    made = []

    def make(fmu_id=request.param, **kw):
        u = Unit(fmu_id=fmu_id, name=f"mt{len(made)}", ints=case["mesh"],
                 h=H * case["stride"], **kw)
        made.append(u)
        return u

    make.case = case
    yield make
    for u in made:
        u.close()


def tendon_force(eps, eps0, f0):
    """Thelen's tendon curve F0 f_T(eps) (MODEL_NOTES "Musculotendon unit")."""
    eps_toe = 0.609 * eps0
    if eps <= 0.0:
        return 0.0
    if eps <= eps_toe:
        return f0 * 0.33 * math.expm1(3.0 * eps / eps_toe) / math.expm1(3.0)
    return f0 * (1.712 / eps0 * (eps - eps_toe) + 0.33)


def protocol(i, rest, stride=1):
    """Activation rising, a stretch, a hold, a path jump, a slack phase: the
    inputs of step i of 500 at H, or of step i of 500 / stride at stride * H
    (the same inputs at every stride-th millisecond)."""
    i = (i + 1) * stride - 1
    t = (i + 1) * H
    u = min(5.0 * t, 1.0) if i < 300 else (1.0 if i < 400 else 0.0)
    if i < 100:
        path = rest
    elif i < 200:
        path = rest + 0.02 * (t - 0.1)
    elif i < 250:
        path = rest + 0.002
    elif i < 300:
        path = rest + 0.012
    else:
        path = rest - 0.03
    return u, path


@pytest.mark.parametrize("alpha0", [0.0, 0.4])
def test_the_equilibrium_holds_after_every_step(unit, alpha0):
    m = unit(reals={"pennation_angle": alpha0})
    stride, rtol = unit.case["stride"], unit.case["rtol"]
    rest = m.start("length")
    f0 = m.start("sigma0") * m.start("area")
    lts, eps0, area = m.start("tendon_slack_length"), m.start("tendon_strain_at_F0"), m.start("area")
    worst, slack, n = 0.0, 0, 500 // stride
    for i in range(n):
        u, path = protocol(i, rest, stride)
        m.step(u, path)
        force, stress, l_m, eps, alpha = m.get(*OUTPUTS[:5])
        assert abs(force - tendon_force(eps, eps0, f0)) <= 1e-12 * f0, i
        residual = stress * area * math.cos(alpha) - force
        worst = max(worst, abs(residual) / f0)
        assert abs(residual) <= rtol * f0, (i, residual)
        assert abs(lts * (1 + eps) + l_m * math.cos(alpha) - path) <= 1e-12 * path
        if eps < 0:
            slack += 1
            assert force == 0.0
    assert slack > n // 10
    print(f"{m.id} pennation_angle {alpha0}: worst residual {worst:.2e} F0")


def test_a_rigid_tendon_without_pennation_is_the_plain_muscle(unit):
    m = unit(bools={"compliant_tendon": False})
    stride = unit.case["stride"]
    rest, lts = m.start("length"), m.start("tendon_slack_length")
    plain = unit(fmu_id=unit.case["plain"], reals={"L0": m.start("L0"), "area": m.start("area")},
                 length=rest - lts)
    for i in range(300 // stride):
        u, path = protocol(i, rest, stride)
        path = max(path, rest - 0.01)
        m.step(u, path)
        plain.step(u, path - lts)
        a = np.array(m.get("force", "stress", "activation_level"))
        b = np.array(plain.get("force", "stress", "activation_level"))
        assert (a.view(np.int64) == b.view(np.int64)).all(), (i, a, b)
        assert m.get("stiffness")[0] == plain.dd("force", "length")
        assert m.get("tendon_strain")[0] == 0.0


@pytest.mark.parametrize("alpha0,compliant", [(0.0, True), (0.4, True), (0.4, False)])
def test_directional_derivatives_match_finite_differences(unit, alpha0, compliant):
    m = unit(reals={"pennation_angle": alpha0}, bools={"compliant_tendon": compliant},
             activation=0.3)
    rest = m.start("length")
    names = OUTPUTS[:6]
    dl, du = 1e-6, 1e-5
    worst = 0.0
    for i in range(unit.case["dd_steps"]):
        u, path = 0.3 + 0.01 * i, rest + 0.005 + 1e-4 * i
        if i % 10 != 9:
            m.step(u, path)
            continue
        before = m.fmu.getFMUstate()

        def at(du_, dl_):
            m.fmu.setFMUstate(before)
            m.set(activation=u + du_, length=path + dl_)
            m.fmu.doStep(m.t, m.h)
            return np.array(m.get(*names))

        lp, lm, up, um = at(0, dl), at(0, -dl), at(du, 0), at(-du, 0)
        m.fmu.setFMUstate(before)
        m.fmu.freeFMUstate(before)
        m.step(u, path)
        values = np.array(m.get(*names))
        for k, name in enumerate(names):
            for known, plus, minus, d in [("length", lp, lm, dl), ("activation", up, um, du)]:
                fd = (plus[k] - minus[k]) / (2 * d)
                dd = m.dd(name, known)
                scale = max(abs(fd), abs(dd))
                err = abs(fd - dd)
                assert err <= 1e-4 * scale + 1e-9 * abs(values[k]) / d, (i, name, known, dd, fd)
                if scale > 1e-6:
                    worst = max(worst, err / scale)
        assert m.get("stiffness")[0] == m.dd("force", "length")
    print(f"{m.id} alpha0 {alpha0} compliant {compliant}: worst relative error {worst:.2e}")


def test_states_save_restore_and_serialize_bit_identical(unit):
    m = unit(reals={"pennation_angle": 0.3})
    stride = unit.case["stride"]
    rest = m.start("length")
    for i in range(150 // stride):
        m.step(*protocol(i, rest, stride))
    state = m.fmu.getFMUstate()
    data = m.fmu.serializeFMUstate(state)
    t0 = m.t

    def run():
        m.t = t0
        out = []
        for i in range(150 // stride, 350 // stride):
            m.step(*protocol(i, rest, stride))
            out.append(m.get(*OUTPUTS))
        return np.array(out)

    first = run()
    m.fmu.setFMUstate(state)
    assert bytes(m.fmu.serializeFMUstate(m.fmu.getFMUstate())) == bytes(data)
    second = run()
    restored = m.fmu.deSerializeFMUstate(data)
    m.fmu.setFMUstate(restored)
    third = run()
    for other in (second, third):
        assert (first.view(np.int64) == other.view(np.int64)).all()
    m.fmu.freeFMUstate(state)
    m.fmu.freeFMUstate(restored)


@pytest.mark.parametrize("name,values,rng", [
    ("tendon_slack_length", [0.0, -0.1, 20.0, math.nan, math.inf], "[1e-4, 10]"),
    ("tendon_strain_at_F0", [0.0, -0.04, 2.0, math.nan], "[1e-6, 1]"),
    ("pennation_angle", [-0.1, 1.2, math.nan], "[0, 1]"),
])
def test_bad_unit_parameters_are_refused_and_change_nothing(unit, name, values, rng):
    from fmpy.fmi1 import FMICallException

    m = unit(initialize=False)
    stride = unit.case["stride"]
    for v in values:
        m.log.clear()
        with pytest.raises(FMICallException):
            m.fmu.setReal([m.vr[name]], [v])
        msgs = " | ".join(msg for _, _, msg in m.log)
        assert f"parameter {name} = " in msgs, msgs
        assert f"is out of range: must be finite and in {rng}" in msgs, msgs
    m.initialize(0.5, None)
    twin = unit(activation=0.5)
    assert m.get(name) == twin.get(name)
    rest = m.start("length")
    for i in range(100 // stride):
        m.step(*protocol(i, rest, stride))
        twin.step(*protocol(i, rest, stride))
        assert m.get(*OUTPUTS) == twin.get(*OUTPUTS)


@pytest.mark.parametrize("u", [0.0, 1.0])
def test_a_slack_tendon_carries_nothing(unit, u):
    m = unit(reals={"initial_activation": u}, activation=u, length=None)
    rest = m.start("length")
    f0 = m.start("sigma0") * m.start("area")
    m.step(u, rest - 0.04)
    for i in range(50 // unit.case["stride"]):
        m.step(u, rest - 0.04)
        force, stress, eps, k = m.get("force", "stress", "tendon_strain", "stiffness")
        assert force == 0.0 and eps < 0.0 and k == 0.0
        assert abs(stress * m.start("area")) <= unit.case["rtol"] * f0


def test_a_path_jump_in_one_step_is_solved(unit):
    m = unit(reals={"initial_activation": 1.0}, activation=1.0)
    rest, f0, area = m.start("length"), m.start("sigma0") * m.start("area"), m.start("area")
    forces = [m.get("force")[0]]
    for path in [rest + 0.02, rest + 0.02, rest, rest - 0.02]:
        m.step(1.0, path)
        force, stress, alpha = m.get("force", "stress", "pennation")
        assert abs(stress * area * math.cos(alpha) - force) <= unit.case["rtol"] * f0
        forces.append(force)
    assert forces[1] > forces[0] and forces[3] < forces[2] and forces[4] < forces[3], forces
