#!/usr/bin/env python3
"""Per-multibody-step cost: the MuJoCo elbow with HillMuscle1D in the loop vs
MuJoCo's own built-in muscle on the same arm.

The arm is ``examples/arm_mujoco.py``'s (``ARM_XML``: planar elbow, forearm +
hand load, the flexor as a wrapping spatial tendon; MuJoCo step 1 ms, Euler).
Every loop runs ``--steps`` MuJoCo steps from the hanging arm at rest under
the same open-loop activation command, u(t) = 0.35 + 0.15 sin(2 pi t) (the arm
swings between 0 and ~130 deg with the FMU muscle, 0 and ~80 deg with
MuJoCo's; no joint limit is reached), and the figure is wall time / steps.
Loops:

``builtin_rollout``  MuJoCo alone with its built-in muscle: the flexor's
                     actuator replaced by an MJCF ``<muscle force="350">``
                     on the same tendon (F_max = sigma0 * area of the FMU's
                     arm muscle; MuJoCo's own FL/FV/FP curves, activation
                     dynamics, length range computed at compile time), run by
                     ``mujoco.rollout`` (a C loop: no Python per step).
``builtin_python``   the same, from a Python loop: ``ctrl[0] = u``,
                     ``mj_step``.
``mujoco_rollout``   the co-simulation arm (``general`` actuator on the
                     tendon) with ctrl = the coupled run's force trace, in
                     ``mujoco.rollout``: MuJoCo's own step of the coupled
                     model on the same motion, no Python.
``mujoco_glue``      the co-simulation master loop without the FMU: read
                     ``ten_length``, set ``ctrl``, ``mj_step2``, ``mj_step1``
                     (the force a stored trace): MuJoCo plus the master's
                     Python.
``fmpy``             the coupled run with HillMuscle1D through fmpy's
                     ``FMU2Slave``, explicit scheme at H = dt (one FMU step
                     per MuJoCo step, the FMU's worst case): read L, set
                     length and activation (``setReal``), ``doStep``,
                     ``getReal(force)``, ``ctrl = -F``, ``mj_step2``,
                     ``mj_step1``.
``ctypes``           the same coupled run calling the FMU's C ABI directly:
                     the shared library is loaded from the FMU with ctypes,
                     and the loop calls ``fmi2SetReal``, ``fmi2DoStep``,
                     ``fmi2GetReal`` on preallocated arrays (``CApiMuscle``).
``fmu_fmpy``,        the FMU alone: the same calls replaying the length and
``fmu_ctypes``       command trace of the coupled run, no MuJoCo.
``fmu_c``            the same calls on the same trace from a C loop
                     (``C_HARNESS``, compiled with ``cc -O2`` at run time;
                     skipped without a compiler): the FMU's own cost.

The split of a coupled run (per MuJoCo step): MuJoCo's step
(``mujoco_rollout``: the co-simulation arm under the coupled run's force
trace, which reproduces its motion bit for bit), the FMU's step
(``fmu_c``), the importer's call overhead (``fmu_ctypes`` or ``fmu_fmpy``
minus ``fmu_c``), and the rest, the master's Python (loop, ``mjData`` field
access, the binding calls of ``mj_step1/2``) = coupled - ``mujoco_rollout``
- ``fmu_ctypes`` (or ``fmu_fmpy``). The coupled fmpy and ctypes runs and the
C loop are checked to give the same forces bit for bit.

Each loop is timed ``--repeats`` times, interleaved (loop A, B, ..., then
again), and the median is reported::

    python examples/bench_arm.py                 # 4000 steps, 9 repeats
    python examples/bench_arm.py --steps 2000 --repeats 5 --json out/bench_arm.json
"""

from __future__ import annotations

import argparse
import ctypes
import datetime
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import arm_mujoco as am  # noqa: E402
from elongation import DEFAULT_FMU, Muscle, load_fmu  # noqa: E402

DT = 1e-3
BUILTIN_MUSCLE = '<muscle name="muscle" tendon="flexor" force="{force:g}"/>'
GENERAL_ACTUATOR = '<general name="muscle" tendon="flexor" gainprm="1" biasprm="0 0 0" ctrllimited="false"/>'


