#!/usr/bin/env python3
"""Parameter sweeps of the muscle FMUs on dask.distributed: one FMU simulation per task.

    .venv/bin/python examples/sweep_dask.py                          # local cluster, every available model
    .venv/bin/python examples/sweep_dask.py --scheduler tcp://host:8786
    .venv/bin/python examples/sweep_dask.py --models 1d --compare-serial --inject-failure
    .venv/bin/python examples/sweep_dask.py --render --out docs/sweeps  # page + figures from a run's tables

The sweeps (the paper's sensitivity study, as a full factorial design):

* 1D (1,100 runs, h = 1e-3 s with input derivatives): activated elongation
  over sigma0 (8 values, 0.16-1.0 MPa) x kc (5, 4.0-5.88) x ke (5, 3.14-7.56)
  x d (5, 1.1-1.8) = 1,000 runs, and passive elongation over D (10, 1e-9 to
  1e-6 1/Pa, log) x sigma0 (10) = 100 runs;
* FE (50 runs, its default mesh, h = 1e-3 s): passive over D (5) x sigma0
  (5), activated over kc (5) x d (5).

Each task runs one simulation (``run_task``) and returns one row of the tidy
table: run id, model, scene, step, the swept parameters, ``status`` ("ok" or
"error"), ``error`` (the FMU's message), engineering stress at 5/10/15/20 %
strain, peak force, FE diagnostics (volume ratios, Newton iterations; empty
for 1D), wall time and worker. A run that fails inside the FMU is a row with
status "error"; a task that dies with its worker is a row with status "lost"
— every requested run is in the table, none is dropped.

Cluster: a ``LocalCluster`` on 127.0.0.1 (one single-threaded worker
process per core, ``--workers``) unless ``--scheduler`` names an existing
one. The FMU is extracted once per worker process (``elongation.load_fmu``
caches it); with ``--scheduler`` (or ``--ship-fmu``) the FMU file itself is
broadcast to the workers once and written to each worker's temporary
directory, and the helper modules are uploaded, so remote workers need only
the Python environment.

Output: a CSV table (Parquet too when pyarrow is installed), a figure of the
main effects at 20 % strain, and a Markdown summary with the wall times;
``--compare-serial`` also runs the same runs in a plain loop in this process
and reports the speed-up.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import logging
import os
import platform
import socket
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

import muscle_models as mm  # noqa: E402
import provenance  # noqa: E402
import scenes as sc  # noqa: E402

REPO = mm.REPO
STRAINS = (0.05, 0.10, 0.15, 0.20)
STRESS_COLUMNS = tuple(f"stress_{round(100 * e):02d}" for e in STRAINS)
FE_DIAGNOSTICS = ("volume_ratio_min", "volume_ratio_max", "newton_iterations")
HELPER_MODULES = ("elongation.py", "scenes.py", "muscle_models.py", "sweep_dask.py")
FAILING_PARAMS = {"d": 0.5}
"""The injected failing run: d = 0.5 is outside the FMU's range [1, 100]."""


# --------------------------------------------------------------------------
# The sweeps
# --------------------------------------------------------------------------

def factorial(**axes):
    names = list(axes)
    return [dict(zip(names, map(float, values))) for values in itertools.product(*axes.values())]


def sweep_1d():
    sigma0 = np.linspace(0.16e6, 1.0e6, 8)
    active = factorial(sigma0=sigma0, kc=np.linspace(4.0, 5.88, 5), ke=np.linspace(3.14, 7.56, 5),
                       d=np.linspace(1.1, 1.8, 5))
    passive = factorial(D=np.logspace(-9, -6, 10), sigma0=np.linspace(0.16e6, 1.0e6, 10))
    return [("activated", p) for p in active] + [("passive", p) for p in passive]


def sweep_fe():
    passive = factorial(D=np.logspace(-9, -6, 5), sigma0=np.linspace(0.16e6, 1.0e6, 5))
    active = factorial(kc=np.linspace(4.0, 5.88, 5), d=np.linspace(1.1, 1.8, 5))
    return [("passive", p) for p in passive] + [("activated", p) for p in active]


SWEEPS = {"1D": (sweep_1d, 1e-3), "FE": (sweep_fe, 1e-3)}


