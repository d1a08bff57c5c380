"""fmi2GetDirectionalDerivative in initialization mode with respect to parameters.

FMI 2.0 sections 2.1.9 and 2.2.8: in Initialization Mode the unknowns are those
of <InitialUnknowns> and the knowns the variables their dependencies may name:
the inputs and the variables with initial = "exact", i.e. the parameters. The
FMU differentiates its initialization with respect to a Real parameter
(differences at 1e-3 relative, Richardson-combined; src/fmi2/initial_sensitivity.rs).

For every shipped FMU (each scene) and every Real parameter, in initialization
mode at a stretched, half-activated initial state:
- where an output's <InitialUnknowns> entry names the parameter, the FMU's
  derivative agrees with this test's own differences, two orders more
  accurate (separate instances initialized at p(1 + k eps), eps = 1e-3,
  extrapolated to sixth order: `reference_column`);
- where it does not, this test's perturbed initial values are bit for bit
  those at p (so the declared dependencies are right) and the FMU gives 0.
Exact checks: d activation_level / d initial_activation = 1 (also at both
bounds of initial_activation, where the FMU's stencil is one-sided), and for
the 1D model d force / d area = stress.
"""

from __future__ import annotations

import shutil
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SCENES = sorted(
    tomllib.loads(p.read_text())["model_identifier"]
    for p in (REPO / "fmu_build" / "scenes").glob("*.toml")
)


def declares(fmu_id: str, name: str) -> bool:
    """Whether the committed modelDescription of `fmu_id` has variable `name`."""
    text = (REPO / "modelDescription" / f"{fmu_id}.xml").read_text()
    return f'name="{name}"' in text


# An FE scene with its mesh compiled in (mesh_constant) runs the default
# 2,592-tetrahedron mesh: ~2 s per initialization here, 6-8 s when activated,
# so it is checked on one parameter, not activated; HillMuscleFE and
# HillPassiveFE get every parameter on a 6 x 1 mesh.
FIXED_MESH_FE = [s for s in SCENES if s.endswith("FE") and not declares(s, "n_axial")]
L0 = 0.05
EPS = 1e-3
# Agreement of the FMU's derivative with the reference, |p| |error| as a
# fraction of the output's scale (`scales`). The 1D initialization is solved
# to round-off; the FE one to the Newton tolerance 1e-10 (src/fe/newton.rs),
# which differences at the FMU's step magnify to ~1e-7. Measured worst
# (2026-12-03): 3.1e-8 1D (d stiffness / d L0, HillActuator1D), 6.8e-8 FE
# (d force / d area, HillPassiveFE); the FMU's differences without their
# Richardson step fail here (HillMuscle1D: 2.1e-6 at d force / d lambda_opt).
TOL = {"1d": 1e-7, "fe": 1e-6}
# Small mesh for the FE FMUs (where the mesh is a parameter): cheap inits.
FE_MESH = {"n_axial": 6, "n_radial": 1}


