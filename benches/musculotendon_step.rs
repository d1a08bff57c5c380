//! Per-step cost of `HillMusculotendon1D` against `HillMuscle1D` through the
//! C ABI.
//!
//! Loads the binaries of `dist/HillMuscle1D.fmu` and
//! `dist/HillMusculotendon1D.fmu` (build them first with
//! `scripts/build_fmus.sh`) with dlopen and times, per communication step,
//! fmi2SetReal(activation, length) + fmi2DoStep + fmi2GetReal(force, stress)
//! with activation 1 and a 2 Hz stretch-and-release of ±10 % L0: of the
//! muscle's length for `HillMuscle1D` (as `benches/step.rs`), of the path
//! around its rest path L_TS + L0 for the unit. The unit runs with a
//! compliant tendon (ε0 = 0.04, the scene's), a near-rigid one (ε0 = 1e-4)
//! and a rigid one (`compliant_tendon` false), at `HillMuscle1D`'s
//! `substep_tolerance` (1e-3, like with like), and the compliant one at its
//! scene's default tolerance; all five run alternately in one process, so
//! that they see the same machine load. Also counted
//! in-process on the same loop: the evaluations of the muscle's piece law
//! per step (pieces tried, plus the equilibrium's evaluations for the unit).
//!
//! `cargo bench --bench musculotendon_step` — prints a Markdown table per
//! step size and one JSON line per case. `MT_BENCH_QUICK=1` runs 20x fewer
//! steps.

use std::ffi::c_uint;
use std::time::Instant;

use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hill1d::{Hill1D, Var as Var1D, DEFAULT_L0};
use hill_muscle::fmus::musculotendon1d::{Musculotendon, Var as VarMt};

use cabi::{load, median, Api, Instance};
use testkit::cabi;

const REPEATS: usize = 7;

/// The unit's scene parameters (`fmu_build/scenes/musculotendon_1d.toml`):
/// L0 and the tendon slack length; no pennation, so the rest path is their
/// sum.
const MT_L0: f64 = 0.1102;
const MT_LTS: f64 = 0.2723;

/// `HillMuscle1D`'s default `substep_tolerance`.
const MUSCLE_TOLERANCE: f64 = 1e-3;

/// One case: which FMU, its rest length (muscle or path), the tendon's
/// setting (`None`: the plain muscle; `Some(None)`: rigid; `Some(Some(ε0))`)
/// and the unit's `substep_tolerance` (`None`: the scene's default).
#[derive(Clone, Copy)]
struct Case {
    name: &'static str,
    tendon: Option<Option<f64>>,
    tolerance: Option<f64>,
}

const CASES: [Case; 5] = [
    Case {
        name: "HillMuscle1D",
        tendon: None,
        tolerance: None,
    },
    Case {
        name: "HillMusculotendon1D, compliant ε0 = 0.04",
        tendon: Some(Some(0.04)),
        tolerance: Some(MUSCLE_TOLERANCE),
    },
    Case {
        name: "HillMusculotendon1D, near-rigid ε0 = 1e-4",
        tendon: Some(Some(1e-4)),
        tolerance: Some(MUSCLE_TOLERANCE),
    },
    Case {
        name: "HillMusculotendon1D, rigid (compliant_tendon false)",
        tendon: Some(None),
        tolerance: Some(MUSCLE_TOLERANCE),
    },
    Case {
        name: "HillMusculotendon1D, compliant ε0 = 0.04, the scene's default substep_tolerance",
        tendon: Some(Some(0.04)),
        tolerance: None,
    },
];

/// Activation 1 and the length input at the end of step `i`: ±10 % of L0
/// at 2 Hz around the rest length (the muscle's) or rest path (the unit's).
fn inputs(case: Case, i: usize, h: f64) -> (f64, f64) {
    let t = (i + 1) as f64 * h;
    let s = 0.1 * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
    match case.tendon {
        None => (1.0, DEFAULT_L0 * (1.0 + s)),
        Some(_) => (1.0, MT_LTS + MT_L0 * (1.0 + s)),
    }
}

