"""Threads (issue 4 §3): the real FMUs from several threads, through fmpy.

ctypes releases the GIL around every FMI call, so the instances below really
step at the same time. FMI 2.0 lets an importer call different instances from
different threads, and one instance from any thread as long as its calls do
not overlap (libcosim creates instances on one thread and steps them on a
worker pool). The FMUs keep no global mutable state, so:

* 8 instances stepping in parallel give bit-identical results to the same
  runs done one after the other (each instance its own parameters and
  inputs, so a mix-up between instances would show);
* an instance created on one thread, stepped on a second and finished on a
  third gives bit-identical results to a run on one thread.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

import pytest
from elongation import L0, Muscle

REPO = Path(__file__).resolve().parents[2]
H = 1e-3

# Per-FMU: extra parameters (a small FE mesh keeps the FE runs short; the
# threads see the same code paths as on the default mesh) and steps per run.
CASES = {
    "HillMuscle1D": ({}, 400),
    "HillMuscleFE": ({"n_axial": 4, "n_radial": 1}, 40),
}


def fmu(name):
    path = REPO / "dist" / f"{name}.fmu"
    assert path.is_file(), f"{path} missing: run scripts/build_fmus.sh"
    return path


def inputs(k, n):
    """Instance k's inputs at step n: its own activation level and stretch."""
    activation = 0.2 + 0.1 * (k % 8) if n > 5 else 0.0
    length = L0 * (1.0 + 0.002 * (1 + k) * math.sin(40.0 * n * H) + 0.0005 * k)
    return length, activation


def params(name, k):
    extra, _ = CASES[name]
    return {**extra, "sigma0": 3.0e5 + 1.0e4 * k}


def run(name, k, n_steps, muscle=None, start=0, stop=None):
    """Steps start .. stop of instance k's run; returns the outputs per step."""
    m = muscle or Muscle(fmu(name), params(name, k), name=f"{name}-{k}").initialize(
        length=inputs(k, 0)[0], activation=0.0)
    out = []
    for n in range(start, n_steps if stop is None else stop):
        length, activation = inputs(k, n + 1)
        m.step(H, length=length, activation=activation)
        out.append(tuple(m.output_vector()))
    if muscle is None:
        m.free()
    return out


def in_threads(target, jobs):
    results, errors = {}, []

    def work(key, args):
        try:
            results[key] = target(*args)
        except BaseException as e:  # reported in the main thread
            errors.append((key, e))

    threads = [threading.Thread(target=work, args=(key, args)) for key, args in jobs.items()]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    return results


@pytest.mark.parametrize("name", list(CASES))
def test_parallel_instances_match_sequential_runs_bitwise(name):
    n_instances = 8
    n_steps = CASES[name][1]
    sequential = {k: run(name, k, n_steps) for k in range(n_instances)}
    parallel = in_threads(run, {k: (name, k, n_steps) for k in range(n_instances)})
    for k in range(n_instances):
        assert parallel[k] == sequential[k], f"instance {k} differs when run in parallel"
    # The instances did differ from one another (the comparison is not vacuous).
    assert len({sequential[k][-1] for k in range(n_instances)}) == n_instances


@pytest.mark.parametrize("name", list(CASES))
def test_instance_moves_between_threads(name):
    k, n_steps = 3, CASES[name][1]
    reference = run(name, k, n_steps)

    made = in_threads(lambda: Muscle(fmu(name), params(name, k), name="moved").initialize(
        length=inputs(k, 0)[0], activation=0.0), {"m": ()})["m"]
    half = n_steps // 2
    first = in_threads(run, {"a": (name, k, n_steps, made, 0, half)})["a"]
    second = in_threads(run, {"b": (name, k, n_steps, made, half, n_steps)})["b"]
    made.free()
    assert first + second == reference
