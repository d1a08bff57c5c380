"""Subprocess half of test_state.py: restore a serialized FMU state in a fresh
process and continue.

    python state_worker.py FMU STATE_FILE SCHEDULE_JSON

STATE_FILE holds the bytes of fmi2SerializeFMUstate. SCHEDULE_JSON is
{"h": .., "steps": [[t, length, activation], ...]} (floats as float.hex
strings, so that the times and inputs are bit-identical to the parent's). The worker
instantiates the FMU (no initialization: the state carries everything, the
way fmpy's simulate_fmu(fmu_state=...) restores), de-serializes and sets the
state, then for each entry sets the inputs and does one step from t, and
prints the outputs after every step as JSON (float.hex strings,
exact).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))

from elongation import Muscle  # noqa: E402


def main(fmu, state_file, schedule_json):
    schedule = json.loads(schedule_json)
    m = Muscle(fmu, name="restored")
    state = m.slave.deSerializeFMUstate(Path(state_file).read_bytes())
    m.slave.setFMUstate(state)
    m.slave.freeFMUstate(state)
    h = float.fromhex(schedule["h"])
    rows = []
    for t, length, activation in schedule["steps"]:
        m.set_inputs(length=float.fromhex(length), activation=float.fromhex(activation))
        m.slave.doStep(float.fromhex(t), h)
        rows.append([x.hex() for x in m.output_vector()])
    m.free()
    print(json.dumps(rows))


if __name__ == "__main__":
    main(*sys.argv[1:4])
