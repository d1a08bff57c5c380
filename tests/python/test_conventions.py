"""The co-simulation conventions of MODEL_NOTES, one by one, through fmpy:
initial equilibrium, activation start level and dynamics switch, input
derivatives (end of step, held for one step only), variable step sizes."""

from __future__ import annotations

import math

import numpy as np
import pytest

import elongation as el

H = 1e-3


def test_initial_state_is_isometric_equilibrium(muscle):
    """Initialized fully activated (initial_activation = 1, u = 1) at L0, the
    muscle is in isometric equilibrium: stepping at the same length and
    command changes nothing (stress constant to 1e-12 relative over 50 steps)
    and the stress is sigma0 * f_lambda(1/lambda_opt)-scale."""
    m = muscle(params={"initial_activation": 1.0}, activation=1.0)
    s0 = m.outputs()
    assert s0["activation_level"] == 1.0
    assert 0.9 * 7e5 < s0["stress"] < 7e5
    for _ in range(50):
        m.step(H, length=el.L0, activation=1.0)
    s1 = m.outputs()
    for name in ("stress", "force", "see_stretch", "ce_stretch"):
        assert s1[name] == pytest.approx(s0[name], rel=1e-12, abs=1e-12), name


def test_activation_level_starts_at_initial_activation(muscle):
    """The activation level starts at initial_activation whatever the input,
    and follows a = u + (a0 - u) exp(-S t) for a held command."""
    m = muscle(params={"initial_activation": 0.3}, activation=1.0)
    assert m.outputs()["activation_level"] == 0.3
    for n in range(1, 101):
        m.step(H, length=el.L0, activation=1.0)
        expected = 1.0 - 0.7 * math.exp(-50.0 * n * H)
        assert abs(m.outputs()["activation_level"] - expected) < 1e-12


def test_activation_dynamics_off_uses_the_command(muscle):
    """With activation_dynamics = false the activation level is the command,
    at initialization and after every step."""
    m = muscle(params={"activation_dynamics": False}, activation=0.4)
    assert m.outputs()["activation_level"] == 0.4
    for u in (0.0, 0.7, 1.0, 0.25):
        m.step(H, length=el.L0, activation=u)
        assert m.outputs()["activation_level"] == u


def test_input_derivative_sets_end_of_step_and_holds_one_step(muscle):
    """With dL/dt set, the step ends at L + h dL/dt (same outputs, bit for
    bit, as an instance given that length directly); the derivative is
    forgotten after the step: the next step without a derivative ends at the
    input length on both instances."""
    a, b = muscle(activation=1.0), muscle(activation=1.0)
    for m in (a, b):
        for _ in range(100):
            m.step(H, length=el.L0, activation=1.0)
    L, dL = 0.0502, 0.3
    a.step(H, length=L, activation=1.0, dlength=dL, dactivation=0.0)
    b.step(H, length=L + H * dL, activation=1.0)
    assert a.output_vector() == b.output_vector()
    for m in (a, b):
        m.step(H, length=0.0504, activation=1.0)
    assert a.output_vector() == b.output_vector()


def test_input_derivative_removes_the_lag_on_a_ramp(fmu_path):
    """On the passive ramp with input derivatives the muscle is at L(t) at
    every communication point, so its stress at 20 % equals the stress of the
    lagged run one step later (the same length), to 1e-9 relative."""
    t1, L1, o1 = el.passive_elongation(fmu_path, step=1e-2, input_derivatives=True)
    t2, L2, o2 = el.passive_elongation(fmu_path, step=1e-2, input_derivatives=False)
    assert L1[-1] == pytest.approx(L2[-1], rel=1e-14)
    assert t2[-1] == pytest.approx(t1[-1] + 1e-2)
    assert o1["stress"][-1] == pytest.approx(o2["stress"][-1], rel=1e-9)


def test_variable_communication_step_sizes(muscle):
    """Steps of varying size (canHandleVariableCommunicationStepSize): the
    activation level is exact at the sum of the steps, and the passive
    stress at a length reached with uneven steps equals the one reached
    with even steps."""
    sizes = [1e-3, 5e-3, 2e-4, 1e-2, 3e-3, 7.5e-4]
    a = muscle(activation=1.0)
    t = 0.0
    for h in sizes:
        a.slave.setReal([a.vr["length"], a.vr["activation"]], [el.L0, 1.0])
        a.slave.doStep(t, h)
        t += h
        assert abs(a.outputs()["activation_level"] - (1 - math.exp(-50.0 * t))) < 1e-12

    p, q = muscle(), muscle()
    t = 0.0
    for i, h in enumerate(sizes):
        p.slave.setReal([p.vr["length"]], [el.L0 * (1 + 0.02 * (i + 1))])
        p.slave.doStep(t, h)
        t += h
    for i in range(len(sizes)):
        q.step(2e-3, length=el.L0 * (1 + 0.02 * (i + 1)))
    assert p.outputs()["stress"] == pytest.approx(q.outputs()["stress"], rel=1e-9)
    assert p.outputs()["stress"] > 0


@pytest.mark.parametrize("name, values", [("kc", (4.0, 5.0, 5.88)), ("d", (1.1, 1.5, 1.8))])
def test_activated_stress_rises_with_kc_and_d(fmu_path, name, values):
    """Paper section 3: in activated elongation the stress rises with k_c and
    with d (eccentric force-velocity shape and offset), over the paper's
    ranges, at every tabulated strain."""
    table = []
    for v in values:
        t, L, o = el.activated_elongation(fmu_path, step=2e-3, params={name: v})
        table.append(el.stress_at_strains(L, o["stress"]))
    table = np.array(table)
    assert np.all(np.diff(table, axis=0) > 0), table
