//! Per-step cost of `HillMuscleFE` (issue 3, "Performance"):
//! `cargo bench --bench fe_step [-- --quick]`.
//!
//! Workloads, 1 ms communication steps:
//! - **passive pull** (MODEL_NOTES "Experiments"): from rest, the free face
//!   pulled at 5 mm/s to 20 % strain (2,000 steps), activation 0;
//! - **activated elongation**: activated at rest length for 0.5 s (u = 1),
//!   then pulled at 5 mm/s to 20 % (2,500 steps).
//!
//! Part 1 drives the binary of `dist/HillMuscleFE.fmu` through its C ABI
//! (dlopen; fmi2SetReal length + activation, fmi2DoStep, fmi2GetReal force
//! and stress) on the default mesh, and on the same mesh with uniform rings
//! (`radial_grading` 0, the default before 2026-12-05), runs alternating:
//! wall time per step (median, mean, 90th percentile) over the whole run,
//! median over the repetitions.
//!
//! Part 2 runs the passive pull on the FE muscle in-process
//! ([`Muscle::advance`]) for meshes from 576 to 13,500 tetrahedra: time per
//! step, Newton corrections (linear solves), residual evaluations and
//! tangent factorisations per step, the unit cost of each kind of work
//! measured at the 10 % strain state (so the split is count × unit cost),
//! and the memory of the sparse tangent, its Cholesky factor and one muscle
//! state.
//!
//! `--quick`: one repetition and the three smallest meshes.

use std::ffi::c_uint;
use std::sync::Arc;
use std::time::Instant;

use hill_muscle::fe::mesh::{Resolution, LUMPED, LUMPED_GRADING};
use hill_muscle::fe::muscle::{Discretization, Muscle};
use hill_muscle::fmi2::Model;
use hill_muscle::fmus::hillfe::HillFE;
use hill_muscle::law::{FibreHistory, FibreRate, Params};
use hill_muscle::specimen::{LENGTH as L0, MEAN_AREA};

use cabi::{load, median, Instance};
use testkit::cabi;

const H: f64 = 1e-3;
const SPEED: f64 = 0.005;

/// Inputs (activation command, length) of step i (ending at (i + 1) h).
fn passive(i: usize) -> (f64, f64) {
    (0.0, L0 + SPEED * (i + 1) as f64 * H)
}

fn activated(i: usize) -> (f64, f64) {
    let t = (i + 1) as f64 * H;
    (1.0, L0 + SPEED * (t - 0.5).max(0.0))
}

fn vr_of(name: &str) -> c_uint {
    HillFE::variables()
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}")) as c_uint
}

/// Per-step wall times [s] and linear solves (`newton_iterations`, read
/// outside the timed calls) of one run through the C ABI with the Real
/// `parameters` set (name, value), and the last force.
fn run_cabi(
    api: &cabi::Api,
    steps: usize,
    inputs: fn(usize) -> (f64, f64),
    parameters: &[(&str, f64)],
) -> (Vec<f64>, Vec<i32>, f64) {
    let ins = [vr_of("activation"), vr_of("length")];
    let outs = [vr_of("force"), vr_of("stress")];
    let parameters: Vec<(c_uint, f64)> = parameters.iter().map(|&(n, v)| (vr_of(n), v)).collect();
    let instance = Instance::with_parameters(api, &api.guid, &parameters);
    let mut out = [0.0; 2];
    let mut times = Vec::with_capacity(steps);
    let mut solves = Vec::with_capacity(steps);
    let iterations = vr_of("newton_iterations");
    for i in 0..steps {
        let (a, l) = inputs(i);
        let t = Instant::now();
        instance.step(&ins, &[a, l], i as f64 * H, H, &outs, &mut out);
        times.push(t.elapsed().as_secs_f64());
        solves.push(instance.integer(iterations));
    }
    (times, solves, out[0])
}

struct Summary {
    median: f64,
    mean: f64,
    p90: f64,
    max: f64,
    /// Linear solves per step.
    solves: f64,
    /// Median time of the steps with one linear solve and with two (the
    /// step times are bimodal: about 40 % of the passive pull's steps take a
    /// second solve, so the overall median sits in the tail of the one-solve
    /// steps and moves with their share).
    one_solve: f64,
    two_solves: f64,
}

