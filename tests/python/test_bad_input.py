"""Bad input is rejected and never changes the instance.

A rejected set returns fmi2Error (fmpy raises FMICallException with status 3),
logs a message naming the variable and its valid range, and leaves the
instance as it was: its outputs are unchanged and a later legal call behaves
as if the rejected one never happened (compared with a twin instance that
never saw the bad call). Each row of docs/reference/bad-input.md has a
test here, run on both FMUs (the FE muscle on a small 4 x 1 mesh: the
checks are the same code paths as on the default mesh, in a fraction of the
time).
"""

from __future__ import annotations

import math
import re
from ctypes import c_double, c_uint32

import pytest
from conftest import FMU_PATH, REPO
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Discard, fmi2Error, fmi2False, fmi2LastSuccessfulTime, fmi2OK, fmi2Warning

H = 1e-3
FE_SMALL = {"n_axial": 4, "n_radial": 1}


@pytest.fixture(params=["HillMuscle1D", "HillMuscleFE"])
def muscle(request):
    """conftest's factory of initialized muscles, for each FMU in turn."""
    from elongation import L0, Muscle

    path = FMU_PATH if request.param == "HillMuscle1D" else REPO / "dist" / "HillMuscleFE.fmu"
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs with scripts/build_fmus.sh", pytrace=False)
    extra = FE_SMALL if request.param == "HillMuscleFE" else {}
    made = []

    def make(params=None, length=L0, activation=0.0, log=None, logging_on=False, initialize=True):
        m = Muscle(path, {**extra, **(params or {})}, log=log, logging_on=logging_on,
                   name=f"muscle{len(made)}")
        made.append(m)
        if initialize:
            m.initialize(length=length, activation=activation)
        return m

    yield make
    for m in made:
        m.free()


def set_real_status(m, name, value):
    """fmi2SetReal of one variable; returns the fmi2Status (fmpy's setReal
    drops it, and raises for status > warning)."""
    vr = (c_uint32 * 1)(m.vr[name])
    val = (c_double * 1)(value)
    try:
        return m.slave.fmi2SetReal(m.slave.component, vr, 1, val)
    except FMICallException as e:
        return e.status


def drive(m, n, start=0):
    """n steps of an activated stretch (the same on every instance)."""
    for i in range(start, start + n):
        m.step(H, length=0.05 * (1 + 0.05 * math.sin(7.0 * i * H)), activation=0.8)


def twins(muscle, n=60):
    """Two instances with identical histories: the one under test and the
    reference that never sees the bad call."""
    a, b = muscle(log=[]), muscle()
    drive(a, n)
    drive(b, n)
    assert a.output_vector() == b.output_vector()
    return a, b


def messages(m, status=None):
    return [msg for st, _, msg in m.log if status is None or st == status]


def names_variable_and_range(msg, name):
    """The message names the variable (as a whole word) and states the valid
    range ("... must be ..." / "... [0, 1]")."""
    named = re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", msg)
    ranged = re.search(r"must be|range|\[0, 1\]", msg)
    return bool(named and ranged)


def names_word(msg, name):
    return re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", msg) is not None


def names_length_L0_and_stretch_range(msg):
    """The message names `length` and `L0` and states the valid range of the
    stretch length/L0 ("stretch ... range / must be / between ...")."""
    return bool(names_word(msg, "length") and names_word(msg, "L0")
                and re.search(r"stretch|length\s*/\s*L0", msg)
                and re.search(r"must be|range|between|[\[(]\s*[-+0-9.eE]+\s*,\s*[-+0-9.eE]+\s*[\])]", msg))


def assert_continues_like_twin(a, b, n=30, start=60):
    drive(a, n, start)
    drive(b, n, start)
    assert a.output_vector() == b.output_vector()
    assert a.get("length", "activation") == b.get("length", "activation")


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 0.0, -0.01, -0.0, 9e-6, 101.0, 1e10])
def test_bad_length_is_rejected_and_changes_nothing(muscle, bad):
    """length NaN / +-inf / 0 / negative / outside its declared [1e-5, 100] m:
    fmpy raises FMICallException with fmi2Error; the outputs and the input's
    value are unchanged; the error is logged naming `length` and its range;
    stepping on gives exactly what an instance that never saw the bad set
    gives."""
    a, b = twins(muscle)
    before = a.output_vector()
    length_before = a.get("length")
    with pytest.raises(FMICallException) as exc:
        a.slave.setReal([a.vr["length"]], [bad])
    assert exc.value.status == fmi2Error
    assert a.output_vector() == before
    assert a.get("length") == length_before
    assert any(names_variable_and_range(msg, "length") and "[1e-5, 100]" in msg
               for msg in messages(a, fmi2Error)), a.log
    assert_continues_like_twin(a, b)


