"""Subprocess half of test_libcosim.py: run a muscle FMU (HillMuscle1D,
HillMusculotendon1D, HillMusculotendonFE: any FMU with `length` and `activation` inputs and a
`force` output) under libcosim (libcosimpy), so that a crash in libcosim
fails the test instead of killing pytest (and libcosim's and fmpy's copies
of the FMU never share a process).

    python libcosim_worker.py FMU PLAN_JSON

PLAN_JSON (floats as float.hex strings, so that they cross exactly):

- ``step_ns``: the execution's fixed step [ns];
- ``lengths``: the length input for steps 0 .. N-1;
- ``activation`` (one value for every step) or ``activations`` (one per step):
  the activation command;
- ``params`` (optional): {name: value} Real parameters, given to libcosim as
  initial values (applied before the FMU leaves initialization mode);
- ``integers`` (optional): {name: value} Integer parameters (e.g. an FE
  unit's mesh), given to libcosim as initial values the same way;
- ``initial`` (optional): {"length": ..., "activation": ...}, the inputs'
  values at initialization (default: those of step 0).

The execution has a fixed step of step_ns nanoseconds and the single slave.
Before step i an override manipulator sets length = lengths[i] and the
activation command of step i; a time-series observer records `force` and
`length` after steps 1..N. Prints one JSON line: {"time_ns": [...],
"step": [...], "force": [hex...], "length": [hex...], "ok": bool}.
"""

from __future__ import annotations

import json
import sys

from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave


def main(fmu, plan_json):
    plan = json.loads(plan_json)
    lengths = [float.fromhex(x) for x in plan["lengths"]]
    n = len(lengths)
    if "activations" in plan:
        activations = [float.fromhex(x) for x in plan["activations"]]
    else:
        activations = [float.fromhex(plan["activation"])] * n
    assert len(activations) == n, "one activation per step"
    initial = {k: float.fromhex(v) for k, v in plan.get("initial", {}).items()}
    log_output_level(CosimLogLevel.WARNING)

    execution = CosimExecution.from_step_size(step_size=int(plan["step_ns"]))
    slave = CosimLocalSlave(fmu_path=fmu, instance_name="muscle")
    index = execution.add_local_slave(local_slave=slave)
    assert index >= 0, "cannot add the slave"
    vr = {v.name.decode(): v.reference for v in execution.slave_variables(index)}

    for name, value in plan.get("params", {}).items():
        assert execution.real_initial_value(index, vr[name], float.fromhex(value)), f"initial value of {name}"
    for name, value in plan.get("integers", {}).items():
        assert execution.integer_initial_value(index, vr[name], int(value)), f"initial value of {name}"
    assert execution.real_initial_value(index, vr["length"], initial.get("length", lengths[0]))
    assert execution.real_initial_value(index, vr["activation"], initial.get("activation", activations[0]))

    manipulator = CosimManipulator.create_override()
    assert execution.add_manipulator(manipulator=manipulator)
    observer = CosimObserver.create_time_series()
    assert execution.add_observer(observer=observer)
    for name in ("force", "length"):
        assert observer.start_time_series(index, value_reference=vr[name], variable_type=CosimVariableType.REAL)

    ok = True
    for i in range(n):
        ok &= manipulator.slave_real_values(index, [vr["length"], vr["activation"]], [lengths[i], activations[i]])
        ok &= execution.step()
    out = {"ok": bool(ok)}
    for name in ("force", "length"):
        # from_step=1: libcosimpy trims its result by the number of zero step
        # numbers, which would also drop a genuine step 0 (the initial values).
        times, steps, values = observer.time_series_real_samples(
            index, value_reference=vr[name], from_step=1, sample_count=n)
        out["time_ns"], out["step"], out[name] = list(times), list(steps), [float(x).hex() for x in values]
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
