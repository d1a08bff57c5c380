"""The memory check of issue 4 §3 (scripts/memory_check.py) in a short form.

The full run (10,000 instance and 10,000 state cycles per FMU, reported in
docs/memory.md) takes minutes; here a few hundred cycles of the 1D FMU and a
few of the FE FMU must show zero leaks under LeakSanitizer, and the check's
self-test (the harness skips fmi2FreeInstance) must report a leak, so a clean
result means something.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "memory_check.py"
DIST = REPO / "dist"


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=600)


@pytest.mark.parametrize("fmu, cycles", [("HillMuscle1D", 300), ("HillMuscleFE", 5)])
def test_no_leaks_under_leak_sanitizer(fmu, cycles):
    path = DIST / f"{fmu}.fmu"
    assert path.is_file(), f"{path} missing: run scripts/build_fmus.sh"
    proc = run(str(path), "--cycles", str(cycles), "--state-cycles", str(10 * cycles))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"{fmu}: lsan, {cycles} instance" in proc.stdout
    assert "leaked 0 bytes in 0 blocks, 0 other errors, harness ok" in proc.stdout


def test_self_test_sees_the_fmu_s_own_allocations_leak():
    proc = run(str(DIST / "HillMuscle1D.fmu"), "--cycles", "3", "--state-cycles", "1", "--self-test")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "leaked 0 bytes" not in proc.stdout
