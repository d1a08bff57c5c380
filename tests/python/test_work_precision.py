"""examples/work_precision.py --quick: convergence orders, the two cost paths,
the report, failing cases, and the FE code path.

The orders asserted are those the quick sweep (h = 1e-1 .. 1e-4 s, reference
h = 1e-5 s with input derivatives, fit over h <= 1e-2 s) measures:

* "1D one-step" (``adaptive_substeps`` off: one backward-Euler CE-SEE update
  per communication step): without input derivatives first order in every
  scene (the one-step lag); with input derivatives the passive ramp is exact at
  every communication point (to round-off: the step ends exactly at L(t + h)
  and the passive force is a function of the length), and with the
  contractile element active the backward-Euler CE-SEE update keeps first
  order, with a smaller error than without derivatives;
* "1D" (the default, error-controlled substeps): the CE-SEE error is held near
  the tolerance whatever h is, so with input derivatives the activated scene
  stays within 1e-3 of the peak force at every h up to 0.1 s, and no error is
  above the one-step scheme's for h <= 1e-2.

"all points" = the error over each run's own communication points (the
common grid of the coarsest step has only 6 points in the 0.6 s fast scene).
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

import muscle_models as mm
import scenes as sc
import work_precision as wp


@pytest.fixture(scope="module")
def quick(fmu_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("wp")
    started = time.perf_counter()
    rc = wp.main(["--quick", "--no-fe", "--fmu", str(fmu_path), "--out", str(out), "--doc", str(out / "wp.md"),
                  "--json", str(out / "wp.json"), "--quiet"])
    elapsed = time.perf_counter() - started
    assert rc == 0
    result = json.loads((out / "wp.json").read_text())
    orders = {tuple(json.loads(k)): v for k, v in result["orders"].items()}
    return {"dir": out, "result": result, "orders": orders, "elapsed": elapsed}


ONE_STEP = "1D one-step"


def _rows(quick, scene, derivatives, family="1D"):
    return sorted((r for r in quick["result"]["rows"]
                   if r["scene"] == scene and r["derivatives"] == derivatives and r["family"] == family),
                  key=lambda r: -r["h"])


def test_quick_mode_runs_under_two_minutes(quick):
    assert quick["elapsed"] < 120, quick["elapsed"]
    assert quick["result"]["meta"]["references"]["1D"]["h"] == pytest.approx(1e-5)


@pytest.mark.parametrize("scene", ["passive", "activated", "fast"])
def test_first_order_without_input_derivatives(quick, scene):
    """LS order of the RMS error (all points and common grid) is 1 +- 0.1
    (common grid +- 0.15), and the error falls at every halving of h <= 1e-2."""
    o = quick["orders"][(ONE_STEP, scene, False)]
    assert 0.9 < o["rms_all"]["slope"] < 1.1, o
    assert 0.85 < o["rms"]["slope"] < 1.15, o
    errs = [r["rms_all"] for r in _rows(quick, scene, False, ONE_STEP) if r["h"] <= 1e-2]
    assert np.all(np.diff(errs) < 0), errs


def test_passive_ramp_with_input_derivatives_is_exact(quick):
    """With input derivatives the passive ramp matches the reference to
    round-off at every communication point, for every h (also 0.1 s), while
    without them the error at h = 1e-2 is above 1e-3 of the peak force."""
    rows = _rows(quick, "passive", True)
    assert len(rows) == len(wp.H_1D["quick"])
    assert max(r["max_all"] for r in rows) < wp.ROUND_OFF
    lagged = next(r for r in _rows(quick, "passive", False) if r["h"] == 1e-2)
    assert lagged["max_all"] > 1e-3


@pytest.mark.parametrize("scene", ["activated", "fast"])
def test_active_scenes_stay_first_order_with_input_derivatives(quick, scene):
    """With the CE active the order with derivatives is still 1 +- 0.1 (all
    points): the CE-SEE update is backward Euler. The derivatives still lower
    the error at every h <= 1e-2."""
    o = quick["orders"][(ONE_STEP, scene, True)]
    assert 0.9 < o["rms_all"]["slope"] < 1.1, o
    with_d = {r["h"]: r["rms_all"] for r in _rows(quick, scene, True, ONE_STEP)}
    without = {r["h"]: r["rms_all"] for r in _rows(quick, scene, False, ONE_STEP)}
    for h in with_d:
        if h <= 1e-2:
            assert with_d[h] < without[h], (h, with_d[h], without[h])


def test_substeps_hold_the_activated_error_at_the_tolerance(quick):
    """With error-controlled substeps (the default) and input derivatives the
    activated scene's RMS error stays below 1e-3 of the peak force at every h,
    also at 0.1 s, where the one-step scheme is 30x above it."""
    adaptive = _rows(quick, "activated", True)
    one_step = _rows(quick, "activated", True, ONE_STEP)
    assert len(adaptive) == len(wp.H_1D["quick"])
    assert max(r["rms_all"] for r in adaptive) < 1e-3, [r["rms_all"] for r in adaptive]
    assert one_step[0]["h"] == 0.1 and one_step[0]["rms_all"] > 3e-2


@pytest.mark.parametrize("scene", ["activated", "fast"])
@pytest.mark.parametrize("derivatives", [False, True])
def test_substeps_never_worse_than_one_step(quick, scene, derivatives):
    """For h <= 1e-2 the default's error is at most the one-step scheme's
    (the substeps only ever refine a step), and equal where no step needed a
    substep (h = 1e-4: same value to 1e-9 relative)."""
    adaptive = {r["h"]: r["rms_all"] for r in _rows(quick, scene, derivatives)}
    one_step = {r["h"]: r["rms_all"] for r in _rows(quick, scene, derivatives, ONE_STEP)}
    for h, e in adaptive.items():
        if h <= 1e-2:
            assert e <= one_step[h] * (1 + 1e-9), (h, e, one_step[h])
    assert adaptive[1e-4] == pytest.approx(one_step[1e-4], rel=1e-9)


def test_c_abi_and_fmpy_agree_and_costs_are_medians_of_the_runs(quick):
    """Both paths give bit-identical forces in every case, each row's step
    count is t_end / h, and each cost is the median of that row's recorded runs
    per simulated second (one per repeat, all positive and finite).

    How the two costs compare is a benchmark, not a test: it is measured by
    the full report (docs/work-precision.md) and BENCHMARKS.md, on a shared
    machine whose timings a test cannot rely on."""
    rows = quick["result"]["rows"]
    repeats = quick["result"]["meta"]["repeats"]
    assert rows and all(r["identical"] for r in rows)
    t_end = {s.name: s.t_end for s in (sc.passive(), sc.activated(), sc.fast())}
    for r in rows:
        assert r["steps"] == round(t_end[r["scene"]] / r["h"]), r
        for path in ("fmpy", "cabi"):
            runs = r[f"{path}_runs_s"]
            assert len(runs) == repeats and all(np.isfinite(runs)) and min(runs) > 0, r
            assert r[f"{path}_s_per_s"] == pytest.approx(float(np.median(runs)) / t_end[r["scene"]], rel=1e-12)


def test_report_has_tables_orders_plots_and_pending_fe(quick):
    text = (quick["dir"] / "wp.md").read_text()
    for needle in ("Observed orders", "Machine:", "fmpy", "C ABI", "1D reduction vs FE muscle", "Pending",
                   "exact to round-off", "first order", "h = 1e-05"):
        assert needle in text, needle
    for scene in ("passive", "activated", "fast"):
        png = quick["dir"] / f"work_precision_{scene}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert png.name in text


def test_failing_case_is_a_row_with_its_error(fmu_path):
    """A case the FMU refuses (d = 0.5 is outside [1, 100]) becomes a row with
    the FMU's message, NaN errors, and no order is fitted to it."""
    family = wp.Family(mm.model_1d(fmu_path), {"d": 0.5}, (1e-2,), 1)
    scene = sc.passive()
    ref = wp.run_reference(wp.Reference(mm.model_1d(fmu_path), {}, 1e-3), scene)
    row = wp.measure(family, scene, 1e-2, False, ref)
    assert "d = 0.5" in row["error"] and "out of range" in row["error"]
    assert np.isnan(row["rms"])
    assert wp.observed_orders([row]) == {}


