"""Run a muscle FMU through its C ABI from a C loop (``cabi_driver.c``).

Why C and not ctypes per call, nor a Rust binary: a Python loop calling the
FMU's functions through ctypes pays ~1 us of interpreter and ctypes overhead
per call, several times the FMU's own ~0.3 us per step, so it would measure
ctypes again (fmpy's FMU2Slave is that loop already). A Rust bench binary
would need a Cargo target in the workspace that other work is editing. The C
loop needs only the system C compiler (``cc``) and fmpy's own copy of the
FMI 2.0 headers; it is compiled once into the temporary directory (cached by
the source's hash), and one ctypes call runs a whole simulation.

``simulate_cabi(fmu, inputs, params, outputs)`` mirrors
``muscle_models.simulate`` (same calls, same results) and returns a
``muscle_models.Run`` whose ``wall`` is the C loop's own time from
fmi2Instantiate to fmi2FreeInstance.
"""

from __future__ import annotations

import ctypes
import hashlib
import platform
import subprocess
import tempfile
from pathlib import Path

import numpy as np

import elongation as el
import muscle_models as mm

SOURCE = Path(__file__).resolve().parent / "cabi_driver.c"
_LIB = None


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).resolve().parent / "c-code"


def compile_driver() -> Path:
    """Compile cabi_driver.c (once per source version) and return the .so path."""
    digest = hashlib.sha256(SOURCE.read_bytes()).hexdigest()[:16]
    target = Path(tempfile.gettempdir()) / f"hill_muscle_cabi_{digest}.so"
    if not target.exists():
        tmp = target.with_suffix(".tmp.so")
        cmd = ["cc", "-O2", "-shared", "-fPIC", "-I", str(fmi_headers()), str(SOURCE), "-o", str(tmp), "-ldl"]
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        tmp.replace(target)
    return target


def compiler_version() -> str:
    try:
        return subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    except Exception as exc:  # pragma: no cover - reported, not fatal
        return f"unknown ({exc})"


def _lib():
    global _LIB
    if _LIB is None:
        lib = ctypes.CDLL(str(compile_driver()))
        P = ctypes.POINTER
        u, d, i = P(ctypes.c_uint), P(ctypes.c_double), P(ctypes.c_int)
        lib.hm_run.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                               ctypes.c_int, u, d, ctypes.c_int, u, i, ctypes.c_int, u, i,
                               ctypes.c_uint, ctypes.c_uint, ctypes.c_int, u,
                               ctypes.c_int, ctypes.c_double, d, d, d, d, ctypes.c_int,
                               d, d, ctypes.c_char_p, ctypes.c_int]
        lib.hm_run.restype = ctypes.c_int
        _LIB = lib
    return _LIB


def fmu_library(loaded) -> Path:
    """The FMU's shared library inside its extracted directory."""
    md = loaded.model_description
    arch = {"x86_64": "linux64", "aarch64": "aarch64-linux"}.get(platform.machine(), "linux64")
    return Path(loaded.unzipdir) / "binaries" / arch / f"{md.coSimulation.modelIdentifier}.so"


def _array(values, ctype):
    return (ctype * max(1, len(values)))(*values)


def _split_params(loaded, params):
    groups = {"Real": ([], []), "Integer": ([], []), "Boolean": ([], [])}
    for name, value in (params or {}).items():
        kind = loaded.variables[name].type
        groups[kind][0].append(loaded.vr[name])
        groups[kind][1].append(float(value) if kind == "Real" else int(value))
    return groups


def simulate_cabi(fmu, inputs: mm.Inputs, params=None, outputs=("force",)) -> mm.Run:
    loaded = el.load_fmu(fmu)
    groups = _split_params(loaded, params)
    n, n_out = inputs.n_steps, len(outputs)
    out = np.zeros((n + 1) * n_out)
    elapsed = ctypes.c_double()
    err = ctypes.create_string_buffer(4096)
    as_d = lambda a: np.ascontiguousarray(a, dtype=float).ctypes.data_as(ctypes.POINTER(ctypes.c_double))  # noqa
    arrays = [np.ascontiguousarray(a, dtype=float) for a in
              (inputs.length, inputs.activation, inputs.dlength, inputs.dactivation)]
    rc = _lib().hm_run(
        str(fmu_library(loaded)).encode(), loaded.model_description.guid.encode(),
        Path(loaded.unzipdir, "resources").as_uri().encode(),
        len(groups["Real"][0]), _array(groups["Real"][0], ctypes.c_uint), _array(groups["Real"][1], ctypes.c_double),
        len(groups["Integer"][0]), _array(groups["Integer"][0], ctypes.c_uint),
        _array(groups["Integer"][1], ctypes.c_int),
        len(groups["Boolean"][0]), _array(groups["Boolean"][0], ctypes.c_uint),
        _array(groups["Boolean"][1], ctypes.c_int),
        loaded.vr["length"], loaded.vr["activation"], n_out, _array([loaded.vr[o] for o in outputs], ctypes.c_uint),
        n, inputs.h, *(as_d(a) for a in arrays), int(inputs.input_derivatives),
        out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), ctypes.byref(elapsed), err, len(err))
    if rc != 0:
        raise mm.FmuError(f"C ABI run failed ({rc}): {err.value.decode(errors='replace')}", [])
    values = out.reshape(n + 1, n_out)
    t = np.arange(n + 1) * inputs.h
    length = np.concatenate([[inputs.length[0]], inputs.reached()])
    return mm.Run(t, length, {name: values[:, j].copy() for j, name in enumerate(outputs)}, elapsed.value)
