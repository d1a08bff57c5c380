"""The muscle FMUs the issue-5 scripts compare, and a lean fmpy driver for them.

Two models share one interface (the variables of ``HillMuscle1D``: inputs
``activation`` and ``length``, outputs ``force``, ``stress``, ...):

* ``1D`` — ``dist/HillMuscle1D.fmu`` (override: ``HILL_MUSCLE_FMU``);
* ``FE`` — ``dist/HillMuscleFE.fmu`` (override: ``HILL_MUSCLE_FE_FMU``), the
  tetrahedral fusiform muscle, which adds the Integer parameters ``n_axial``
  and ``n_radial`` (mesh level) and the outputs ``volume_ratio_min``,
  ``volume_ratio_max``, ``max_fibre_stretch`` and ``newton_iterations``.

Every script asks ``Model.available()`` and, when the FMU file is missing,
prints ``Model.skip_reason()`` and leaves that model out of its results (the
reports say so). Nothing else in the scripts depends on which model it is,
except the FE mesh levels (``fe_mesh_levels``).

``simulate`` drives one FMU instance over a fixed communication step with
fmpy's ``FMU2Slave`` (setReal, optionally setRealInputDerivatives, doStep,
getReal per step: the least overhead an fmpy master has) from input arrays
computed before the loop; ``isometric`` reads the initial (isometric
equilibrium) outputs at a given length. Parameters of any FMI type are set by
name (Real, Integer, Boolean).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import elongation as el

REPO = Path(__file__).resolve().parent.parent
FMU_1D = Path(os.environ.get("HILL_MUSCLE_FMU", REPO / "dist" / "HillMuscle1D.fmu"))
FMU_FE = Path(os.environ.get("HILL_MUSCLE_FE_FMU", REPO / "dist" / "HillMuscleFE.fmu"))

FE_MESH_PARAMETERS = ("n_axial", "n_radial")
FE_DEFAULT_LEVELS = ((12, 2), (18, 3), (24, 4))
"""(n_axial, n_radial) of the FE mesh levels 0, 1, 2 of ``src/fe/mesh.rs``
(864, 2,916, 6,912 tetrahedra; n_axial = 6 n_radial keeps the element shapes),
graded toward the clamped faces like the FMU's default 16 x 3 mesh
(``axial_grading`` 0.9, ``radial_grading`` 0.6, the FMU's defaults; docs/fe.md)."""
FE_EXTRA_OUTPUTS = ("volume_ratio_min", "volume_ratio_max", "max_fibre_stretch", "newton_iterations")


@dataclass(frozen=True)
class Model:
    """One FMU variant: ``key`` ("1D" or "FE") and the FMU's path."""

    key: str
    fmu: Path
    description: str

    def problem(self):
        """None when the FMU can be used, else why not (missing file, or a
        model description fmpy refuses)."""
        path = Path(self.fmu)
        if not path.is_file():
            return f"{path} does not exist (build it with scripts/build_fmus.sh once it is part of the build)"
        key = (str(path.resolve()), path.stat().st_mtime_ns)
        if key not in _PROBLEMS:
            try:
                el.load_fmu(path)
                _PROBLEMS[key] = None
            except Exception as exc:  # e.g. fmpy's ValidationError
                text = " ".join(str(exc).split())
                _PROBLEMS[key] = f"{path} cannot be loaded by fmpy: {text}"
        return _PROBLEMS[key]

    def available(self) -> bool:
        return self.problem() is None

    def skip_reason(self) -> str:
        return f"{self.key} model skipped: {self.problem()}"


_PROBLEMS: dict = {}


def snapshot(model: Model) -> Model:
    """The same model on a private copy of its FMU (in the temporary directory,
    named by the content's hash), so that a long study is not affected by a
    rebuild of ``dist/`` while it runs. Unavailable models are returned as they are."""
    if not model.available():
        return model
    data = Path(model.fmu).read_bytes()
    target = Path(tempfile.gettempdir()) / "hill_muscle_fmus" / hashlib.sha256(data).hexdigest()[:16] / Path(model.fmu).name
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(data)
        tmp.replace(target)
    return Model(model.key, target, model.description)


def model_1d(fmu=None) -> Model:
    return Model("1D", Path(fmu or FMU_1D), "HillMuscle1D: the law in homogeneous uniaxial stress")


def model_fe(fmu=None) -> Model:
    return Model("FE", Path(fmu or FMU_FE), "HillMuscleFE: fusiform tetrahedral muscle, one end clamped")


def all_models(fmu_1d=None, fmu_fe=None) -> list:
    """Both models, available or not (callers filter with ``available()``)."""
    return [model_1d(fmu_1d), model_fe(fmu_fe)]


def variable_names(fmu) -> set:
    return set(el.load_fmu(fmu).variables)


def fe_mesh_levels(fmu, levels=FE_DEFAULT_LEVELS) -> list:
    """Mesh levels of the FE FMU as parameter dicts, coarsest first.

    ``levels=()`` means one level, the FMU's default mesh (``[{}]``: also how
    the scripts' FE code path is tested with the 1D FMU standing in). Fails
    with a clear message when the FMU does not declare the Integer parameters
    ``n_axial`` and ``n_radial``."""
    if not levels:
        return [{}]
    variables = el.load_fmu(fmu).variables
    missing = [n for n in FE_MESH_PARAMETERS if n not in variables]
    if missing:
        raise KeyError(f"{fmu} has no parameter(s) {missing}: cannot choose FE mesh levels")
    return [dict(zip(FE_MESH_PARAMETERS, level)) for level in levels]


def parse_levels(text) -> tuple:
    """``"12x2,18x3,24x4"`` -> ((12, 2), (18, 3), (24, 4)); ``""`` -> () (the default mesh)."""
    if not text.strip():
        return ()
    out = []
    for item in text.split(","):
        a, r = item.lower().split("x")
        out.append((int(a), int(r)))
    return tuple(out)


def level_label(params) -> str:
    """``{"n_axial": 12, "n_radial": 2}`` -> ``"12x2"``; ``{"adaptive_substeps":
    False}`` -> ``"one-step"``; "" otherwise."""
    if "n_axial" in (params or {}):
        return f"{params['n_axial']}x{params['n_radial']}"
    if (params or {}).get("adaptive_substeps") is False:
        return ONE_STEP
    return ""


ONE_STEP = "one-step"
"""Label of the 1D muscle with ``adaptive_substeps`` off: one backward-Euler
CE-SEE update per communication step (the plain first-order scheme)."""


# --------------------------------------------------------------------------
# One instance
# --------------------------------------------------------------------------

class FmuError(RuntimeError):
    """An FMI call failed; ``log`` holds the FMU's messages (status, category, text)."""

    def __init__(self, message, log):
        super().__init__(message)
        self.log = log


class Instance:
    """An FMU2Slave instance of a muscle FMU with the FMU's log captured.

    ``Instance(fmu, params)`` instantiates and sets the parameters (any FMI
    type); ``initialize(length, activation, stop_time)`` runs the
    initialization. Used as a context manager it frees the instance."""

    def __init__(self, fmu, params=None, name="muscle"):
        from fmpy.fmi2 import FMU2Slave

        self.loaded = el.load_fmu(fmu)
        md = self.loaded.model_description
        self.vr = self.loaded.vr
        self.log = []
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=self.loaded.unzipdir,
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self._callbacks, self._log_key = el.logger_callbacks(self.log)
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=False)
        self.initialized = False
        try:
            for key, value in (params or {}).items():
                self.set_parameter(key, value)
        except Exception as exc:
            error = self._error(exc)
            self.free()
            raise error from exc

    def _error(self, exc):
        messages = "; ".join(text for status, _, text in self.log if status >= 2)
        return FmuError(f"{exc}" + (f": {messages}" if messages else ""), list(self.log))

    def set_parameter(self, name, value):
        variables = self.loaded.variables
        if name not in variables:
            raise KeyError(f"the FMU has no variable {name!r}")
        kind = variables[name].type
        if kind == "Boolean":
            self.slave.setBoolean([self.vr[name]], [bool(value)])
        elif kind == "Integer":
            self.slave.setInteger([self.vr[name]], [int(value)])
        else:
            self.slave.setReal([self.vr[name]], [float(value)])

    def initialize(self, length, activation=0.0, stop_time=None):
        try:
            self.slave.setupExperiment(startTime=0.0, stopTime=stop_time)
            self.slave.enterInitializationMode()
            self.slave.setReal([self.vr["length"], self.vr["activation"]], [float(length), float(activation)])
            self.slave.exitInitializationMode()
        except Exception as exc:
            raise self._error(exc) from exc
        self.initialized = True
        return self

    def reader(self, names):
        """A function returning the outputs ``names`` (Real, or Integer such
        as the FE's ``newton_iterations``) as a list of floats, in order."""
        variables = self.loaded.variables
        real = [i for i, n in enumerate(names) if variables[n].type == "Real"]
        if len(real) == len(names):
            vrs = [self.vr[n] for n in names]
            return lambda: self.slave.getReal(vrs)
        other = [i for i in range(len(names)) if i not in real]
        real_vrs, other_vrs = [self.vr[names[i]] for i in real], [self.vr[names[i]] for i in other]

        def read():
            out = [0.0] * len(names)
            for i, v in zip(real, self.slave.getReal(real_vrs) if real_vrs else []):
                out[i] = v
            for i, v in zip(other, self.slave.getInteger(other_vrs)):
                out[i] = float(v)
            return out

        return read

    def get(self, names):
        return self.reader(list(names))()

    def free(self):
        if self.slave is not None:
            if self.initialized:
                try:
                    self.slave.terminate()
                except Exception:
                    pass
            self.slave.freeInstance()
            self.slave = None
            el.release_logger(self._log_key)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