def test_declared_length_range_is_the_one_enforced(muscle):
    """The modelDescription's min/max of `length` are what fmi2SetReal
    enforces: both bounds are accepted, the next doubles outside refused."""
    m = muscle()
    var = m.loaded.variables["length"]
    lo, hi = float(var.min), float(var.max)
    assert (lo, hi) == (1e-5, 100.0)
    for ok in (lo, hi):
        assert set_real_status(m, "length", ok) == fmi2OK
    for bad in (math.nextafter(lo, 0.0), math.nextafter(hi, math.inf)):
        assert set_real_status(m, "length", bad) == fmi2Error


def test_non_finite_directional_derivative_seed_is_rejected(muscle):
    """fmi2GetDirectionalDerivative with a NaN or infinite seed dvKnown:
    fmi2Error naming dvKnown; the instance continues like its twin, and a
    finite seed then gives the derivative."""
    a, b = twins(muscle)
    before = a.output_vector()
    for bad in (math.nan, math.inf):
        with pytest.raises(FMICallException) as exc:
            a.slave.getDirectionalDerivative([a.vr["force"]], [a.vr["length"]], [bad])
        assert exc.value.status == fmi2Error
        assert any("dvKnown[0]" in msg and "must be finite" in msg for msg in messages(a, fmi2Error)), a.log
    assert a.output_vector() == before
    (d,) = a.slave.getDirectionalDerivative([a.vr["force"]], [a.vr["length"]], [1.0])
    assert math.isfinite(d) and d > 0
    assert_continues_like_twin(a, b)


def test_bad_length_then_step_without_new_set(muscle):
    """After a rejected length the next doStep uses the last good length: the
    same step as the twin's with that length."""
    a, b = twins(muscle)
    last = a.get("length")[0]
    with pytest.raises(FMICallException):
        a.slave.setReal([a.vr["length"]], [math.nan])
    a.do_step(H)
    b.step(H, length=last)
    assert a.output_vector() == b.output_vector()


def test_nan_activation_is_rejected_and_changes_nothing(muscle):
    """activation NaN: fmi2Error, logged naming `activation`, no change;
    stepping on matches the twin."""
    a, b = twins(muscle)
    before = a.output_vector()
    u_before = a.get("activation")
    with pytest.raises(FMICallException) as exc:
        a.slave.setReal([a.vr["activation"]], [math.nan])
    assert exc.value.status == fmi2Error
    assert a.output_vector() == before
    assert a.get("activation") == u_before
    assert any(names_variable_and_range(msg, "activation") for msg in messages(a, fmi2Error)), a.log
    assert_continues_like_twin(a, b)


def test_rejected_pair_set_changes_nothing(muscle):
    """A setReal of (length, activation) with a bad length is rejected as a
    whole: the good activation in the same call does not slip through
    either (the instance stays in its state)."""
    a, b = twins(muscle)
    u_before = a.get("activation")
    with pytest.raises(FMICallException):
        a.slave.setReal([a.vr["activation"], a.vr["length"]], [0.1, math.nan])
    assert a.get("activation") == u_before
    assert_continues_like_twin(a, b)


# A length the law cannot evaluate: finite and positive (so the set itself is
# legal) but length/L0 far outside the physical range of the stretch.
UNEVALUABLE_LENGTHS = [5.0, 1e-4]  # with the default L0 = 0.05: stretch 100 and 0.002


@pytest.mark.parametrize("bad", UNEVALUABLE_LENGTHS)
def test_unevaluable_length_fails_exit_initialization(muscle, bad):
    """length = 5.0 m (or 1e-4 m) with L0 = 0.05 m set in initialization mode:
    fmi2ExitInitializationMode returns fmi2Error (fmpy raises) and logs a
    message naming `length` and `L0` with the valid stretch range. The
    instance stays in initialization mode: after setting length = 0.05 the
    exit succeeds, and the instance then has the outputs of, and steps
    exactly like, one initialized at 0.05 from the start."""
    a = muscle(log=[], initialize=False)
    a.slave.setupExperiment(startTime=0.0)
    a.slave.enterInitializationMode()
    a.slave.setReal([a.vr["length"], a.vr["activation"]], [bad, 0.0])  # legal: finite, positive
    with pytest.raises(FMICallException) as exc:
        a.slave.exitInitializationMode()
    assert exc.value.status == fmi2Error
    assert any(names_length_L0_and_stretch_range(msg) for msg in messages(a, fmi2Error)), a.log
    a.slave.setReal([a.vr["length"]], [0.05])
    a.slave.exitInitializationMode()  # raises if the instance had left initialization mode
    a.time = a.start_time = 0.0
    b = muscle(length=0.05)
    assert a.get("length") == [0.05]
    assert a.output_vector() == b.output_vector()
    drive(a, 30)
    drive(b, 30)
    assert a.output_vector() == b.output_vector()


