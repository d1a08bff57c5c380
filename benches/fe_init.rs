//! The activated initialization of the FE muscle and the factorisations of
//! an indefinite tangent (docs/fe.md, "Linear solver"):
//! `cargo bench --bench fe_init [-- --runs N]`.
//!
//! Part 1, on the default mesh (16 × 3 graded): the tangent an activated
//! initialization meets first — the rate-free (isometric) tangent at the
//! passive equilibrium at L0 with the activation level raised to 0.5, fibre
//! tension not yet balanced by pressure: indefinite — factorised by each
//! method of [`hill_muscle::fe::assembly::Pattern::factorize_as`]:
//! Cholesky (which fails on it, after part of the work), supernodal LBLᵀ
//! (Bunch–Kaufman within supernodes) and sparse LU; and, for scale, the
//! positive definite tangent of a 1 ms step there. Median of 21
//! factorisations each, with the probe solve's backward error, and which
//! method `factorize` chooses.
//!
//! Part 2: [`Muscle::isometric`] (the FMU's initialization) on the default
//! mesh at rest length with levels 0.5 and 1 and at 1.1 L0 with 0.5: wall
//! time (median and range of `--runs`, default 3), its counted work (linear
//! solves, residual evaluations, factorisations: deterministic; every
//! attempt, the discretization's ledger, with the converged attempts'
//! share in parentheses), the force,
//! and which factorisation the equilibrium's tangent gets. With
//! `HM_DUMP=DIR` each case writes its force and positions (one value a
//! line, full digits) to `DIR/x_<L/L0>_<level>.txt`, to compare two builds'
//! equilibria. `--case L/L0,level` (repeatable) replaces the three cases.
//!
//! Part 3: the `HillMusculotendonFE` scene's initialization
//! (`Model::initialize` in-process, the scene's defaults: its default
//! mesh, muscle and tendon) at its start path length and at 1.05× it, with
//! `initial_activation` and the command at 0, 0.5 and 1: wall time (median
//! and range of `--runs`), its counted work (every attempt), the
//! equilibrium's trials and the tendon force. `--unit` runs part 3 alone.

use std::sync::Arc;
use std::time::Instant;

use hill_muscle::fe::assembly::FactorKind;
use hill_muscle::fe::mesh::{LUMPED, LUMPED_GRADING};
use hill_muscle::fe::muscle::{Discretization, Muscle};
use hill_muscle::fe::musculotendon::UnitOutput;
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::musculotendonfe::MusculotendonFe;
use hill_muscle::law::{FibreHistory, FibreRate, Params};
use hill_muscle::specimen::LENGTH as L0;

