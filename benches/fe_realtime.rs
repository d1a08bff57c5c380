//! The real-time workloads of `HillMuscleFE` through its C ABI:
//! `cargo bench --bench fe_realtime [-- --runs N] [-- --only NAME]`.
//!
//! Each workload drives the binary of `dist/HillMuscleFE.fmu` (or
//! `$HM_DIST/HillMuscleFE.fmu`, to run an older build beside this one) on its
//! default mesh with fmi2SetReal (activation, length), fmi2DoStep and
//! fmi2GetReal (force), and reports the wall time per step over the whole run
//! — the mean (what a real-time budget spends), the median, the 90th
//! percentile and the largest — with the linear solves per step
//! (`newton_iterations`, read outside the timed calls) and the force at the
//! end (what must not change when the work does):
//!
//! - `passive`: from rest, activation 0, pulled at 5 mm/s to 20 % strain
//!   (MODEL_NOTES "Experiments"), h = 1 ms, 2,000 steps;
//! - `stretch-release`: activation command 0, then 1 from t = 0.2 s; length
//!   L0 → 1.1 L0 over the first second and back to L0 over the second,
//!   h = 1 ms, 2,000 steps;
//! - `init`: fmi2Instantiate to fmi2ExitInitializationMode with
//!   `initial_activation` 1 and the activation command 1 (the static
//!   equilibrium at level 1 at L0), per run;
//! - `large-steps`: the two stepping workloads at h = 1, 10 and 100 ms: wall
//!   time per simulated second (it should fall as h grows);
//! - `arm`: the coupled arm's calls (`examples/arm_mujoco.py --model fe
//!   --scheme implicit`, H = 10 ms, 100 steps: fmi2SetReal,
//!   fmi2SetRealInputDerivatives, fmi2DoStep, fmi2GetReal,
//!   fmi2GetDirectionalDerivative), replayed from the committed trace
//!   `benches/data/arm_fe_implicit.csv` ([`arm`]).
//!
//! A last table counts the work of the stepping workloads in-process (the
//! FMU's step map on the same mesh, activation dynamics on, no substep
//! control, as the FMU's defaults): linear solves, residual evaluations,
//! tangent factorisations and substeps per step, every attempt counted
//! (the discretization's ledger, [`hill_muscle::fe::work`]: failed attempts
//! before a continuation or substeps included), with the converged
//! attempts' share, what a step reports, beside it. The counts are
//! deterministic; they say what the times are made of. It also runs the two
//! other work-precision scenes (docs/work-precision.md) at h = 1, 10, 100 ms:
//! `activated` (command 1 from t = 0, held at L0 for 0.5 s, then pulled at
//! 5 mm/s to 20 % strain, 2.5 s) and `fast` (command 1 on [0.10, 0.15) s,
//! L = L0 (1 + 0.05 sin(2π 5 t)), 0.6 s), and the arm's trace (each step's
//! work and the time of its d force / d length, and the factorisations its
//! steps attempted by kind).
//!
//! `--runs N` (default 3) repeats each row and reports the median of the runs'
//! figures; `--only NAME` runs one workload once (for `perf record`);
//! `--in-process` prints only the in-process table (no FMU needed), with the
//! mean and median wall time of the step map's steps and the force in full
//! (with `--only NAME`, of that workload alone); `--cabi-only` leaves that
//! table out (to alternate FMUs of several builds, whose in-process tables
//! would all be this build's); `--mesh A,R` meshes every instance
//! n_axial = A, n_radial = R, through the C ABI and in-process (the arm's
//! replay then reports how far that mesh's forces are from the default
//! mesh's trace).

use std::ffi::c_uint;
use std::time::Instant;

#[path = "fe_realtime/arm.rs"]
mod arm;

use hill_muscle::fe::mesh::{FibreLayout, Resolution, LUMPED, LUMPED_GRADING};
use hill_muscle::fe::muscle::Muscle;
use hill_muscle::fe::step_map::{discretization, StepLevel};
use hill_muscle::law::Params;
use hill_muscle::specimen::MEAN_AREA;

use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hillfe::HillFE;
use hill_muscle::specimen::LENGTH as L0;

use cabi::{load, median, Instance};
use testkit::cabi;

/// The passive pull's speed [m/s].
const SPEED: f64 = 0.005;

