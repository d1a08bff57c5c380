"""FMU state: get/set and serialize/de-serialize continue bit for bit."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

H = 1e-3
WORKER = Path(__file__).resolve().parent / "state_worker.py"


def drive(t):
    """Inputs at time t: activation command switched on at t = 0 and a
    stretch-release of the length (the CE is active and moving, so the
    history variables matter)."""
    length = 0.05 * (1.0 + 0.1 * (1.0 - math.cos(2.0 * math.pi * t / 0.3)))
    activation = 0.6 if t < 0.12 else 1.0
    return length, activation


def run_steps(m, n):
    """n steps from the muscle's current time; returns the outputs after each
    step and the (t, length, activation) schedule used."""
    rows, schedule = [], []
    for _ in range(n):
        t = m.time
        length, activation = drive(t)
        schedule.append((t, length, activation))
        m.step(H, length=length, activation=activation)
        rows.append(m.output_vector())
    return rows, schedule


def test_get_set_state_continues_bit_for_bit(muscle):
    """100 steps, getFMUstate, 100 more steps recording the outputs,
    setFMUstate, the same 100 steps again: the outputs are identical (==).
    Also checks the restored outputs before the first repeated step equal
    those at the saved point."""
    m = muscle()
    run_steps(m, 100)
    saved_outputs = m.output_vector()
    saved_time, saved_n = m.time, m.n_steps
    state = m.slave.getFMUstate()
    first, schedule = run_steps(m, 100)
    assert first[-1] != saved_outputs  # it did move on
    m.slave.setFMUstate(state)
    assert m.output_vector() == saved_outputs
    m.time, m.n_steps = saved_time, saved_n
    second, schedule2 = run_steps(m, 100)
    assert schedule2 == schedule
    assert second == first
    m.slave.freeFMUstate(state)


def test_state_survives_further_stepping_and_reuse(muscle):
    """A saved state can be restored more than once, after the instance has
    gone elsewhere each time, and gives the same continuation every time."""
    m = muscle()
    run_steps(m, 50)
    saved_time, saved_n = m.time, m.n_steps
    state = m.slave.getFMUstate()
    runs = []
    for extra in (10, 37):
        rows, _ = run_steps(m, 20)
        runs.append(rows)
        run_steps(m, extra)
        m.slave.setFMUstate(state)
        m.time, m.n_steps = saved_time, saved_n
    rows, _ = run_steps(m, 20)
    runs.append(rows)
    assert runs[0] == runs[1] == runs[2]
    m.slave.freeFMUstate(state)


def test_serialized_state_restores_in_another_process(muscle, fmu_path, tmp_path):
    """Serialize after 100 steps, write the bytes to a file, restore them in a
    fresh Python process (new instance of the FMU, de-serialize, set state) and
    continue 100 steps there: the outputs equal the parent's continuation
    exactly (compared as float.hex)."""
    m = muscle()
    run_steps(m, 100)
    state = m.slave.getFMUstate()
    blob = m.slave.serializeFMUstate(state)
    m.slave.freeFMUstate(state)
    assert isinstance(blob, bytes) and len(blob) > 0
    state_file = tmp_path / "state.bin"
    state_file.write_bytes(blob)

    parent_rows, schedule = run_steps(m, 100)
    payload = {"h": H.hex(), "steps": [[t.hex(), L.hex(), u.hex()] for t, L, u in schedule]}
    proc = subprocess.run(
        [sys.executable, str(WORKER), str(fmu_path), str(state_file), json.dumps(payload)],
        capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode == 0, f"worker failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}"
    child_rows = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(child_rows) == 100
    assert child_rows == [[x.hex() for x in row] for row in parent_rows]


def test_serialize_round_trip_in_process(muscle):
    """De-serializing a serialized state into a second instance of the same
    process gives the same outputs now and after 50 more steps."""
    a = muscle()
    run_steps(a, 80)
    state = a.slave.getFMUstate()
    blob = a.slave.serializeFMUstate(state)
    a.slave.freeFMUstate(state)
    b = muscle()
    restored = b.slave.deSerializeFMUstate(blob)
    b.slave.setFMUstate(restored)
    b.slave.freeFMUstate(restored)
    assert b.output_vector() == a.output_vector()
    b.time, b.n_steps, b.h, b.start_time = a.time, a.n_steps, a.h, a.start_time
    rows_a, _ = run_steps(a, 50)
    rows_b, _ = run_steps(b, 50)
    assert rows_a == rows_b
