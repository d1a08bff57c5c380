//! The FE muscle's opt-in element threads ([`hill_muscle::fe::threads`]):
//! `cargo bench --bench fe_threads [-- --quick] [--large] [--threads N]`.
//!
//! In-process ([`Muscle::advance`], 1 ms steps) on the default mesh and on
//! a 32 × 4 one (9,216 tetrahedra), at 1 thread and at N (default 2), the two run
//! alternately: the unit costs of a residual evaluation and of a tangent
//! evaluation (forces, tangent and ∂f/∂a) at the 10 % strain state (median
//! of repeated calls), and the time per step (mean and median over the run)
//! of two workloads: the passive pull (5 mm/s to 20 %, activation 0) and an
//! activated pull (activation ramped to 1 over the first 0.2 s, then 5 mm/s
//! from 0.5 s); on the larger mesh the first quarter of each run. Each run's forces are checked to be the same bits at both
//! counts. Also printed: the share of one thread's step time spent in the
//! threaded element loops (the residual's law and the tangent's element
//! work, from counts × unit costs), the Amdahl bound of that share.
//!
//! `--quick`: one repetition of each run (default 3); `--large`: the larger
//! mesh only.

use std::sync::Arc;
use std::time::Instant;

use hill_muscle::fe::mesh::{Resolution, LUMPED};
use hill_muscle::fe::muscle::{Discretization, Muscle};
use hill_muscle::fe::threads::Threads;
use hill_muscle::law::{FibreHistory, FibreRate, Params};
use hill_muscle::specimen::LENGTH as L0;

const H: f64 = 1e-3;
/// Tetrahedra of the default mesh.
const LUMPED_ELEMENTS: usize = 2592;
const SPEED: f64 = 0.005;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// (activation, length) of step i (ending at (i + 1) h).
fn passive(i: usize) -> (f64, f64) {
    (0.0, L0 + SPEED * (i + 1) as f64 * H)
}

fn activated(i: usize) -> (f64, f64) {
    let t = (i + 1) as f64 * H;
    ((t / 0.2).min(1.0), L0 + SPEED * (t - 0.5).max(0.0))
}

/// Per-step times, the forces (bits), residual evaluations and
/// factorisations per step, and the state at the middle of the run.
struct Run {
    times: Vec<f64>,
    forces: Vec<u64>,
    residuals: f64,
    factorizations: f64,
    middle: Muscle,
}

fn run(d: &Arc<Discretization>, steps: usize, inputs: fn(usize) -> (f64, f64)) -> Run {
    let p = Params::default();
    let (mut m, _) = Muscle::isometric(d.clone(), &p, L0, 0.0).unwrap();
    let (mut times, mut forces) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
    let (mut residuals, mut factorizations) = (0, 0);
    let mut middle = None;
    for i in 0..steps {
        let (a, l) = inputs(i);
        let t = Instant::now();
        let r = m.advance(&p, l, H, &move |_| a).unwrap();
        times.push(t.elapsed().as_secs_f64());
        residuals += r.residuals;
        factorizations += r.factorizations;
        m = r.muscle;
        let ev = d
            .evaluate(&p, &m.x, a, &m.history, FibreRate::Step { h: H }, false)
            .unwrap();
        forces.push(d.reaction(&ev.forces).to_bits());
        if i == steps / 2 {
            middle = Some(m.clone());
        }
    }
    Run {
        times,
        forces,
        residuals: residuals as f64 / steps as f64,
        factorizations: factorizations as f64 / steps as f64,
        middle: middle.unwrap(),
    }
}