def command(n, dt=DT):
    """The activation command of step i (open loop, the same for every loop)."""
    t = np.arange(n) * dt
    return 0.35 + 0.15 * np.sin(2.0 * np.pi * t)


def builtin_model():
    """The arm with MuJoCo's built-in muscle on the flexor tendon."""
    import mujoco

    assert GENERAL_ACTUATOR in am.ARM_XML
    xml = am.ARM_XML.replace(GENERAL_ACTUATOR, BUILTIN_MUSCLE.format(force=am.F_MAX))
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.timestep = DT
    return model


# --------------------------------------------------------------------------
# The FMU's C ABI through ctypes
# --------------------------------------------------------------------------

# fmi2CallbackLogger is variadic (printf-style message + arguments); this
# callback declares the first variadic argument as a string, which is where
# an x86-64 System V caller puts it (this FMU logs as "%s", text).
_LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                           ctypes.c_char_p)
_LOGGED = [0]


class _Callbacks(ctypes.Structure):
    _fields_ = [("logger", _LOGGER), ("allocateMemory", ctypes.c_void_p), ("freeMemory", ctypes.c_void_p),
                ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]


@_LOGGER
def _log(env, name, status, category, message, arg):
    if status < 1 or _LOGGED[0] >= 20:
        return
    _LOGGED[0] += 1
    text = arg if message == b"%s" and platform.machine() == "x86_64" else message
    print(f"[FMU status {status}] {(text or b'').decode(errors='replace')}", file=sys.stderr)


