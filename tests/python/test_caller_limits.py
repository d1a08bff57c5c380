"""What a caller sends cannot make the FMUs report something no legal input
gives: the activation command stays in [0, 1] over a whole step, whatever
its input derivative, on both FMUs (the FE muscle on a small 4 x 1 mesh, the
same code path as the default mesh).
"""

from __future__ import annotations

import math

import pytest
from conftest import FMU_PATH, REPO

FE_SMALL = {"n_axial": 4, "n_radial": 1}
S = 50.0  # the activation rate constant's default [1/s]


@pytest.fixture(params=["HillMuscle1D", "HillMuscleFE"])
def muscle(request):
    """Factory of initialized muscles of each full FMU (freed after the test)."""
    from elongation import L0, Muscle

    path = FMU_PATH if request.param == "HillMuscle1D" else REPO / "dist" / "HillMuscleFE.fmu"
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs with scripts/build_fmus.sh", pytrace=False)
    extra = FE_SMALL if request.param == "HillMuscleFE" else {}
    made = []

    def make(activation=0.0, params=None):
        m = Muscle(path, {**extra, **(params or {})}, name=f"muscle{len(made)}")
        made.append(m)
        m.initialize(length=L0, activation=activation)
        return m

    yield make
    for m in made:
        m.free()


@pytest.mark.parametrize("command, rate, a0", [(1.0, 1000.0, 0.0), (0.0, -1000.0, 0.6)])
def test_an_input_derivative_cannot_push_the_command_out_of_the_unit_interval(muscle, command, rate, a0):
    """A command at a bound with a derivative pushing it outward gives the
    same step as the command held at the bound (the exact level
    command + (a0 - command) e^(-S h)); before, the unclamped line drove the
    level to 1 (or 0) with fmi2OK."""
    h = 0.01
    params = {"initial_activation": a0}
    pushed, held = muscle(activation=command, params=params), muscle(activation=command, params=params)
    pushed.step(h, activation=command, dactivation=rate)
    held.step(h, activation=command)
    want = command + (a0 - command) * math.exp(-S * h)
    (level,) = pushed.get("activation_level")
    assert level == pytest.approx(want, rel=1e-12, abs=1e-15)
    for name in ("activation_level", "force", "stress"):
        (a,), (b,) = pushed.get(name), held.get(name)
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12), name
