"""The FMU's packaging and model description, as fmpy reads them."""

from __future__ import annotations

import pytest

PARAMETERS = {
    # name: (unit, default)
    "b": ("1", 23.46),
    "c": ("Pa", 379.0),
    "alpha": ("1", 10.0),
    "beta": ("Pa", 1.0e3),
    "A": ("1", 4.0),
    "sigma0": ("Pa", 7.0e5),
    "S": ("1/s", 50.0),
    "kc": ("1", 5.0),
    "ke": ("1", 5.0),
    "d": ("1", 1.5),
    "lambda_dot_min": ("1/s", -17.0),
    "lambda_opt": ("1", 1.05),
    "D": ("1/Pa", 1.0e-9),
    "k": ("1", 0.3),
    "L0": ("m", 0.05),
    # The mean cross-section V0/L0 of the fusiform specimen (src/specimen.rs):
    # r(x) = r_e + (r_m - r_e) sin(pi x / L), V0 = pi [r_e^2 L + 2 r_e d (2L/pi) + d^2 L/2].
    "area": ("m2", 3.141592653589793 * (0.0045**2 * 0.05 + 2 * 0.0045 * 0.00425 * (2 * 0.05 / 3.141592653589793) + 0.00425**2 * 0.05 / 2) / 0.05),
    "initial_activation": ("1", 0.0),
}
INPUTS = {"activation": ("1", 0.0), "length": ("m", 0.05)}
OUTPUTS = {
    "force": "N",
    "stress": "Pa",
    "cauchy_stress": "Pa",
    "activation_level": "1",
    "fibre_stretch": "1",
    "ce_stretch": "1",
    "see_stretch": "1",
    "active_stress": "Pa",
    "passive_stress": "Pa",
}
# ModelStructure/InitialUnknowns: what each output depends on at initialization
# (the isometric equilibrium). The rate parameters S, kc, ke, d, lambda_dot_min
# do not affect the isometric start.
_FORCE_DEPENDENCIES = {"activation", "length", "b", "c", "alpha", "beta", "A", "sigma0", "lambda_opt", "D",
                       "k", "L0", "area", "activation_dynamics", "initial_activation"}
INITIAL_DEPENDENCIES = {name: _FORCE_DEPENDENCIES - {"area"} for name in OUTPUTS}
INITIAL_DEPENDENCIES["force"] = _FORCE_DEPENDENCIES
INITIAL_DEPENDENCIES["activation_level"] = {"activation", "activation_dynamics", "initial_activation"}
# Units whose dimension is fixed by physics (fmpy reads BaseUnit exponents).
UNIT_DIMENSIONS = {"m": {"m": 1}, "N": {"kg": 1, "m": 1, "s": -2}, "Pa": {"kg": 1, "m": -1, "s": -2},
                   "1/s": {"s": -1}, "1/Pa": {"kg": -1, "m": 1, "s": 2}, "m2": {"m": 2}}


def test_validate_fmu_reports_no_problems(fmu_path):
    """fmpy's validator (XML schema, variable names, model structure, start
    values, causality/variability combinations, units) finds nothing."""
    from fmpy.validation import validate_fmu

    problems = validate_fmu(str(fmu_path))
    assert problems == []


def test_co_simulation_capabilities(loaded):
    """The capability flags the co-simulation conventions rely on."""
    md = loaded.model_description
    assert md.fmiVersion == "2.0"
    assert md.modelExchange is None
    cs = md.coSimulation
    assert cs is not None and cs.modelIdentifier == "HillMuscle1D"
    assert cs.canHandleVariableCommunicationStepSize
    assert cs.canGetAndSetFMUstate
    assert cs.canSerializeFMUstate
    assert cs.providesDirectionalDerivative
    assert cs.canInterpolateInputs
    assert cs.maxOutputDerivativeOrder == 0