class CApiMuscle:
    """HillMuscle1D driven through its FMI 2.0 C functions, loaded with ctypes
    from the extracted FMU (no importer library): fmi2Instantiate,
    SetupExperiment, Enter/ExitInitializationMode, then per step
    ``step(t, h, length, activation) -> force`` = fmi2SetReal (2 values) +
    fmi2DoStep + fmi2GetReal (1 value) on preallocated arrays."""

    def __init__(self, fmu=DEFAULT_FMU, params=None, name="ctypes"):
        loaded = load_fmu(fmu)
        md = loaded.model_description
        ident = md.coSimulation.modelIdentifier
        lib_path = Path(loaded.unzipdir) / "binaries" / "linux64" / f"{ident}.so"
        self.lib = lib = ctypes.CDLL(str(lib_path))
        self.vr = loaded.vr
        c_void_p, c_int, c_double, c_size_t = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_size_t
        lib.fmi2Instantiate.restype = c_void_p
        lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, c_int, ctypes.c_char_p, ctypes.c_char_p,
                                        ctypes.POINTER(_Callbacks), c_int, c_int]
        for fn in ("fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate"):
            getattr(lib, fn).argtypes, getattr(lib, fn).restype = [c_void_p], c_int
        lib.fmi2FreeInstance.argtypes, lib.fmi2FreeInstance.restype = [c_void_p], None
        lib.fmi2SetupExperiment.argtypes = [c_void_p, c_int, c_double, c_double, c_int, c_double]
        lib.fmi2SetupExperiment.restype = c_int
        # the per-step functions have no argtypes: ctypes then passes the
        # preallocated arrays as pointers without conversion checks (with
        # POINTER argtypes fmi2SetReal costs ~1.0 us per call from Python
        # instead of ~0.45 us, measured), and the doubles of fmi2DoStep are
        # passed as c_double objects
        self._set, self._do, self._get = lib.fmi2SetReal, lib.fmi2DoStep, lib.fmi2GetReal
        for f in (self._set, self._do, self._get):
            f.restype = c_int
        libc = ctypes.CDLL(None)
        self._callbacks = _Callbacks(_log, ctypes.cast(libc.calloc, c_void_p), ctypes.cast(libc.free, c_void_p),
                                     None, None)
        resources = (Path(loaded.unzipdir) / "resources").as_uri().encode()
        c = lib.fmi2Instantiate(name.encode(), 1, md.guid.encode(), resources, ctypes.byref(self._callbacks), 0, 0)
        if not c:
            raise RuntimeError("fmi2Instantiate failed")
        self.c = c_void_p(c)
        for k, v in (params or {}).items():
            self._check(self._set(self.c, (ctypes.c_uint * 1)(self.vr[k]), 1, (c_double * 1)(float(v))), f"set {k}")
        self._in_vr = (ctypes.c_uint * 2)(self.vr["length"], self.vr["activation"])
        self._in = (c_double * 2)()
        self._out_vr = (ctypes.c_uint * 1)(self.vr["force"])
        self._out = (c_double * 1)()

    def hot(self):
        """What a tight master loop needs, as locals: (fmi2SetReal,
        fmi2DoStep, fmi2GetReal, instance, input vrs, input array, output vr,
        output array); see ``step`` for the call sequence."""
        return self._set, self._do, self._get, self.c, self._in_vr, self._in, self._out_vr, self._out

    @staticmethod
    def _check(status, what):
        if status != 0:
            raise RuntimeError(f"{what}: fmi2Status {status}")

    def initialize(self, length, activation=0.0):
        lib, c = self.lib, self.c
        self._check(lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment")
        self._check(lib.fmi2EnterInitializationMode(c), "fmi2EnterInitializationMode")
        self._in[0], self._in[1] = length, activation
        self._check(self._set(c, self._in_vr, 2, self._in), "fmi2SetReal")
        self._check(lib.fmi2ExitInitializationMode(c), "fmi2ExitInitializationMode")
        self._check(self._get(c, self._out_vr, 1, self._out), "fmi2GetReal")
        return self._out[0]

    def step(self, t, h, length, activation):
        """One communication step; the force at t + h. (Status checks are on:
        a nonzero status raises.)"""
        inp, c, dbl = self._in, self.c, ctypes.c_double
        inp[0] = length
        inp[1] = activation
        if self._set(c, self._in_vr, 2, inp) or self._do(c, dbl(t), dbl(h), 1) or self._get(c, self._out_vr, 1, self._out):
            raise RuntimeError(f"FMU call failed at t = {t}")
        return self._out[0]

    def free(self):
        if self.c is not None:
            self.lib.fmi2Terminate(self.c)
            self.lib.fmi2FreeInstance(self.c)
            self.c = None


# --------------------------------------------------------------------------
# The FMU's own cost: the same calls from a C loop (no Python)
# --------------------------------------------------------------------------

C_HARNESS = r"""
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
typedef struct {
  void (*logger)(void *, const char *, int, const char *, const char *, ...);
  void *(*allocateMemory)(size_t, size_t);
  void (*freeMemory)(void *);
  void *stepFinished, *componentEnvironment;
} Callbacks;
static void logger(void *env, const char *name, int status, const char *cat, const char *msg, ...) {
  if (status < 1) return;
  va_list ap; va_start(ap, msg); vfprintf(stderr, msg, ap); va_end(ap); fputc('\n', stderr);
}
typedef void *(*Inst)(const char *, int, const char *, const char *, const Callbacks *, int, int);
typedef int (*Comp)(void *);
typedef int (*Setup)(void *, int, double, double, int, double);
typedef int (*Real)(void *, const unsigned *, size_t, double *);
typedef int (*Step)(void *, double, double, int);
typedef void (*Free)(void *);
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
/* so guid resources trace n dt vr_length vr_activation vr_force vr_L0 L0 vr_area area
   trace: n lengths then n activations (doubles). Prints "ns_per_step last_force(hex)". */
int main(int argc, char **argv) {
  if (argc != 14) { fprintf(stderr, "usage\n"); return 2; }
  void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
  if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
  Inst inst = (Inst)dlsym(lib, "fmi2Instantiate");
  Setup setup = (Setup)dlsym(lib, "fmi2SetupExperiment");
  Comp enter = (Comp)dlsym(lib, "fmi2EnterInitializationMode"), exit_ = (Comp)dlsym(lib, "fmi2ExitInitializationMode");
  Comp term = (Comp)dlsym(lib, "fmi2Terminate");
  Real set = (Real)dlsym(lib, "fmi2SetReal"), get = (Real)dlsym(lib, "fmi2GetReal");
  Step step = (Step)dlsym(lib, "fmi2DoStep");
  Free fre = (Free)dlsym(lib, "fmi2FreeInstance");
  long n = atol(argv[5]); double dt = atof(argv[6]);
  double *trace = malloc(2 * n * sizeof(double));
  FILE *f = fopen(argv[4], "rb");
  if (!f || fread(trace, sizeof(double), 2 * n, f) != (size_t)(2 * n)) { fprintf(stderr, "trace\n"); return 1; }
  fclose(f);
  unsigned in_vr[2] = {atoi(argv[7]), atoi(argv[8])}, out_vr = atoi(argv[9]);
  unsigned par_vr[2] = {atoi(argv[10]), atoi(argv[12])};
  double par[2] = {atof(argv[11]), atof(argv[13])};
  Callbacks cb = {logger, calloc, free, 0, 0};
  void *c = inst("c_loop", 1, argv[2], argv[3], &cb, 0, 0);
  if (!c) return 1;
  double in[2] = {trace[0], 0.0}, force = 0.0;
  if (set(c, par_vr, 2, par) || setup(c, 0, 0.0, 0.0, 0, 0.0) || enter(c) || set(c, in_vr, 2, in) || exit_(c)) return 1;
  double t0 = now();
  for (long i = 0; i < n; i++) {
    in[0] = trace[i]; in[1] = trace[n + i];
    if (set(c, in_vr, 2, in) || step(c, i * dt, dt, 1) || get(c, &out_vr, 1, &force)) { fprintf(stderr, "step %ld failed\n", i); return 1; }
  }
  double t1 = now();
  printf("%.3f %a\n", (t1 - t0) / n * 1e9, force);
  term(c); fre(c);
  return 0;
}
"""


class CLoop:
    """The FMU driven by ``C_HARNESS`` (compiled once with ``cc -O2``): the
    same fmi2SetReal + fmi2DoStep + fmi2GetReal per step as the Python loops,
    on the length/command trace of the coupled run, timed in C. ``None`` when
    no C compiler is found."""

    def __init__(self, fmu, lengths, u, workdir):
        import shutil
        import subprocess

        self.ok = False
        cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
        if cc is None:
            return
        workdir = Path(workdir)
        src, exe = workdir / "fmu_c_loop.c", workdir / "fmu_c_loop"
        src.write_text(C_HARNESS)
        subprocess.run([cc, "-O2", "-o", str(exe), str(src), "-ldl"], check=True)
        trace = workdir / "trace.bin"
        np.concatenate([np.asarray(lengths, float), np.asarray(u, float)]).tofile(trace)
        loaded = load_fmu(fmu)
        md = loaded.model_description
        vr = loaded.vr
        lib = Path(loaded.unzipdir) / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
        self.cmd = [str(exe), str(lib), md.guid, (Path(loaded.unzipdir) / "resources").as_uri(), str(trace),
                    str(len(lengths)), repr(DT), str(vr["length"]), str(vr["activation"]), str(vr["force"]),
                    str(vr["L0"]), repr(am.MUSCLE_PARAMS["L0"]), str(vr["area"]), repr(am.MUSCLE_PARAMS["area"])]
        self.ok = True

    def __call__(self):
        import subprocess

        out = subprocess.run(self.cmd, check=True, capture_output=True, text=True).stdout.split()
        return float(out[0]) * 1e-9 * int(self.cmd[5]), float.fromhex(out[1])


# --------------------------------------------------------------------------
# The loops (each returns (seconds, result))
# --------------------------------------------------------------------------

def _arm(model_fn=None):
    import mujoco

    model = model_fn() if model_fn else am.build_model(DT)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def loop_builtin_rollout(n, u):
    import mujoco
    import mujoco.rollout

    model, data = _arm(builtin_model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)
    ctrl = u.reshape(1, n, 1).copy()
    t0 = time.perf_counter()
    state, _ = mujoco.rollout.rollout(model, data, state0[None, :], ctrl)
    elapsed = time.perf_counter() - t0
    return elapsed, state[0, -1, 1 + model.nq - 1]  # last angle (state: time, qpos, ...)


def builtin_angles(n, u):
    """(min, max) elbow angle of the built-in muscle arm under the command."""
    import mujoco

    model, data = _arm(builtin_model)
    lo = hi = float(data.qpos[0])
    for i in range(n):
        data.ctrl[0] = u[i]
        mujoco.mj_step(model, data)
        lo, hi = min(lo, data.qpos[0]), max(hi, data.qpos[0])
    return lo, hi


def loop_builtin_python(n, u):
    import mujoco

    model, data = _arm(builtin_model)
    step, ctrl = mujoco.mj_step, data.ctrl
    t0 = time.perf_counter()
    for i in range(n):
        ctrl[0] = u[i]
        step(model, data)
    elapsed = time.perf_counter() - t0
    return elapsed, float(data.qpos[0])


def loop_mujoco_rollout(n, u, forces):
    """The co-simulation arm under the coupled run's force trace: the same
    motion, MuJoCo alone."""
    import mujoco
    import mujoco.rollout

    model, data = _arm()
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)
    ctrl = -np.asarray(forces, float).reshape(1, n, 1)
    t0 = time.perf_counter()
    state, _ = mujoco.rollout.rollout(model, data, state0[None, :], ctrl)
    elapsed = time.perf_counter() - t0
    return elapsed, state[0, -1, 1]