class Fmu:
    """An FMU extracted once; instances are set up in initialization mode."""

    def __init__(self, fmu_id: str):
        from fmpy import extract, read_model_description

        path = REPO / "dist" / f"{fmu_id}.fmu"
        if not path.is_file():
            pytest.fail(f"{path} not found: build the FMUs first with `scripts/build_fmus.sh`",
                        pytrace=False)
        self.id = fmu_id
        self.md = read_model_description(str(path))
        self.dir = extract(str(path))
        self.var = {v.name: v for v in self.md.modelVariables}
        self.outputs = [v for v in self.md.modelVariables
                        if v.causality == "output" and v.type == "Real"]
        self.params = [v for v in self.md.modelVariables
                       if v.causality == "parameter" and v.type == "Real"]
        self.deps = {u.variable.name: {d.name for d in (u.dependencies or [])}
                     for u in self.md.initialUnknowns}
        self.kind = "fe" if fmu_id.endswith("FE") else "1d"
        self.setup = {}
        if "initial_activation" in self.var and fmu_id not in FIXED_MESH_FE:
            self.setup["initial_activation"] = 0.5
        for name, value in FE_MESH.items():
            if name in self.var:
                self.setup[name] = value
        self.inputs = {}
        if "length" in self.var:
            # 10 % past the length's start: L0 for a muscle, the rest path
            # (tendon slack length + L0 cos alpha0) for a musculotendon unit,
            # whose tendon would otherwise be slack and carry nothing.
            self.inputs["length"] = 1.1 * float(self.var["length"].start)
        if "activation" in self.var:
            self.inputs["activation"] = 0.5

    def initializing(self, overrides=None):
        """An instance in initialization mode with the setup, `overrides` and
        the inputs set."""
        from fmpy.fmi2 import FMU2Slave

        s = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                      modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=self.id)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        values = {**self.setup, **(overrides or {}), **self.inputs}
        for k, v in values.items():
            var = self.var[k]
            if var.type == "Integer":
                s.setInteger([var.valueReference], [int(v)])
            else:
                s.setReal([var.valueReference], [float(v)])
        return s

    def initial_outputs(self, overrides=None):
        s = self.initializing(overrides)
        try:
            return np.array(s.getReal([v.valueReference for v in self.outputs]))
        finally:
            s.freeInstance()

    def fmu_column(self, param, overrides=None):
        """The FMU's d outputs / d param in initialization mode (one call)."""
        s = self.initializing(overrides)
        try:
            d = s.getDirectionalDerivative([v.valueReference for v in self.outputs],
                                           [self.var[param].valueReference], [1.0])
            return np.array(d)
        finally:
            s.freeInstance()

    def reference_column(self, param, p):
        """(derivative, perturbed initial values) by this test's differences,
        one order more accurate than the FMU's: central differences D(h) at
        h = 2 eps, eps, eps/2 (eps = EPS relative), extrapolated twice
        (Richardson: h^2 then h^4 terms removed, sixth order) where p +- 2 eps
        is inside the declared range, else the one-sided second-order formula
        at the same h (h^2 then h^3 removed, fourth order)."""
        v = self.var[param]
        lo = -np.inf if v.min is None else float(v.min)
        hi = np.inf if v.max is None else float(v.max)
        e = EPS * (abs(p) if p != 0 else 1.0)
        at = lambda x: self.initial_outputs({param: x})
        hs = (2 * e, e, e / 2)
        if lo <= p - 2 * e and p + 2 * e <= hi:
            f = {k: at(p + k * e) for k in (-2, -1, -0.5, 0.5, 1, 2)}
            d = [(f[h / e] - f[-h / e]) / (2 * h) for h in hs]
            r = [(4 * d[1] - d[0]) / 3, (4 * d[2] - d[1]) / 3]
            return (16 * r[1] - r[0]) / 15, f
        s = 1.0 if hi - p >= p - lo else -1.0
        f = {k: at(p + s * k * e) for k in (0, 0.5, 1, 2, 4)}
        d = [s * (-3 * f[0] + 4 * f[h / e] - f[2 * h / e]) / (2 * h) for h in hs]
        r = [(4 * d[1] - d[0]) / 3, (4 * d[2] - d[1]) / 3]
        return (8 * r[1] - r[0]) / 7, f

    def close(self):
        shutil.rmtree(self.dir, ignore_errors=True)


def real_parameters(fmu_id: str) -> list[str]:
    """The Real parameters of `fmu_id` by its committed modelDescription, so
    that each is a test case of its own (the built FMU's are the same:
    `test_the_cases_are_the_built_fmus_parameters`)."""
    root = ET.parse(REPO / "modelDescription" / f"{fmu_id}.xml").getroot()
    return [v.get("name") for v in root.iter("ScalarVariable")
            if v.get("causality") == "parameter" and v.find("Real") is not None]


def checked_parameters(fmu_id: str) -> list[str]:
    """The parameters differentiated by: all, or D alone on a fixed mesh."""
    return [n for n in real_parameters(fmu_id) if fmu_id not in FIXED_MESH_FE or n == "D"]


@pytest.mark.parametrize("fmu_id", SCENES)
def test_the_cases_are_the_built_fmus_parameters(fmu_id):
    f = Fmu(fmu_id)
    try:
        assert [v.name for v in f.params] == real_parameters(fmu_id)
    finally:
        f.close()


@pytest.fixture(scope="module")
def opened():
    """`opened(fmu_id)`: the FMU extracted once per module (and test worker),
    with its initial outputs and their scales."""
    cache = {}

    def get(fmu_id):
        if fmu_id not in cache:
            f = Fmu(fmu_id)
            f.y = f.initial_outputs()
            f.scale = scales(f, f.y)
            cache[fmu_id] = f
        return cache[fmu_id]

    yield get
    for f in cache.values():
        f.close()


