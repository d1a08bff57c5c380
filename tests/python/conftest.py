"""Shared fixtures of the Python suite: the built FMU and helpers to drive it.

Nothing is skipped: if dist/HillMuscle1D.fmu is missing every test fails with
a message saying how to build it. ``HILL_MUSCLE_FMU`` may point at another
build of the same FMU.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "examples"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

FMU_PATH = Path(os.environ.get("HILL_MUSCLE_FMU", REPO / "dist" / "HillMuscle1D.fmu"))


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    """Path of the built HillMuscle1D.fmu; fails (not skips) when it is missing."""
    if not FMU_PATH.is_file():
        pytest.fail(
            f"{FMU_PATH} not found: build the FMUs first with `scripts/build_fmus.sh` "
            "(or run everything with `scripts/test.sh`)",
            pytrace=False,
        )
    return FMU_PATH


@pytest.fixture(scope="session")
def loaded(fmu_path):
    """The FMU extracted once, with its model description and value references."""
    from elongation import load_fmu

    return load_fmu(fmu_path)


@pytest.fixture(scope="session")
def vr(loaded):
    """Variable name -> value reference."""
    return loaded.vr


@pytest.fixture
def muscle(fmu_path):
    """Factory of initialized muscles (freed after the test):
    ``muscle(params=None, length=L0, activation=0.0, log=None, logging_on=False)``."""
    from elongation import L0, Muscle

    made = []

    def make(params=None, length=L0, activation=0.0, log=None, logging_on=False, initialize=True):
        m = Muscle(fmu_path, params, log=log, logging_on=logging_on, name=f"muscle{len(made)}")
        made.append(m)
        if initialize:
            m.initialize(length=length, activation=activation)
        return m

    yield make
    for m in made:
        m.free()