# --------------------------------------------------------------------------
# Fixed-step runs
# --------------------------------------------------------------------------

@dataclass
class Inputs:
    """Input arrays at the communication points t_n = n h, n = 0 .. N - 1
    (the values set before the step from t_n), their derivatives, and the
    length the muscle has reached at t_{n+1}."""

    h: float
    time: np.ndarray
    length: np.ndarray
    activation: np.ndarray
    dlength: np.ndarray
    dactivation: np.ndarray
    input_derivatives: bool

    @property
    def n_steps(self):
        return self.time.size

    def reached(self):
        if self.input_derivatives:
            return self.length + self.h * self.dlength
        return self.length.copy()


def n_steps_for(t_end, h):
    n = int(round(t_end / h))
    if n < 1 or abs(n * h - t_end) > 1e-9 * max(1.0, t_end):
        raise ValueError(f"t_end = {t_end} is not a multiple of the step {h}")
    return n


def scene_inputs(scene, h, input_derivatives) -> Inputs:
    """Sample a scene (see ``scenes.Scene``) at t_n = n h for its whole duration."""
    t = np.arange(n_steps_for(scene.t_end, h)) * h
    zeros = np.zeros_like(t)
    return Inputs(h, t, scene.length(t), scene.activation(t),
                  scene.dlength(t) if input_derivatives else zeros,
                  scene.dactivation(t) if input_derivatives else zeros, input_derivatives)


