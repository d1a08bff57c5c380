#!/usr/bin/env python3
"""The paper's passive and activated elongation of a 5 cm muscle through fmpy.

Runs the ``HillMuscle1D`` FMU (FMI 2.0 Co-Simulation) — and beside it
``HillMuscleFE`` when ``dist/HillMuscleFE.fmu`` exists (``--fe-fmu ''``
skips it) — with fmpy's ``FMU2Slave`` in a plain master loop, prints the
engineering stress at 5, 10, 15 and 20 % strain for both experiments and both
variants and writes plots (both variants on the same axes) into an output
directory::

    python examples/elongation.py --out out
    python examples/elongation.py --fmu dist/HillMuscle1D.fmu --out out

Experiments (Lu et al. 2011, section 3; MODEL_NOTES "Experiments"):

* passive: activation command 0, pulled from the rest length L0 = 0.05 m at
  5 mm/s to 20 % strain (L = L0 + 0.005 t, t = 0 .. 2 s);
* activated: held at L0 with the command u = 1 from t = 0 for 0.5 s, then
  pulled at 5 mm/s to 20 % strain (t = 0.5 .. 2.5 s), command held at 1.

Co-simulation convention of the FMU: inputs set before ``doStep(t, h)`` hold
over the step and the muscle moves from its length to the input length during
the step. A master that sets the input L(t) therefore lags the protocol by one
step; with ``input_derivatives=True`` the loop also sets dL/dt (the slope of
the protocol over the coming step) and the step ends at L(t) + h dL/dt =
L(t + h), which removes the lag. Without derivatives the loop takes one extra
step at the end so that the muscle reaches the final length.

The functions are importable (the Python tests and the benchmark reuse them):
``open_muscle`` gives an initialized instance, ``run_protocol`` drives it with
piecewise-linear input signals, ``passive_elongation`` and
``activated_elongation`` run the two experiments and return
``(time, length, outputs)``.
"""

from __future__ import annotations

import argparse
import atexit
import os
import shutil
import sys
from ctypes import byref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEFAULT_FMU = REPO / "dist" / "HillMuscle1D.fmu"
DEFAULT_FE_FMU = REPO / "dist" / "HillMuscleFE.fmu"

L0 = 0.05
"""Rest length of the paper's specimen [m] (the FMU's default ``L0``)."""
SPEED = 0.005
"""Pulling speed [m/s]."""
MAX_STRAIN = 0.20
"""Final engineering strain of both experiments."""
HOLD = 0.5
"""Isometric activation phase of the activated experiment [s]."""
TABLE_STRAINS = (0.05, 0.10, 0.15, 0.20)

OUTPUT_NAMES = (
    "force",
    "stress",
    "cauchy_stress",
    "activation_level",
    "fibre_stretch",
    "ce_stretch",
    "see_stretch",
    "active_stress",
    "passive_stress",
)
INPUT_NAMES = ("activation", "length")


# --------------------------------------------------------------------------
# Loading and instantiating the FMU
# --------------------------------------------------------------------------

@dataclass
class LoadedFmu:
    """An FMU extracted once per process, with its model description."""

    path: Path
    unzipdir: str
    model_description: object
    vr: dict

    @property
    def variables(self):
        return {v.name: v for v in self.model_description.modelVariables}


_LOADED: dict = {}


def _cleanup_extracted():
    for loaded in _LOADED.values():
        shutil.rmtree(loaded.unzipdir, ignore_errors=True)
    _LOADED.clear()


atexit.register(_cleanup_extracted)


