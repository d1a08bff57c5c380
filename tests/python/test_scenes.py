"""The shipped scenes' FMUs (issue 6) as an importer sees them, through fmpy.

- Every scene's FMU passes fmpy's validator, lists exactly the scene's
  variables (fmu_build/scenes/<file>.toml: inputs, outputs, parameters that are
  not compiled-in constants) and has its own GUID; HillMuscle1D and
  HillMuscleFE keep their interface.
- Each scene computes what the full FMU computes on the same inputs: bit for
  bit where the arithmetic is the same (passive, activated, actuator, the FE
  scenes), to 1e-12 relative for the isometric scene (its f_v has no
  lengthening branch, so its CE-SEE iterations differ at round-off).
- The actuator's ``stiffness`` output is its fmi2GetDirectionalDerivative
  (force, length) and the finite difference of the step map (FMU states).
"""

from __future__ import annotations

import ctypes
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SCENES = {
    (d := tomllib.loads(p.read_text()))["model_identifier"]: d
    for p in sorted((REPO / "fmu_build" / "scenes").glob("*.toml"))
}
L0 = 0.05


def fmu_path(fmu_id: str) -> Path:
    path = REPO / "dist" / f"{fmu_id}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs first with `scripts/build_fmus.sh`",
                    pytrace=False)
    return path


class Slave:
    """One initialized instance of an FMU, addressed by variable names."""

    def __init__(self, fmu_id: str, name: str, log: list | None = None):
        from elongation import logger_callbacks
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(str(fmu_path(fmu_id)))
        self.dir = extract(str(fmu_path(fmu_id)))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.log = [] if log is None else log
        self._callbacks, self._log_key = logger_callbacks(self.log)
        self.fmu.instantiate(callbacks=self._callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def set(self, **values):
        if values:
            self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, h):
        self.fmu.doStep(self.t, h)  # fmpy raises on a status other than OK/warning
        self.t += h

    def close(self):
        from elongation import release_logger

        self.fmu.freeInstance()
        release_logger(self._log_key)
        shutil.rmtree(self.dir, ignore_errors=True)


def real_outputs(fmu_id):
    return [o for o in SCENES[fmu_id]["outputs"] if o != "newton_iterations"]


def run_pair(fmu_id, full_id, n, h, inputs):
    """The scene and the full FMU stepped on the same inputs; per step the
    scene's outputs (the full FMU's d force / d length for ``stiffness``) and
    d force / d (each input) of both."""
    scene, full = Slave(fmu_id, "scene"), Slave(full_id, "full")
    names = real_outputs(fmu_id)
    full_names = [("force" if o == "stiffness" else o) for o in names]
    has = SCENES[fmu_id]["inputs"]
    rows_s, rows_f = [], []
    try:
        for i in range(n):
            t = (i + 1) * h
            values = {k: v for k, v in inputs(t).items() if k in has}
            scene.set(**values)
            full.set(**values)
            scene.step(h)
            full.step(h)
            rs, rf = list(scene.get(names)), list(full.get(full_names))
            for k in has:
                rs += scene.fmu.getDirectionalDerivative([scene.vr["force"]], [scene.vr[k]], [1.0])
                rf += full.fmu.getDirectionalDerivative([full.vr["force"]], [full.vr[k]], [1.0])
            if "stiffness" in names:
                j = names.index("stiffness")
                rf[j] = full.fmu.getDirectionalDerivative([full.vr["force"]], [full.vr["length"]], [1.0])[0]
            rows_s.append(rs)
            rows_f.append(rf)
    finally:
        scene.close()
        full.close()
    return np.array(rows_s), np.array(rows_f)


def pull(t):
    return L0 + 0.005 * t


def activated_pull(t):
    return L0 + 0.005 * max(t - 0.5, 0.0)


def swing(t):
    u = (0.6 if t < 1.0 else 1.0) if (t % 0.5) < 0.2 else 0.0
    return {"activation": u, "length": L0 * (1 + 0.08 * math.sin(2 * math.pi * 2 * t))}


@pytest.mark.parametrize("fmu_id", sorted(SCENES))
def test_validate_fmu_is_clean(fmu_id):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu_path(fmu_id))) == []


