"""Communication-step convergence through fmpy's simulate_fmu.

The FMU's convention (MODEL_NOTES "Co-simulation conventions"): the input set
before doStep(t, h) holds over the step and the muscle ends the step at that
input length, so the outputs at t + h are those of L(t): a one-step lag, error
O(h). With set_input_derivatives=True fmpy also sets dL/dt and the step ends at
L(t) + h dL/dt = L(t + h) + O(h^2).

How fmpy computes the derivative (fmpy.simulation.Input.interpolate): the slope
of the piecewise-linear input table on the segment that contains t; at a
sample time exactly it takes the segment to the LEFT (a backward difference of
the table). The length signal is therefore given on a fine table (1e-5 s), so
that this slope is the true derivative to O(1e-5), well below the O(h) terms
measured here.

The test uses the passive muscle (activation 0) on a smooth length signal: the
CE carries nothing, so the stress is a function of the current length and the
only error is the input convention — a clean measure of it. (With the CE
active the backward-Euler CE-SEE update adds its own O(h) error: the same
signal with u = 1 measured errors 310e3, 182e3, 92e3, 44e3 Pa without and
310e3, 176e3, 87e3, 41e3 Pa with input derivatives, both first order. That is
the integrator's order, not the input convention, and is not asserted here.)

fmpy 0.3.32's simulate_fmu(set_input_derivatives=True) cannot run with this
FMU as it is (its Input sizes the derivative buffer for 9 inputs); the runs
with derivatives go through examples/fmpy_input_derivatives.py, which fixes
that for the duration of the call.
"""

from __future__ import annotations

import numpy as np
import pytest

import elongation as el
from fmpy_input_derivatives import simulate_with_input_derivatives

PERIOD = 1.0
T_END = 0.8
STEPS = (4e-2, 2e-2, 1e-2, 5e-3)
H_REF = 1e-4
COMMON = np.arange(1, int(round(T_END / STEPS[0])) + 1) * STEPS[0]  # 0.04, 0.08, ..., 0.8


def length_signal(t):
    """L0 (1 + 0.1 (1 - cos(2 pi t / PERIOD))): 0 -> 20 % strain and back, smooth."""
    return el.L0 * (1.0 + 0.1 * (1.0 - np.cos(2.0 * np.pi * t / PERIOD)))


def input_table(activation=0.0, dt=1e-5):
    t = np.linspace(0.0, T_END, int(round(T_END / dt)) + 1)
    signals = np.zeros(t.size, dtype=[("time", np.float64), ("activation", np.float64), ("length", np.float64)])
    signals["time"] = t
    signals["activation"] = activation
    signals["length"] = length_signal(t)
    return signals


def stress_at_common_times(fmu_path, h, derivatives, signals, output="stress"):
    from fmpy import simulate_fmu

    # fmpy 0.3.32 cannot set input derivatives on this FMU without the fix in
    # examples/fmpy_input_derivatives.py.
    simulate = simulate_with_input_derivatives if derivatives else simulate_fmu
    result = simulate(
        str(fmu_path), start_time=0.0, stop_time=T_END, output_interval=h, input=signals, output=[output],
    )
    t = result["time"]
    idx = [int(np.argmin(abs(t - tc))) for tc in COMMON]
    assert np.allclose(t[idx], COMMON, rtol=0, atol=1e-9)
    return result[output][idx]


def errors_and_orders(fmu_path, derivatives, signals):
    """Max error over the common times, per step, against a run at H_REF with
    input derivatives (whose own error is O(H_REF^2)); the observed orders
    between successive steps and the least-squares slope of log e vs log h."""
    ref = stress_at_common_times(fmu_path, H_REF, True, signals)
    errors = np.array([np.max(abs(stress_at_common_times(fmu_path, h, derivatives, signals) - ref))
                       for h in STEPS])
    h = np.array(STEPS)
    pairwise = np.log(errors[:-1] / errors[1:]) / np.log(h[:-1] / h[1:])
    slope = np.polyfit(np.log(h), np.log(errors), 1)[0]
    return errors, pairwise, slope, np.max(abs(ref))


@pytest.fixture(scope="module")
def passive_signals():
    return input_table(activation=0.0)


@pytest.fixture(scope="module")
def lagged(fmu_path, passive_signals):
    return errors_and_orders(fmu_path, False, passive_signals)


@pytest.fixture(scope="module")
def with_derivatives(fmu_path, passive_signals):
    return errors_and_orders(fmu_path, True, passive_signals)


def test_first_order_without_input_derivatives(lagged):
    """Without input derivatives the error is first order in h (the one-step
    lag): observed order ~ 1.
    Measured (max over t = 0.04 .. 0.8 s, stress up to 218 kPa): errors
    40.0e3, 20.3e3, 10.2e3, 5.07e3 Pa at h = 4e-2 .. 5e-3; pairwise orders
    0.978, 0.997, 1.001; least-squares slope 0.993."""
    errors, pairwise, slope, scale = lagged
    print("without derivatives: errors", errors, "orders", pairwise, "slope", slope, "scale", scale)
    assert np.all((pairwise > 0.8) & (pairwise < 1.2)), pairwise
    assert 0.9 < slope < 1.1, slope


def test_second_order_with_input_derivatives(lagged, with_derivatives):
    """With fmpy's set_input_derivatives=True the lag is gone: the error is
    second order in h and far smaller than without derivatives at the same h.
    Measured: errors 13.5e3, 3.27e3, 811, 202 Pa at h = 4e-2 .. 5e-3;
    pairwise orders 2.039, 2.013, 2.004; slope 2.018."""
    errors, pairwise, slope, scale = with_derivatives
    print("with derivatives: errors", errors, "orders", pairwise, "slope", slope, "scale", scale)
    assert np.all(pairwise > 1.8), pairwise
    assert slope > 1.9, slope
    # The gain grows like 1/h: ~3x at h = 4e-2 (the passive law is very
    # nonlinear, b = 23.46), 12x at 1e-2, 25x at 5e-3.
    gain = lagged[0] / errors
    assert np.all(np.diff(gain) > 0), gain
    assert np.all(gain[np.array(STEPS) <= 1e-2] > 10), gain