def loop_mujoco_glue(n, u, forces):
    """The coupled master loop with the FMU call replaced by a stored force."""
    import mujoco

    model, data = _arm()
    step1, step2 = mujoco.mj_step1, mujoco.mj_step2
    step1(model, data)
    ten_length, ctrl = data.ten_length, data.ctrl
    t0 = time.perf_counter()
    for i in range(n):
        L = ten_length[0]  # noqa: F841  (read as the coupled loop does)
        ctrl[0] = -forces[i]
        step2(model, data)
        step1(model, data)
    elapsed = time.perf_counter() - t0
    return elapsed, float(data.qpos[0])


def loop_fmpy(n, u, fmu, record=None):
    import mujoco

    model, data = _arm()
    step1, step2 = mujoco.mj_step1, mujoco.mj_step2
    step1(model, data)
    ten_length, ctrl = data.ten_length, data.ctrl
    with Muscle(fmu, am.MUSCLE_PARAMS, name="bench_fmpy") as m:
        m.initialize(length=float(ten_length[0]), activation=0.0)
        slave = m.slave
        in_vrs, out_vrs = [m.vr["length"], m.vr["activation"]], [m.vr["force"]]
        setReal, doStep, getReal = slave.setReal, slave.doStep, slave.getReal
        t0 = time.perf_counter()
        for i in range(n):
            L = ten_length[0]
            setReal(in_vrs, [L, u[i]])
            doStep(i * DT, DT)
            F = getReal(out_vrs)[0]
            ctrl[0] = -F
            step2(model, data)
            step1(model, data)
            if record is not None:
                record.append((L, F, float(data.qpos[0])))
        elapsed = time.perf_counter() - t0
    return elapsed, float(data.qpos[0])


