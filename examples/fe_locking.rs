//! Passive stress at 20 % strain per mesh:
//! `cargo run --release --example fe_locking [-- [--plain] [--grading β] [--radial-grading g] n_axial:n_radial ...]`.
//!
//! `--grading β`: slices graded toward the clamped faces
//! ([`hill_muscle::fe::mesh::graded_slice`]; default 0, uniform);
//! `--radial-grading g`: rings graded toward the lateral surface
//! ([`hill_muscle::fe::mesh::graded_ring`]; default 0, uniform);
//! `--plain`: the plain displacement tetrahedron instead of the
//! average-nodal-pressure element.
//!
//! The clamped fusiform specimen (D = 1e-9, Table 2) pulled quasi-statically
//! to 20 % strain in 20 steps of 1 % (passive: the response is elastic, so the
//! step size only affects the path the solver takes). Prints per mesh the
//! engineering stress force / (V0/L0) and, for verification item 3, the
//! largest |J − 1| of the element volume ratios (each element's mean nodal
//! J) in the elements touching an end face's rim, in all others, and in those
//! whose centroid lies more than 1 mm from the rims, and the share of the
//! volume where |J − 1| > 1e-3; and the linear solves Newton took over the
//! 20 steps.

use std::sync::Arc;
use std::time::Instant;

use hill_muscle::fe::mesh::{FibreLayout, Grading, Resolution};
use hill_muscle::fe::muscle::{Discretization, Ends, Muscle, Volumetric};
use hill_muscle::law::Params;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let plain = args.iter().any(|a| a == "--plain");
    args.retain(|a| a != "--plain");
    let mut grading = Grading::UNIFORM;
    for (flag, value) in [
        ("--grading", &mut grading.axial),
        ("--radial-grading", &mut grading.radial),
    ] {
        if let Some(i) = args.iter().position(|a| a == flag) {
            *value = args[i + 1].parse().expect("a grading in [0, 0.95]");
            args.drain(i..i + 2);
        }
    }
    let levels: Vec<(usize, usize)> = if args.is_empty() {
        vec![(12, 2), (18, 3), (24, 4)]
    } else {
        args.iter()
            .map(|a| {
                let (x, r) = a.split_once(':').expect("n_axial:n_radial");
                (x.parse().unwrap(), r.parse().unwrap())
            })
            .collect()
    };
    let p = Params::default();
    let (l0, area) = (0.05, hill_muscle::specimen::MEAN_AREA);
    println!(
        "{} element, axial grading {}, radial grading {}",
        if plain { "plain" } else { "nodal-pressure" },
        grading.axial,
        grading.radial
    );
    println!(
        "| mesh | tets | stress at 20 % (kPa) | max \\|J − 1\\|: touching a rim | elsewhere | beyond 1 mm of the rims | volume share with \\|J − 1\\| > 1e-3 | linear solves | s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (na, nr) in levels {
        let t = Instant::now();
        let res = Resolution {
            n_axial: na,
            n_radial: nr,
        };
        let d = Arc::new(
            Discretization::fusiform_graded(
                l0,
                area,
                res,
                grading,
                FibreLayout::Axial,
                Ends::Clamped,
            )
            .unwrap()
            .with_volumetric(if plain {
                Volumetric::Element
            } else {
                Volumetric::NodalAverage
            }),
        );
        let (mut m, _) = Muscle::isometric(d.clone(), &p, l0, 0.0).unwrap();
        let (mut last, mut solves) = (None, 0);
        for i in 1..=20 {
            let r = m
                .advance(&p, l0 * (1.0 + 0.01 * i as f64), 0.02, &|_| 0.0)
                .unwrap();
            solves += r.iterations;
            last = Some(r.solution.evaluation);
            m = r.muscle;
        }
        let ev = last.expect("20 steps");
        let v = d.volume_ratio_spread(&ev, 1e-3, 1e-3);
        println!(
            "| {na}×{nr} | {} | {:.1} | {:.3e} | {:.3e} | {:.3e} | {:.1e} | {solves} | {:.1} |",
            d.n_elements(),
            d.reaction(&ev.forces) / area / 1e3,
            v.touching_a_rim,
            v.elsewhere,
            v.beyond,
            v.share_over,
            t.elapsed().as_secs_f64()
        );
    }
}