/// A workload's inputs over the step [t0, t]: the activation command and
/// the length at its end.
type Inputs = fn(f64, f64) -> (f64, f64);

fn passive(_t0: f64, t: f64) -> (f64, f64) {
    (0.0, L0 + SPEED * t)
}

fn stretch_release(_t0: f64, t: f64) -> (f64, f64) {
    let u = if t >= 0.2 { 1.0 } else { 0.0 };
    let up = t.min(2.0 - t).clamp(0.0, 1.0);
    (u, L0 * (1.0 + 0.1 * up))
}

/// Switch times within this of a communication point count as on it
/// (examples/scenes.py).
const SWITCH: f64 = 1e-9;

/// Work-precision scene `activated` (examples/scenes.py): command 1, held
/// at L0 until 0.5 s, then pulled at 5 mm/s.
fn activated(_t0: f64, t: f64) -> (f64, f64) {
    (1.0, L0 + SPEED * (t - 0.5).max(0.0))
}

/// Work-precision scene `fast` (examples/scenes.py): the command of the
/// step's start (1 on [0.10, 0.15) s), L = L0 (1 + 0.05 sin(2π 5 t)).
fn fast(t0: f64, t: f64) -> (f64, f64) {
    let u = if (0.10 - SWITCH..0.15 - SWITCH).contains(&t0) {
        1.0
    } else {
        0.0
    };
    (
        u,
        L0 * (1.0 + 0.05 * (2.0 * std::f64::consts::PI * 5.0 * t).sin()),
    )
}