@pytest.mark.parametrize("bad", UNEVALUABLE_LENGTHS)
def test_unevaluable_length_in_step_mode_discards_and_state_restores(muscle, bad):
    """In step mode (after 60 steps): setting length = 5.0 m (or 1e-4 m) is
    accepted (not an error), the following doStep returns fmi2Discard (fmpy
    raises with that status) and logs a message naming `length`. Restoring
    the FMU state saved before the set (setFMUstate) gives back the twin's
    outputs and inputs, and the instance then continues exactly like the
    twin that never saw the bad length."""
    a, b = twins(muscle)
    state = a.slave.getFMUstate()
    assert set_real_status(a, "length", bad) in (fmi2OK, fmi2Warning)
    n_log = len(a.log)
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(a.time, H, noSetFMUStatePriorToCurrentPoint=fmi2False)
    assert exc.value.status == fmi2Discard
    assert any(names_word(msg, "length") for _, _, msg in a.log[n_log:]), a.log
    assert a.slave.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(a.time, abs=1e-12)
    a.slave.setFMUstate(state)
    a.slave.freeFMUstate(state)
    assert a.output_vector() == b.output_vector()
    assert a.get("length", "activation") == b.get("length", "activation")
    assert_continues_like_twin(a, b)


def test_bad_input_derivative_is_rejected(muscle):
    """A non-finite input derivative is rejected (fmi2Error) and the next
    step is the twin's step without any derivative."""
    a, b = twins(muscle)
    with pytest.raises(FMICallException) as exc:
        a.slave.setRealInputDerivatives([a.vr["length"]], [1], [math.inf])
    assert exc.value.status == fmi2Error
    assert_continues_like_twin(a, b)


@pytest.mark.parametrize("value, clamped", [(1.5, 1.0), (-0.25, 0.0)])
def test_activation_outside_unit_interval_is_clamped_with_warning(muscle, value, clamped):
    """activation 1.5 (or -0.25): fmi2Warning with a log message, the command
    is clamped: the instance then behaves exactly like a twin given 1.0
    (or 0.0)."""
    a, b = twins(muscle)
    assert set_real_status(a, "activation", value) == fmi2Warning
    assert any(names_variable_and_range(msg, "activation") for msg in messages(a, fmi2Warning)), a.log
    assert a.get("activation") == [clamped]
    assert set_real_status(b, "activation", clamped) == fmi2OK
    for _ in range(20):
        a.do_step(H)
        b.do_step(H)
    assert a.output_vector() == b.output_vector()
    assert a.outputs()["stress"] == b.outputs()["stress"]


@pytest.mark.parametrize("name, value", [("D", -1.0), ("kc", 0.0), ("d", 0.5), ("lambda_dot_min", 1.0),
                                         ("sigma0", math.nan), ("L0", 0.0), ("area", -1.0),
                                         ("initial_activation", 1.5), ("substep_tolerance", 0.0),
                                         ("substep_tolerance", 2.0), ("substep_tolerance", math.nan)])
def test_bad_parameter_before_initialization(muscle, name, value):
    """An out-of-range parameter set after instantiation is rejected with
    fmi2Error and a log message naming it; the instance keeps the previous
    (default) value and initializes and steps exactly like an untouched
    instance."""
    a = muscle(log=[], initialize=False)
    with pytest.raises(FMICallException) as exc:
        a.slave.setReal([a.vr[name]], [value])
    assert exc.value.status == fmi2Error
    assert any(names_variable_and_range(msg, name) for msg in messages(a, fmi2Error)), a.log
    a.initialize()  # fmi2GetReal is not allowed before initialization mode
    b = muscle()
    assert a.get(name) == b.get(name)
    assert a.output_vector() == b.output_vector()
    drive(a, 20)
    drive(b, 20)
    assert a.output_vector() == b.output_vector()