use cabi::median;
use testkit::cabi;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs = args
        .iter()
        .position(|a| a == "--runs")
        .map_or(3, |i| args[i + 1].parse().expect("--runs N"));
    if args.iter().any(|a| a == "--unit") {
        unit_initialization(runs);
        return;
    }
    let p = Params::default();
    let d = Arc::new(Discretization::specimen(LUMPED).unwrap());
    let (rest, _) = Muscle::isometric(d.clone(), &p, L0, 0.0).unwrap();
    let start = vec![FibreHistory::REST; d.n_elements()];
    println!(
        "Default mesh {}×{} graded {LUMPED_GRADING:?} ({} tetrahedra, {} dofs), passive equilibrium at L0, level 0.5; median of 21",
        LUMPED.n_axial,
        LUMPED.n_radial,
        d.n_elements(),
        3 * d.n_nodes()
    );
    println!("| tangent | factorize chooses | method | ms | probe backward error |");
    println!("|---|---|---|---|---|");
    for (name, rate) in [
        ("rate-free (isometric)", FibreRate::Isometric),
        ("1 ms step", FibreRate::Step { h: 1e-3 }),
    ] {
        let ev = d.evaluate(&p, &rest.x, 0.5, &start, rate, true).unwrap();
        let values = ev.tangent.unwrap();
        let chosen = d.pattern.factorize(&values).map(|f| f.kind());
        for kind in [
            FactorKind::Cholesky,
            FactorKind::BunchKaufman,
            FactorKind::Lu,
        ] {
            let mut times = Vec::new();
            let mut outcome = String::new();
            for _ in 0..21 {
                let t = Instant::now();
                let r = d.pattern.factorize_as(&values, kind);
                times.push(t.elapsed().as_secs_f64());
                outcome = match r {
                    Ok((_, e)) => format!("{e:.1e}"),
                    Err(_) => "fails (not positive definite)".into(),
                };
            }
            println!(
                "| {name} | {chosen:?} | {kind:?} | {:.2} | {outcome} |",
                median(times) * 1e3
            );
        }
    }
    println!();
    println!("Muscle::isometric on the default mesh, {runs} runs");
    println!("| L/L0 | level | median s | range s | solves | residuals | factorisations | force N | tangent at the equilibrium |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let cases: Vec<(f64, f64)> = args
        .iter()
        .zip(args.iter().skip(1))
        .filter(|(flag, _)| *flag == "--case")
        .map(|(_, v)| {
            let (l, a) = v.split_once(',').expect("--case L/L0,level");
            (l.parse().expect("L/L0"), a.parse().expect("level"))
        })
        .collect();
    let cases = if cases.is_empty() {
        vec![(1.0, 0.5), (1.0, 1.0), (1.1, 0.5)]
    } else {
        cases
    };
    for (stretch, level) in cases {
        let mut times = Vec::new();
        let mut force = 0.0;
        let mut kind = None;
        let mut work = ((0, 0), (0, 0), (0, 0));
        for _ in 0..runs {
            let before = d.work.work();
            let t = Instant::now();
            let (m, s) = Muscle::isometric(d.clone(), &p, stretch * L0, level).unwrap();
            times.push(t.elapsed().as_secs_f64());
            force = d.reaction(&s.evaluation.forces);
            if let Ok(dir) = std::env::var("HM_DUMP") {
                let text: Vec<String> = m.x.iter().map(|v| format!("{v:e}")).collect();
                let file = format!("{dir}/x_{stretch}_{level}.txt");
                std::fs::write(file, format!("{force:e}\n{}", text.join("\n"))).unwrap();
            }
            let all = d.work.work() - before;
            work = (
                (all.solves, s.iterations),
                (all.residuals, s.residuals),
                (all.factorizations, s.factorizations),
            );
            let tangent = m.tangent.as_ref().map(|c| c.tangent(&d, &p));
            kind = tangent.map(|t| t.map(|t| t.factor.kind()));
        }
        let (lo, hi) = times
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
        println!(
            "| {stretch} | {level} | {:.3} | {lo:.3}–{hi:.3} | {} ({}) | {} ({}) | {} ({}) | {force:.9} | {kind:?} |",
            median(times),
            work.0 .0,
            work.0 .1,
            work.1 .0,
            work.1 .1,
            work.2 .0,
            work.2 .1
        );
    }
    println!();
    unit_initialization(runs);
}

/// Part 3 (module docs): the FE unit's initialization through its model.
fn unit_initialization(runs: usize) {
    type Unit = MusculotendonFe;
    let var = |name: &str| {
        Unit::variables()
            .into_iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("no variable {name}"))
            .id
    };
    let (length, activation, initial) =
        (var("length"), var("activation"), var("initial_activation"));
    let path0 = Unit::new().get_real(length);
    println!("HillMusculotendonFE initialization (Model::initialize, scene defaults), {runs} runs");
    println!("| path / start path | level | median s | range s | solves | residuals | factorisations | trials | force N |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for stretch in [1.0, 1.05] {
        for level in [0.0, 0.5, 1.0] {
            let mut times = Vec::new();
            let mut row = String::new();
            for _ in 0..runs {
                let mut m = Unit::new();
                m.set_real(initial, level).unwrap();
                m.set_real(activation, level).unwrap();
                m.set_real(length, stretch * path0).unwrap();
                let t = Instant::now();
                m.initialize().unwrap();
                times.push(t.elapsed().as_secs_f64());
                let unit = m.unit().expect("initialized");
                let w = unit.muscle.muscle.disc.work.work();
                row = format!(
                    "{} | {} | {} | {} | {:.9}",
                    w.solves,
                    w.residuals,
                    w.factorizations,
                    unit.trials,
                    unit.output(UnitOutput::Force)
                );
            }
            let (lo, hi) = times
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
            println!(
                "| {stretch} | {level} | {:.3} | {lo:.3}–{hi:.3} | {row} |",
                median(times)
            );
        }
    }
}
