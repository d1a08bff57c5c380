"""The initial length when the importer does not set the `length` input.

If `length` is never set, the muscle starts at its rest length: the
parameter L0 (whatever it is set to), not the input's start value 0.05 m. If
`length` is set, that value is used. Run through fmpy's simulate_fmu, the
way an importer that only sets parameters would run it.
"""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu

OUTPUTS = ["stress", "passive_stress", "fibre_stretch", "force"]
T_END = 0.01
H = 1e-3


def run(fmu_path, start_values, length=None):
    """simulate_fmu with the given start values; `length` (if not None) is a
    constant input signal, otherwise the input is never set (activation is
    not set either: it keeps its start value 0)."""
    signals = None
    if length is not None:
        signals = np.array([(0.0, length), (T_END, length)], dtype=[("time", np.float64), ("length", np.float64)])
    return simulate_fmu(str(fmu_path), start_time=0.0, stop_time=T_END, output_interval=H,
                        start_values=start_values, input=signals, output=OUTPUTS)


def test_unset_length_starts_at_L0(fmu_path):
    """L0 = 0.1 m and no length input: the muscle is at rest from t = 0 (not
    squeezed to the input's start value 0.05 m, half of L0): |stress| < 1 Pa
    and fibre_stretch = 1 to 1e-6, at t = 0 and over the following steps."""
    result = run(fmu_path, {"L0": 0.1})
    assert result["time"][0] == 0.0
    assert abs(result["stress"][0]) < 1.0, result["stress"][0]
    assert result["fibre_stretch"][0] == pytest.approx(1.0, abs=1e-6)
    assert np.all(np.abs(result["stress"]) < 1.0), result["stress"]
    assert np.allclose(result["fibre_stretch"], 1.0, rtol=0, atol=1e-6), result["fibre_stretch"]


def test_set_length_is_used_with_non_default_L0(fmu_path):
    """L0 = 0.1 m with length set to 0.11 m (10 % strain) gives the same
    passive (engineering) stress and fibre stretch as the default L0 = 0.05 m
    at 10 % strain (0.055 m), to 1e-9 relative, at t = 0 and after the steps:
    the set length is used, and the law depends on the stretch only."""
    scaled = run(fmu_path, {"L0": 0.1}, length=0.11)
    default = run(fmu_path, {}, length=0.055)
    assert scaled["stress"][0] > 1e3  # clearly stretched, not at rest
    for name in ("stress", "passive_stress", "fibre_stretch"):
        np.testing.assert_allclose(scaled[name], default[name], rtol=1e-9, atol=0, err_msg=name)
    # force scales with the area only, which is the same here
    np.testing.assert_allclose(scaled["force"], default["force"], rtol=1e-9, atol=0)