@pytest.mark.parametrize("fmu_id", sorted(SCENES))
def test_the_interface_is_exactly_the_scenes(fmu_id):
    from fmpy import read_model_description

    scene = SCENES[fmu_id]
    md = read_model_description(str(fmu_path(fmu_id)))
    by = lambda c: {v.name for v in md.modelVariables if v.causality == c}  # noqa: E731
    assert md.coSimulation.modelIdentifier == fmu_id
    assert by("input") == set(scene["inputs"])
    assert by("output") == set(scene["outputs"])
    params = by("parameter")
    for name in scene.get("constants", {}):
        assert name not in params, f"constant {name} is exposed"
    for name, start in scene.get("parameters", {}).items():
        v = next(v for v in md.modelVariables if v.name == name)
        assert float(v.start) == float(start), name
    # Outputs have no direct feedthrough; their initial dependencies name
    # only variables of this FMU (fmpy resolved the indices).
    for u in md.outputs:
        assert u.dependencies == []
    for u in md.initialUnknowns:
        assert all(d.causality in ("input", "parameter") for d in u.dependencies)


def test_the_scenes_have_their_own_guids_and_the_full_fmus_keep_theirs():
    from fmpy import read_model_description

    guids = {i: read_model_description(str(fmu_path(i))).guid for i in SCENES}
    assert len(set(guids.values())) == len(guids)
    # The full FMUs' GUIDs, as tests/model_description.rs pins them (changed
    # when the length input got its own declared range, and HillMuscleFE when
    # it got the radial_grading parameter, default 0.6, and the tunable
    # threads parameter).
    assert guids["HillMuscle1D"] == "{7c808cb6-7bd7-8378-be77-25860ec4a448}"
    assert guids["HillMuscleFE"] == "{1f07a647-ef8f-8b5c-9be1-9ff36717f4cd}"


def assert_bitwise(a, b, what):
    assert a.shape == b.shape
    diff = np.argwhere(a.view(np.int64) != b.view(np.int64))
    assert diff.size == 0, f"{what}: first difference at (step, column) {diff[0]}: {a[tuple(diff[0])]} vs {b[tuple(diff[0])]}"


def test_passive_1d_equals_the_full_fmu_bit_for_bit():
    s, f = run_pair("HillPassive1D", "HillMuscle1D", 2000, 1e-3, lambda t: {"length": pull(t)})
    assert_bitwise(s, f, "HillPassive1D")
    assert 2.1e5 < s[-1, 1] < 2.3e5  # stress at 20 %: 221.7 kPa (README)


def test_activated_1d_equals_the_full_fmu_bit_for_bit():
    s, f = run_pair("HillActivated1D", "HillMuscle1D", 2500, 1e-3,
                    lambda t: {"activation": 1.0, "length": activated_pull(t)})
    assert_bitwise(s, f, "HillActivated1D")
    assert 9.0e5 < s[-1, 1] < 9.4e5  # 919.2 kPa (README)


def test_isometric_1d_equals_the_full_fmu_to_1e_12():
    s, f = run_pair("HillIsometric1D", "HillMuscle1D", 1000, 1e-3, lambda t: {"activation": 1.0})
    k = len(real_outputs("HillIsometric1D"))
    rel = np.abs(s[:, :k] - f[:, :k]) / np.maximum(np.abs(f[:, :k]), 1e-300)
    assert rel.max() <= 1e-12, rel.max()
    assert s[-1, 0] > 100.0  # a tetanic force of ~117 N


def test_actuator_equals_the_full_fmu_and_stiffness_is_the_directional_derivative():
    s, f = run_pair("HillActuator1D", "HillMuscle1D", 1500, 1e-3, swing)
    # Columns: force, stiffness, d force / d activation, d force / d length.
    assert_bitwise(s, f, "HillActuator1D")
    assert np.array_equal(s[:, 1].view(np.int64), s[:, 3].view(np.int64))
    assert (s[:, 1] > 0).all()


