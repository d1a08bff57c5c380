"""examples/bench_arm.py: its loops do the same work (checked here on a short
run; the timings themselves are in BENCHMARKS.md)."""

from __future__ import annotations

import numpy as np

import bench_arm as ba  # noqa: E402  (conftest puts examples/ on sys.path)


def test_ctypes_master_is_bitwise_fmpy(fmu_path):
    """The coupled run through the FMU's C ABI called with ctypes (no
    importer library) is bit for bit the run through fmpy: same calls, same
    values; and the muscle really moves the arm."""
    n = 300
    a = ba.coupled_trace(n, fmu_path, "fmpy")
    b = ba.coupled_trace(n, fmu_path, "ctypes")
    assert np.array_equal(a, b)
    assert np.degrees(np.ptp(a[:, 2])) > 20.0  # the elbow flexes
    assert np.ptp(a[:, 1]) > 50.0  # the force changes


def test_rollout_under_the_force_trace_reproduces_the_motion(fmu_path):
    """MuJoCo alone (rollout) under the coupled run's force trace ends where
    the coupled run ends: the MuJoCo share of the split is the same motion."""
    n = 300
    a = ba.coupled_trace(n, fmu_path, "ctypes")
    _, angle = ba.loop_mujoco_rollout(n, ba.command(n), a[:, 1])
    assert angle == a[-1, 2]


def test_builtin_muscle_moves_the_arm():
    """MuJoCo's own muscle under the same command flexes the elbow (it does
    real work in the comparison)."""
    lo, hi = ba.builtin_angles(1000, ba.command(1000))
    assert np.degrees(hi - lo) > 20.0