def load_fmu(fmu) -> LoadedFmu:
    """Read the model description and extract the FMU (cached per path)."""
    from fmpy import extract, read_model_description

    path = Path(fmu).resolve()
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist; build it with scripts/build_fmus.sh")
    key = (str(path), path.stat().st_mtime_ns)
    if key not in _LOADED:
        md = read_model_description(str(path))
        unzipdir = extract(str(path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        _LOADED[key] = LoadedFmu(path, unzipdir, md, vr)
    return _LOADED[key]


# fmpy's native logger proxy (fmpy.logging.addLoggerProxy) formats the FMU's
# printf-style message and forwards it to ONE process-wide Python function (the
# last one registered). So every instance here registers the same dispatcher
# and tells its messages apart by the componentEnvironment pointer, which the
# FMU passes back unchanged: a per-instance key into _LOG_SINKS.
_LOG_SINKS: dict = {}
_NEXT_LOG_KEY = [1]


def _dispatch_log(env, instance_name, status, category, message):
    entry = (int(status), (category or b"").decode("utf-8", "replace"),
             (message or b"").decode("utf-8", "replace"))
    sink = _LOG_SINKS.get(env or 0)
    if sink is not None:
        sink.append(entry)
    else:  # an instance that is not ours (e.g. fmpy's default callbacks)
        label = ["OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"][entry[0]] if 0 <= entry[0] < 6 else "?"
        print(f"[{label}] {entry[2]}")


_DISPATCH_C = None


def logger_callbacks(sink):
    """fmi2CallbackFunctions whose logger appends ``(status, category,
    message)`` tuples (str) to the list ``sink``; returns ``(callbacks, key)``
    (``key`` unregisters the sink in ``release_logger``).

    Keep the returned callbacks alive as long as the instance (fmpy's
    ``instantiate`` stores them on the instance).
    """
    from ctypes import c_void_p

    from fmpy import calloc, free
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )
    from fmpy.logging import addLoggerProxy

    global _DISPATCH_C
    if _DISPATCH_C is None:
        _DISPATCH_C = (
            fmi2CallbackLoggerTYPE(_dispatch_log),
            fmi2CallbackAllocateMemoryTYPE(calloc),
            fmi2CallbackFreeMemoryTYPE(free),
        )
    key = _NEXT_LOG_KEY[0]
    _NEXT_LOG_KEY[0] += 1
    _LOG_SINKS[key] = sink
    callbacks = fmi2CallbackFunctions()
    callbacks.logger, callbacks.allocateMemory, callbacks.freeMemory = _DISPATCH_C
    callbacks.componentEnvironment = c_void_p(key)
    addLoggerProxy(byref(callbacks))
    return callbacks, key


def release_logger(key):
    _LOG_SINKS.pop(key, None)


class Muscle:
    """A ``HillMuscle1D`` Co-Simulation instance driven through fmpy's FMU2Slave.

    ``Muscle(fmu, params)`` instantiates; ``initialize(length, activation)``
    runs setupExperiment / initialization mode with the inputs' start values;
    ``step(length, activation, dlength, dactivation)`` sets the inputs (and,
    when given, their first derivatives) and does one communication step.
    """

    def __init__(self, fmu=DEFAULT_FMU, params=None, log=None, logging_on=False, name="muscle"):
        from fmpy.fmi2 import FMU2Slave

        self.loaded = load_fmu(fmu)
        md = self.loaded.model_description
        self.vr = self.loaded.vr
        self.log = [] if log is None else log
        self.slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=self.loaded.unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self._callbacks, self._log_key = logger_callbacks(self.log)
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
        self.time = 0.0
        self.n_steps = 0
        self.h = None
        self._out_vrs = [self.vr[n] for n in OUTPUT_NAMES]
        for name_, value in (params or {}).items():
            self.set_parameter(name_, value)

    # -- set-up -------------------------------------------------------------
    def set_parameter(self, name, value):
        """Set a parameter (Real, Integer or Boolean)."""
        kind = self.loaded.variables[name].type
        if kind == "Boolean":
            self.slave.setBoolean([self.vr[name]], [bool(value)])
        elif kind == "Integer":
            self.slave.setInteger([self.vr[name]], [int(value)])
        else:
            self.slave.setReal([self.vr[name]], [float(value)])

    def initialize(self, length=L0, activation=0.0, start_time=0.0, stop_time=None):
        """Initialization with the inputs' values at the start time."""
        self.slave.setupExperiment(startTime=start_time, stopTime=stop_time)
        self.slave.enterInitializationMode()
        self.slave.setReal([self.vr["length"], self.vr["activation"]], [float(length), float(activation)])
        self.slave.exitInitializationMode()
        self.time = start_time
        self.start_time = start_time
        return self

    # -- stepping -----------------------------------------------------------
    def set_inputs(self, length=None, activation=None, dlength=None, dactivation=None):
        names, values = [], []
        if length is not None:
            names.append("length")
            values.append(float(length))
        if activation is not None:
            names.append("activation")
            values.append(float(activation))
        if names:
            self.slave.setReal([self.vr[n] for n in names], values)
        names, values = [], []
        if dlength is not None:
            names.append("length")
            values.append(float(dlength))
        if dactivation is not None:
            names.append("activation")
            values.append(float(dactivation))
        if names:
            self.slave.setRealInputDerivatives([self.vr[n] for n in names], [1] * len(names), values)

    def do_step(self, h):
        """One step from the current communication point. The communication
        point is start + n h (no accumulated sum), the way fmpy's
        simulate_fmu computes it for a fixed step."""
        if self.h != h:
            self.start_time, self.n_steps, self.h = self.time, 0, h
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.n_steps += 1
        self.time = self.start_time + self.n_steps * h

    def step(self, h, length=None, activation=None, dlength=None, dactivation=None):
        self.set_inputs(length, activation, dlength, dactivation)
        self.do_step(h)

    # -- reading ------------------------------------------------------------
    def outputs(self):
        """All outputs, as a dict name -> float."""
        return dict(zip(OUTPUT_NAMES, self.slave.getReal(self._out_vrs)))

    def output_vector(self):
        return self.slave.getReal(self._out_vrs)

    def get(self, *names):
        return self.slave.getReal([self.vr[n] for n in names])

    def free(self):
        if self.slave is not None:
            try:
                self.slave.terminate()
            except Exception:
                pass
            self.slave.freeInstance()
            self.slave = None
            release_logger(self._log_key)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def open_muscle(fmu=DEFAULT_FMU, params=None, length=L0, activation=0.0, **kwargs) -> Muscle:
    """An instantiated and initialized muscle at time 0."""
    return Muscle(fmu, params, **kwargs).initialize(length=length, activation=activation)


# --------------------------------------------------------------------------
# Input signals and the master loop
# --------------------------------------------------------------------------

@dataclass
class Signal:
    """A piecewise-linear signal through the breakpoints (times, values),
    held constant outside them."""

    times: tuple
    values: tuple

    def __call__(self, t):
        return float(np.interp(t, self.times, self.values))

    def slope(self, t, h):
        """Mean slope over [t, t + h]: the derivative that makes a step of the
        FMU end exactly on the signal (the right derivative for a step of
        piecewise-linear signal whose breakpoints are communication points)."""
        return (self(t + h) - self(t)) / h

    @classmethod
    def constant(cls, value):
        return cls((0.0,), (float(value),))


def run_protocol(fmu, length: Signal, activation: Signal, t_end, step=1e-3, params=None,
                 input_derivatives=False, extra_step=None):
    """Drive the FMU with ``length(t)`` and ``activation(t)`` from t = 0.

    Before the step from t_n = n h the loop sets length(t_n), activation(t_n)
    and, with ``input_derivatives``, their slopes over [t_n, t_n + h]. The
    muscle then ends the step at length(t_n) (no derivatives: one step of lag)
    or at length(t_{n+1}) (with derivatives). ``extra_step`` (default: when no
    derivatives are set) adds one step so that the muscle reaches
    length(t_end).

    Returns ``(time, muscle_length, outputs)``: the communication points
    (t = 0 after initialization, then the end of every step), the length the
    muscle has there, and a dict output name -> numpy array.
    """
    if extra_step is None:
        extra_step = not input_derivatives
    n = int(round(t_end / step))
    if abs(n * step - t_end) > 1e-9 * max(1.0, t_end):
        raise ValueError(f"t_end = {t_end} is not a multiple of the step {step}")
    n_total = n + (1 if extra_step else 0)
    time = np.empty(n_total + 1)
    muscle_length = np.empty(n_total + 1)
    values = np.empty((n_total + 1, len(OUTPUT_NAMES)))
    with Muscle(fmu, params) as m:
        m.initialize(length=length(0.0), activation=activation(0.0))
        time[0], muscle_length[0], values[0] = 0.0, length(0.0), m.output_vector()
        for i in range(n_total):
            t = i * step
            L, u = length(t), activation(t)
            if input_derivatives:
                dL, du = length.slope(t, step), activation.slope(t, step)
                m.step(step, L, u, dL, du)
                reached = L + step * dL
            else:
                m.step(step, L, u)
                reached = L
            time[i + 1], muscle_length[i + 1], values[i + 1] = m.time, reached, m.output_vector()
    outputs = {name: values[:, j].copy() for j, name in enumerate(OUTPUT_NAMES)}
    return time, muscle_length, outputs


def passive_length(l0=L0):
    return Signal((0.0, MAX_STRAIN * l0 / SPEED), (l0, (1 + MAX_STRAIN) * l0))


def activated_length(l0=L0):
    t_ramp = MAX_STRAIN * l0 / SPEED
    return Signal((0.0, HOLD, HOLD + t_ramp), (l0, l0, (1 + MAX_STRAIN) * l0))


def passive_elongation(fmu=DEFAULT_FMU, step=1e-3, params=None, input_derivatives=False):
    """Passive elongation: command 0, L = L0 + 5 mm/s t to 20 % strain (2 s).
    Returns ``(time, length, outputs)`` (see ``run_protocol``)."""
    l0 = (params or {}).get("L0", L0)
    length = passive_length(l0)
    return run_protocol(fmu, length, Signal.constant(0.0), length.times[-1], step, params, input_derivatives)


def activated_elongation(fmu=DEFAULT_FMU, step=1e-3, params=None, input_derivatives=False):
    """Activated elongation: command 1 from t = 0, held at L0 for 0.5 s, then
    pulled at 5 mm/s to 20 % strain (t = 2.5 s). Returns ``(time, length,
    outputs)`` (see ``run_protocol``)."""
    l0 = (params or {}).get("L0", L0)
    length = activated_length(l0)
    return run_protocol(fmu, length, Signal.constant(1.0), length.times[-1], step, params, input_derivatives)


def stress_at_strains(length, stress, strains=TABLE_STRAINS, l0=L0):
    """Engineering stress at the given strains of the final (monotone) pull,
    interpolated linearly in the strain the muscle actually has."""
    strain = np.asarray(length) / l0 - 1.0
    start = int(np.flatnonzero(strain <= 0.0)[-1]) if np.any(strain <= 0.0) else 0
    s, y = strain[start:], np.asarray(stress)[start:]
    if np.any(np.diff(s) <= 0):
        raise ValueError("the strain is not strictly increasing over the pull")
    strains = np.asarray(strains, dtype=float)
    if strains.min() < s[0] or strains.max() > s[-1] * (1 + 1e-12):
        raise ValueError(f"strains {strains} outside the simulated range [{s[0]}, {s[-1]}]")
    return np.interp(strains, s, y)


# --------------------------------------------------------------------------
# The demo: table and plots
# --------------------------------------------------------------------------

def format_table(passive, activated, strains=TABLE_STRAINS, fe=None):
    """The stress table: one column per experiment of ``HillMuscle1D``, and
    with ``fe = (passive, activated)`` the same for ``HillMuscleFE``."""
    head = "Engineering stress [kPa] (default parameters, step 1e-3 s)"
    if fe is None:
        lines = [head.replace("(", "(HillMuscle1D, "), f"{'strain':>8} {'passive':>12} {'activated':>12}"]
        for e, p, a in zip(strains, passive, activated):
            lines.append(f"{100 * e:7.0f}% {p / 1e3:12.3f} {a / 1e3:12.3f}")
        return "\n".join(lines)
    lines = [head, f"{'strain':>8} {'1D passive':>12} {'FE passive':>12} {'1D activated':>13} {'FE activated':>13}"]
    for e, p, fp, a, fa in zip(strains, passive, fe[0], activated, fe[1]):
        lines.append(f"{100 * e:7.0f}% {p / 1e3:12.3f} {fp / 1e3:12.3f} {a / 1e3:13.3f} {fa / 1e3:13.3f}")
    return "\n".join(lines)


def plot(out_dir: Path, runs: dict):
    """stress_strain.png (stress vs strain) and force_activation.png (force
    and activation level vs time) for the runs {label: (t, L, outputs)}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for label, (t, L, o) in runs.items():
        ax.plot(100 * (L / L0 - 1), o["stress"] / 1e3, label=label)
    ax.set_xlabel("strain [%]")
    ax.set_ylabel("engineering stress [kPa]")
    ax.set_title("elongation at 5 mm/s")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    paths = [out_dir / "stress_strain.png"]
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    for label, (t, L, o) in runs.items():
        ax1.plot(t, o["force"], label=label)
        ax2.plot(t, o["activation_level"], label=label)
    ax1.set_ylabel("force [N]")
    ax1.grid(True, alpha=0.3)
    ax1.legend()
    ax2.set_ylabel("activation level [-]")
    ax2.set_xlabel("time [s]")
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    paths.append(out_dir / "force_activation.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    return paths


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fmu", default=str(DEFAULT_FMU), help="path to HillMuscle1D.fmu (default: %(default)s)")
    parser.add_argument("--fe-fmu", default=str(DEFAULT_FE_FMU),
                        help="path to HillMuscleFE.fmu, run beside the 1D muscle when it exists "
                             "(default: %(default)s; '' to skip)")
    parser.add_argument("--out", default="out", help="directory for the plots (default: %(default)s)")
    parser.add_argument("--step", type=float, default=1e-3, help="communication step [s] (default: %(default)s)")
    args = parser.parse_args(argv)

    if not os.path.exists(args.fmu):
        print(f"error: {args.fmu} not found; build it with scripts/build_fmus.sh", file=sys.stderr)
        return 1
    runs = {
        "passive": passive_elongation(args.fmu, step=args.step),
        "activated": activated_elongation(args.fmu, step=args.step),
    }
    passive = stress_at_strains(runs["passive"][1], runs["passive"][2]["stress"])
    activated = stress_at_strains(runs["activated"][1], runs["activated"][2]["stress"])
    fe = None
    if args.fe_fmu and os.path.exists(args.fe_fmu):
        fe_runs = {
            "FE passive": passive_elongation(args.fe_fmu, step=args.step),
            "FE activated": activated_elongation(args.fe_fmu, step=args.step),
        }
        fe = tuple(stress_at_strains(r[1], r[2]["stress"]) for r in fe_runs.values())
        runs = {"1D passive": runs["passive"], "1D activated": runs["activated"], **fe_runs}
    print(format_table(passive, activated, fe=fe))
    for path in plot(Path(args.out), runs):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
