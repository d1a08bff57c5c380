"""The paper's experiments end to end through fmpy (examples/elongation.py),
and the parameter sensitivities the paper reports for passive elongation."""

from __future__ import annotations

import numpy as np
import pytest

import elongation as el


@pytest.fixture(scope="module")
def passive(fmu_path):
    return el.passive_elongation(fmu_path, step=1e-3)


@pytest.fixture(scope="module")
def activated(fmu_path):
    return el.activated_elongation(fmu_path, step=1e-3)


def test_passive_stress_zero_at_rest(passive):
    """At the rest length with no activation the initial equilibrium carries
    no stress (|P| < 1 Pa) and no force."""
    t, L, o = passive
    assert t[0] == 0.0 and L[0] == el.L0
    assert abs(o["stress"][0]) < 1.0
    assert abs(o["force"][0]) < 1.0 * 2.5e-4  # area ~ 2.4e-4 m^2
    assert o["activation_level"][0] == 0.0


def test_passive_run_reaches_twenty_percent(passive):
    """The run is complete: it ends at 20 % strain, every output is finite."""
    t, L, o = passive
    assert L[-1] == pytest.approx(1.2 * el.L0, rel=1e-12)
    for name, values in o.items():
        assert np.all(np.isfinite(values)), name


def test_passive_stress_positive_and_increasing(passive):
    """Passive stress is positive once stretched and increases strictly with
    the strain; without activation it is all passive (active_stress 0,
    activation level 0). (Without input derivatives the first step ends at
    the input set at t = 0, i.e. still at L0: the one-step lag; from there on
    the strain grows every step.)"""
    t, L, o = passive
    strain = L / el.L0 - 1
    assert strain[1] == 0.0 and abs(o["stress"][1]) < 1.0
    assert np.all(np.diff(strain[1:]) > 0)
    assert np.all(o["stress"][2:] > 0)
    assert np.all(np.diff(o["stress"][1:]) > 0)
    assert np.all(o["activation_level"] == 0.0)
    assert np.all(o["active_stress"] == 0.0)
    np.testing.assert_allclose(o["passive_stress"], o["stress"], rtol=0, atol=1e-9)


def test_stress_is_force_over_area(passive, activated, loaded):
    """stress = force / area (engineering stress) at every point of both runs."""
    area = float(loaded.variables["area"].start)
    for t, L, o in (passive, activated):
        np.testing.assert_allclose(o["stress"], o["force"] / area, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(o["passive_stress"], o["stress"] - o["active_stress"], rtol=1e-12, atol=1e-6)


def test_activated_stress_is_sigma0_scale_after_hold(activated):
    """After 0.5 s of full activation at the rest length the stress is on the
    scale of sigma0 = 7e5 Pa (> 1e5 Pa) and mostly active; the muscle is still
    at the rest length then."""
    t, L, o = activated
    i = int(np.argmin(abs(t - el.HOLD)))
    assert t[i] == pytest.approx(el.HOLD, abs=1e-12)
    assert L[i] == el.L0
    assert o["stress"][i] > 1e5
    assert o["stress"][i] < 7e5 * 1.05
    assert o["active_stress"][i] > 0.9 * o["stress"][i]


def test_activation_level_follows_first_order_rise(activated):
    """With u = 1 from t = 0 and initial_activation 0 the activation level is
    1 - exp(-S t), S = 50 1/s, at every communication point (to 1e-9)."""
    t, L, o = activated
    expected = 1.0 - np.exp(-50.0 * t)
    assert np.max(abs(o["activation_level"] - expected)) < 1e-9


def test_activated_stress_above_passive(passive, activated):
    """During the pull the activated muscle carries more stress than the
    passive one at every tabulated strain, and the stresses are finite."""
    p = el.stress_at_strains(passive[1], passive[2]["stress"])
    a = el.stress_at_strains(activated[1], activated[2]["stress"])
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(a))
    assert np.all(a > p)
    assert np.all(np.diff(p) > 0)


def _passive_stress_at_20(fmu_path, **params):
    # Passive stress is a function of the length alone, and with input
    # derivatives the muscle follows the ramp exactly, so a coarse step is
    # enough to get the stress at exactly 20 % strain.
    t, L, o = el.passive_elongation(fmu_path, step=1e-2, params=params, input_derivatives=True)
    assert L[-1] == pytest.approx(1.2 * el.L0, rel=1e-12)
    return o["stress"][-1]


def test_stress_falls_as_compressibility_grows(fmu_path):
    """Paper Fig 11: passive stress at 20 % strain falls as D grows
    (1e-9 -> 1e-6 1/Pa), by a visible amount overall."""
    ds = [1e-9, 1e-8, 1e-7, 1e-6]
    stresses = [_passive_stress_at_20(fmu_path, D=d) for d in ds]
    assert np.all(np.diff(stresses) < 0), stresses
    assert stresses[-1] < 0.99 * stresses[0], stresses


def test_stress_rises_with_sigma0(fmu_path):
    """Passive stress at 20 % strain rises with sigma0 (the PE scales with
    sigma0), over the paper's range 0.16 - 1.0 MPa."""
    s0 = [0.16e6, 0.4e6, 0.7e6, 1.0e6]
    stresses = [_passive_stress_at_20(fmu_path, sigma0=s) for s in s0]
    assert np.all(np.diff(stresses) > 0), stresses
    assert stresses[-1] > 1.5 * stresses[0], stresses


def test_elongation_script_writes_table_and_plots(fmu_path, tmp_path):
    """`python examples/elongation.py --fmu F --out DIR` (as scripts/demo.sh
    runs it) prints the stress table at 5/10/15/20 % and writes both PNGs;
    running it twice gives the same table."""
    import subprocess
    import sys

    cmd = [sys.executable, str(el.REPO / "examples" / "elongation.py"), "--fmu", str(fmu_path),
           "--out", str(tmp_path / "out")]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    for pct in ("5%", "10%", "15%", "20%"):
        assert pct in first.stdout
    for png in ("stress_strain.png", "force_activation.png"):
        data = (tmp_path / "out" / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert second.returncode == 0, second.stderr
    table = [line for line in first.stdout.splitlines() if "%" in line]
    assert table == [line for line in second.stdout.splitlines() if "%" in line]
