"""examples/fmpy_input_derivatives.py: simulate_fmu(set_input_derivatives=True)
with fmpy 0.3.32, and that the fix does not outlive the call."""

from __future__ import annotations

import fmpy
import fmpy.simulation
import numpy as np
import pytest
from fmpy import simulate_fmu

from fmpy_input_derivatives import FMPY_INPUT, fixed_fmpy_input, simulate_with_input_derivatives

DTYPE = [("time", np.float64), ("activation", np.float64), ("length", np.float64)]
# Passive ramp from 0.05 m to 0.055 m (10 % strain) over 0.1 s, steps of 0.01 s.
RAMP = np.array([(0.0, 0.0, 0.05), (0.1, 0.0, 0.055)], dtype=DTYPE)
KWARGS = dict(start_time=0.0, stop_time=0.1, output_interval=0.01, input=RAMP, output=["stress"])


def assert_unpatched():
    assert fmpy.simulation.Input is FMPY_INPUT
    assert (FMPY_INPUT.__module__, FMPY_INPUT.__qualname__) == ("fmpy.simulation", "Input")


def test_helper_sets_input_derivatives_and_restores_fmpy(fmu_path):
    """The helper runs, and the derivatives really reach the FMU: the passive
    muscle ends the ramp at 0.055 m (stress at t = 0.1 equals a run held at
    0.055 m, to 1e-9 relative), while plain simulate_fmu lags one step (ends
    at L(0.09) = 0.0545 m, a clearly lower stress). Afterwards
    fmpy.simulation.Input is fmpy's own class again (and, with fmpy 0.3.32,
    plain simulate_fmu(set_input_derivatives=True) still fails the way the
    module describes)."""
    assert_unpatched()
    with_derivatives = simulate_with_input_derivatives(fmu_path, **KWARGS)
    assert_unpatched()
    lagged = simulate_fmu(str(fmu_path), **KWARGS)
    held = simulate_fmu(str(fmu_path), start_time=0.0, stop_time=0.01, output_interval=0.01,
                        input=np.array([(0.0, 0.0, 0.055)], dtype=DTYPE), output=["stress"])
    assert with_derivatives["time"][-1] == pytest.approx(0.1)
    assert with_derivatives["stress"][-1] == pytest.approx(held["stress"][-1], rel=1e-9)
    assert lagged["stress"][-1] < 0.9 * with_derivatives["stress"][-1]
    if fmpy.__version__ == "0.3.32":
        with pytest.raises(ValueError, match="same size"):
            simulate_fmu(str(fmu_path), set_input_derivatives=True, **KWARGS)
    assert_unpatched()


def test_fmpy_input_restored_after_an_error(fmu_path):
    """fmpy.simulation.Input is restored when the simulation raises (here: the
    step_finished callback) and when the with-block of fixed_fmpy_input
    raises."""

    def fail(time, recorder):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        simulate_with_input_derivatives(fmu_path, step_finished=fail, **KWARGS)
    assert_unpatched()
    with pytest.raises(KeyError):
        with fixed_fmpy_input() as patched:
            assert fmpy.simulation.Input is patched is not FMPY_INPUT
            raise KeyError("inside")
    assert_unpatched()


def test_helper_refuses_set_input_derivatives_argument(fmu_path):
    """set_input_derivatives is the helper's job: passing it is a TypeError
    (and nothing is patched)."""
    with pytest.raises(TypeError):
        simulate_with_input_derivatives(fmu_path, set_input_derivatives=False, **KWARGS)
    assert_unpatched()
