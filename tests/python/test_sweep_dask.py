"""examples/sweep_dask.py on a LocalCluster bound to 127.0.0.1: every run comes
back as a row, a failing run is reported with its parameters and the FMU's
message, the FMU can be shipped to workers as bytes, the results equal a
serial loop's, and the script writes its table and summary."""

from __future__ import annotations

import os

import pandas as pd
import pytest

import muscle_models as mm
import sweep_dask as sd


@pytest.fixture(scope="module")
def client():
    client, cluster = sd.start_client(workers=2)
    assert all(addr.startswith("tcp://127.0.0.1:") for addr in client.scheduler_info()["workers"])
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def specs():
    """Six activated runs varying d (kc, ke, sigma0 fixed) and one failing run."""
    runs = [("activated", {"sigma0": 7e5, "kc": 5.0, "ke": 5.0, "d": d}) for d in (1.1, 1.25, 1.4, 1.55, 1.7, 1.8)]
    return sd.make_specs("1D", runs, 1e-3, inject_failure=True)


@pytest.fixture(scope="module")
def dask_rows(client, specs, fmu_path):
    rows, wall = sd.run_dask(client, specs, str(fmu_path), progress=False)
    return rows


def test_every_run_is_a_row(dask_rows, specs):
    df = sd.table(dask_rows)
    assert list(df["run_id"]) == [s["run_id"] for s in specs]
    assert (df["status"] == "ok").sum() == len(specs) - 1
    assert df["worker"].str.len().min() > 0


def test_failing_run_is_reported_with_its_parameters(dask_rows, specs):
    """The out-of-range d = 0.5 run is in the table: status error, its d, and
    the FMU's message naming the parameter and its range; no stress values."""
    df = sd.table(dask_rows)
    failed = df[df["status"] != "ok"]
    assert len(failed) == 1
    row = failed.iloc[0]
    assert row["run_id"] == specs[-1]["run_id"] and row["d"] == 0.5 and row["scene"] == "passive"
    assert "d = 0.5" in row["error"] and "[1, 100]" in row["error"]
    assert pd.isna(row["stress_20"])


def test_results_are_physical_and_equal_a_serial_loop(dask_rows, specs, fmu_path):
    """Activated stress at 20 % rises with d (paper Fig 12), and a serial loop
    in this process gives the same table."""
    df = sd.table(dask_rows)
    ok = df[df["status"] == "ok"].sort_values("d")
    assert ok["stress_20"].is_monotonic_increasing and ok["stress_20"].min() > 5e5
    serial, _ = sd.run_serial(specs, fmu_path, progress=False)
    assert sd.compare_tables(dask_rows, serial)


def test_fmu_shipped_as_bytes_gives_the_same_results(client, specs, fmu_path, dask_rows):
    """With the FMU broadcast as bytes (how remote workers get it), each
    worker writes it once and the rows are the same."""
    fmu = sd.prepare_workers(client, fmu_path, ship=True)
    rows, _ = sd.run_dask(client, specs, fmu, progress=False)
    assert sd.compare_tables(rows, dask_rows)


def test_script_writes_table_figure_and_summary(fmu_path, tmp_path):
    """`sweep_dask.py --models 1d --limit 6 --inject-failure`: a CSV with 7
    rows (one failed, with its error), the main-effects PNG, and a summary
    that names the failed run."""
    rc = sd.main(["--models", "1d", "--fmu", str(fmu_path), "--limit", "6", "--inject-failure", "--workers", "2",
                  "--no-progress", "--out", str(tmp_path), "--figures", str(tmp_path),
                  "--doc", str(tmp_path / "sweeps.md")])
    assert rc == 0
    df = pd.read_csv(tmp_path / "sweep_1d.csv")
    assert len(df) == 7 and (df["status"] == "error").sum() == 1
    assert "out of range" in df.loc[df["status"] == "error", "error"].iloc[0]
    assert (tmp_path / "sweep_1d.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (tmp_path / "sweeps.md").read_text()
    assert "failed run 6" in text and "dask:" in text
    # --render runs nothing and writes the same page from the tables and timing.json.
    (tmp_path / "sweeps.md").unlink()
    assert sd.main(["--render", "--out", str(tmp_path), "--figures", str(tmp_path),
                    "--doc", str(tmp_path / "sweeps.md")]) == 0
    assert (tmp_path / "sweeps.md").read_text() == text


def test_fe_runs_when_its_fmu_exists(client):
    """With dist/HillMuscleFE.fmu: the first two (passive) runs of its sweep,
    at a coarse 0.05 s step to keep the test short, come back ok with its
    diagnostics (volume ratios near 1, Newton iterations counted)."""
    fe = mm.model_fe()
    if not fe.available():
        pytest.skip(fe.skip_reason())
    make, _ = sd.SWEEPS["FE"]
    specs = sd.make_specs("FE", make()[:2], 5e-2)
    assert {s["scene"] for s in specs} == {"passive"}
    rows, _ = sd.run_dask(client, specs, str(fe.fmu), progress=False)
    df = sd.table(rows)
    assert list(df["status"]) == ["ok", "ok"], list(df["error"])
    assert (df["volume_ratio_min"] > 0.9).all() and (df["volume_ratio_max"] < 1.1).all()
    assert (df["newton_iterations"] > 0).all()
    assert (df["stress_20"] > 0).all()


def _die_on_d_1_4(spec, fmu):
    """A task that takes its worker process down for one spec (d = 1.4)."""
    if spec["params"].get("d") == 1.4:
        os._exit(1)
    return sd.run_task(spec, fmu)


def test_task_lost_with_its_worker_is_a_row(specs, fmu_path):
    """When a worker dies under a task (dask gives up: allowed-failures 0),
    the run is still in the table, status 'lost', with its parameters and
    dask's KilledWorker error."""
    import dask
    import distributed  # noqa: F401  (loads distributed's config defaults before they are overridden)

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        client, cluster = sd.start_client(workers=1)
    try:
        rows, _ = sd.run_dask(client, specs, str(fmu_path), progress=False, task=_die_on_d_1_4)
    finally:
        client.close()
        cluster.close()
    df = sd.table(rows)
    assert list(df["run_id"]) == [s["run_id"] for s in specs]
    lost = df[df["status"] == "lost"]
    # the task that killed its worker is lost; a task queued on that worker at
    # the same moment may be lost with it (allowed-failures 0): both reported
    assert 1.4 in set(lost["d"]) and lost["d"].notna().all()
    assert lost["error"].str.contains("KilledWorker").all()
    assert set(df["status"]) <= {"ok", "error", "lost"} and (df["status"] == "error").sum() == 1