fn vr<M: Model>(name: &str) -> c_uint {
    M::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

/// ns per step through the C ABI, and the force's sum.
fn time_fmi(case: Case, api: &Api, steps: usize, h: f64) -> (f64, f64) {
    let (instance, ins, outs) = match case.tendon {
        None => (
            Instance::new(api, &api.guid),
            [vr::<Hill1D>("activation"), vr::<Hill1D>("length")],
            [vr::<Hill1D>("force"), vr::<Hill1D>("stress")],
        ),
        Some(t) => {
            let eps = vr::<Musculotendon>("tendon_strain_at_F0");
            let compliant = vr::<Musculotendon>("compliant_tendon");
            let mut reals = vec![(eps, t.unwrap_or(0.04))];
            if let Some(tol) = case.tolerance {
                reals.push((vr::<Musculotendon>("substep_tolerance"), tol));
            }
            (
                Instance::with_settings(api, &api.guid, &reals, &[], &[(compliant, t.is_some())]),
                [
                    vr::<Musculotendon>("activation"),
                    vr::<Musculotendon>("length"),
                ],
                [vr::<Musculotendon>("force"), vr::<Musculotendon>("stress")],
            )
        }
    };
    let mut out = [0.0; 2];
    let mut checksum = 0.0;
    let start = Instant::now();
    for i in 0..steps {
        let (a, l) = inputs(case, i, h);
        instance.step(&ins, &[a, l], i as f64 * h, h, &outs, &mut out);
        checksum += out[0];
    }
    (start.elapsed().as_nanos() as f64 / steps as f64, checksum)
}

/// Mean evaluations of the muscle's piece law per step, in-process on the
/// same loop, and the force's sum (checked against the C ABI's).
fn evaluations(case: Case, steps: usize, h: f64) -> (f64, f64) {
    let mut total = 0u64;
    let mut checksum = 0.0;
    match case.tendon {
        None => {
            let mut m = Hill1D::new();
            m.initialize().unwrap();
            for i in 0..steps {
                let (a, l) = inputs(case, i, h);
                m.set_real(Var1D::Activation, a).unwrap();
                m.set_real(Var1D::Length, l).unwrap();
                m.do_step(i as f64 * h, h).unwrap();
                let s = m.last_step_statistics();
                total += u64::from(s.substeps + s.rejected_substeps);
                checksum += m.get_real(Var1D::Out(hill_muscle::fmus::hill1d::Output::Force));
            }
        }
        Some(t) => {
            let id = |n: &str| {
                Musculotendon::variables()
                    .into_iter()
                    .find(|v| v.name == n)
                    .unwrap()
                    .id
            };
            let mut m = Musculotendon::new();
            m.set_real(id("tendon_strain_at_F0"), t.unwrap_or(0.04))
                .unwrap();
            m.set_boolean(id("compliant_tendon"), t.is_some()).unwrap();
            if let Some(tol) = case.tolerance {
                m.set_real(id("substep_tolerance"), tol).unwrap();
            }
            m.initialize().unwrap();
            let force: VarMt = id("force");
            for i in 0..steps {
                let (a, l) = inputs(case, i, h);
                m.set_real(VarMt::Activation, a).unwrap();
                m.set_real(VarMt::Length, l).unwrap();
                m.do_step(i as f64 * h, h).unwrap();
                total += u64::from(m.last_step_evaluations());
                checksum += m.get_real(force);
            }
        }
    }
    (total as f64 / steps as f64, checksum)
}

fn main() {
    let quick = std::env::var_os("MT_BENCH_QUICK").is_some();
    let plain = load("HillMuscle1D");
    let unit = load("HillMusculotendon1D");
    for (h, steps) in [(1e-4, 200_000), (1e-3, 100_000)] {
        let steps = if quick { steps / 20 } else { steps };
        let mut runs = vec![Vec::new(); CASES.len()];
        let mut ratios = vec![Vec::new(); CASES.len()];
        for _ in 0..REPEATS {
            let mut this = [0.0; CASES.len()];
            for (k, &case) in CASES.iter().enumerate() {
                let api = if case.tendon.is_some() { &unit } else { &plain };
                this[k] = time_fmi(case, api, steps, h).0;
                runs[k].push(this[k]);
            }
            for k in 0..CASES.len() {
                ratios[k].push(this[k] / this[0]);
            }
        }
        println!(
            "\nh = {h} s, {steps} steps per run, activation 1, length ±10 % L0 at 2 Hz; \
             {REPEATS} runs alternating the cases"
        );
        println!();
        println!("| case | C ABI ns/step, mean | median | ratio to HillMuscle1D (median of per-run ratios; range) | piece-law evaluations per step |");
        println!("|---|---|---|---|---|");
        for (k, &case) in CASES.iter().enumerate() {
            let api = if case.tendon.is_some() { &unit } else { &plain };
            let (_, c_abi) = time_fmi(case, api, steps, h);
            let (evals, direct) = evaluations(case, steps, h);
            assert!(
                (c_abi - direct).abs() <= 1e-9 * direct.abs(),
                "{}: C ABI and direct model disagree: {c_abi} vs {direct}",
                case.name
            );
            let mean = runs[k].iter().sum::<f64>() / runs[k].len() as f64;
            let med = median(runs[k].clone());
            let mut rs = ratios[k].clone();
            rs.sort_by(|a, b| a.partial_cmp(b).unwrap());
            println!(
                "| {} | {mean:.1} | {med:.1} | {:.2} ({:.2}–{:.2}) | {evals:.2} |",
                case.name,
                median(ratios[k].clone()),
                rs[0],
                rs[rs.len() - 1]
            );
        }
        for (k, &case) in CASES.iter().enumerate() {
            println!(
                "{{\"bench\":\"musculotendon_step\",\"h\":{h},\"case\":\"{}\",\"mean_ns\":{:.1},\"median_ns\":{:.1},\"ratio\":{:.3}}}",
                case.name,
                runs[k].iter().sum::<f64>() / runs[k].len() as f64,
                median(runs[k].clone()),
                median(ratios[k].clone())
            );
        }
    }
}