fn summary(times: Vec<f64>, solves: Vec<i32>) -> Summary {
    let n = times.len();
    let median_of = |k: i32| {
        let t: Vec<f64> = times
            .iter()
            .zip(&solves)
            .filter(|&(_, &s)| s == k)
            .map(|(&t, _)| t)
            .collect();
        if t.is_empty() {
            f64::NAN
        } else {
            median(t)
        }
    };
    let (one_solve, two_solves) = (median_of(1), median_of(2));
    let mut t = times;
    t.sort_by(|a, b| a.partial_cmp(b).unwrap());
    Summary {
        median: t[n / 2],
        mean: t.iter().sum::<f64>() / n as f64,
        p90: t[(9 * n) / 10],
        max: t[n - 1],
        solves: solves.iter().map(|&s| s as f64).sum::<f64>() / n as f64,
        one_solve,
        two_solves,
    }
}

/// Seconds per call of `f`, median of `n` calls.
fn unit<T>(n: usize, mut f: impl FnMut() -> T) -> f64 {
    let mut v = Vec::with_capacity(n);
    for _ in 0..n {
        let t = Instant::now();
        std::hint::black_box(f());
        v.push(t.elapsed().as_secs_f64());
    }
    median(v)
}

/// Peak resident memory of this process [MiB] (VmHWM).
fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).map(|k| k.parse::<f64>().ok()))
        })
        .flatten()
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn mesh_row(res: Resolution) {
    let p = Params::default();
    let d = Arc::new(Discretization::specimen(res).unwrap());
    let (mut m, _) = Muscle::isometric(d.clone(), &p, L0, 0.0).unwrap();
    let steps = 2000;
    let (mut solves, mut residuals, mut factorizations) = (0, 0, 0);
    let mut times = Vec::with_capacity(steps);
    let mut step_solves = Vec::with_capacity(steps);
    let mut at_10 = None;
    for i in 0..steps {
        let (_, l) = passive(i);
        let t = Instant::now();
        let r = m.advance(&p, l, H, &|_| 0.0).unwrap();
        times.push(t.elapsed().as_secs_f64());
        solves += r.iterations;
        step_solves.push(r.iterations as i32);
        residuals += r.residuals;
        factorizations += r.factorizations;
        m = r.muscle;
        if i == steps / 2 {
            at_10 = Some(m.clone());
        }
    }
    let force = {
        let ev = d
            .evaluate(&p, &m.x, 0.0, &m.history, FibreRate::Step { h: H }, false)
            .unwrap();
        d.reaction(&ev.forces)
    };
    // Unit costs at the 10 % strain state.
    let s = at_10.unwrap();
    let hist: Vec<FibreHistory> = s.history.clone();
    let rate = FibreRate::Step { h: H };
    let n = if d.n_elements() > 8000 { 5 } else { 21 };
    let residual = unit(n, || d.evaluate(&p, &s.x, 0.0, &hist, rate, false).unwrap());
    let with_tangent = unit(n, || d.evaluate(&p, &s.x, 0.0, &hist, rate, true).unwrap());
    let ev = d.evaluate(&p, &s.x, 0.0, &hist, rate, true).unwrap();
    let values = ev.tangent.clone().unwrap();
    let factorize = unit(n, || d.pattern.factorize(&values).unwrap());
    let factor = d.pattern.factorize(&values).unwrap();
    let mut b = ev.forces.clone();
    let solve = unit(n, || factor.solve_in_place(&mut b));
    let tangent = with_tangent - residual;
    let k = steps as f64;
    let split = [
        residuals as f64 / k * residual,
        factorizations as f64 / k * tangent,
        factorizations as f64 / k * factorize,
        solves as f64 / k * solve,
    ];
    let total: f64 = split.iter().sum();
    let sm = summary(times, step_solves);
    let state_bytes =
        8 * (m.x.len() * (1 + m.trend.increments.len() + 1) + 2 * 2 * m.history.len());
    println!(
        "| {}×{} | {} | {} | {:.3} | {:.3} | {:.2} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.0} / {:.0} / {:.0} / {:.0} % | {:.1} | {:.1} | {:.0} | {:.2} |",
        res.n_axial,
        res.n_radial,
        d.n_elements(),
        3 * d.n_nodes(),
        sm.median * 1e3,
        sm.mean * 1e3,
        solves as f64 / k,
        residuals as f64 / k,
        factorizations as f64 / k,
        residual * 1e3,
        tangent * 1e3,
        factorize * 1e3,
        solve * 1e3,
        100.0 * split[0] / total,
        100.0 * split[1] / total,
        100.0 * split[2] / total,
        100.0 * split[3] / total,
        8.0 * d.pattern.nnz() as f64 / 1048576.0,
        8.0 * d.pattern.factor_values() as f64 / 1048576.0,
        state_bytes as f64 / 1024.0,
        force / MEAN_AREA / 1e3,
    );
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let repeats = if quick { 1 } else { 3 };

    // Part 1: the FMU through its C ABI, default mesh.
    let api = load("HillMuscleFE");
    println!(
        "HillMuscleFE through the C ABI (SetReal + DoStep + GetReal), default mesh {}×{} graded {LUMPED_GRADING:?}, h = {H} s; median of {repeats} runs",
        LUMPED.n_axial, LUMPED.n_radial
    );
    println!("Rows \"radial_grading 0\": the same mesh with uniform rings (the default before 2026-12-05), runs alternating with the default's.");
    println!("| workload | mesh | steps | median ms/step | mean ms/step | p90 ms/step | max ms/step | solves/step | median ms, 1-solve / 2-solve steps | stress at the end (kPa) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let variants: [(&str, &[(&str, f64)]); 2] = [
        ("default", &[]),
        ("radial_grading 0", &[("radial_grading", 0.0)]),
    ];
    for (name, steps, inputs) in [
        ("passive pull", 2000, passive as fn(usize) -> (f64, f64)),
        ("activated elongation", 2500, activated),
    ] {
        let mut runs: Vec<Vec<Summary>> = variants.iter().map(|_| Vec::new()).collect();
        let mut force = vec![0.0; variants.len()];
        for _ in 0..repeats {
            for (k, (_, parameters)) in variants.iter().enumerate() {
                let (t, s, f) = run_cabi(&api, steps, inputs, parameters);
                force[k] = f;
                runs[k].push(summary(t, s));
            }
        }
        for (k, (mesh, _)) in variants.iter().enumerate() {
            let m = |f: fn(&Summary) -> f64| median(runs[k].iter().map(f).collect());
            println!(
                "| {name} | {mesh} | {steps} | {:.3} | {:.3} | {:.3} | {:.1} | {:.3} | {:.3} / {:.3} | {:.1} |",
                m(|s| s.median) * 1e3,
                m(|s| s.mean) * 1e3,
                m(|s| s.p90) * 1e3,
                m(|s| s.max) * 1e3,
                m(|s| s.solves),
                m(|s| s.one_solve) * 1e3,
                m(|s| s.two_solves) * 1e3,
                force[k] / MEAN_AREA / 1e3
            );
        }
    }

    // Part 2: cost against mesh size, in-process.
    println!();
    println!("Passive pull in-process (Muscle::advance), per mesh; unit costs at 10 % strain; split = count × unit cost");
    println!("| mesh | tets | dofs | median ms/step | mean ms/step | solves/step | residuals/step | factorisations/step | residual ms | tangent ms | factorise ms | solve ms | split residual / tangent / factorise / solve | tangent MiB | factor MiB | state KiB | stress at 20 % (kPa) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let meshes: &[(usize, usize)] = if quick {
        &[(8, 2), (12, 2), (16, 3)]
    } else {
        &[(8, 2), (12, 2), (16, 3), (18, 3), (24, 4), (30, 5)]
    };
    for &(n_axial, n_radial) in meshes {
        mesh_row(Resolution { n_axial, n_radial });
    }
    println!();
    println!(
        "peak resident memory of the benchmark process: {:.0} MiB",
        peak_rss_mib()
    );
}