def loop_ctypes(n, u, fmu, record=None):
    import mujoco

    model, data = _arm()
    step1, step2 = mujoco.mj_step1, mujoco.mj_step2
    step1(model, data)
    ten_length, ctrl = data.ten_length, data.ctrl
    m = CApiMuscle(fmu, am.MUSCLE_PARAMS)
    try:
        m.initialize(float(ten_length[0]), 0.0)
        set_, do, get, c, in_vr, inp, out_vr, out = m.hot()
        dbl, h = ctypes.c_double, ctypes.c_double(DT)
        t0 = time.perf_counter()
        for i in range(n):
            L = ten_length[0]
            inp[0] = L
            inp[1] = u[i]
            if set_(c, in_vr, 2, inp) or do(c, dbl(i * DT), h, 1) or get(c, out_vr, 1, out):
                raise RuntimeError(f"FMU call failed at step {i}")
            F = out[0]
            ctrl[0] = -F
            step2(model, data)
            step1(model, data)
            if record is not None:
                record.append((L, F, float(data.qpos[0])))
        elapsed = time.perf_counter() - t0
    finally:
        m.free()
    return elapsed, float(data.qpos[0])


def loop_fmu_fmpy(n, u, fmu, lengths):
    with Muscle(fmu, am.MUSCLE_PARAMS, name="bench_fmu_fmpy") as m:
        m.initialize(length=lengths[0], activation=0.0)
        slave = m.slave
        in_vrs, out_vrs = [m.vr["length"], m.vr["activation"]], [m.vr["force"]]
        setReal, doStep, getReal = slave.setReal, slave.doStep, slave.getReal
        t0 = time.perf_counter()
        for i in range(n):
            setReal(in_vrs, [lengths[i], u[i]])
            doStep(i * DT, DT)
            F = getReal(out_vrs)[0]
        elapsed = time.perf_counter() - t0
    return elapsed, F


