"""fmi2GetDirectionalDerivative against finite differences of the step map.

The FMU's directional derivatives are the partials of the outputs after a step
with respect to the inputs set before that step (history fixed). The finite
difference repeats that step from a saved FMU state with one input perturbed
by +-delta (central difference), restoring the state in between.
"""

from __future__ import annotations

import numpy as np
import pytest

from elongation import OUTPUT_NAMES

H = 1e-3


def prepare(muscle, n_ramp=150):
    """An activated muscle being stretched (lengthening branch of f_v, away
    from the f_v kink at zero CE rate and the f_lambda kinks): u = 1 for
    0.2 s at L0, then a ramp at 20 mm/s."""
    m = muscle()
    for _ in range(200):
        m.step(H, length=0.05, activation=1.0)
    for i in range(n_ramp):
        m.step(H, length=0.05 + 0.02 * (i + 1) * H, activation=1.0)
    return m


def step_from(m, state, t, length, activation):
    """Outputs after one step from the saved state with the given inputs."""
    m.slave.setFMUstate(state)
    m.slave.setReal([m.vr["length"], m.vr["activation"]], [length, activation])
    m.slave.doStep(t, H)
    return np.array(m.output_vector())


def derivatives_and_fd(muscle, u_nominal):
    """(analytic, central FD) d outputs / d length and / d activation for the
    step taken with activation command u_nominal at the next ramp length."""
    m = prepare(muscle)
    t = m.time
    L = 0.05 + 0.02 * (m.n_steps - 200 + 1) * H
    state = m.slave.getFMUstate()
    base = step_from(m, state, t, L, u_nominal)
    out_vrs = [m.vr[n] for n in OUTPUT_NAMES]
    analytic = {
        "length": np.array(m.slave.getDirectionalDerivative(out_vrs, [m.vr["length"]], [1.0])),
        "activation": np.array(m.slave.getDirectionalDerivative(out_vrs, [m.vr["activation"]], [1.0])),
    }
    # Steps chosen by a sweep (1e-10 .. 1e-5 m, 1e-8 .. 1e-3): the central
    # difference is best at 1e-7 m (~2e-6 relative: ~2e-8 error in dF/dL) and
    # at 1e-3 in the command (~3e-8 error in dF/du; the force moves by only
    # ~1.7 N per unit command over one step, da/du = 1 - exp(-S h) = 0.049, so
    # smaller steps drown in the solver's round-off).
    deltas = {"length": 1e-7, "activation": 1e-3}
    fd = {}
    for name, delta in deltas.items():
        plus = step_from(m, state, t, L + delta if name == "length" else L,
                         u_nominal + delta if name == "activation" else u_nominal)
        minus = step_from(m, state, t, L - delta if name == "length" else L,
                          u_nominal - delta if name == "activation" else u_nominal)
        fd[name] = (plus - minus) / (2 * delta)
    m.slave.freeFMUstate(state)
    return base, analytic, fd


@pytest.fixture(scope="module")
def measured(fmu_path):
    """Derivatives at u = 0.5 (inside (0, 1), so no clamping and da/du > 0)."""
    from elongation import Muscle

    made = []

    def make():
        m = Muscle(fmu_path, name=f"dd{len(made)}")
        made.append(m)
        return m.initialize()

    try:
        yield derivatives_and_fd(make, 0.5)
    finally:
        for m in made:
            m.free()


def rel_err(a, b):
    return abs(a - b) / max(abs(a), abs(b))


def test_dforce_dlength_matches_finite_difference(measured):
    """d force / d length of the step map agrees with a central finite
    difference to 1e-5 relative. Measured: 149701.5114 (analytic) vs
    149701.5084 N/m (FD), 2.0e-8 relative."""
    base, analytic, fd = measured
    i = OUTPUT_NAMES.index("force")
    print("dF/dL analytic", analytic["length"][i], "fd", fd["length"][i])
    assert analytic["length"][i] > 0
    assert rel_err(analytic["length"][i], fd["length"][i]) < 1e-5


def test_dforce_dactivation_matches_finite_difference(measured):
    """d force / d activation command of the step map (through the activation
    dynamics, da/du = 1 - exp(-S h)) agrees with a central finite difference
    to 1e-5 relative. Measured: 1.74033621 vs 1.74033626 N, 2.8e-8 relative."""
    base, analytic, fd = measured
    i = OUTPUT_NAMES.index("force")
    print("dF/du analytic", analytic["activation"][i], "fd", fd["activation"][i])
    assert analytic["activation"][i] > 0
    assert rel_err(analytic["activation"][i], fd["activation"][i]) < 1e-5


@pytest.mark.parametrize("wrt", ["length", "activation"])
def test_all_output_derivatives_match_finite_difference(measured, wrt):
    """Every output's derivative w.r.t. each input agrees with the finite
    difference to 1e-5 of its scale: the larger of |analytic| and |fd|, and
    for passive_stress (= stress - active_stress, a difference of two large
    numbers whose derivatives nearly cancel w.r.t. the command) the scale of
    d stress. An output that does not depend on an input (activation_level on
    the length) must give exactly 0 in both.
    Measured worst: 7.5e-8 (ce_stretch) w.r.t. the length, 5.1e-8
    (fibre_stretch) w.r.t. the command."""
    base, analytic, fd = measured
    a, f = analytic[wrt], fd[wrt]
    stress = OUTPUT_NAMES.index("stress")
    rel = {}
    for j, name in enumerate(OUTPUT_NAMES):
        scale = max(abs(a[j]), abs(f[j]))
        if name == "passive_stress":
            scale = max(scale, abs(a[stress]))
        rel[name] = 0.0 if scale == 0.0 else abs(a[j] - f[j]) / scale
    print({k: f"{v:.1e}" for k, v in rel.items()})
    bad = {k: (v, a[OUTPUT_NAMES.index(k)], f[OUTPUT_NAMES.index(k)]) for k, v in rel.items() if v > 1e-5}
    assert not bad, bad
    if wrt == "length":
        j = OUTPUT_NAMES.index("activation_level")
        assert a[j] == 0.0 and f[j] == 0.0


def test_activation_level_derivative_is_exact(measured):
    """d activation_level / d command over one step is 1 - exp(-S h) with
    S = 50 (exact activation update), and 0 with respect to the length."""
    base, analytic, fd = measured
    i = OUTPUT_NAMES.index("activation_level")
    assert analytic["activation"][i] == pytest.approx(1 - np.exp(-50 * H), rel=1e-12)
    assert analytic["length"][i] == 0.0