@dataclass
class Run:
    """A finished run: ``time`` (0 and every communication point), the
    muscle length there, the recorded outputs, and the wall time [s] from
    instantiation to freeing the instance (FMU extraction excluded)."""

    time: np.ndarray
    length: np.ndarray
    outputs: dict
    wall: float
    extra: dict = field(default_factory=dict)


def simulate(fmu, inputs: Inputs, params=None, outputs=("force",), initial=None) -> Run:
    """Run ``inputs`` through one fresh instance with fmpy's FMU2Slave.

    Initialization is at the first input values (``initial`` overrides:
    ``(length, activation)``); ``setupExperiment`` gets the end time as stop
    time. Raises ``FmuError`` (with the FMU's messages) when a call fails."""
    started = time.perf_counter()
    h, n = inputs.h, inputs.n_steps
    values = np.empty((n + 1, len(outputs)))
    length0, act0 = initial or (inputs.length[0], inputs.activation[0])
    with Instance(fmu, params) as m:
        m.initialize(length0, act0, stop_time=n * h)
        slave, vr = m.slave, m.vr
        in_vrs = [vr["length"], vr["activation"]]
        read = m.reader(outputs)
        L, u = inputs.length.tolist(), inputs.activation.tolist()
        dL, du = inputs.dlength.tolist(), inputs.dactivation.tolist()
        try:
            values[0] = read()
            for i in range(n):
                slave.setReal(in_vrs, [L[i], u[i]])
                if inputs.input_derivatives:
                    slave.setRealInputDerivatives(in_vrs, [1, 1], [dL[i], du[i]])
                slave.doStep(i * h, h)
                values[i + 1] = read()
        except Exception as exc:
            raise m._error(exc) from exc
    wall = time.perf_counter() - started
    t = np.arange(n + 1) * h
    length = np.concatenate([[length0], inputs.reached()])
    return Run(t, length, {name: values[:, j] for j, name in enumerate(outputs)}, wall)


def isometric(fmu, length, activation, params=None, outputs=("stress", "fibre_stretch")) -> dict:
    """Outputs right after initialization at ``length`` with command
    ``activation``: the isometric equilibrium (with ``activation_dynamics``
    false the activation level is the command)."""
    with Instance(fmu, params) as m:
        m.initialize(length, activation)
        return dict(zip(outputs, m.get(outputs)))