pub(crate) fn vr_of(name: &str) -> c_uint {
    HillFE::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

/// One run over `duration` seconds in steps of `h`: wall time per step [s],
/// linear solves per step, the force at the end.
fn run(
    api: &cabi::Api,
    mesh: &[(c_uint, i32)],
    inputs: Inputs,
    h: f64,
    duration: f64,
) -> (Vec<f64>, Vec<i32>, f64) {
    let ins = [vr_of("activation"), vr_of("length")];
    let outs = [vr_of("force")];
    let solves_vr = vr_of("newton_iterations");
    let instance = Instance::with_settings(api, &api.guid, &[], mesh, &[]);
    let steps = (duration / h).round() as usize;
    let (mut times, mut solves) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
    let mut force = [0.0];
    for i in 0..steps {
        let (u, l) = inputs(i as f64 * h, (i + 1) as f64 * h);
        let t = Instant::now();
        instance.step(&ins, &[u, l], i as f64 * h, h, &outs, &mut force);
        times.push(t.elapsed().as_secs_f64());
        solves.push(instance.integer(solves_vr));
    }
    (times, solves, force[0])
}

/// mean, median, p90, max of per-step times [s], and mean solves per step.
fn stats(times: &[f64], solves: &[i32]) -> [f64; 5] {
    let n = times.len();
    let mut t = times.to_vec();
    t.sort_by(|a, b| a.total_cmp(b));
    [
        t.iter().sum::<f64>() / n as f64,
        t[n / 2],
        t[(9 * n) / 10],
        t[n - 1],
        solves.iter().map(|&s| f64::from(s)).sum::<f64>() / n as f64,
    ]
}

/// Seconds from fmi2Instantiate to fmi2ExitInitializationMode at level 1.
fn init(api: &cabi::Api, mesh: &[(c_uint, i32)]) -> f64 {
    let level_1 = [
        (vr_of("initial_activation"), 1.0),
        (vr_of("activation"), 1.0),
    ];
    let t = Instant::now();
    let instance = Instance::with_settings(api, &api.guid, &level_1, mesh, &[]);
    let s = t.elapsed().as_secs_f64();
    drop(instance);
    s
}

/// One in-process step: wall time [s], linear solves, factorisations.
type StepWork = (f64, usize, usize);

/// Per step of one in-process run: linear solves, residual evaluations,
/// factorisations (every attempt, the discretization's ledger), substeps,
/// and the solves and factorisations of the attempts that converged (what
/// the step reports) (means), the force at the end, and each step's
/// [`StepWork`].
fn counts(
    inputs: Inputs,
    h: f64,
    duration: f64,
    mesh: Resolution,
) -> ([f64; 6], f64, Vec<StepWork>) {
    let p = Params::default();
    let d = discretization(
        None,
        L0,
        MEAN_AREA,
        mesh,
        LUMPED_GRADING,
        FibreLayout::Axial,
    )
    .expect("the mesh");
    let (mut m, _) = Muscle::isometric(d, &p, L0, 0.0).expect("rest");
    let steps = (duration / h).round() as usize;
    let (mut sum, mut a0, mut force) = ([0usize; 6], 0.0, f64::NAN);
    let mut times = Vec::with_capacity(steps);
    for i in 0..steps {
        let (u, l) = inputs(i as f64 * h, (i + 1) as f64 * h);
        let level = StepLevel::new(true, p.s, a0, u, 0.0, h, (-p.s * h).exp());
        let before = m.disc.work.work();
        let t = Instant::now();
        let adv = m
            .advance(&p, l, h, &|tau| level.at(tau))
            .expect("the workload's step");
        let elapsed = t.elapsed().as_secs_f64();
        let all = adv.muscle.disc.work.work() - before;
        times.push((elapsed, all.solves, all.factorizations));
        sum[0] += all.solves;
        sum[1] += all.residuals;
        sum[2] += all.factorizations;
        sum[3] += adv.substeps;
        sum[4] += adv.iterations;
        sum[5] += adv.factorizations;
        force = adv.muscle.disc.reaction(&adv.solution.evaluation.forces);
        a0 = level.end;
        m = adv.muscle;
    }
    (sum.map(|c| c as f64 / steps as f64), force, times)
}

/// The in-process tables (of the workload `only` alone when given): the
/// work per step and its wall time.
fn in_process(only: Option<&str>, mesh: Resolution) {
    let wanted = |name: &str| only.map_or(true, |o| o == name);
    println!("Work per step in-process (the FMU's step map, its defaults; every attempt counted, and in parentheses the attempts that converged, as the step reports them)");
    println!("| workload | h (ms) | solves/step | residuals/step | factorisations/step | substeps/step | mean ms/step | median ms/step | wall s per simulated s | force at the end (N) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut kinds = Vec::new();
    for (name, inputs, duration) in STEPPING.into_iter().chain(SCENES) {
        if !wanted(name) {
            continue;
        }
        for h in [1e-3, 1e-2, 1e-1] {
            let (
                [solves, residuals, factorizations, substeps, solves_ok, factorizations_ok],
                force,
                steps,
            ) = counts(inputs, h, duration, mesh);
            let times: Vec<f64> = steps.iter().map(|s| s.0).collect();
            let [mean, med, ..] = stats(&times, &[0]);
            println!(
                "| {name} | {} | {solves:.3} ({solves_ok:.3}) | {residuals:.3} | {factorizations:.3} ({factorizations_ok:.3}) | {substeps:.3} | {:.3} | {:.3} | {:.3} | {force:.14} |",
                h * 1e3,
                mean * 1e3,
                med * 1e3,
                times.iter().sum::<f64>() / duration
            );
            if h == 1e-3 {
                kinds.push((name, steps));
            }
        }
    }
    println!();
    println!("The 1 ms steps by their work: share of the steps, mean ms, share of the run's time");
    println!("| workload | one solve | two solves | three or more solves | with a factorisation |");
    println!("|---|---|---|---|---|");
    for (name, steps) in kinds {
        let total: f64 = steps.iter().map(|s| s.0).sum();
        let class = |keep: &dyn Fn(usize, usize) -> bool| {
            let t: Vec<f64> = steps
                .iter()
                .filter(|s| keep(s.1, s.2))
                .map(|s| s.0)
                .collect();
            let sum: f64 = t.iter().sum();
            format!(
                "{:.1} %, {:.3} ms, {:.1} %",
                100.0 * t.len() as f64 / steps.len() as f64,
                1e3 * sum / t.len().max(1) as f64,
                100.0 * sum / total
            )
        };
        println!(
            "| {name} | {} | {} | {} | {} |",
            class(&|s, f| f == 0 && s == 1),
            class(&|s, f| f == 0 && s == 2),
            class(&|s, f| f == 0 && s > 2),
            class(&|_, f| f > 0)
        );
    }
    if wanted("arm") {
        println!();
        arm_in_process(mesh);
    }
}

/// The arm's trace in-process: the work of its steps and of their
/// d force / d length, and its most expensive steps.
fn arm_in_process(mesh: Resolution) {
    let trace = arm::load();
    let (work, force, stiffness, attempts) = arm::in_process(&trace, mesh);
    let n = work.len() as f64;
    let mean = |f: &dyn Fn(&arm::Work) -> f64| work.iter().map(f).sum::<f64>() / n;
    let step: Vec<f64> = work.iter().map(|w| w.step + w.derivative).collect();
    let [step_mean, step_median, ..] = stats(&step, &[0]);
    println!(
        "The coupled arm's trace in-process ({} steps of {} ms)",
        work.len(),
        trace.h * 1e3
    );
    println!("| solves/step | residuals/step | factorisations/step | substeps/step | steps in substeps | mean ms/step (step + derivative) | median ms/step | derivative mean ms | force at the end (N) | d force / d length at the end (N/m) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {:.3} ({:.3}) | {:.3} | {:.3} ({:.3}) | {:.3} | {} | {:.3} | {:.3} | {:.3} | {force:.14} | {stiffness:.10} |",
        mean(&|w| w.solves as f64),
        mean(&|w| w.converged.0 as f64),
        mean(&|w| w.residuals as f64),
        mean(&|w| w.factorizations as f64),
        mean(&|w| w.converged.1 as f64),
        mean(&|w| w.substeps as f64),
        work.iter().filter(|w| w.substeps > 1).count(),
        step_mean * 1e3,
        step_median * 1e3,
        mean(&|w| w.derivative) * 1e3,
    );
    let with = |lo: usize, hi: usize| {
        work.iter()
            .filter(|w| (lo..=hi).contains(&w.factorizations))
            .count()
    };
    println!(
        "Steps by their factorisations: none {}, one {}, two {}, three to five {}, more {}",
        with(0, 0),
        with(1, 1),
        with(2, 2),
        with(3, 5),
        with(6, usize::MAX)
    );
    println!(
        "Factorisations attempted (steps and derivatives): f32 Cholesky {}, f64 Cholesky {} (skipped as certainly failing: {}), LBLT {} (in vain before an f64 Cholesky: {}), LU {}",
        attempts.single, attempts.cholesky, attempts.cholesky_skipped, attempts.lblt, attempts.lblt_unused, attempts.lu
    );
    let mut order: Vec<usize> = (0..work.len()).collect();
    order.sort_by(|&a, &b| step[b].total_cmp(&step[a]));
    println!();
    println!("Its most expensive steps");
    println!("| t (s) | command | length (m) | dL/dt (m/s) | solves | factorisations | substeps | step ms | derivative ms |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for &i in order.iter().take(8) {
        let (r, w) = (&trace.rows[i], &work[i]);
        println!(
            "| {:.2} | {:.3} | {:.5} | {:.4} | {} | {} | {} | {:.2} | {:.2} |",
            r.t,
            r.activation,
            r.length,
            r.der_length,
            w.solves,
            w.factorizations,
            w.substeps,
            w.step * 1e3,
            w.derivative * 1e3
        );
    }
}

/// The arm's trace through the C ABI, `runs` times: its table row.
fn arm_cabi(api: &cabi::Api, mesh: &[(c_uint, i32)], runs: usize) {
    let trace = arm::load();
    let replays: Vec<arm::Replayed> = (0..runs).map(|_| arm::cabi(api, mesh, &trace)).collect();
    let m = |f: &dyn Fn(&arm::Replayed) -> f64| median(replays.iter().map(f).collect());
    let st = |r: &arm::Replayed| stats(&r.times, &r.solves);
    let last = replays.last().expect("a run");
    println!(
        "The coupled arm's calls replayed ({} steps of {} ms, median of {runs} runs)",
        trace.rows.len(),
        trace.h * 1e3
    );
    println!("| mean ms/step | median ms/step | p90 ms/step | max ms/step | of which fmi2GetDirectionalDerivative, mean ms | solves/step | wall s per simulated s | force at the end (N) | d force / d length at the end (N/m) | largest force − recorded (N) | largest relative K − recorded |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {:.3} | {:.3} | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | {:.6} | {:.3} | {:.2e} | {:.2e} |",
        m(&|r| st(r)[0]) * 1e3,
        m(&|r| st(r)[1]) * 1e3,
        m(&|r| st(r)[2]) * 1e3,
        m(&|r| st(r)[3]) * 1e3,
        m(&|r| r.derivative.iter().sum::<f64>() / r.derivative.len() as f64) * 1e3,
        st(last)[4],
        m(&|r| r.times.iter().sum::<f64>()) / (trace.h * trace.rows.len() as f64),
        last.force,
        last.stiffness,
        last.force_deviation,
        last.stiffness_deviation,
    );
}

const STEPPING: [(&str, Inputs, f64); 2] = [
    ("passive", passive as Inputs, 2.0),
    ("stretch-release", stretch_release as Inputs, 2.0),
];

/// The other work-precision scenes (in-process only).
const SCENES: [(&str, Inputs, f64); 2] = [
    ("activated", activated as Inputs, 2.5),
    ("fast", fast as Inputs, 0.6),
];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let runs: usize = value("--runs").map_or(3, |v| v.parse().expect("--runs N"));
    // `--mesh A,R`: every instance meshed n_axial = A, n_radial = R.
    let resolution = value("--mesh").map(|v| {
        let (a, r) = v.split_once(',').expect("--mesh N_AXIAL,N_RADIAL");
        Resolution {
            n_axial: a.parse().expect("n_axial"),
            n_radial: r.parse().expect("n_radial"),
        }
    });
    if args.iter().any(|a| a == "--in-process") {
        in_process(value("--only").as_deref(), resolution.unwrap_or(LUMPED));
        return;
    }
    let api = load("HillMuscleFE");
    let mesh: Vec<(c_uint, i32)> = resolution.map_or(Vec::new(), |r| {
        vec![
            (vr_of("n_axial"), r.n_axial as i32),
            (vr_of("n_radial"), r.n_radial as i32),
        ]
    });
    let mesh_name = resolution.map_or("default mesh".to_string(), |r| {
        format!("mesh {} × {}", r.n_axial, r.n_radial)
    });

    if let Some(only) = value("--only") {
        if only == "init" {
            println!("init: {:.3} s", init(&api, &mesh));
            return;
        }
        if only == "arm" {
            arm_cabi(&api, &mesh, 1);
            return;
        }
        let (_, inputs, duration) = STEPPING
            .iter()
            .find(|w| w.0 == only)
            .unwrap_or_else(|| panic!("--only passive | stretch-release | init | arm"));
        let (t, s, f) = run(&api, &mesh, *inputs, 1e-3, *duration);
        let [mean, med, ..] = stats(&t, &s);
        println!(
            "{only}: mean {:.3} ms, median {:.3} ms, force {f:.4} N",
            mean * 1e3,
            med * 1e3
        );
        return;
    }

    println!("HillMuscleFE through the C ABI, {mesh_name}; median of {runs} runs");
    println!("| workload | h (ms) | steps | mean ms/step | median ms/step | p90 ms/step | max ms/step | solves/step | wall s per simulated s | force at the end (N) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, inputs, duration) in STEPPING {
        for h in [1e-3, 1e-2, 1e-1] {
            let mut rows = Vec::new();
            let mut force = f64::NAN;
            for _ in 0..runs {
                let (t, s, f) = run(&api, &mesh, inputs, h, duration);
                force = f;
                rows.push((stats(&t, &s), t.iter().sum::<f64>() / duration));
            }
            let m = |k: usize| median(rows.iter().map(|r| r.0[k]).collect());
            let per_second = median(rows.iter().map(|r| r.1).collect());
            println!(
                "| {name} | {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {:.3} | {per_second:.3} | {force:.6} |",
                h * 1e3,
                (duration / h).round(),
                m(0) * 1e3,
                m(1) * 1e3,
                m(2) * 1e3,
                m(3) * 1e3,
                m(4),
            );
        }
    }
    println!();
    arm_cabi(&api, &mesh, runs);
    println!();
    if !args.iter().any(|a| a == "--cabi-only") {
        in_process(None, resolution.unwrap_or(LUMPED));
    }
    let t: Vec<f64> = (0..runs).map(|_| init(&api, &mesh)).collect();
    println!();
    println!(
        "activated initialization (command 1): median {:.3} s, min {:.3} s, max {:.3} s over {runs} runs",
        median(t.clone()),
        t.iter().cloned().fold(f64::INFINITY, f64::min),
        t.iter().cloned().fold(0.0, f64::max)
    );
}
