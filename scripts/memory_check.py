#!/usr/bin/env python3
"""Memory check of the FMUs through their C ABI.

Builds tests/memory/memory_cycles.c and runs it on each FMU's binary: CYCLES
instantiate / initialize / step / rejected calls / state round trip / reset /
step / terminate / free cycles, then STATE_CYCLES get / serialize /
deserialize / set / free cycles of an FMU state on one instance (see the C
file). Two checkers:

* ``lsan`` (default): the harness built with -fsanitize=address; its
  LeakSanitizer reports every heap block left unreachable at exit, and
  AddressSanitizer any invalid access the harness makes with what the FMU
  hands out;
* ``valgrind``: the plain harness under valgrind --leak-check=full (slow: use
  fewer cycles).

A run passes when the harness completes, the checker reports zero leaked bytes
(definitely, indirectly and possibly lost for valgrind) and no error. With
``--self-test`` the harness skips fmi2FreeInstance in every cycle, and the
run passes only if the checker reports the FMU's allocations as leaked (proof
the check sees allocations made inside the uninstrumented FMU binary). ``--report`` writes docs/memory.md.

    .venv/bin/python scripts/memory_check.py                       # 10,000 + 10,000, both FMUs, LSan
    .venv/bin/python scripts/memory_check.py --tool valgrind --cycles 200 --state-cycles 200
    .venv/bin/python scripts/memory_check.py --report docs/memory.md
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import provenance  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SOURCE = REPO / "tests" / "memory" / "memory_cycles.c"
FMUS = [REPO / "dist" / "HillMuscle1D.fmu", REPO / "dist" / "HillMuscleFE.fmu"]
# The FE cycles use a small mesh (2 x 1: 36 tetrahedra): the allocations are
# the same kinds as on the default mesh (mesh, patterns, symbolic and numeric
# factors, element histories), only fewer elements, and 10,000 cycles stay
# affordable.
FE_MESH = {"n_axial": 2, "n_radial": 1}


@dataclass
class Result:
    fmu: str
    tool: str
    cycles: int
    state_cycles: int
    leaked_bytes: int
    leaked_blocks: int
    errors: int
    harness_ok: bool
    seconds: float
    detail: str

    @property
    def clean(self) -> bool:
        return self.harness_ok and self.leaked_bytes == 0 and self.errors == 0


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def compile_harness(tool: str, out_dir: Path) -> Path:
    exe = out_dir / f"memory_cycles_{tool}"
    flags = ["-g", "-O1", "-fno-omit-frame-pointer"]
    if tool == "lsan":
        flags.append("-fsanitize=address")
    cmd = ["cc", *flags, "-I", str(fmi_headers()), str(SOURCE), "-o", str(exe), "-ldl", "-lm"]
    subprocess.run(cmd, check=True)
    return exe


def fmu_arguments(fmu: Path, work: Path) -> tuple[list[str], str]:
    """The harness's arguments for an FMU (extracted under work): library,
    GUID, resource URI, value references and integer parameters."""
    from fmpy import extract, read_model_description

    md = read_model_description(str(fmu))
    unzipped = Path(extract(str(fmu), unzipdir=str(work / fmu.stem)))
    library = unzipped / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ints = [f"{vr[name]}={value}" for name, value in FE_MESH.items() if name in vr]
    args = [str(library), md.guid, (unzipped / "resources").as_uri(),
            str(vr["length"]), str(vr["activation"]), str(vr["force"])]
    return args + ints, md.modelName


def parse_lsan(stderr: str) -> tuple[int, int, int]:
    """(leaked bytes, leaked blocks, other errors) from ASan/LSan output."""
    m = re.search(r"SUMMARY: AddressSanitizer: (\d+) byte\(s\) leaked in (\d+) allocation", stderr)
    leaked = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
    errors = len(re.findall(r"ERROR: AddressSanitizer: (?!.*leak)", stderr))
    return leaked[0], leaked[1], errors


def parse_valgrind(stderr: str) -> tuple[int, int, int]:
    total_bytes = total_blocks = 0
    for kind in ("definitely lost", "indirectly lost", "possibly lost"):
        m = re.search(rf"{kind}: ([\d,]+) bytes in ([\d,]+) blocks", stderr)
        if m:
            total_bytes += int(m.group(1).replace(",", ""))
            total_blocks += int(m.group(2).replace(",", ""))
    m = re.search(r"ERROR SUMMARY: ([\d,]+) errors", stderr)
    # Leak records count as errors in valgrind's summary: keep only the rest.
    errors = int(m.group(1).replace(",", "")) if m else 1
    leak_records = len(re.findall(r"are (definitely|indirectly|possibly) lost in loss record", stderr))
    return total_bytes, total_blocks, max(errors - leak_records, 0)


def run_one(exe: Path, tool: str, fmu: Path, cycles: int, state_cycles: int, leak: bool,
            work: Path, timeout: float) -> Result:
    args, name = fmu_arguments(fmu, work)
    cmd = [str(exe), *args[:6], str(cycles), str(state_cycles), "1" if leak else "0", *args[6:]]
    env = dict(os.environ)
    if tool == "lsan":
        env["ASAN_OPTIONS"] = "detect_leaks=1:exitcode=0"
        env["LSAN_OPTIONS"] = "exitcode=0:max_leaks=5"
    else:
        cmd = ["valgrind", "--leak-check=full", "--show-leak-kinds=definite,indirect,possible",
               "--num-callers=12", *cmd]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    seconds = time.perf_counter() - start
    parse = parse_lsan if tool == "lsan" else parse_valgrind
    leaked_bytes, leaked_blocks, errors = parse(proc.stderr)
    ok = proc.returncode == 0 and "cycles ok" in proc.stdout
    detail = (proc.stdout.strip().splitlines() or [""])[-1]
    if not ok:
        detail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
    return Result(name, tool, cycles, state_cycles, leaked_bytes, leaked_blocks, errors, ok,
                  seconds, detail)


def report(results: list[Result], command: str) -> str:
    lines = [
        "# Memory check of the FMUs",
        "",
        provenance.header(),
        "",
        f"Command: `{command}` — generated by `scripts/memory_check.py`, "
        f"{datetime.date.today().isoformat()}, {platform.machine()} {platform.system()}, "
        f"{os.cpu_count()} cores, {subprocess.run(['cc', '--version'], capture_output=True, text=True).stdout.splitlines()[0]}.",
        "",
        "Each instance cycle: fmi2Instantiate, parameters, setup, initialization, three steps of an activated pull,",
        "a rejected `fmi2SetReal` (NaN length) and a rejected `fmi2DoStep` (wrong communication point), an FMU",
        "state get/serialize/deserialize/set/free, a second state the importer never frees (`fmi2FreeInstance`",
        "reclaims it, FMI 2.0 §2.1.8), `fmi2Reset`, re-initialization, one step, `fmi2Terminate`,",
        "`fmi2FreeInstance`. Each state cycle: get, size, serialize, deserialize, set, free both, on one running",
        "instance. The FE cycles use a 2 × 1 mesh (36 tetrahedra; same allocations as the default mesh, fewer",
        f"elements). `lsan` = harness built with `-fsanitize=address` (LeakSanitizer at exit); `valgrind` =",
        "`valgrind --leak-check=full` (definitely + indirectly + possibly lost). The FMU binaries are the",
        "release builds in `dist/`.",
        "",
        "| FMU | checker | instance cycles | state cycles | leaked bytes (blocks) | other errors | harness | wall s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r.fmu} | {r.tool} | {r.cycles:,} | {r.state_cycles:,} | {r.leaked_bytes} ({r.leaked_blocks}) | "
            f"{r.errors} | {'completed' if r.harness_ok else 'FAILED: ' + r.detail} | {r.seconds:.1f} |")
    lines += [
        "",
        "The check can fail: `scripts/memory_check.py --self-test` skips `fmi2FreeInstance` in every cycle and",
        "passes only if the checker reports the FMU's own allocations as leaked (run in CI by",
        "`tests/python/test_memory.py` with a few cycles, together with a clean run).",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("fmus", nargs="*", type=Path, default=FMUS)
    p.add_argument("--tool", choices=["lsan", "valgrind", "both"], default="lsan")
    p.add_argument("--cycles", type=int, default=10_000)
    p.add_argument("--state-cycles", type=int, default=10_000)
    p.add_argument("--valgrind-cycles", type=int, default=200,
                   help="instance and state cycles under valgrind with --tool both")
    p.add_argument("--valgrind-fe-cycles", type=int, default=20,
                   help="the same for the FE FMU (a cycle costs seconds under valgrind)")
    p.add_argument("--self-test", action="store_true", help="leak one state per cycle; pass only if seen")
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds per FMU")
    p.add_argument("--report", type=Path, help="write the Markdown report here")
    args = p.parse_args(argv)
    if shutil.which("cc") is None:
        print("memory_check: needs a C compiler `cc`", file=sys.stderr)
        return 2
    if args.tool in ("valgrind", "both") and shutil.which("valgrind") is None:
        print("memory_check: valgrind not found", file=sys.stderr)
        return 2
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        plan = {"lsan": [("lsan", args.cycles, args.state_cycles)],
                "valgrind": [("valgrind", args.cycles, args.state_cycles)],
                "both": [("lsan", args.cycles, args.state_cycles),
                         ("valgrind", args.valgrind_cycles, args.valgrind_cycles)]}[args.tool]
        for tool, cycles, state_cycles in plan:
            exe = compile_harness(tool, work)
            for fmu in args.fmus:
                if args.tool == "both" and tool == "valgrind" and "FE" in fmu.stem:
                    cycles = state_cycles = args.valgrind_fe_cycles
                results.append(run_one(exe, tool, fmu, cycles, state_cycles, args.self_test, work,
                                       args.timeout))
                r = results[-1]
                print(f"{r.fmu}: {tool}, {r.cycles} instance + {r.state_cycles} state cycles, "
                      f"leaked {r.leaked_bytes} bytes in {r.leaked_blocks} blocks, {r.errors} other errors, "
                      f"harness {'ok' if r.harness_ok else 'FAILED'} ({r.detail}), {r.seconds:.1f} s", flush=True)
    if args.report:
        command = "scripts/memory_check.py " + " ".join(argv if argv is not None else sys.argv[1:])
        args.report.write_text(report(results, command.strip()))
    if args.self_test:
        return 0 if all(r.harness_ok and r.leaked_bytes > 0 for r in results) else 1
    return 0 if all(r.clean for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