def make_specs(model_key, runs, h, start_id=0, inject_failure=False):
    """Task specifications (plain dicts): run id, model, scene, step, parameters."""
    if inject_failure:
        runs = list(runs) + [("passive", dict(FAILING_PARAMS))]
    return [{"run_id": start_id + i, "model": model_key, "scene": scene, "h": h, "params": params}
            for i, (scene, params) in enumerate(runs)]


# --------------------------------------------------------------------------
# One task
# --------------------------------------------------------------------------

def local_fmu(fmu):
    """A path to the FMU on this worker: ``fmu`` itself when it is a path,
    else (bytes broadcast by the client) a file in the temporary directory
    named by the content's hash, written once per machine."""
    if isinstance(fmu, (str, Path)):
        return Path(fmu)
    digest = hashlib.sha256(fmu).hexdigest()[:16]
    target = Path(tempfile.gettempdir()) / "hill_muscle_sweep" / f"{digest}.fmu"
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(fmu)
        tmp.replace(target)
    return target


def _scene(name):
    return {"passive": sc.passive, "activated": sc.activated}[name]()


def summarise_run(run, l0=sc.L0):
    """Stress at the tabulated strains of the final pull, peak force, FE diagnostics."""
    strain = run.length / l0 - 1.0
    start = int(np.flatnonzero(strain <= 0.0)[-1])
    stress = np.interp(STRAINS, strain[start:], run.outputs["stress"][start:])
    out = dict(zip(STRESS_COLUMNS, map(float, stress)))
    out["peak_force"] = float(np.max(run.outputs["force"]))
    if "volume_ratio_min" in run.outputs:
        out["volume_ratio_min"] = float(np.min(run.outputs["volume_ratio_min"]))
        out["volume_ratio_max"] = float(np.max(run.outputs["volume_ratio_max"]))
        out["newton_iterations"] = float(np.sum(run.outputs["newton_iterations"]))
    return out