def test_fe_code_path_with_the_1d_fmu_standing_in(fmu_path, tmp_path):
    """The FE rows, their reference and the 1D-vs-FE comparison run end to end
    when an FE model is given (here the 1D FMU stands in, on its one
    'mesh level'): FE rows appear and the comparison section has a table."""
    rc = wp.main(["--quick", "--fmu", str(fmu_path), "--fe-fmu", str(fmu_path), "--fe-levels", "",
                  "--steps", "1e-2,5e-3", "--fe-steps", "1e-2,5e-3", "--fe-ref-step", "2.5e-4",
                  "--scenes", "passive,activated", "--repeats", "1", "--out", str(tmp_path),
                  "--doc", str(tmp_path / "wp.md"), "--json", str(tmp_path / "wp.json"), "--quiet"])
    assert rc == 0
    result = json.loads((tmp_path / "wp.json").read_text())
    assert {r["model"] for r in result["rows"]} == {"1D", "FE"}
    assert set(result["comparison"]) == {"passive", "activated"}
    # the same model at two reference steps: a model-form difference at the
    # level of the 1D reference's own error, far below 1 %
    assert 0 < result["comparison"]["activated"]["model_form"]["rms_all"] < 1e-2
    assert "cheapest 1D run" in (tmp_path / "wp.md").read_text()


