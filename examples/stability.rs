//! The stability matrix: runs every model of
//! `testkit::stability` over the full grid and writes `docs/stability.md`
//! (the report) and `docs/stability.csv` (every cell).
//!
//! ```sh
//! cargo run --release --example stability                  # full matrix, ~35 min on 2 cores (docs/stability.md)
//! cargo run --release --example stability -- --subset      # the CI subset only
//! cargo run --release --example stability -- --baseline docs/stability-before.csv
//! ```
//!
//! Options: `--subset` (the CI subset), `--model NAME` (one model only:
//! writes `stability-<name>.md`/`.csv`),
//! `--d LIST`, `--h LIST` (comma-separated values of D resp. h: a reduced
//! selection, which the page's header names with the cells left out),
//! `--out DIR` (default `docs`),
//! `--baseline CSV` (a CSV of an earlier run: adds a before/after section),
//! `--csv-only`. `STABILITY_THREADS` sets the worker threads.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;
use testkit::stability::{self, *};

/// A job of the run: an index into `models()` and a cell.
type Job = (usize, Cell);

fn main() {
    let mut subset = false;
    let mut out = PathBuf::from("docs");
    let mut baseline: Option<PathBuf> = None;
    let mut csv_only = false;
    let mut only: Option<String> = None;
    let mut keep_d: Option<Vec<f64>> = None;
    let mut keep_h: Option<Vec<f64>> = None;
    let list = |v: Option<String>, what: &str| -> Vec<f64> {
        v.unwrap_or_else(|| panic!("{what} LIST"))
            .split(',')
            .map(|x| {
                x.trim()
                    .parse()
                    .unwrap_or_else(|e| panic!("{what} {x}: {e}"))
            })
            .collect()
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--subset" => subset = true,
            "--out" => out = args.next().expect("--out DIR").into(),
            "--baseline" => baseline = Some(args.next().expect("--baseline CSV").into()),
            "--csv-only" => csv_only = true,
            "--model" => only = Some(args.next().expect("--model NAME")),
            "--d" => keep_d = Some(list(args.next(), "--d")),
            "--h" => keep_h = Some(list(args.next(), "--h")),
            other => {
                eprintln!("unknown argument {other}");
                std::process::exit(2);
            }
        }
    }
    let entries = models();
    let cells = if subset { ci_subset() } else { full_grid() };
    let selected: Vec<Job> = entries
        .iter()
        .enumerate()
        .filter(|(_, entry)| !subset || entry.in_ci_subset.is_some())
        .filter(|(_, entry)| only.as_deref().map_or(true, |m| m == entry.name))
        .flat_map(|(e, entry)| {
            cells
                .iter()
                .filter(|c| (entry.select)(c))
                .filter(move |c| !subset || entry.in_ci_subset.is_some_and(|ci| ci(c)))
                .map(move |c| (e, *c))
        })
        .collect();
    // A reduced selection (`--d`, `--h`): the cells it leaves out are named
    // in the page's header.
    let kept = |values: &Option<Vec<f64>>, x: f64| values.as_ref().map_or(true, |v| v.contains(&x));
    let (jobs, left_out): (Vec<Job>, Vec<Job>) = selected
        .into_iter()
        .partition(|(_, c)| kept(&keep_d, c.d_comp) && kept(&keep_h, c.h));
    let reduced = Reduced {
        d: keep_d.clone(),
        h: keep_h.clone(),
        left_out: left_out.len(),
    };
    let threads = threads();
    eprintln!("stability: {} cells on {threads} threads", jobs.len());
    let started = Instant::now();
    let results = run_jobs(&entries, &jobs, threads, true);
    let wall = started.elapsed().as_secs_f64();
    std::fs::create_dir_all(&out).unwrap();
    // The page and CSV of a run: `stability[-subset][-<model>]`.
    let name = format!(
        "stability{}{}",
        if subset { "-subset" } else { "" },
        only.as_deref()
            .map_or(String::new(), |m| format!("-{}", m.to_lowercase()))
    );
    let csv_path = out.join(format!("{name}.csv"));
    std::fs::write(&csv_path, csv(&results)).unwrap();
    eprintln!("stability: wrote {}", csv_path.display());
    if !csv_only {
        let base = baseline.map(|p| {
            let text =
                std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p, parse_csv(&text))
        });
        let md = report(
            &results,
            wall,
            threads,
            subset,
            only.as_deref(),
            &reduced,
            &name,
            base.as_ref(),
        );
        let md_path = out.join(format!("{name}.md"));
        std::fs::write(&md_path, md).unwrap();
        eprintln!("stability: wrote {}", md_path.display());
    }
    let failures: usize = results.iter().filter(|r| !acceptance(r).is_empty()).count();
    eprintln!("stability: {failures} cells fail the acceptance criteria ({wall:.0} s)");
    if failures > 0 {
        std::process::exit(1);
    }
}

// ---------------------------------------------------------------------------
// CSV
// ---------------------------------------------------------------------------

const CSV_HEADER: &str = "model,scenario,params,D,alpha,S,h,max_input_rate,outcome,end_t,steps,\
discards,retried_pieces_max,nonfinite_steps,bound_violations,iterations_mean,iterations_max,\
ce_iterations_mean,ce_iterations_max,substeps_mean,substeps_max,max_active_ratio,reference,\
reference_outcome,agree_stress,agree_stress_t,agree_active,agree_active_t,seconds,message";

