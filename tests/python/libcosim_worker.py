"""Subprocess half of test_libcosim.py: run HillMuscle1D under libcosim
(libcosimpy), so that a crash in libcosim fails the test instead of killing
pytest.

    python libcosim_worker.py FMU PLAN_JSON

PLAN_JSON: {"step_ns": int, "activation": float (hex), "lengths": [hex, ...]}.
The execution has a fixed step of step_ns nanoseconds and the single slave.
`length` and `activation` get initial values (length: the first entry);
before step i an override manipulator sets length = lengths[i] and the
activation; a time-series observer records `force` and `length` after steps 1..N. Prints one
JSON line: {"time_ns": [...], "step": [...], "force": [hex...],
"length": [hex...], "ok": bool}.
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
    activation = float.fromhex(plan["activation"])
    n = len(lengths)
    log_output_level(CosimLogLevel.WARNING)

    execution = CosimExecution.from_step_size(step_size=int(plan["step_ns"]))
    slave = CosimLocalSlave(fmu_path=fmu, instance_name="muscle")
    index = execution.add_local_slave(local_slave=slave)
    assert index >= 0, "cannot add the slave"
    vr = {v.name.decode(): v.reference for v in execution.slave_variables(index)}

    assert execution.real_initial_value(index, vr["length"], lengths[0])
    assert execution.real_initial_value(index, vr["activation"], activation)

    manipulator = CosimManipulator.create_override()
    assert execution.add_manipulator(manipulator=manipulator)
    observer = CosimObserver.create_time_series()
    assert execution.add_observer(observer=observer)
    for name in ("force", "length"):
        assert observer.start_time_series(index, value_reference=vr[name], variable_type=CosimVariableType.REAL)

    ok = True
    for i in range(n):
        ok &= manipulator.slave_real_values(index, [vr["length"], vr["activation"]], [lengths[i], activation])
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