def test_actuator_stiffness_matches_finite_differences_of_the_step_map():
    a = Slave("HillActuator1D", "fd")
    try:
        h, checked = 1e-3, 0
        for i in range(900):
            t = (i + 1) * h
            x = swing(t)
            a.set(activation=x["activation"])
            if i % 111 == 55:
                state = a.fmu.getFMUstate()
                e = 1e-7 * L0
                forces = []
                for dl in (e, -e):
                    a.fmu.setFMUstate(state)
                    a.set(length=x["length"] + dl)
                    a.fmu.doStep(a.t, h)
                    forces.append(a.get(["force"])[0])
                a.fmu.setFMUstate(state)
                a.fmu.freeFMUstate(state)
                a.set(length=x["length"])
                a.step(h)
                k = a.get(["stiffness"])[0]
                fd = (forces[0] - forces[1]) / (2 * e)
                assert abs(k - fd) <= 1e-5 * abs(k), (t, k, fd)
                checked += 1
            else:
                a.set(length=x["length"])
                a.step(h)
        assert checked >= 8
    finally:
        a.close()


def test_isometric_scene_discards_relaxation_naming_the_branch():
    """Relaxing lengthens the CE; the isometric scene has no lengthening
    branch of f_v, so that step is refused with fmi2Discard and a message
    naming the branch, and the instance is as before it."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Discard

    m = Slave("HillIsometric1D", "iso", log=[])
    try:
        m.set(activation=1.0)
        for _ in range(300):
            m.step(1e-3)
        m.set(activation=0.0)
        before = m.get(real_outputs("HillIsometric1D"))
        n_log = len(m.log)
        with pytest.raises(FMICallException) as exc:
            m.fmu.doStep(m.t, 1e-3)
        assert exc.value.status == fmi2Discard
        assert any("lengthening" in msg and "fv_lengthening = false" in msg
                   for _, _, msg in m.log[n_log:]), m.log[n_log:]
        assert m.get(real_outputs("HillIsometric1D")) == before
    finally:
        m.close()


def fe_inputs(t):
    return {"activation": 1.0, "length": L0 + 0.05 * max(t - 0.02, 0.0)}


@pytest.mark.parametrize("fmu_id", ["HillPassiveFE", "HillActivatedFE"])
def test_fe_scenes_equal_the_full_fe_muscle_bit_for_bit(fmu_id):
    s, f = run_pair(fmu_id, "HillMuscleFE", 8, 5e-3, fe_inputs)
    assert_bitwise(s, f, fmu_id)
    assert s[-1, 0] > 0.0


@pytest.mark.parametrize("full, scene", [("HillMuscle1D", "HillPassive1D"),
                                         ("HillMuscle1D", "HillActuator1D"),
                                         ("HillMuscleFE", "HillPassiveFE")])
def test_an_instance_of_another_fmu_of_the_same_variant_is_rejected(full, scene):
    """The scenes' binaries of one variant export the same model type; each
    binary's functions still reject a component another binary created
    (fmi2Error, nothing done to it), and that instance goes on exactly like a
    twin that was never given to the wrong binary."""
    a, b, twin = Slave(full, "full"), Slave(scene, "scene"), Slave(scene, "twin")
    force = (ctypes.c_uint * 1)(b.vr["force"])
    value = (ctypes.c_double * 1)(-1.0)
    fmi2_error = 3
    wrong = a.fmu.dll  # the full FMU's functions, given the scene's instance
    wrong.fmi2GetReal.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t,
                                  ctypes.c_void_p]
    wrong.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double,
                                 ctypes.c_int]
    wrong.fmi2FreeInstance.argtypes = [ctypes.c_void_p]
    wrong.fmi2FreeInstance.restype = None
    assert wrong.fmi2GetReal(b.fmu.component, force, 1, value) == fmi2_error
    assert value[0] == -1.0
    assert wrong.fmi2DoStep(b.fmu.component, 0.0, 1e-3, 1) == fmi2_error
    wrong.fmi2FreeInstance(b.fmu.component)  # not its instance: nothing happens
    for s in (b, twin):
        s.set(length=0.051)
        s.step(1e-3)
    assert b.get(["force"]) == twin.get(["force"])
    for s in (a, b, twin):
        s.close()
