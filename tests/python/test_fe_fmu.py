"""HillMuscleFE through fmpy: validation, the paper's experiments, FMU state,
directional derivatives and bad input (issue 3, verification item 6).

The FE step costs milliseconds, so these runs use 10 ms communication steps
(the passive pull is 200 steps, the activated one 250).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from elongation import L0, Muscle, activated_elongation, passive_elongation, stress_at_strains

REPO = Path(__file__).resolve().parents[2]
FE = REPO / "dist" / "HillMuscleFE.fmu"
ONE_D = REPO / "dist" / "HillMuscle1D.fmu"
H = 1e-2


@pytest.fixture(scope="module")
def fe_path():
    if not FE.is_file():
        pytest.fail(f"{FE} not found: build the FMUs with scripts/build_fmus.sh", pytrace=False)
    return FE


def test_validate_fmu_is_clean(fe_path):
    assert validate_fmu(str(fe_path)) == []


@pytest.fixture(scope="module")
def passive(fe_path):
    return passive_elongation(str(fe_path), step=H)


@pytest.fixture(scope="module")
def activated(fe_path):
    return activated_elongation(str(fe_path), step=H)


def test_passive_elongation_stiffens_monotonically(passive):
    t, length, out = passive
    stress = out["stress"]
    assert np.all(np.isfinite(stress))
    assert abs(stress[0]) < 1.0  # at rest: no load (Pa)
    # The first step holds L0 (inputs lag one step): round-off there.
    assert np.all(np.abs(stress[:2]) < 1.0)
    assert np.all(np.diff(stress[1:]) > 0), "the passive pull stiffens monotonically"
    # Convex (exponential matrix and quadratic PE): the slope grows.
    s10, s20 = stress_at_strains(length, stress, [0.1, 0.2])
    assert s20 > 2.5 * s10


def test_activated_elongation_is_above_passive(passive, activated):
    _, lp, op = passive
    _, la, oa = activated
    sp = stress_at_strains(lp, op["stress"], [0.05, 0.1, 0.2])
    sa = stress_at_strains(la, oa["stress"], [0.05, 0.1, 0.2])
    assert np.all(np.asarray(sa) > np.asarray(sp) + 2e5)
    # Activation level rises as 1 - exp(-S t) with S = 50 /s.
    t = np.asarray(activated[0])
    i = np.searchsorted(t, 0.1)
    assert oa["activation_level"][i] == pytest.approx(1 - np.exp(-50 * t[i]), rel=1e-9)


def _default_pull(fe_path):
    """simulate_fmu on the passive pull to 20 % strain with the FE diagnostics."""
    sig = np.array([(0.0, 0.0, L0), (2.0, 0.0, 1.2 * L0)],
                   dtype=[("time", float), ("activation", float), ("length", float)])
    return simulate_fmu(str(fe_path), stop_time=2.0, output_interval=H, input=sig,
                        output=["force", "volume_ratio_min", "volume_ratio_max",
                                "max_fibre_stretch", "newton_iterations"])


def test_simulate_fmu_runs_with_the_fe_diagnostics(fe_path):
    """The diagnostics at 20 % strain, D = 1e-9: a pulled specimen, volume ratios
    bracketing 1 within 2e-3 (the largest sits at the clamped faces' rims; the
    interior bound of 1e-3 and the rim singularity are tested in
    tests/fe_verification.rs), the thin ends stretched beyond the mean, a few Newton
    corrections per step."""
    last = _default_pull(fe_path)[-1]
    assert last["force"] > 10.0
    assert 1 - 2e-3 < last["volume_ratio_min"] <= 1 <= last["volume_ratio_max"] < 1 + 2e-3
    assert last["max_fibre_stretch"] > 1.2  # the thin ends stretch more than the mean
    assert 1 <= last["newton_iterations"] <= 10


@pytest.mark.xfail(strict=True, reason=(
    "issue 3 item 3 holds away from the end faces' rims only: at 20 % strain the largest element "
    "volume ratio (mean of its nodal J) is 1.00186 on the default mesh, in the layer at a clamped "
    "face's rim, where a clamped face meets the free surface and the nearly incompressible pressure "
    "is singular, p ~ r^-0.45 (it grows under refinement: 1.00088, 1.00186, 1.00226, 1.00370, "
    "1.00507 on 12x2, 16x3, 24x4, 36x6, 48x8 graded like the default; tests/fe_verification.rs, "
    "docs/fe.md)"))
def test_volume_ratio_is_within_1e3_in_every_element(fe_path):
    """The pointwise claim of issue 3 item 3, including the rim elements."""
    last = _default_pull(fe_path)[-1]
    assert abs(last["volume_ratio_min"] - 1) < 1e-3
    assert abs(last["volume_ratio_max"] - 1) < 1e-3


def run_steps(m, n, start, rate):
    for i in range(n):
        m.step(H, length=start + rate * (i + 1) * H, activation=1.0)


def test_fmu_state_restores_exactly(fe_path):
    with Muscle(str(fe_path)) as m:
        m.initialize()
        run_steps(m, 10, L0, 0.01)
        state = m.slave.getFMUstate()
        t = m.time
        run_steps(m, 5, L0 + 0.1 * 0.01, 0.01)
        first = m.output_vector()
        m.slave.setFMUstate(state)
        m.time, m.start_time, m.n_steps = t, t, 0
        run_steps(m, 5, L0 + 0.1 * 0.01, 0.01)
        assert m.output_vector() == first
        # Serialized and restored into a fresh instance.
        blob = m.slave.serializeFMUstate(state)
        with Muscle(str(fe_path)) as other:
            other.initialize()
            s2 = other.slave.deSerializeFMUstate(blob)
            other.slave.setFMUstate(s2)
            other.time, other.start_time, other.n_steps = t, t, 0
            run_steps(other, 5, L0 + 0.1 * 0.01, 0.01)
            assert other.output_vector() == first


def test_directional_derivatives_match_finite_differences(fe_path):
    with Muscle(str(fe_path)) as m:
        m.initialize()
        run_steps(m, 20, L0, 0.01)
        t = m.time
        state = m.slave.getFMUstate()
        L = L0 + 0.21 * 0.01
        vr_f, vr_l, vr_a = m.vr["force"], m.vr["length"], m.vr["activation"]

        def force(length, act):
            m.slave.setFMUstate(state)
            m.slave.setReal([vr_l, vr_a], [length, act])
            m.slave.doStep(t, H)
            return m.slave.getReal([vr_f])[0]

        f0 = force(L, 0.6)
        dl = m.slave.getDirectionalDerivative([vr_f], [vr_l], [1.0])[0]
        da = m.slave.getDirectionalDerivative([vr_f], [vr_a], [1.0])[0]
        el, ea = 1e-7, 1e-5
        fd_l = (force(L + el, 0.6) - force(L - el, 0.6)) / (2 * el)
        fd_a = (force(L, 0.6 + ea) - force(L, 0.6 - ea)) / (2 * ea)
        assert f0 > 0
        assert dl == pytest.approx(fd_l, rel=1e-5)
        assert da == pytest.approx(fd_a, rel=1e-5)


def test_bad_input_is_refused_and_names_the_variable(fe_path):
    log = []
    with Muscle(str(fe_path), log=log) as m:
        with pytest.raises(Exception):
            m.set_parameter("n_axial", 0)
        assert any("n_axial" in e[2] and "[1, 96]" in e[2] for e in log), log
        m.initialize()
        with pytest.raises(Exception):
            m.slave.setReal([m.vr["length"]], [float("nan")])
        run_steps(m, 2, L0, 0.01)  # the instance still works
        assert np.isfinite(m.output_vector()).all()