def test_fe_rows_when_its_fmu_exists(fmu_path, tmp_path):
    """With dist/HillMuscleFE.fmu: a small passive sweep on its coarsest level
    gives finite errors and costs; with input derivatives the passive FE
    matches its own reference to the Newton tolerance (< 1e-8 of the peak)."""
    fe = mm.model_fe()
    if not fe.available():
        pytest.skip(fe.skip_reason())
    rc = wp.main(["--quick", "--fmu", str(fmu_path), "--steps", "1e-2,5e-3", "--fe-steps", "0.1",
                  "--fe-ref-step", "0.05", "--scenes", "passive", "--out", str(tmp_path),
                  "--doc", str(tmp_path / "wp.md"), "--json", str(tmp_path / "wp.json"), "--quiet"])
    assert rc == 0
    result = json.loads((tmp_path / "wp.json").read_text())
    fe_rows = [r for r in result["rows"] if r["model"] == "FE"]
    assert len(fe_rows) == 2 and not any(r["error"] for r in fe_rows)
    assert all(np.isfinite(r["cabi_s_per_s"]) and r["cabi_s_per_s"] > 0 for r in fe_rows)
    assert all(r["max_all"] < 1e-8 for r in fe_rows if r["derivatives"])
    assert "passive" in result["comparison"]


def test_several_jobs_give_the_same_rows_in_the_same_order(fmu_path, tmp_path):
    """``--jobs 2`` measures two cases at a time in forked workers: the rows
    (errors, steps, order) and the fitted orders are those of ``--jobs 1``,
    only the costs differ; the report says how the costs were measured."""
    results = {}
    for jobs in (1, 2):
        out = tmp_path / f"jobs{jobs}"
        rc = wp.main(["--quick", "--no-fe", "--fmu", str(fmu_path), "--steps", "1e-1,5e-2,1e-2",
                      "--scenes", "passive,fast", "--repeats", "1", "--jobs", str(jobs), "--out", str(out),
                      "--doc", str(out / "wp.md"), "--json", str(out / "wp.json"), "--quiet"])
        assert rc == 0
        results[jobs] = json.loads((out / "wp.json").read_text())
    keys = ("family", "scene", "h", "derivatives", "steps", "rms", "max", "rms_all", "max_all", "end")
    one, two = ([tuple(r[k] for k in keys) for r in results[j]["rows"]] for j in (1, 2))
    assert len(one) == 2 * 2 * 2 * 3 and one == two
    assert results[1]["orders"] == results[2]["orders"]
    assert results[2]["meta"]["jobs"] == 2
    assert "`--jobs 2`" in (tmp_path / "jobs2" / "wp.md").read_text()
    assert "One case at a time" in (tmp_path / "jobs1" / "wp.md").read_text()


def test_run_all_keeps_the_task_order_and_reports_every_task():
    done = []
    assert wp._run_all(abs, [-3, 1, -2, 5], [1, 4, 2, 3], 2, lambda i, r: done.append((i, r))) == [3, 1, 2, 5]
    assert sorted(done) == [(0, 3), (1, 1), (2, 2), (3, 5)]