@pytest.mark.parametrize("name, value", [("D", -1.0), ("kc", 0.0), ("d", 0.5), ("lambda_dot_min", 1.0)])
def test_bad_parameter_in_initialization_mode(muscle, name, value):
    """The same rejection in initialization mode; exitInitializationMode then
    succeeds with the previous (valid) value."""
    a = muscle(log=[], initialize=False)
    a.slave.setupExperiment(startTime=0.0)
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        a.slave.setReal([a.vr[name]], [value])
    assert exc.value.status == fmi2Error
    assert any(names_variable_and_range(msg, name) for msg in messages(a, fmi2Error)), a.log
    a.slave.exitInitializationMode()
    a.time = 0.0
    a.start_time = 0.0
    b = muscle()
    assert a.get(name) == b.get(name)
    drive(a, 10)
    drive(b, 10)
    assert a.output_vector() == b.output_vector()


@pytest.mark.parametrize("h", [0.0, -1e-3, math.nan])
def test_non_positive_step_is_rejected(muscle, h):
    """doStep with h <= 0 (or NaN) is an error; nothing changes and the
    instance continues like its twin."""
    a, b = twins(muscle)
    before = a.output_vector()
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(a.time, h)
    assert exc.value.status == fmi2Error
    assert a.output_vector() == before
    assert_continues_like_twin(a, b)


@pytest.mark.parametrize("offset", [0.5, -2 * H, 10 * H])
def test_mismatched_communication_point_is_rejected(muscle, offset):
    """doStep at a communication point that is not the current time is an
    error; nothing changes and the instance continues like its twin."""
    a, b = twins(muscle)
    before = a.output_vector()
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(a.time + offset, H)
    assert exc.value.status == fmi2Error
    assert a.output_vector() == before
    assert_continues_like_twin(a, b)


def test_outputs_cannot_be_set(muscle):
    """Setting an output is refused (fmi2Error) and changes nothing."""
    a, b = twins(muscle)
    with pytest.raises(FMICallException):
        a.slave.setReal([a.vr["force"]], [1.0])
    assert a.output_vector() == b.output_vector()
    assert_continues_like_twin(a, b)


def test_fixed_parameter_cannot_be_set_after_initialization(muscle):
    """Parameters are fixed: a set after initialization is refused and has
    no effect on the continuation."""
    a, b = twins(muscle)
    with pytest.raises(FMICallException):
        a.slave.setReal([a.vr["sigma0"]], [1.0e6])
    assert a.get("sigma0") == b.get("sigma0")
    assert_continues_like_twin(a, b)



def test_activation_warning_every_time_logged_once(muscle):
    """An out-of-range activation is a warning at every set, but the log
    gets one message per instance (a master setting 1.2 at 1 kHz is not
    flooded)."""
    a = muscle(log=[])
    for _ in range(3):
        assert set_real_status(a, "activation", 1.2) == fmi2Warning
        a.do_step(H)
    assert len(messages(a, fmi2Warning)) == 1, a.log


def test_contractile_element_of_non_positive_length_discards(muscle):
    """k = 10: the CE length (1 + k) lambda_f - k lambda_s reaches 0 when the
    fibre shortens below about k / (1 + k) = 0.91. Shortening the activated
    muscle to 0.8 L0 in one step is refused with fmi2Discard and a message
    naming the bound; the instance is as before the step: same outputs as
    its twin, and (after fmi2SetFMUstate, the way out of FMI's stepFailed
    state) it continues like the twin."""
    params = {"k": 10.0}
    a = muscle(params=params, log=[], activation=1.0)
    b = muscle(params=params, activation=1.0)
    for m in (a, b):
        for _ in range(20):
            m.step(H, activation=1.0)
    state = a.slave.getFMUstate()
    assert set_real_status(a, "length", 0.8 * 0.05) == fmi2OK
    n_log = len(a.log)
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(a.time, H)
    assert exc.value.status == fmi2Discard
    assert any("non-positive length" in msg and "contractile element" in msg
               for _, _, msg in a.log[n_log:]), a.log
    assert a.slave.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(a.time, abs=1e-12)
    assert a.output_vector() == b.output_vector()
    a.slave.setFMUstate(state)
    a.slave.freeFMUstate(state)
    for m in (a, b):
        for _ in range(10):
            m.step(H, length=0.05, activation=1.0)
    assert a.output_vector() == b.output_vector()