def loop_fmu_ctypes(n, u, fmu, lengths):
    m = CApiMuscle(fmu, am.MUSCLE_PARAMS)
    try:
        m.initialize(lengths[0], 0.0)
        set_, do, get, c, in_vr, inp, out_vr, out = m.hot()
        dbl, h = ctypes.c_double, ctypes.c_double(DT)
        t0 = time.perf_counter()
        for i in range(n):
            inp[0] = lengths[i]
            inp[1] = u[i]
            if set_(c, in_vr, 2, inp) or do(c, dbl(i * DT), h, 1) or get(c, out_vr, 1, out):
                raise RuntimeError(f"FMU call failed at step {i}")
            F = out[0]
        elapsed = time.perf_counter() - t0
    finally:
        m.free()
    return elapsed, F


def coupled_trace(n, fmu, via):
    """(length, force, angle) per step of the coupled run through ``via``
    ("fmpy" or "ctypes")."""
    rec = []
    (loop_fmpy if via == "fmpy" else loop_ctypes)(n, command(n), fmu, record=rec)
    return np.array(rec)


# --------------------------------------------------------------------------

def machine():
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    import fmpy
    import mujoco

    return {"date": datetime.date.today().isoformat(), "cpu": cpu, "cores": os.cpu_count(),
            "python": platform.python_version(), "mujoco": mujoco.__version__, "fmpy": fmpy.__version__,
            "platform": platform.platform()}


