//! Cost of the FE muscle's step and its parts, per mesh size (issue 3
//! "Performance"): `cargo run --release --example fe_bench [-- n_axial:n_radial ...]`.
//!
//! Meshes graded like the default one (`LUMPED_AXIAL_GRADING`); default
//! sizes 12×2, 16×3 (the default), 18×3, 24×4.
//!
//! Workload: the passive pull of the paper (5 mm/s) with 1 ms communication
//! steps from rest, 50 steps after 20 warm-up steps; reported: median wall
//! time per step over 5 repetitions, Newton iterations per step, and the
//! cost split of one Newton iteration (residual only, residual + tangent
//! assembly, factorisation, solve) as medians of 20 calls.

use std::sync::Arc;
use std::time::Instant;

use hill_muscle::fe::mesh::{FibreLayout, Resolution, LUMPED_AXIAL_GRADING};
use hill_muscle::fe::muscle::{Discretization, Ends, Muscle};
use hill_muscle::law::{FibreHistory, FibreRate, Params};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time<T>(n: usize, mut f: impl FnMut() -> T) -> f64 {
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

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let levels: Vec<(usize, usize)> = if args.is_empty() {
        vec![(12, 2), (16, 3), (18, 3), (24, 4)]
    } else {
        args.iter()
            .map(|a| {
                let (x, r) = a.split_once(':').expect("n_axial:n_radial");
                (x.parse().unwrap(), r.parse().unwrap())
            })
            .collect()
    };
    let p = Params::default();
    println!("| mesh | tets | dofs | nnz | ms/step (1 ms pull) | Newton it./step | residual ms | +tangent ms | factorise ms | solve ms |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (na, nr) in levels {
        let res = Resolution {
            n_axial: na,
            n_radial: nr,
        };
        let d = Arc::new(
            Discretization::fusiform_graded(
                0.05,
                hill_muscle::specimen::MEAN_AREA,
                res,
                LUMPED_AXIAL_GRADING,
                FibreLayout::Axial,
                Ends::Clamped,
            )
            .unwrap(),
        );
        let h = 1e-3;
        let (mut m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
        let mut l = 0.05;
        for _ in 0..20 {
            l += 0.005 * h;
            m = m.advance(&p, l, h, &|_| 0.0).unwrap().muscle;
        }
        let reps = if d.n_elements() > 10_000 { 1 } else { 5 };
        let steps = 50;
        let mut per_step = Vec::new();
        let mut its = 0;
        for _ in 0..reps {
            let mut mm = m.clone();
            let mut ll = l;
            its = 0;
            let t = Instant::now();
            for _ in 0..steps {
                ll += 0.005 * h;
                let r = mm.advance(&p, ll, h, &|_| 0.0).unwrap();
                its += r.iterations;
                mm = r.muscle;
            }
            per_step.push(t.elapsed().as_secs_f64() / steps as f64);
        }
        let hist = vec![FibreHistory::REST; d.n_elements()];
        let rate = FibreRate::Step { h };
        let n = if d.n_elements() > 10_000 { 3 } else { 20 };
        let res_only = time(n, || d.evaluate(&p, &m.x, 0.0, &hist, rate, false).unwrap());
        let with_tangent = time(n, || d.evaluate(&p, &m.x, 0.0, &hist, rate, true).unwrap());
        let ev = d.evaluate(&p, &m.x, 0.0, &hist, rate, true).unwrap();
        let values = ev.tangent.clone().unwrap();
        let fact = time(n, || d.pattern.factorize(&values).unwrap());
        let f = d.pattern.factorize(&values).unwrap();
        let mut b = ev.forces.clone();
        let solve = time(n, || f.solve_in_place(&mut b));
        println!(
            "| {na}×{nr} | {} | {} | {} | {:.2} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} |",
            d.n_elements(),
            3 * d.n_nodes(),
            d.pattern.nnz(),
            median(per_step) * 1e3,
            its as f64 / steps as f64,
            res_only * 1e3,
            with_tangent * 1e3,
            fact * 1e3,
            solve * 1e3
        );
    }
}