@pytest.mark.parametrize("name", sorted(PARAMETERS))
def test_parameters(loaded, name):
    """Each law/geometry parameter: Real, causality parameter, fixed
    variability, its unit and the paper's Table 2 default as start value."""
    unit, default = PARAMETERS[name]
    v = loaded.variables[name]
    assert (v.type, v.causality, v.variability) == ("Real", "parameter", "fixed")
    assert v.unit == unit
    assert float(v.start) == pytest.approx(default, rel=1e-15)


def test_activation_dynamics_switch(loaded):
    """The activation-dynamics switch is a fixed Boolean parameter, on by default."""
    v = loaded.variables["activation_dynamics"]
    assert (v.type, v.causality, v.variability) == ("Boolean", "parameter", "fixed")
    assert v.start in (True, "true", "1", 1)


@pytest.mark.parametrize("name", sorted(INPUTS))
def test_inputs(loaded, name):
    """The two continuous Real inputs with their units and start values."""
    unit, start = INPUTS[name]
    v = loaded.variables[name]
    assert (v.type, v.causality, v.variability) == ("Real", "input", "continuous")
    assert v.unit == unit
    assert float(v.start) == start


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_outputs(loaded, name):
    """The nine continuous Real outputs and their units."""
    v = loaded.variables[name]
    assert (v.type, v.causality, v.variability) == ("Real", "output", "continuous")
    assert v.unit == OUTPUTS[name]


def dependency_names(unknown):
    """Names of an Unknown's dependencies; None when the attribute is absent
    (which in FMI 2.0 means "depends on everything", not "on nothing")."""
    if unknown.dependencies is None:
        return None
    return sorted(d.name for d in unknown.dependencies)


def test_model_structure_outputs_list_each_output_once(loaded):
    """ModelStructure/Outputs lists exactly the nine outputs, once each, in
    the order of the model variables (FMI 2.0 requires that order)."""
    md = loaded.model_description
    names = [u.variable.name for u in md.outputs]
    assert sorted(names) == sorted(OUTPUTS)
    order = [v.name for v in md.modelVariables if v.causality == "output"]
    assert names == order


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_outputs_have_no_direct_feedthrough(loaded, name):
    """Each output's Outputs/Unknown carries dependencies="" (present and
    empty): an input set at a communication point changes no output until
    the next doStep. An absent attribute would mean the opposite (depends on
    everything), so it must be there."""
    unknowns = {u.variable.name: u for u in loaded.model_description.outputs}
    assert name in unknowns
    deps = dependency_names(unknowns[name])
    assert deps is not None, f"{name}: dependencies attribute absent in <Outputs>"
    assert deps == []
    assert not unknowns[name].dependenciesKind  # absent or empty with no dependencies


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_initial_unknowns_dependencies(loaded, name):
    """InitialUnknowns lists every output with exactly what it depends on at
    initialization (the isometric equilibrium): the passive/active law and
    geometry parameters and both inputs, but not the rate parameters (S, kc,
    ke, d, lambda_dot_min), which do not affect the isometric start; only
    `force` depends on `area`; `activation_level` only on the activation."""
    md = loaded.model_description
    unknowns = {u.variable.name: u for u in md.initialUnknowns}
    assert sorted(unknowns) == sorted(OUTPUTS)
    deps = dependency_names(unknowns[name])
    assert deps is not None, f"{name}: dependencies attribute absent in <InitialUnknowns>"
    assert deps == sorted(INITIAL_DEPENDENCIES[name])
    assert len(deps) == len(unknowns[name].dependencies)  # no duplicates


def test_no_unexpected_variables(loaded):
    """Exactly the documented interface: no extra inputs or outputs."""
    md = loaded.model_description
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    assert inputs == set(INPUTS)
    assert outputs == set(OUTPUTS)


def test_unit_definitions(loaded):
    """Unit definitions carry the SI base-unit exponents of their names."""
    units = {u.name: u for u in loaded.model_description.unitDefinitions}
    for name, dims in UNIT_DIMENSIONS.items():
        assert name in units, name
        bu = units[name].baseUnit
        assert bu is not None, name
        got = {k: getattr(bu, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad") if getattr(bu, k)}
        assert got == dims, name