def run_task(spec, fmu):
    """One simulation; never raises: a failure is returned as a row."""
    started, cpu_started = time.perf_counter(), time.process_time()
    row = {"run_id": spec["run_id"], "model": spec["model"], "scene": spec["scene"], "h": spec["h"],
           **spec["params"], "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        path = local_fmu(fmu)
        outputs = ["force", "stress"]
        if "volume_ratio_min" in mm.variable_names(path):
            outputs += list(FE_DIAGNOSTICS)
        inputs = mm.scene_inputs(_scene(spec["scene"]), spec["h"], True)
        run = mm.simulate(path, inputs, spec["params"], tuple(outputs))
        row.update(summarise_run(run), status="ok", error="")
    except Exception as exc:  # reported in the table, with the parameters
        row.update(status="error", error=f"{type(exc).__name__}: {' '.join(str(exc).split())}")
    row["wall_s"] = time.perf_counter() - started
    row["cpu_s"] = time.process_time() - cpu_started
    return row


def lost_row(spec, exc):
    """A task whose worker died (or that dask could not run): still a row."""
    return {"run_id": spec["run_id"], "model": spec["model"], "scene": spec["scene"], "h": spec["h"],
            **spec["params"], "status": "lost", "error": f"{type(exc).__name__}: {exc}", "worker": ""}


# --------------------------------------------------------------------------
# Running: dask and serial
# --------------------------------------------------------------------------

class Progress:
    """A one-line text progress bar on stderr (or nothing)."""

    def __init__(self, total, label, enabled=True, width=30):
        self.total, self.label, self.enabled, self.width = total, label, enabled, width
        self.done = self.failed = 0
        self.started = time.perf_counter()

    def update(self, row):
        self.done += 1
        self.failed += row["status"] != "ok"
        if self.enabled and (self.done == self.total or self.done % max(1, self.total // 200) == 0):
            filled = int(self.width * self.done / self.total)
            sys.stderr.write(f"\r{self.label} [{'#' * filled}{' ' * (self.width - filled)}] {self.done}/{self.total}"
                             f" ({self.failed} failed) {time.perf_counter() - self.started:6.1f} s")
            if self.done == self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def start_client(scheduler=None, workers=None):
    """(client, cluster): the named scheduler, or a LocalCluster on loopback
    (its HTTP/dashboard server on a free port, so several can coexist)."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    cluster = LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=":0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


def prepare_workers(client, fmu_path, ship, upload_modules=False):
    """What the tasks get as ``fmu``: the path, or (``ship``) a future of the
    FMU's bytes broadcast to every worker. ``upload_modules`` sends the helper
    modules to the workers (an external cluster). Not for a LocalCluster:
    ``upload_file`` also (re)imports the modules in the scheduler, which
    there is this process."""
    if upload_modules:
        here = Path(__file__).resolve().parent
        for name in HELPER_MODULES:
            client.upload_file(str(here / name))
    if not ship:
        return str(fmu_path)
    return client.scatter(Path(fmu_path).read_bytes(), broadcast=True)


def run_dask(client, specs, fmu, progress=True, label="dask", task=None):
    """Submit one task per spec; gather rows as they complete. Returns (rows,
    wall). ``task`` (default ``run_task``) is for tests."""
    from dask.distributed import as_completed

    import sweep_dask  # by reference, so workers import the module rather than unpickling __main__

    task = task or sweep_dask.run_task
    started = time.perf_counter()
    futures = {client.submit(task, spec, fmu, pure=False): spec for spec in specs}
    bar, rows = Progress(len(specs), label, progress), []
    for future in as_completed(futures):
        try:
            row = future.result()
        except Exception as exc:
            row = lost_row(futures[future], exc)
        rows.append(row)
        bar.update(row)
    return rows, time.perf_counter() - started


def run_serial(specs, fmu_path, progress=True, label="serial"):
    started = time.perf_counter()
    bar, rows = Progress(len(specs), label, progress), []
    for spec in specs:
        rows.append(run_task(spec, str(fmu_path)))
        bar.update(rows[-1])
    return rows, time.perf_counter() - started


# --------------------------------------------------------------------------
# The table, the figure, the summary
# --------------------------------------------------------------------------

def table(rows):
    import pandas as pd

    df = pd.DataFrame(rows).sort_values("run_id").reset_index(drop=True)
    first = ["run_id", "model", "scene", "h", "status", "error"]
    return df[first + [c for c in df.columns if c not in first]]


def write_table(df, path):
    """CSV always; Parquet beside it when pyarrow is installed. Returns the paths."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False)
    written = [path]
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return written
    df.to_parquet(path.with_suffix(".parquet"), index=False)
    return written + [path.with_suffix(".parquet")]


def main_effects(df, model):
    """{(scene, parameter): (values, mean stress at 20 %)} over the ok runs."""
    out = {}
    ok = df[(df["status"] == "ok") & (df["model"] == model)]
    for scene in ("passive", "activated"):
        part = ok[ok["scene"] == scene]
        for name in ("D", "sigma0", "kc", "ke", "d"):
            if name in part and part[name].notna().any() and part[name].nunique() > 1:
                means = part.groupby(name)["stress_20"].mean()
                out[(scene, name)] = (means.index.to_numpy(), means.to_numpy())
    return out


def plot_main_effects(effects, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(effects), figsize=(3.2 * len(effects), 3.4), squeeze=False)
    for ax, ((scene, name), (x, y)) in zip(axes[0], effects.items()):
        ax.plot(x, y / 1e3, "o-")
        if name == "D":
            ax.set_xscale("log")
        ax.set(xlabel=name, title=scene)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("mean stress at 20 % [kPa]")
    fig.suptitle(title)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def waited(df):
    """What the gap between the runs' wall and CPU times on the cluster says, if it says anything."""
    wall, cpu = df["wall_s"].sum(), df["cpu_s"].sum()
    return f" (wall {wall / cpu - 1:.0%} above CPU: the workers waited for a core)" if wall > 1.1 * cpu else ""


def cpu_ratio(df, t):
    """The cluster runs' CPU time against the serial loop's: above 1, each run cost more beside another."""
    ratio = df["cpu_s"].sum() / t["serial_cpu_s"]
    if ratio <= 1.05:
        return ""
    return (f" — the cluster's runs took {ratio:.2f}x that CPU time (two runs side by side share the caches and "
            f"the memory bandwidth), which keeps the speed-up below the worker count")


def summary_text(model, df, timing, files, effects):
    ok, failed = df[df["status"] == "ok"], df[df["status"] != "ok"]
    lines = [f"## {model}: {len(df)} runs", ""]
    lines.append(f"- {len(ok)} ok, {len(failed)} failed; every run is a row of `{files[0]}`.")
    t = timing
    lines.append(f"- dask: {t['dask_s']:.1f} s wall for the {len(df)} runs on {t['workers']} worker processes "
                 f"({t['cluster']}; cluster start-up {t['startup_s']:.1f} s, not included); "
                 f"per-run wall times sum to {df['wall_s'].sum():.1f} s, their CPU times to {df['cpu_s'].sum():.1f} s"
                 f"{waited(df)}. 1-minute load average {t['load_before']:.2f} before, {t['load_after_dask']:.2f} after.")
    if "serial_s" in t:
        lines.append(f"- serial loop in one process: {t['serial_s']:.1f} s; speed-up {t['serial_s'] / t['dask_s']:.2f}x "
                     f"(with cluster start-up: {t['serial_s'] / (t['dask_s'] + t['startup_s']):.2f}x); CPU time of "
                     f"the serial runs {t['serial_cpu_s']:.1f} s{cpu_ratio(df, t)}; load average after it "
                     f"{t['load_after_serial']:.2f}; the two tables agree: {t['serial_matches']}.")
    for _, r in failed.iterrows():
        params = {k: r[k] for k in ("sigma0", "D", "kc", "ke", "d") if k in r and r[k] == r[k]}
        lines.append(f"- failed run {r['run_id']} ({r['scene']}, {params}): {r['error']}")
    lines.append("")
    lines.append("| scene | parameter | mean stress at 20 % strain over the other parameters [kPa], lowest → highest value |")
    lines.append("|---|---|---|")
    for (scene, name), (x, y) in effects.items():
        lines.append(f"| {scene} | {name} ({x[0]:.3g} … {x[-1]:.3g}) | {', '.join(f'{v / 1e3:.1f}' for v in y)} |")
    return lines


def display_path(path):
    """``path`` relative to the repository when it lies inside it (the page is committed), else as given."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(REPO.resolve()))
    except ValueError:
        return str(path)


def versions():
    """Python and the packages the sweep runs on, for the page's header."""
    import dask
    import distributed
    import fmpy
    import pandas as pd

    return (f"Python {platform.python_version()}, dask {dask.__version__}, distributed {distributed.__version__}, "
            f"fmpy {fmpy.__version__}, numpy {np.__version__}, pandas {pd.__version__}")


def compare_tables(a, b):
    """Whether two result tables agree run by run (stress to 1e-9 relative, same statuses)."""
    cols = ["status"] + list(STRESS_COLUMNS)
    a, b = table(a)[["run_id"] + cols], table(b)[["run_id"] + cols]
    if list(a["run_id"]) != list(b["run_id"]) or list(a["status"]) != list(b["status"]):
        return False
    x, y = a[list(STRESS_COLUMNS)].to_numpy(float), b[list(STRESS_COLUMNS)].to_numpy(float)
    return bool(np.allclose(x, y, rtol=1e-9, atol=0, equal_nan=True))


# --------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------

def sweep_model(client, model, args, cluster_info):
    make, h = SWEEPS[model.key]
    runs = make()[: args.limit] if args.limit else make()
    specs = make_specs(model.key, runs, h, inject_failure=args.inject_failure)
    fmu = prepare_workers(client, model.fmu, args.ship_fmu or bool(args.scheduler), bool(args.scheduler))
    timing = dict(cluster_info, load_before=os.getloadavg()[0])
    rows, timing["dask_s"] = run_dask(client, specs, fmu, not args.no_progress, f"{model.key} dask")
    timing["load_after_dask"] = os.getloadavg()[0]
    if args.compare_serial:
        serial_rows, serial_s = run_serial(specs, model.fmu, not args.no_progress, f"{model.key} serial")
        timing.update(serial_s=serial_s, serial_matches=compare_tables(rows, serial_rows),
                      serial_cpu_s=float(sum(r["cpu_s"] for r in serial_rows)),
                      load_after_serial=os.getloadavg()[0])
    return table(rows), timing


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scheduler", default=None, help="address of an existing dask scheduler")
    parser.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: cores)")
    parser.add_argument("--models", default="1d,fe", help="comma-separated: 1d, fe (default: both if available)")
    parser.add_argument("--fmu", default=str(mm.FMU_1D))
    parser.add_argument("--fe-fmu", default=str(mm.FMU_FE))
    parser.add_argument("--limit", type=int, default=None, help="only the first N runs of each sweep (tests)")
    parser.add_argument("--inject-failure", action="store_true", help=f"add one run with {FAILING_PARAMS}")
    parser.add_argument("--compare-serial", action="store_true", help="also run a serial loop; report speed-up")
    parser.add_argument("--ship-fmu", action="store_true", help="broadcast the FMU bytes even on a local cluster")
    parser.add_argument("--no-progress", action="store_true")
    parser.add_argument("--out", default=str(REPO / "out"), help="directory of the tables (default: %(default)s)")
    parser.add_argument("--figures", default=str(REPO / "docs" / "figures"), help="figure directory")
    parser.add_argument("--doc", default=str(REPO / "docs" / "sweeps.md"), help="summary page")
    parser.add_argument("--render", action="store_true",
                        help="run nothing: write the page and figures again from the tables and timing.json in --out")
    args = parser.parse_args(argv)

    wanted = {m.strip().upper() for m in args.models.split(",")}
    models = [m for m in mm.all_models(args.fmu, args.fe_fmu) if m.key in wanted]
    skipped = [m.skip_reason() for m in models if not m.available()]
    for reason in skipped:
        print(reason)
    models = [mm.snapshot(m) for m in models if m.available()]
    if not models:
        print("error: no model to sweep", file=sys.stderr)
        return 1

    if args.render:
        return render(args)
    started = time.perf_counter()
    client, cluster = start_client(args.scheduler, args.workers)
    cluster_info = {"startup_s": time.perf_counter() - started,
                    "workers": len(client.scheduler_info()["workers"]),
                    "cluster": f"scheduler {args.scheduler}" if args.scheduler else "LocalCluster on 127.0.0.1"}
    command = " ".join([".venv/bin/python examples/sweep_dask.py"] + list(sys.argv[1:] if argv is None else argv))
    record = {"command": command, "run_at": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
              "machine": f"{os.cpu_count()} cores, {platform.platform()}", "versions": versions(),
              "cluster": cluster_info, "skipped": skipped, "models": {}}
    try:
        for model in models:
            df, timing = sweep_model(client, model, args, cluster_info)
            files = write_table(df, Path(args.out) / f"sweep_{model.key.lower()}.csv")
            record["models"][model.key] = {"runs": len(df), "failed": int((df["status"] != "ok").sum()), **timing,
                                           "files": [display_path(f) for f in files]}
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    Path(args.out, "timing.json").write_text(json.dumps(record, indent=1, default=str) + "\n")
    print(json.dumps(record["models"], indent=1, default=str))
    return render(args)


def render(args):
    """The page and the figures from the tables and ``timing.json`` in ``--out`` (what a run wrote)."""
    import pandas as pd

    record = json.loads(Path(args.out, "timing.json").read_text())
    info = record["cluster"]
    lines = ["# Parameter sweeps on dask.distributed", "", provenance.header(), "",
             "Generated by `examples/sweep_dask.py` (its docstring describes the sweeps and the table):", "",
             f"```sh\n{record['command']}\n```", "",
             f"Run {record['run_at']}; machine: {record['machine']}; {info['cluster']}, {info['workers']} workers; "
             f"{record['versions']}.", ""]
    lines += [f"**{reason}**" for reason in record["skipped"]] + ([""] if record["skipped"] else [])
    for key, timing in record["models"].items():
        files = timing["files"]
        df = pd.read_csv(REPO / files[0] if not Path(files[0]).is_absolute() else files[0])
        effects = main_effects(df, key)
        fig = plot_main_effects(effects, Path(args.figures) / f"sweep_{key.lower()}.png",
                                f"{key}: main effects on the stress at 20 % strain")
        lines += summary_text(key, df, timing, files, effects)
        lines += ["", f"![{key} main effects]({os.path.relpath(fig, Path(args.doc).parent)})", ""]
    Path(args.doc).parent.mkdir(parents=True, exist_ok=True)
    Path(args.doc).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