def scales(fmu, y):
    """Per output, the scale its errors are measured against: the largest
    |value| among the initial outputs of the same unit (stresses against the
    largest stress, ...), at least 1 for dimensionless ones (angles too)."""
    unit = [v.declaredType.unit if v.declaredType else v.unit for v in fmu.outputs]
    out = []
    for u in unit:
        same = [abs(y[i]) for i in range(len(y)) if unit[i] == u]
        out.append(max(max(same), 1.0 if u in (None, "1", "", "rad") else 0.0))
    return np.array(out)


@pytest.mark.parametrize("fmu_id,name", [(s, n) for s in SCENES for n in checked_parameters(s)])
def test_every_real_parameter_is_a_known_with_the_declared_structure(opened, fmu_id, name):
    fmu = opened(fmu_id)
    y, scale = fmu.y, fmu.scale
    param = fmu.var[name]
    assert param.causality == "parameter" and param.type == "Real", name
    p = float(fmu.setup.get(name, param.start))
    analytic = fmu.fmu_column(name)
    ref, perturbed = fmu.reference_column(name, p)
    worst = (0.0, None)
    for j, out in enumerate(fmu.outputs):
        if name in fmu.deps[out.name]:
            err = abs(p if p != 0 else 1.0) * abs(analytic[j] - ref[j]) / scale[j]
            assert err < TOL[fmu.kind], (
                f"d({out.name})/d({name}) at {name} = {p}: FMU {analytic[j]!r}, "
                f"reference {ref[j]!r}, error {err:.2e} of scale {scale[j]:.3g}")
            if err > worst[0]:
                worst = (err, f"d({out.name})/d({name})")
        else:
            for x, values in perturbed.items():
                assert values[j] == y[j], (
                    f"{out.name} moves with {name} (at {p} {x:+} steps), but its "
                    f"InitialUnknowns entry does not name {name}")
            assert analytic[j] == 0.0, (out.name, name, analytic[j])
    print(f"{fmu.id}: worst {worst[0]:.2e} ({worst[1]})")


@pytest.mark.parametrize("fmu_id", [s for s in SCENES if declares(s, "initial_activation")
                                    and s not in FIXED_MESH_FE])
@pytest.mark.parametrize("a0", [0.0, 0.5, 1.0])
def test_activation_level_moves_one_for_one_with_initial_activation(fmu_id, a0):
    """At a0 = 0 and 1 (the bounds of initial_activation) the FMU's stencil
    is one-sided: force still agrees with the reference, activation_level's
    derivative is 1."""
    fmu = Fmu(fmu_id)
    try:
        names = [v.name for v in fmu.outputs]
        d = fmu.fmu_column("initial_activation", {"initial_activation": a0})
        if "activation_level" in names:
            assert d[names.index("activation_level")] == pytest.approx(1.0, rel=1e-10)
        ref, _ = fmu.reference_column("initial_activation", a0)
        i = names.index("force")
        assert d[i] > 0, d[i]
        assert abs(d[i] - ref[i]) / max(abs(d[i]), abs(ref[i])) < TOL[fmu.kind], (a0, d[i], ref[i])
    finally:
        fmu.close()


def test_force_over_area_is_stress_in_1d():
    f = Fmu("HillMuscle1D")
    try:
        names = [v.name for v in f.outputs]
        y = f.initial_outputs()
        d = f.fmu_column("area")
        assert d[names.index("force")] == pytest.approx(y[names.index("stress")], rel=1e-10)
        assert d[names.index("stress")] == 0.0
    finally:
        f.close()


def test_parameters_are_knowns_only_in_initialization_mode():
    """After fmi2ExitInitializationMode the knowns are the inputs: a parameter
    is refused with fmi2Error and a message naming the rule."""
    from fmpy.fmi1 import FMICallException

    from elongation import logger_callbacks, release_logger

    f = Fmu("HillMuscle1D")
    log = []
    callbacks, key = logger_callbacks(log)
    s = None
    try:
        from fmpy.fmi2 import FMU2Slave

        s = FMU2Slave(guid=f.md.guid, unzipDirectory=f.dir,
                      modelIdentifier=f.md.coSimulation.modelIdentifier, instanceName="after")
        s.instantiate(callbacks=callbacks)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        with pytest.raises(FMICallException):
            s.getDirectionalDerivative([f.var["force"].valueReference],
                                       [f.var["sigma0"].valueReference], [1.0])
        assert any(status == 3 and "'sigma0'" in message
                   and "Real parameters only in initialization mode" in message
                   for status, _, message in log), log
    finally:
        if s is not None:
            s.freeInstance()
        release_logger(key)
        f.close()
