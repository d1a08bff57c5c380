//! The 1D musculotendon unit over a twitch, at two step sizes:
//! `cargo run --release --example musculotendon_1d [-- substep_tolerance]`
//! (default 1e-3, the FMUs' default, relative to sigma0).
//!
//! The default 1D muscle (L0 = 5 cm, F0 = sigma0 · area ≈ 118 N) in series
//! with a 4 cm tendon, no pennation, its path held at L_TS + 1.02 L0; the
//! command is 1 for 10 ms, then 0, over 100 ms. For a tendon of strain at
//! F0 0.04 and 1e-4, and a rigid one, the tendon force is run with
//! h = 1 ms and h = 0.01 ms; printed: the force every 10 ms at both steps,
//! the largest difference over the 1 ms points relative to F0, the substeps
//! the error control took per 1 ms step (1: none forced), the
//! equilibrium's largest residual, and the mean evaluations of the muscle's
//! piece law per step (the rigid tendon without pennation is the plain
//! muscle's step: one per piece).

use hill_muscle::law::musculotendon::UnitParams;
use hill_muscle::law::FullLaw;
use hill_muscle::muscle1d::{Muscle1D, Musculotendon1D, Output, UnitOutput};

const L_TS: f64 = 0.04;
const T_END: f64 = 0.1;

fn command_at(t: f64) -> f64 {
    if t < 0.010 {
        1.0
    } else {
        0.0
    }
}

/// The tendon force at every 1 ms point, the most substeps of a step, the
/// largest equilibrium residual / F0 and the mean evaluations per step.
fn run(eps0: Option<f64>, h: f64, tol: f64) -> (Vec<f64>, u32, f64, f64) {
    let p = UnitParams {
        tendon_slack_length: L_TS,
        tendon_strain_at_f0: eps0.unwrap_or(0.04),
        pennation_angle: 0.0,
        compliant_tendon: eps0.is_some(),
    };
    let mut mt = Musculotendon1D::<FullLaw>::new(Muscle1D::new(tol), p);
    mt.set_path(L_TS + 1.02 * 0.05);
    mt.initialize().expect("initial equilibrium");
    let f0 = mt.unit().tendon.f0;
    let n = (T_END / h).round() as usize;
    let every = (1e-3 / h).round() as usize;
    let (mut forces, mut most, mut worst, mut evals) = (Vec::new(), 0u32, 0.0f64, 0u64);
    for i in 0..n {
        mt.set_command(command_at(i as f64 * h));
        mt.step(h).expect("step");
        let cos = mt
            .unit()
            .pennation
            .at(mt.output(UnitOutput::FibreLength))
            .cos;
        let r = mt.muscle.output(Output::Force) * cos - mt.output(UnitOutput::Force);
        worst = worst.max(r.abs() / f0);
        most = most.max(mt.muscle.last_step_statistics().substeps);
        evals += u64::from(mt.last_step_evaluations());
        if (i + 1) % every == 0 {
            forces.push(mt.output(UnitOutput::Force));
        }
    }
    (forces, most, worst, evals as f64 / n as f64)
}

fn main() {
    let tol: f64 = std::env::args()
        .nth(1)
        .map_or(1e-3, |a| a.parse().expect("substep_tolerance"));
    let f0 = 7.0e5 * hill_muscle::muscle1d::DEFAULT_AREA;
    println!(
        "F0 = {f0:.3} N; twitch: command 1 for 10 ms, path held at L_TS + 1.02 L0; \
         substep_tolerance {tol:e}\n"
    );
    for (name, eps0) in [
        ("eps0 = 0.04", Some(0.04)),
        ("eps0 = 1e-4", Some(1e-4)),
        ("rigid", None),
    ] {
        let (coarse, substeps, res_coarse, evals) = run(eps0, 1e-3, tol);
        let (fine, _, res_fine, evals_fine) = run(eps0, 1e-5, tol);
        println!("{name}:");
        println!("   t (ms)   F_T h=1ms (N)   F_T h=0.01ms (N)");
        for k in (9..coarse.len()).step_by(10) {
            println!("   {:6}   {:13.6}   {:16.6}", k + 1, coarse[k], fine[k]);
        }
        let err = coarse
            .iter()
            .zip(&fine)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "   max |F(1 ms) - F(0.01 ms)| / F0 = {:.3e}; most substeps per 1 ms step: {substeps}; \
             largest equilibrium residual / F0: {:.1e} (1 ms), {:.1e} (0.01 ms); \
             muscle evaluations per step: {evals:.2} (1 ms), {evals_fine:.2} (0.01 ms)\n",
            err / f0,
            res_coarse,
            res_fine,
        );
    }
}