fn outcome_code(o: &Option<Outcome>) -> (&'static str, f64, String) {
    match o {
        Some(Outcome::Completed) => ("completed", f64::NAN, String::new()),
        Some(Outcome::Discarded { t, message }) => ("discarded", *t, message.clone()),
        Some(Outcome::Error { message }) => ("error", f64::NAN, message.clone()),
        Some(Outcome::Timeout { t }) => ("timeout", *t, String::new()),
        None => ("none", f64::NAN, String::new()),
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or(String::new(), |v| format!("{v:.3}"))
}

fn csv(results: &[CellResult]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in results {
        let c = &r.cell;
        let run = &r.coarse;
        let (code, t, mut msg) = outcome_code(&run.outcome);
        if msg.is_empty() {
            if let Some(d) = run.discards.first() {
                msg = d.message.clone();
            }
        }
        for f in std::iter::once(run).chain(r.fine.as_ref()) {
            for v in f.violations.iter().chain(&f.nonfinite) {
                msg = format!("{msg} [{v}]");
            }
        }
        let (ref_code, ..) = r
            .fine
            .as_ref()
            .map_or(("", f64::NAN, String::new()), |f| outcome_code(&f.outcome));
        let a = r.agreement;
        let _ = writeln!(
            s,
            "{},{},{},{:e},{},{:e},{:e},{:.4},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.6},{},{},{},{},{},{},{:.3},\"{}\"",
            r.model,
            c.scenario.name(),
            c.params.name(),
            c.d_comp,
            c.alpha,
            c.s,
            c.h,
            r.max_input_rate,
            code,
            if t.is_nan() { String::new() } else { format!("{t:e}") },
            run.steps,
            run.discards.len(),
            run.discards.iter().filter_map(|d| d.recovered_with).max().map_or(String::new(), |n| n.to_string()),
            run.n_nonfinite + r.fine.as_ref().map_or(0, |f| f.n_nonfinite),
            run.n_violations + r.fine.as_ref().map_or(0, |f| f.n_violations),
            opt(run.iterations.mean()),
            run.iterations.max,
            opt(run.ce_iterations.mean()),
            run.ce_iterations.max,
            opt(run.substeps.mean()),
            run.substeps.max,
            run.max_active_ratio,
            if r.fine.is_some() { "h/100" } else { "skipped" },
            ref_code,
            a.map_or(String::new(), |a| format!("{:.3e}", a.stress)),
            a.map_or(String::new(), |a| format!("{:e}", a.stress_t)),
            a.map_or(String::new(), |a| format!("{:.3e}", a.active)),
            a.map_or(String::new(), |a| format!("{:e}", a.active_t)),
            run.seconds + r.fine.as_ref().map_or(0.0, |f| f.seconds),
            msg.replace('"', "'"),
        );
    }
    s
}

/// A row of a CSV written by [`csv`], as column name → value.
type Row = BTreeMap<String, String>;

fn parse_csv(text: &str) -> Vec<Row> {
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(String::from)
        .collect();
    lines
        .map(|l| {
            // The last column (message) is quoted and may hold commas.
            let (head, msg) = match l.find(",\"") {
                Some(i) => (&l[..i], l[i + 2..].trim_end_matches('"')),
                None => (l, ""),
            };
            let mut row: Row = header
                .iter()
                .cloned()
                .zip(head.split(',').map(String::from))
                .collect();
            row.insert("message".into(), msg.into());
            row
        })
        .collect()
}

// ---------------------------------------------------------------------------
// The report
// ---------------------------------------------------------------------------

/// Matrix-view code of a cell (see the legend in the report).
fn code(r: &CellResult) -> char {
    if !acceptance(r).is_empty() {
        return 'X';
    }
    match r.coarse.outcome {
        Some(Outcome::Discarded { .. }) => return 'D',
        Some(Outcome::Completed) => {}
        _ => return 'X',
    }
    let retried = !r.coarse.discards.is_empty();
    match r.agreement {
        Some(a) if !a.within() => 'a',
        _ if retried => 'r',
        Some(_) => '.',
        None => 'n',
    }
}

fn fmt_h(h: f64) -> String {
    if h >= 0.1 {
        format!("{h}")
    } else {
        format!("{h:e}")
    }
}

/// A communication point, short.
fn fmt_t(t: f64) -> String {
    let s = format!("{t:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// The mean of `c` to two decimals, "—" when it has no samples.
fn mean2(c: &Counts) -> String {
    c.mean().map_or("—".to_string(), |v| format!("{v:.2}"))
}

fn pct(n: usize, of: usize) -> String {
    if of == 0 {
        "—".into()
    } else {
        format!("{n}/{of}")
    }
}

/// A reduced selection of the command line: the values of D and h kept
/// (`None`: all) and the number of cells of the model's selection left out.
struct Reduced {
    d: Option<Vec<f64>>,
    h: Option<Vec<f64>>,
    left_out: usize,
}

impl Reduced {
    fn args(&self) -> Vec<String> {
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:e}"))
                .collect::<Vec<_>>()
                .join(",")
        };
        let mut a = Vec::new();
        if let Some(d) = &self.d {
            a.push(format!("--d {}", join(d)));
        }
        if let Some(h) = &self.h {
            a.push(format!("--h {}", join(h)));
        }
        a
    }

    /// The header's paragraph on the reduced selection (empty if none).
    fn describe(&self, cells: usize) -> String {
        if self.d.is_none() && self.h.is_none() {
            return String::new();
        }
        let set = |v: &Option<Vec<f64>>, all: &[f64]| {
            v.as_deref()
                .unwrap_or(all)
                .iter()
                .map(|x| format!("{x:e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "**A reduced selection:** only the cells with D ∈ {{{}}} 1/Pa and h ∈ {{{}}} s of the \
             model's part of the grid were run ({cells} cells); the other {} cells of that part were not \
             run, so this page says nothing about them. Rerun without `--d`/`--h` for the full selection.\n\n",
            set(&self.d, &D_VALUES),
            set(&self.h, &H_VALUES),
            self.left_out
        )
    }
}

#[allow(clippy::too_many_arguments)]
fn report(
    results: &[CellResult],
    wall: f64,
    threads: usize,
    subset: bool,
    only: Option<&str>,
    reduced: &Reduced,
    name: &str,
    baseline: Option<&(PathBuf, Vec<Row>)>,
) -> String {
    let mut s = String::new();
    let mut args: Vec<String> = Vec::new();
    if subset {
        args.push("--subset".into());
    }
    if let Some(m) = only {
        args.push(format!("--model {m}"));
    }
    args.extend(reduced.args());
    if let Some((p, _)) = baseline {
        args.push(format!("--baseline {}", p.display()));
    }
    let command = if args.is_empty() {
        "cargo run --release --example stability".to_string()
    } else {
        format!(
            "cargo run --release --example stability -- {}",
            args.join(" ")
        )
    };
    let models: Vec<&str> = {
        let mut m: Vec<&str> = results.iter().map(|r| r.model).collect();
        m.dedup();
        m
    };
    let _ = writeln!(
        s,
        "# Stability matrix\n\n{}\n\n\
         Generated by `{command}` ({} cells, {} worker threads, {wall:.0} s wall time). \
         Every cell is in [`{name}.csv`]({name}.csv). Do not edit: \
         rerun the command.\n",
        testkit::provenance::header(),
        results.len(),
        threads,
    );
    s.push_str(&reduced.describe(results.len()));
    let _ = writeln!(
        s,
        "Models: {}. The harness is `testkit::stability` (shared with the CI subset, \
         `tests/stability_subset.rs`); its module documentation is the full specification.\n",
        models.join(", ")
    );
    s.push_str(
        "## What a cell is\n\n\
         One model × D × alpha × S × communication step h × input program × parameter set, driven through \
         the FMI 2.0 functions in-process (`hill_muscle::fmi2::api::*::<Model>`, the functions every \
         exported `fmi2Xxx` symbol forwards to; the runner is generic over the model, so another FMU joins \
         with one entry in `models()`):\n\n",
    );
    let _ = writeln!(
        s,
        "- D ∈ {{{}}} 1/Pa, alpha ∈ {{{}}}, S ∈ {{{}}} 1/s, h ∈ {{{}}} s;",
        D_VALUES.map(|v| format!("{v:e}")).join(", "),
        ALPHA_VALUES.map(|v| v.to_string()).join(", "),
        S_VALUES.map(|v| format!("{v:e}")).join(", "),
        H_VALUES.map(fmt_h).join(", ")
    );
    s.push_str("- parameter sets: `table2` (Table 2), `paper-min` (sigma0 0.16 MPa, kc 4.0, ke 3.14, d 1.1), `paper-max` (sigma0 1.0 MPa, kc 5.88, ke 7.56, d 1.8); every other parameter at Table 2, L0 = 0.05 m;\n- input programs (stretch = length/L0; the force-length support is fibre stretch 0.42–1.68, so 0.3 and 2.0 lie outside it):\n");
    for sc in Scenario::ALL {
        let _ = writeln!(s, "  - `{}`: {}", sc.name(), sc.describe());
    }
    if models.contains(&"HillMusculotendon1D") {
        s.push_str(&unit_programs());
    }
    if models.contains(&"HillMusculotendonFE") {
        s.push_str(&fe_unit_programs(results));
    }
    let _ = writeln!(
        s,
        "\nEvery breakpoint of a program lies on the cell's communication grid (durations rounded to whole steps, \
         at least one), and before each step the master sets the command of the step and the length at its \
         end. The reference run takes {FINE_FACTOR} steps per communication step on the same input signal \
         (length interpolated linearly, command held), so it solves the same continuous problem; it is made \
         when it costs at most {FINE_BUDGET} steps for the 1D model (so not at h = 1e-6 s) and 20,000 for the FE \
         muscle (h ≥ 1e-2 s; the FE runs a 6 × 1 mesh and the part of the grid `fe_cell` selects: every D, \
         (alpha, S) ∈ {{(10, 50), (1000, 1e5)}}, h ≥ 1e-3 s, Table 2 parameters). The master saves the FMU state \
         before every step; after an `fmi2Discard` it checks `fmi2LastSuccessfulTime`, restores the state and \
         retries the step cut into 2, 4, …, {MAX_RETRY_PIECES} pieces; if that fails the cell ends there \
         (`discarded`).\n\n\
         Checks after every completed step of both runs: every Real output finite; activation_level in [0, 1]; \
         0 ≤ active_stress ≤ f_v,max·sigma0·activation_level with f_v,max = d + (d − 1)/(ke·kc) (the eccentric \
         asymptote, MODEL_NOTES \"Hill fibre\"), up to a relative 1e-9 and one ulp of the SEE stretch \
         (alpha (σ_s + beta)·ε·λs: the resolution of σ_s); for the 1D model, the nominal stress of the matrix and \
         the PE, stress − active_stress·fibre_stretch/stretch = [2 U_I' (λ̄f² − 1/λ̄f) + λ̄f σ_p]/λ, ≥ 0 in fibre \
         tension and ≤ 0 in compression (relative 1e-9). Agreement: at every communication point \
         |x − x_ref| ≤ {AGREEMENT_TOL}·max(sigma0, |x_ref|) for x = stress and active_stress (2 % of the \
         maximum isometric stress, or of the stress where that is larger); for a musculotendon unit x = force \
         (relative to F0 = sigma0·area instead of sigma0) and stress, reported in the columns of stress and \
         active_stress.\n\n\
         Each cell is bounded in time: {}s of CPU time of the thread running it for both runs (checked \
         between steps; past it the cell is a `timeout`; CPU time, so a cell's outcome does not depend on the \
         machine's load; the seconds reported are wall time), and a watchdog ends the whole run, naming the cell, if one FMI call does not return \
         within {}s.\n",
        CELL_TIME_LIMIT.as_secs(),
        HANG_LIMIT.as_secs()
    );
    // ---- Acceptance
    let failing: Vec<(&CellResult, Vec<String>)> = results
        .iter()
        .map(|r| (r, acceptance(r)))
        .filter(|(_, f)| !f.is_empty())
        .collect();
    let count = |f: &dyn Fn(&CellResult) -> bool| results.iter().filter(|r| f(r)).count();
    let runs = |r: &CellResult| -> Vec<Run> {
        std::iter::once(r.coarse.clone())
            .chain(r.fine.clone())
            .collect()
    };
    let any_run = |f: &dyn Fn(&Run) -> bool| count(&|r| runs(r).iter().any(f));
    s.push_str("## Acceptance\n\n| criterion | cells failing |\n|---|---|\n");
    let _ = writeln!(
        s,
        "| no crash, no fmi2Error/fmi2Fatal | {} |",
        any_run(&|x| matches!(x.outcome, Some(Outcome::Error { .. })))
    );
    let _ = writeln!(
        s,
        "| no NaN or infinity in any output | {} |",
        any_run(&|x| x.n_nonfinite > 0)
    );
    let _ = writeln!(
        s,
        "| no hang (each cell's run at h within its time bound) | {} |",
        count(&|r| matches!(r.coarse.outcome, Some(Outcome::Timeout { .. })))
    );
    let _ = writeln!(
        s,
        "| every discard explained | {} |",
        any_run(&|x| x.discards.iter().any(|d| explain(&d.message).is_none()))
    );
    let _ = writeln!(
        s,
        "| no completed step outside its bounds | {} |",
        any_run(&|x| x.n_violations > 0)
    );
    let _ = writeln!(
        s,
        "| **all of the above** | **{}** of {} |\n",
        failing.len(),
        results.len()
    );
    for (r, f) in failing.iter().take(40) {
        let _ = writeln!(s, "- {} {}: {}", r.model, r.cell.key(), f.join("; "));
    }
    if failing.len() > 40 {
        let _ = writeln!(s, "- … and {} more (see the CSV)", failing.len() - 40);
    }
    // Reference runs the time bound cut: not compared (a reference is made
    // where affordable), listed so that nothing is hidden.
    let cut: Vec<(&CellResult, f64)> = results
        .iter()
        .filter_map(|r| match r.fine.as_ref().and_then(|f| f.outcome.as_ref()) {
            Some(Outcome::Timeout { t }) => Some((r, *t)),
            _ => None,
        })
        .collect();
    if !cut.is_empty() {
        let _ = writeln!(
            s,
            "\nReference runs (h/100) cut by the cell's time bound — not compared with the run at h; \
             their steps up to the cut are held to every check above: {} cells.\n",
            cut.len()
        );
        for (r, t) in &cut {
            let _ = writeln!(
                s,
                "- {} {}: cut at t = {}",
                r.model,
                r.cell.key(),
                fmt_t(*t)
            );
        }
    }
    // ---- Outcomes
    s.push_str("\n## Outcomes\n\n| model | cells | completed | of which after a master retry | discarded | error | timeout |\n|---|---|---|---|---|---|---|\n");
    for m in &models {
        let of = |f: &dyn Fn(&CellResult) -> bool| count(&|r| r.model == *m && f(r));
        let _ = writeln!(
            s,
            "| {m} | {} | {} | {} | {} | {} | {} |",
            of(&|_| true),
            of(&|r| r.coarse.outcome == Some(Outcome::Completed)),
            of(&|r| r.coarse.outcome == Some(Outcome::Completed) && !r.coarse.discards.is_empty()),
            of(&|r| matches!(r.coarse.outcome, Some(Outcome::Discarded { .. }))),
            of(&|r| matches!(r.coarse.outcome, Some(Outcome::Error { .. }))),
            of(&|r| matches!(r.coarse.outcome, Some(Outcome::Timeout { .. }))),
        );
    }
    // ---- Discards
    let mut groups: BTreeMap<&'static str, Vec<(&CellResult, &Discard, &str)>> = BTreeMap::new();
    for r in results {
        for (what, run) in [("h", Some(&r.coarse)), ("h/100", r.fine.as_ref())] {
            if let Some(run) = run {
                for d in &run.discards {
                    groups
                        .entry(explain(&d.message).unwrap_or("UNEXPLAINED"))
                        .or_default()
                        .push((r, d, what));
                }
            }
        }
    }
    s.push_str("\n## Discards, explained\n\n");
    if groups.is_empty() {
        s.push_str("No step was discarded.\n");
    }
    for (why, list) in &groups {
        let cells: std::collections::BTreeSet<String> =
            list.iter().map(|(r, _, _)| r.cell.key()).collect();
        let recovered = list
            .iter()
            .filter(|(_, d, _)| d.recovered_with.is_some())
            .count();
        let _ = writeln!(
            s,
            "### {why}\n\n{} discarded steps in {} cells ({} completed by the master's retry with smaller steps, \
             at most {} pieces). First message: `{}`\n",
            list.len(),
            cells.len(),
            recovered,
            list.iter().filter_map(|(_, d, _)| d.recovered_with).max().unwrap_or(0),
            list[0].1.message
        );
        for c in cells.iter().take(12) {
            let _ = writeln!(s, "- {c}");
        }
        if cells.len() > 12 {
            let _ = writeln!(s, "- … {} more cells (CSV)", cells.len() - 12);
        }
        s.push('\n');
    }
    // ---- Agreement
    let _ = writeln!(
        s,
        "\n## Agreement with the run at h/100\n\nCells within the tolerance ({AGREEMENT_TOL} relative, above) \
         of those compared, and the worst deviation, by communication step and input program:\n"
    );
    for entry in stability::models() {
        let compared: Vec<_> = results
            .iter()
            .filter(|r| r.model == entry.name)
            .filter_map(|r| r.agreement)
            .collect();
        if compared.is_empty() {
            continue;
        }
        let within = compared.iter().filter(|a| a.within()).count();
        let _ = write!(
            s,
            "- {}: {within}/{} compared cells within",
            entry.name,
            compared.len()
        );
        if entry.time_error_controlled && entry.in_ci_subset.is_some() {
            let _ = writeln!(
                s,
                " (its time error is controlled; the CI subset asserts agreement);"
            );
        } else if entry.time_error_controlled {
            let _ = writeln!(
                s,
                " (its time error is controlled; not in the CI subset, which runs the FE muscle on its \
                 defaults);"
            );
        } else {
            let _ = writeln!(
                s,
                " — **without time error control** (its default): one backward-Euler step of the CE–SEE \
                 update per communication step (substeps only when Newton does not converge), first order in \
                 h, so it deviates at coarse steps with fast activation (S h ≥ 0.5) or a stiff SEE \
                 (alpha = 1000); reported here, not asserted by the CI subset. With `adaptive_substeps = \
                 true` it controls that error (the section on the FE muscle below);"
            );
        }
    }
    s.push('\n');
    let _ = write!(s, "| program |");
    for h in H_VALUES {
        let _ = write!(s, " h = {} |", fmt_h(h));
    }
    s.push_str("\n|---|");
    for _ in H_VALUES {
        s.push_str("---|");
    }
    s.push('\n');
    for sc in Scenario::ALL {
        let _ = write!(s, "| `{}` |", sc.name());
        for h in H_VALUES {
            let a: Vec<Agreement> = results
                .iter()
                .filter(|r| r.cell.scenario == sc && r.cell.h == h)
                .filter_map(|r| r.agreement)
                .collect();
            let within = a.iter().filter(|a| a.within()).count();
            let worst = a.iter().map(|a| a.worst()).fold(0.0, f64::max);
            if a.is_empty() {
                s.push_str(" not affordable |");
            } else {
                let _ = write!(s, " {} (worst {:.1e}) |", pct(within, a.len()), worst);
            }
        }
        s.push('\n');
    }
    s.push_str("\nBy SEE exponent alpha and communication step (all programs):\n\n| alpha |");
    for h in H_VALUES {
        let _ = write!(s, " h = {} |", fmt_h(h));
    }
    s.push_str("\n|---|");
    for _ in H_VALUES {
        s.push_str("---|");
    }
    s.push('\n');
    for alpha in ALPHA_VALUES {
        let _ = write!(s, "| {alpha} |");
        for h in H_VALUES {
            let a: Vec<Agreement> = results
                .iter()
                .filter(|r| r.cell.alpha == alpha && r.cell.h == h)
                .filter_map(|r| r.agreement)
                .collect();
            let within = a.iter().filter(|a| a.within()).count();
            let worst = a.iter().map(|a| a.worst()).fold(0.0, f64::max);
            if a.is_empty() {
                s.push_str(" — |");
            } else {
                let _ = write!(s, " {} (worst {:.1e}) |", pct(within, a.len()), worst);
            }
        }
        s.push('\n');
    }
    let mut worst: Vec<&CellResult> = results.iter().filter(|r| r.agreement.is_some()).collect();
    worst.sort_by(|a, b| {
        b.agreement
            .unwrap()
            .worst()
            .total_cmp(&a.agreement.unwrap().worst())
    });
    s.push_str("\nThe ten worst cells (t: the communication point of the largest deviation):\n\n| cell | stress | at t | active_stress | at t |\n|---|---|---|---|---|\n");
    for r in worst.iter().take(10) {
        let a = r.agreement.unwrap();
        let _ = writeln!(
            s,
            "| {} | {:.2e} | {} | {:.2e} | {} |",
            r.cell.key(),
            a.stress,
            fmt_t(a.stress_t),
            a.active,
            fmt_t(a.active_t)
        );
    }
    // ---- The FE muscle with and without time-error control
    s.push_str(&fe_time_control(results));
    // ---- Iterations (the models whose runs count them: the 1D ones)
    let mut work = String::new();
    for model in &models {
        for alpha in ALPHA_VALUES {
            for h in H_VALUES {
                let sel: Vec<&CellResult> = results
                    .iter()
                    .filter(|r| r.model == *model && r.cell.alpha == alpha && r.cell.h == h)
                    .collect();
                let agg = |f: &dyn Fn(&Run) -> Counts| {
                    let mut c = Counts::default();
                    for r in &sel {
                        let x = f(&r.coarse);
                        c.sum += x.sum;
                        c.n += x.n;
                        c.max = c.max.max(x.max);
                    }
                    c.mean().map(|m| format!("{m:.2} ({})", c.max))
                };
                let cols = [
                    agg(&|r| r.iterations),
                    agg(&|r| r.ce_iterations),
                    agg(&|r| r.substeps),
                ];
                if cols.iter().all(Option::is_none) {
                    continue;
                }
                let [it, ce, sub] = cols.map(|c| c.unwrap_or_else(|| "—".to_string()));
                let _ = writeln!(
                    work,
                    "| {model} | {alpha} | {} | {it} | {ce} | {sub} |",
                    fmt_h(h)
                );
            }
        }
    }
    if !work.is_empty() {
        s.push_str("\n## Solver work per communication step (run at h)\n\nMean (max) over every step of the cells: Newton iterations of the lateral solve (evaluations of the law), CE–SEE iterations summed over them, internal substeps; for the models whose runs count them.\n\n| model | alpha | h | lateral iterations | CE–SEE iterations | substeps |\n|---|---|---|---|---|---|\n");
        s.push_str(&work);
    }
    // ---- Before / after
    if let Some((path, rows)) = baseline {
        s.push_str(&before_after(results, path, rows));
    }
    // ---- Matrix view
    s.push_str(
        "\n## Every cell\n\nOne block per program and parameter set; rows D and alpha, columns S and h \
         (h = 1e-6, 1e-4, 1e-3, 1e-2, 0.1 in each S group). `.` completed, every check passed, agrees with \
         the run at h/100; `n` the same with no reference run (not affordable); `r` the same after a master \
         retry of a discarded step; `a` completed, every check passed, deviates from the run at h/100 by \
         more than the tolerance; `D` discarded (explained above); `X` fails an acceptance criterion.\n",
    );
    for m in &models {
        for sc in Scenario::ALL {
            for ps in ParamSet::ALL {
                let block: Vec<&CellResult> = results
                    .iter()
                    .filter(|r| r.model == *m && r.cell.scenario == sc && r.cell.params == ps)
                    .collect();
                if block.is_empty() {
                    continue;
                }
                let _ = writeln!(s, "\n{m} `{}` `{}`\n```", sc.name(), ps.name());
                let _ = write!(s, "{:<22}", "");
                for sv in S_VALUES {
                    let _ = write!(s, "| S={:<8}", format!("{sv:e}"));
                }
                s.push('\n');
                for d in D_VALUES {
                    for alpha in ALPHA_VALUES {
                        let _ = write!(s, "{:<22}", format!("D={d:e} alpha={alpha}"));
                        for sv in S_VALUES {
                            s.push_str("| ");
                            for h in H_VALUES {
                                let c = block
                                    .iter()
                                    .find(|r| {
                                        r.cell.d_comp == d
                                            && r.cell.alpha == alpha
                                            && r.cell.s == sv
                                            && r.cell.h == h
                                    })
                                    .map_or(' ', |r| code(r));
                                s.push(c);
                                s.push(' ');
                            }
                        }
                        s.push('\n');
                    }
                }
                s.push_str("```\n");
            }
        }
    }
    s
}

/// One side of [`fe_time_control`]'s table at one h.
struct Side {
    cells: usize,
    compared: usize,
    within: usize,
    worst: f64,
    discards: usize,
    iterations: Counts,
    seconds: f64,
}

/// The FE muscle with and without time-error control, from this run: the same
/// cells with one backward-Euler CE–SEE step per communication step
/// (`HillMuscleFE`, the default) and with `adaptive_substeps = true`
/// ([`FE_ADAPTIVE`]). Empty unless both ran.
/// The page's paragraph on a musculotendon unit's programs (the harness's
/// `unit` module says the same), with the caps of each parameter set over D.
fn unit_programs() -> String {
    let caps: Vec<String> = ParamSet::ALL
        .iter()
        .map(|&params| {
            let of = |d_comp| {
                unit_cap(
                    &Cell {
                        d_comp,
                        alpha: ALPHA_VALUES[0],
                        s: S_VALUES[0],
                        h: H_VALUES[0],
                        params,
                        scenario: Scenario::Toggle,
                    }
                    .law(),
                )
            };
            let (lo, hi) = D_VALUES
                .iter()
                .map(|&d| of(d))
                .fold((f64::INFINITY, 0.0f64), |(lo, hi), c| {
                    (lo.min(c), hi.max(c))
                });
            format!("`{}` {lo:.3}–{hi:.3}", params.name())
        })
        .collect();
    format!(
        "- for a musculotendon unit, whose `length` is its whole path (tendon slack length L_TS = 4 cm, \
         tendon_strain_at_F0 0.04, no pennation), the stretch is its fibres': the path is the fibres' share, \
         the path at which the relaxed unit holds its fibres at the stretch, L_TS (1 + ε_T(F_p(λ)/F0)) + λ L0, \
         with F_p the relaxed muscle's static force at fibre stretch λ (the 1D law, isometric at activation 0; 0 \
         for λ ≤ 1, where the path is L_TS + λ L0 and a slack tendon cannot push) and ε_T the tendon's strain at \
         that force. Every program is capped at the stretch where the relaxed fibres carry \
         {RELAXED_FORCE_CAP} F0, the end of the passive range a musculoskeletal model is used in; here {} over D \
         (a soft volumetric term lets the fibres thin and reach further). The law's relaxed fibres stiffen \
         steeply past 1.2 (its matrix term c b e^(b (Ī1 − 3))): with D ≤ 1e-9 they carry 3 to 17 F0 at 1.3 and \
         thousands to millions of F0 at 2.0, far more than the tendon carries at its rupture strain \
         2.5·tendon_strain_at_F0 (3.567 F0), so no unit holds its fibres there: such a path is refused \
         (`fmi2Discard`, the instance unchanged; its own test in `tests/stability_subset.rs`, not a cell of the \
         matrix). A fully active muscle adds at most f_v,max F0 ≤ 1.82 F0, so every capped program stays short \
         of rupture. A capped program keeps its timing (a ramp to 2.0 ramps at the same rate to the cap and \
         holds there until the muscle's program turns); `act-jumps@2` runs at the cap. Between the program's \
         breakpoints the path is interpolated \
         linearly.\n",
        caps.join(", ")
    )
}

/// The FE unit's programs: the fibres' share and the cap by its own relaxed
/// equilibrium (`testkit::stability::RelaxedUnit`), the caps of its cells.
#[cfg(feature = "fe")]
fn fe_unit_programs(results: &[CellResult]) -> String {
    let mut caps: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for r in results.iter().filter(|r| r.model == "HillMusculotendonFE") {
        let cap = musculotendon_fe_relaxed(&r.cell).cap();
        let e = caps
            .entry(format!("D = {:e}", r.cell.d_comp))
            .or_insert((f64::INFINITY, 0.0));
        *e = (e.0.min(cap), e.1.max(cap));
    }
    let caps: Vec<String> = caps
        .iter()
        .map(|(d, (lo, hi))| {
            if (hi - lo).abs() < 5e-4 {
                format!("{lo:.3} with {d}")
            } else {
                format!("{lo:.3}–{hi:.3} with {d}")
            }
        })
        .collect();
    format!(
        "- for the FE musculotendon unit, whose `length` is its whole path (tendon slack length L_TS = 4 cm, \
         tendon_strain_at_F0 0.04, no pennation), the stretch is its fibres': the path is the fibres' share, \
         the path at which the relaxed unit (activation 0, at rest) holds its fibres at the stretch, \
         L_TS (1 + ε_T(F_p(λ)/F0)) + λ L0, with F_p the FE unit's own relaxed force at fibre stretch λ (its FE \
         muscle on the matrix's 6 × 1 mesh, clamped at its ends: the unit initialized at activation 0 through \
         its FMI functions, `RelaxedUnit`; 0 for λ ≤ 1, where the path is L_TS + λ L0 and a slack tendon cannot \
         push) and ε_T the tendon's strain at that force. Every program is capped at the stretch where these \
         relaxed fibres carry {RELAXED_FORCE_CAP} F0: here {}. The clamped FE specimen carries more than the 1D \
         law in uniaxial stress at the same stretch (with D = 1e-4 some 3.6 F0 at 2.0, where the law carries \
         less than F0), so a cap by the law would take its tendon past its rupture strain \
         2.5·tendon_strain_at_F0 (3.567 F0), a path the unit refuses (`fmi2Discard`, the instance unchanged; \
         its own test in `tests/stability_subset.rs`, not a cell of the matrix). A fully active muscle adds at \
         most f_v,max F0 ≤ 1.82 F0, so every capped program stays short of rupture. A capped program keeps its \
         timing (a ramp to 2.0 ramps at the same rate to the cap and holds there until the muscle's program \
         turns); `act-jumps@2` runs at the cap. Between the program's breakpoints the path is interpolated \
         linearly.\n",
        caps.join(", ")
    )
}

#[cfg(not(feature = "fe"))]
fn fe_unit_programs(_: &[CellResult]) -> String {
    String::new()
}

fn fe_time_control(results: &[CellResult]) -> String {
    let mut s = String::new();
    let of =
        |name: &str| -> Vec<&CellResult> { results.iter().filter(|r| r.model == name).collect() };
    let (plain, adaptive) = (of("HillMuscleFE"), of(FE_ADAPTIVE));
    if plain.is_empty() || adaptive.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "\n## The FE muscle with and without time-error control\n\n\
         The same {} cells (those of the FE's part of the grid with a reference run, h ≥ 1e-2 s) run by \
         `HillMuscleFE` on its defaults (one backward-Euler step of the CE–SEE update \
         per communication step) and with `adaptive_substeps = true` (`{FE_ADAPTIVE}`: each step cut into \
         pieces until the CE–SEE error estimate is below `substep_tolerance` = 1e-3 sigma0, docs/fe.md). \
         Agreement with the run at h/100 (cells within {AGREEMENT_TOL} of those compared; worst deviation), \
         steps the master saw discarded, the Newton iterations per communication step (`newton_iterations`, \
         mean over every step of the run at h) and the wall time of the cells (both runs of each cell; the two \
         models ran interleaved on the same worker threads of this run, so the ratio is meaningful, the \
         seconds are not).\n\n\
         | h | cells | within: default | adaptive | worst: default | adaptive | discarded steps: default → adaptive \
         | Newton iterations per step: default → adaptive | wall s: default → adaptive |\n\
         |---|---|---|---|---|---|---|---|---|",
        adaptive.len()
    );
    // The cells both ran (the adaptive run selects a part of the FE's).
    let key = |r: &CellResult| r.cell.key();
    let both: std::collections::BTreeSet<String> = adaptive.iter().map(|r| key(r)).collect();
    let plain: Vec<&CellResult> = plain
        .into_iter()
        .filter(|r| both.contains(&key(r)))
        .collect();
    let hs: std::collections::BTreeSet<u64> = adaptive.iter().map(|r| r.cell.h.to_bits()).collect();
    for h in hs.into_iter().map(f64::from_bits) {
        let at = |list: &[&CellResult]| -> Side {
            let sel: Vec<&&CellResult> = list.iter().filter(|r| r.cell.h == h).collect();
            let compared: Vec<Agreement> = sel.iter().filter_map(|r| r.agreement).collect();
            let mut iterations = Counts::default();
            for r in &sel {
                iterations.sum += r.coarse.iterations.sum;
                iterations.n += r.coarse.iterations.n;
            }
            Side {
                cells: sel.len(),
                compared: compared.len(),
                within: compared.iter().filter(|a| a.within()).count(),
                worst: compared.iter().map(|a| a.worst()).fold(0.0, f64::max),
                discards: sel.iter().map(|r| r.coarse.discards.len()).sum(),
                iterations,
                seconds: sel
                    .iter()
                    .map(|r| r.coarse.seconds + r.fine.as_ref().map_or(0.0, |f| f.seconds))
                    .sum(),
            }
        };
        let (a, b) = (at(&plain), at(&adaptive));
        let worst = |c: usize, w: f64| {
            if c == 0 {
                "—".to_string()
            } else {
                format!("{w:.1e}")
            }
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} → {} | {} → {} | {:.0} → {:.0} |",
            fmt_h(h),
            a.cells,
            pct(a.within, a.compared),
            pct(b.within, b.compared),
            worst(a.compared, a.worst),
            worst(b.compared, b.worst),
            a.discards,
            b.discards,
            mean2(&a.iterations),
            mean2(&b.iterations),
            a.seconds,
            b.seconds,
        );
    }
    s
}

/// Before/after against a baseline CSV (same grid).
fn before_after(results: &[CellResult], path: &std::path::Path, rows: &[Row]) -> String {
    let mut s = String::new();
    let key = |m: &str, sc: &str, ps: &str, d: &str, a: &str, sv: &str, h: &str| {
        format!("{m} {sc} {ps} {d} {a} {sv} {h}")
    };
    let base: BTreeMap<String, &Row> = rows
        .iter()
        .map(|r| {
            (
                key(
                    &r["model"],
                    &r["scenario"],
                    &r["params"],
                    &r["D"],
                    &r["alpha"],
                    &r["S"],
                    &r["h"],
                ),
                r,
            )
        })
        .collect();
    let _ = writeln!(
        s,
        "\n## Before and after (baseline `{}`)\n\nThe same cells in the baseline run (the matrix as of the \
         commit before the 1D model's error-controlled substeps) and now: agreement with the run at h/100 (cells within the \
         tolerance of those compared, and the worst deviation), discarded steps of the run at h, and the \
         solver work per communication step of the run at h (means over every step of the \
         cells; the substeps and the CE–SEE iterations of the baseline are 1 and its iterations). Wall \
         times are not compared here: the two runs were made at different loads of the shared machine \
         (see BENCHMARKS.md for the per-step cost measured in one session).\n\n\
         | h | within tolerance before | after | worst before | worst after | discarded steps before → after \
         | lateral iterations before → after | CE–SEE iterations before → after | substeps after |\n\
         |---|---|---|---|---|---|---|---|---|",
        path.display()
    );
    for h in H_VALUES {
        let (mut nb, mut wb, mut na, mut wa, mut n) = (0, 0.0f64, 0, 0.0f64, 0);
        let (mut db, mut da) = (0u64, 0u64);
        let mut iters = [Counts::default(); 4];
        let mut subs = Counts::default();
        for r in results.iter().filter(|r| r.cell.h == h) {
            let c = &r.cell;
            let k = key(
                r.model,
                &c.scenario.name(),
                c.params.name(),
                &format!("{:e}", c.d_comp),
                &c.alpha.to_string(),
                &format!("{:e}", c.s),
                &format!("{:e}", c.h),
            );
            let Some(b) = base.get(&k) else { continue };
            let num = |col: &str| b.get(col).and_then(|v| v.parse::<f64>().ok());
            db += num("discards").unwrap_or(0.0) as u64;
            da += r.coarse.discards.len() as u64;
            let steps = num("steps").unwrap_or(0.0);
            for (i, col) in ["iterations_mean", "ce_iterations_mean"].iter().enumerate() {
                if let Some(m) = num(col) {
                    iters[i].sum += (m * steps).round() as u64;
                    iters[i].n += steps as u64;
                }
            }
            for (i, x) in [r.coarse.iterations, r.coarse.ce_iterations]
                .iter()
                .enumerate()
            {
                iters[2 + i].sum += x.sum;
                iters[2 + i].n += x.n;
            }
            subs.sum += r.coarse.substeps.sum;
            subs.n += r.coarse.substeps.n;
            if let (Some(x), Some(y)) = (num("agree_stress"), r.agreement) {
                let before = x.max(num("agree_active").unwrap_or(0.0));
                n += 1;
                nb += usize::from(before <= AGREEMENT_TOL);
                wb = wb.max(before);
                na += usize::from(y.within());
                wa = wa.max(y.worst());
            }
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1e} | {:.1e} | {db} → {da} | {} → {} | {} → {} | {} |",
            fmt_h(h),
            pct(nb, n),
            pct(na, n),
            wb,
            wa,
            mean2(&iters[0]),
            mean2(&iters[2]),
            mean2(&iters[1]),
            mean2(&iters[3]),
            mean2(&subs),
        );
    }
    s
}