def test_call_not_allowed_in_the_current_state(muscle):
    """doStep and getReal before initialization, exitInitializationMode
    without enterInitializationMode: fmi2Error with a message naming the
    function; the instance then initializes and runs like an untouched one."""
    a = muscle(log=[], initialize=False)
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(0.0, H)
    assert exc.value.status == fmi2Error
    with pytest.raises(FMICallException):
        a.slave.getReal([a.vr["force"]])
    with pytest.raises(FMICallException):
        a.slave.exitInitializationMode()
    for fn in ("fmi2DoStep", "fmi2GetReal", "fmi2ExitInitializationMode"):
        assert any(fn in msg for msg in messages(a, fmi2Error)), (fn, a.log)
    a.initialize()
    b = muscle()
    drive(a, 20)
    drive(b, 20)
    assert a.output_vector() == b.output_vector()


def test_unknown_value_reference_is_rejected(muscle):
    """Set and get of a value reference that does not exist: fmi2Error, the
    message names the reference; nothing changes."""
    a, b = twins(muscle)
    with pytest.raises(FMICallException) as exc:
        a.slave.setReal([a.vr["length"], 99999], [0.051, 1.0])
    assert exc.value.status == fmi2Error
    with pytest.raises(FMICallException):
        a.slave.getReal([99999])
    assert any("99999" in msg for msg in messages(a, fmi2Error)), a.log
    assert a.get("length") == b.get("length")
    assert_continues_like_twin(a, b)


def test_null_pointers_are_rejected(muscle):
    """NULL value-reference or value arrays (n > 0) and a NULL instance:
    fmi2Error, no crash, nothing changes."""
    a, b = twins(muscle)
    for call in (lambda: a.slave.fmi2SetReal(a.slave.component, None, 1, None),
                 lambda: a.slave.fmi2GetReal(a.slave.component, None, 1, None),
                 lambda: a.slave.fmi2GetFMUstate(a.slave.component, None)):
        with pytest.raises(FMICallException) as exc:
            call()
        assert exc.value.status == fmi2Error
    assert messages(a, fmi2Error), a.log
    with pytest.raises(FMICallException) as exc:
        a.slave.fmi2DoStep(None, a.time, H, fmi2False)
    assert exc.value.status == fmi2Error
    assert_continues_like_twin(a, b)


def test_step_past_the_stop_time_is_rejected(muscle):
    """With stopTime = 10 ms, the 10 steps up to it succeed and the 11th is
    an error naming the stop time; the instance keeps its outputs."""
    a = muscle(log=[], initialize=False)
    a.initialize(stop_time=10 * H)
    drive(a, 10)
    before = a.output_vector()
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(a.time, H)
    assert exc.value.status == fmi2Error
    assert any("stop" in msg.lower() for msg in messages(a, fmi2Error)), a.log
    assert a.output_vector() == before


@pytest.mark.parametrize("args, name", [
    (dict(tolerance=float("nan")), "tolerance"),
    (dict(tolerance=-1e-6), "tolerance"),
    (dict(startTime=float("inf")), "startTime"),
    (dict(stopTime=-1.0), "stopTime"),
])
def test_bad_setup_experiment_is_rejected(muscle, args, name):
    """fmi2SetupExperiment with a non-finite start time, a stop time before
    the start, or a defined tolerance that is not finite and >= 0: fmi2Error
    naming the argument; the instance then initializes and runs like an
    untouched one."""
    a = muscle(log=[], initialize=False)
    call = {"tolerance": None, "startTime": 0.0, "stopTime": None, **args}
    with pytest.raises(FMICallException) as exc:
        a.slave.setupExperiment(**call)
    assert exc.value.status == fmi2Error
    assert any(name in msg for msg in messages(a, fmi2Error)), a.log
    a.initialize()
    b = muscle()
    drive(a, 20)
    drive(b, 20)
    assert a.output_vector() == b.output_vector()


def test_step_to_an_infinite_time_is_rejected(muscle):
    """A step whose end time overflows (t = 1e308, h = 1e308): fmi2Error
    naming it; the instance keeps its outputs and its time."""
    a = muscle(log=[], initialize=False)
    a.initialize(start_time=1e308)
    before = a.output_vector()
    with pytest.raises(FMICallException) as exc:
        a.slave.doStep(1e308, 1e308)
    assert exc.value.status == fmi2Error
    assert any("not a finite time" in msg for msg in messages(a, fmi2Error)), a.log
    assert a.output_vector() == before