/// Median time of `n` calls of `f`.
fn unit<T>(n: usize, mut f: impl FnMut() -> T) -> f64 {
    median(
        (0..n)
            .map(|_| {
                let t = Instant::now();
                std::hint::black_box(f());
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn mesh(res: Resolution, threads: Threads, repeats: usize) {
    let d = Arc::new(Discretization::specimen(res).unwrap());
    let p = Params::default();
    let counts = [Threads::ONE, threads];
    let label = |t: Threads| t.get();
    // The larger mesh's runs stop at a quarter of the steps (5 % strain).
    let scale = if d.n_elements() > 4 * LUMPED_ELEMENTS {
        4
    } else {
        1
    };
    for (name, inputs, steps) in [
        (
            "passive pull",
            passive as fn(usize) -> (f64, f64),
            2000 / scale,
        ),
        ("activated pull", activated, 2500 / scale),
    ] {
        // Per count: step times (all repetitions), the unit costs.
        let mut times = [Vec::new(), Vec::new()];
        let mut residual = [Vec::new(), Vec::new()];
        let mut tangent = [Vec::new(), Vec::new()];
        let mut reference: Option<Run> = None;
        let mut extra = (0.0, 0.0);
        for _ in 0..repeats {
            for (k, &t) in counts.iter().enumerate() {
                d.set_threads(t);
                let r = run(&d, steps, inputs);
                times[k].extend_from_slice(&r.times);
                match &reference {
                    None => reference = Some(r),
                    Some(first) => assert!(
                        first.forces == r.forces,
                        "{name}: forces differ between thread counts"
                    ),
                }
            }
        }
        let reference = reference.unwrap();
        let s = &reference.middle;
        let hist: Vec<FibreHistory> = s.history.clone();
        let a = inputs(steps / 2).0;
        let rate = FibreRate::Step { h: H };
        for _ in 0..5 {
            for (k, &t) in counts.iter().enumerate() {
                d.set_threads(t);
                residual[k].push(unit(9, || {
                    d.evaluate(&p, &s.x, a, &hist, rate, false).unwrap()
                }));
                tangent[k].push(unit(5, || {
                    d.evaluate(&p, &s.x, a, &hist, rate, true).unwrap()
                }));
            }
        }
        let residual = residual.map(median);
        let tangent = tangent.map(median);
        d.set_threads(Threads::ONE);
        let ev = d.evaluate(&p, &s.x, a, &hist, rate, true).unwrap();
        let values = ev.tangent.clone().unwrap();
        let factorize = unit(9, || d.pattern.factorize(&values).unwrap());
        extra.0 = factorize;
        let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
        let step_mean = [mean(&times[0]), mean(&times[1])];
        let step_median = [median(times[0].clone()), median(times[1].clone())];
        // The threaded share of one thread's step: residuals × residual
        // cost (when the residual is threaded at this size) + tangents ×
        // tangent cost.
        let residual_threaded = threads.for_loop(
            d.n_elements(),
            hill_muscle::fe::threads::RESIDUAL_ELEMENTS_PER_THREAD,
        ) > 1;
        let share = ((if residual_threaded {
            reference.residuals * residual[0]
        } else {
            0.0
        }) + reference.factorizations * tangent[0])
            / step_mean[0];
        println!(
            "| {}×{} ({} tets) | {name}, {steps} steps | {} vs {} | {:.3} / {:.3} ({:.2}) | {:.3} / {:.3} ({:.2}) | {:.3} / {:.3} ({:.2}) | {:.2} / {:.2} ({:.2}) | {:.2} | {:.2} | {:.2} | {:.0} % |",
            res.n_axial,
            res.n_radial,
            d.n_elements(),
            label(counts[0]),
            label(counts[1]),
            step_mean[0] * 1e3,
            step_mean[1] * 1e3,
            step_mean[0] / step_mean[1],
            step_median[0] * 1e3,
            step_median[1] * 1e3,
            step_median[0] / step_median[1],
            residual[0] * 1e3,
            residual[1] * 1e3,
            residual[0] / residual[1],
            tangent[0] * 1e3,
            tangent[1] * 1e3,
            tangent[0] / tangent[1],
            extra.0 * 1e3,
            reference.residuals,
            reference.factorizations,
            100.0 * share,
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let threads = args
        .iter()
        .position(|a| a == "--threads")
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(2), |n| n.parse::<usize>().map_err(|e| e.to_string()))
        .and_then(Threads::new)
        .expect("--threads N, N in 1..=64");
    let repeats = if quick { 1 } else { 3 };
    println!(
        "FE muscle in-process, h = {H} s, 1 thread vs {} alternating, {repeats} repetition(s) of each run; unit costs median of 5 × median of 9 (residual) / 5 (tangent) calls at the run's middle state",
        threads.get()
    );
    println!("| mesh | workload | threads | mean ms/step (ratio) | median ms/step (ratio) | residual ms (ratio) | tangent ms (ratio) | factorisation ms | residuals/step | tangents/step | threaded share of 1 thread's step |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    // The default mesh, and one large enough (9,216 tetrahedra) for the
    // residual's loop to be threaded at 2 threads.
    let meshes = [
        LUMPED,
        Resolution {
            n_axial: 2 * LUMPED.n_axial,
            n_radial: LUMPED.n_radial + 1,
        },
    ];
    // `--large`: the larger mesh only.
    let large = args.iter().any(|a| a == "--large");
    for res in meshes.into_iter().skip(usize::from(large)) {
        mesh(res, threads, repeats);
    }
}