def main(argv=None):
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument("--steps", type=int, default=4000)
    p.add_argument("--repeats", type=int, default=9)
    p.add_argument("--json", default=None, help="also write the results as JSON here")
    args = p.parse_args(argv)
    n, fmu = args.steps, args.fmu
    u_arr = command(n)
    u = u_arr.tolist()

    # the coupled run once: its trace feeds the FMU-only, glue and rollout
    # loops, and the fmpy and ctypes paths must agree bit for bit
    a, b = coupled_trace(n, fmu, "fmpy"), coupled_trace(n, fmu, "ctypes")
    if not np.array_equal(a, b):
        raise SystemExit(f"fmpy and ctypes coupled runs differ: max {np.max(np.abs(a - b))}")
    lengths, forces, angles = a[:, 0].tolist(), a[:, 1].tolist(), a[:, 2]
    _, rollout_angle = loop_mujoco_rollout(n, u_arr, forces)
    if rollout_angle != angles[-1]:
        print(f"note: MuJoCo's rollout under the coupled force trace ends {rollout_angle - angles[-1]:.3g} rad "
              "from the coupled run")
    _, builtin_angle = loop_builtin_python(n, u)
    builtin_range = builtin_angles(n, u_arr)
    print(f"workload: {n} steps of {DT * 1e3:g} ms, u = 0.35 + 0.15 sin 2 pi t. Coupled run (fmpy and ctypes "
          f"bit-identical): angle {np.degrees(angles.min()):.1f} .. {np.degrees(angles.max()):.1f} deg, force "
          f"{min(forces):.1f} .. {max(forces):.1f} N, length {min(lengths):.4f} .. {max(lengths):.4f} m; "
          f"MuJoCo rollout under its force trace ends at {np.degrees(rollout_angle):.4f} deg "
          f"(coupled {np.degrees(angles[-1]):.4f}); built-in muscle arm {np.degrees(builtin_range[0]):.1f} .. "
          f"{np.degrees(builtin_range[1]):.1f} deg")

    with tempfile.TemporaryDirectory() as tmp:
        c_loop = CLoop(fmu, lengths, u, tmp)
        loops = {
            "builtin_rollout": lambda: loop_builtin_rollout(n, u_arr),
            "builtin_python": lambda: loop_builtin_python(n, u),
            "mujoco_rollout": lambda: loop_mujoco_rollout(n, u_arr, forces),
            "mujoco_glue": lambda: loop_mujoco_glue(n, u, forces),
            "fmpy": lambda: loop_fmpy(n, u, fmu),
            "ctypes": lambda: loop_ctypes(n, u, fmu),
            "fmu_fmpy": lambda: loop_fmu_fmpy(n, u, fmu, lengths),
            "fmu_ctypes": lambda: loop_fmu_ctypes(n, u, fmu, lengths),
        }
        if c_loop.ok:
            loops["fmu_c"] = c_loop
            if c_loop()[1] != forces[-1]:
                raise SystemExit("the C loop's last force differs from the coupled run's")
        else:
            print("no C compiler: the FMU's cost from C (fmu_c) is not measured")
        for f in loops.values():  # warm-up
            f()
        runs = {k: [] for k in loops}
        for _ in range(args.repeats):
            for k, f in loops.items():
                runs[k].append(f()[0] / n * 1e9)
    med = {k: statistics.median(v) for k, v in runs.items()}

    print(f"\nper MuJoCo step, ns (median of {args.repeats} interleaved runs of {n} steps; min .. max)")
    for k in loops:
        print(f"  {k:16s} {med[k]:9.0f}   ({min(runs[k]):.0f} .. {max(runs[k]):.0f})")
    fmu_c = med.get("fmu_c", float("nan"))
    split = {"mujoco_step": med["mujoco_rollout"], "fmu_step": fmu_c,
             "ctypes_calls": med["fmu_ctypes"] - fmu_c,
             "python_glue": med["ctypes"] - med["mujoco_rollout"] - med["fmu_ctypes"]}
    split_fmpy = {"mujoco_step": med["mujoco_rollout"], "fmu_step": fmu_c,
                  "fmpy_calls": med["fmu_fmpy"] - fmu_c,
                  "python_glue": med["fmpy"] - med["mujoco_rollout"] - med["fmu_fmpy"]}
    for name, sp, total in (("ctypes", split, med["ctypes"]), ("fmpy", split_fmpy, med["fmpy"])):
        print(f"split of the coupled {name} run ({total:.0f} ns): "
              + ", ".join(f"{k} {v:.0f} ns ({100 * v / total:.0f} %)" for k, v in sp.items()))
    ratios = {"ctypes/builtin_python": med["ctypes"] / med["builtin_python"],
              "fmpy/builtin_python": med["fmpy"] / med["builtin_python"],
              "ctypes/builtin_rollout": med["ctypes"] / med["builtin_rollout"],
              "fmu_c/mujoco_rollout": fmu_c / med["mujoco_rollout"]}
    print("ratios: " + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items())
          + f"; the FMU in the loop adds {med['ctypes'] - med['mujoco_glue']:.0f} ns (ctypes), "
          f"{med['fmpy'] - med['mujoco_glue']:.0f} ns (fmpy) to the master loop without it")
    out = {"bench": "arm", "machine": machine(), "steps": n, "repeats": args.repeats, "dt": DT,
           "ns_per_step_median": med, "ns_per_step_all": runs, "split_ctypes": split, "split_fmpy": split_fmpy,
           "ratios": ratios}
    print(json.dumps(out))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
