//! Verification of the FE muscle on the paper's fusiform specimen (issue 3,
//! "Verification" items 2, 4 and 5), through the public API of `hill_muscle::fe`:
//!
//! - the passive stress converges under refinement and the default mesh is
//!   within 3 % of the finest level; the plain displacement tetrahedron is
//!   far stiffer on the same meshes (same law, D = 1e-9);
//! - objectivity: the discrete forces of a rigidly rotated deformed
//!   configuration are the rotated forces (and the reaction the same);
//! - the paper's trends (Figs 11–12) on the 3D specimen: passive stress falls
//!   as D grows and rises with sigma0; activated stress rises with kc and d.
//!
//! Apart from the locking study, the mesh is small (12 × 1 or 6 × 1): those
//! checks are properties of the discretization and the law, not of the mesh's
//! resolution.

use std::sync::Arc;

use hill_muscle::fe::mesh::{FibreLayout, Grading, Resolution, LUMPED, LUMPED_GRADING};
use hill_muscle::fe::muscle::{Discretization, Ends, Muscle, Volumetric};
use hill_muscle::law::{FibreRate, Params};
use hill_muscle::specimen::MEAN_AREA;
use nalgebra::{Rotation3, Vector3};

const L0: f64 = 0.05;

fn specimen(n_axial: usize, n_radial: usize, volumetric: Volumetric) -> Arc<Discretization> {
    graded(
        Resolution { n_axial, n_radial },
        Grading::UNIFORM,
        volumetric,
    )
}

fn graded(res: Resolution, grading: Grading, volumetric: Volumetric) -> Arc<Discretization> {
    Arc::new(
        Discretization::fusiform_graded(
            L0,
            MEAN_AREA,
            res,
            grading,
            FibreLayout::Axial,
            Ends::Clamped,
        )
        .unwrap()
        .with_volumetric(volumetric),
    )
}

/// Engineering stress force / (V0/L0) along the paper's elongation: from
/// rest at L0, the activation level ramped linearly to `a` over 0.25 s and
/// held at L0 to 0.5 s (10 steps of 0.05 s), then the pull at 5 mm/s (steps
/// of 1 % strain = 0.1 s) up to `strain`.
fn pulled_stress(d: &Arc<Discretization>, p: &Params, a: f64, strain: f64) -> f64 {
    let (mut m, _) = Muscle::isometric(d.clone(), p, L0, 0.0).unwrap();
    let level = |t: f64| a * (t / 0.25).min(1.0);
    if a > 0.0 {
        for i in 0..10 {
            let t0 = 0.05 * i as f64;
            let r = m
                .advance(p, L0, 0.05, &|tau| level(t0 + tau))
                .unwrap_or_else(|e| panic!("hold step {i}: {e}"));
            m = r.muscle;
        }
    }
    let n = (strain / 0.01).round() as usize;
    let mut force = f64::NAN;
    for i in 1..=n {
        let r = m
            .advance(p, L0 * (1.0 + 0.01 * i as f64), 0.1, &|_| a)
            .unwrap_or_else(|e| panic!("step {i}: {e}"));
        force = d.reaction(&r.solution.evaluation.forces);
        m = r.muscle;
    }
    force / MEAN_AREA
}

/// The locking study of issue 3 (verification item 2), at D = 1e-9: the
/// passive stress at 20 % strain on three levels graded like the default
/// mesh (12 × 2, 18 × 3, 24 × 4) falls and converges (each difference
/// smaller than the last), and the default mesh ([`LUMPED`], 16 × 3) lies
/// within 3 % of the finest of them. (Measured, docs/fe.md: 229.9, 221.6,
/// 219.3 kPa, default 222.0 kPa; 48 × 8 gives 216.1 kPa.)
#[test]
fn passive_stress_converges_under_refinement_and_the_default_is_within_3_percent() {
    let p = Params::default();
    let stress = |res| {
        pulled_stress(
            &graded(res, LUMPED_GRADING, Volumetric::NodalAverage),
            &p,
            0.0,
            0.20,
        )
    };
    let levels: Vec<f64> = [(12, 2), (18, 3), (24, 4)]
        .iter()
        .map(|&(n_axial, n_radial)| stress(Resolution { n_axial, n_radial }))
        .collect();
    assert!(
        levels.windows(2).all(|w| w[1] < w[0]),
        "not monotone: {levels:?}"
    );
    assert!(
        (levels[1] - levels[2]).abs() < (levels[0] - levels[1]).abs(),
        "not converging: {levels:?}"
    );
    let default = stress(LUMPED);
    let finest = levels[2];
    assert!(
        ((default - finest) / finest).abs() < 0.03,
        "default {default} Pa vs finest {finest} Pa"
    );
}

/// The plain displacement tetrahedron (one volume constraint per element)
/// on the same meshes: on the uniform 12 × 2 mesh more than 4 times stiffer
/// than the nodal-pressure element (measured 1954 vs 358 kPa), and on the
/// default graded mesh still more than 1.3 times (331 vs 222 kPa; the
/// refined nodal-pressure meshes approach ~215 kPa).
#[test]
fn plain_tetrahedra_are_far_stiffer_on_the_same_mesh() {
    let p = Params::default();
    let pair = |res, grading| {
        let s = |v| pulled_stress(&graded(res, grading, v), &p, 0.0, 0.20);
        (s(Volumetric::NodalAverage), s(Volumetric::Element))
    };
    let uniform = Resolution {
        n_axial: 12,
        n_radial: 2,
    };
    let (anp, plain) = pair(uniform, Grading::UNIFORM);
    assert!(
        anp > 150e3 && anp < 450e3,
        "nodal-pressure element: {anp} Pa"
    );
    assert!(
        plain > 4.0 * anp,
        "12 × 2: plain {plain} Pa vs nodal-pressure {anp} Pa"
    );
    let (anp, plain) = pair(LUMPED, LUMPED_GRADING);
    assert!(
        plain > 1.3 * anp,
        "default: plain {plain} Pa vs nodal-pressure {anp} Pa"
    );
}

#[test]
fn forces_are_objective() {
    let p = Params::default();
    for volumetric in [Volumetric::NodalAverage, Volumetric::Element] {
        let d = specimen(6, 1, volumetric);
        let (m, _) = Muscle::isometric(d.clone(), &p, 1.15 * L0, 0.6).unwrap();
        let q = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.7)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), -1.9);
        let rotate = |v: &[f64]| -> Vec<f64> {
            v.chunks(3)
                .flat_map(|c| {
                    let r = q * Vector3::new(c[0], c[1], c[2]);
                    [r.x, r.y, r.z]
                })
                .collect()
        };
        let hist = m.history.clone();
        let rate = FibreRate::Step { h: 1e-3 };
        let ev = d.evaluate(&p, &m.x, 0.6, &hist, rate, false).unwrap();
        let ev_q = d
            .evaluate(&p, &rotate(&m.x), 0.6, &hist, rate, false)
            .unwrap();
        let expected = rotate(&ev.forces);
        let scale = ev.forces.iter().fold(0.0f64, |s, f| s.max(f.abs()));
        for (i, (a, b)) in ev_q.forces.iter().zip(&expected).enumerate() {
            assert!(
                (a - b).abs() <= 1e-9 * scale,
                "{volumetric:?} dof {i}: {a} vs rotated {b} (scale {scale})"
            );
        }
        // The reaction along the (rotated) axis is the same force.
        let face_sum = |f: &[f64]| {
            d.mesh.moved_face.iter().fold(Vector3::zeros(), |s, &a| {
                s + Vector3::new(f[3 * a], f[3 * a + 1], f[3 * a + 2])
            })
        };
        let axial = face_sum(&ev.forces).x;
        let axial_q = (q.inverse() * face_sum(&ev_q.forces)).x;
        assert!(
            ((axial - axial_q) / axial).abs() < 1e-10,
            "{axial} vs {axial_q}"
        );
        for (e, eq) in ev.elements.iter().zip(&ev_q.elements) {
            assert!((e.lambda_f - eq.lambda_f).abs() < 1e-12);
            assert!((e.j - eq.j).abs() < 1e-12);
        }
    }
}

/// Passive stress at 20 % strain: falls as D grows, rises with sigma0 (paper
/// Fig 11, over its ranges).
#[test]
fn passive_trends_of_the_paper() {
    let d = specimen(12, 1, Volumetric::NodalAverage);
    let with = |f: &dyn Fn(&mut Params)| {
        let mut p = Params::default();
        f(&mut p);
        pulled_stress(&d, &p, 0.0, 0.20)
    };
    let by_d: Vec<f64> = [1e-9, 1e-7, 1e-6]
        .iter()
        .map(|&v| with(&|p| p.d_comp = v))
        .collect();
    assert!(
        by_d.windows(2).all(|w| w[1] < w[0]),
        "passive stress vs D = 1e-9, 1e-7, 1e-6: {by_d:?}"
    );
    let by_sigma0: Vec<f64> = [0.16e6, 0.3e6, 1.0e6]
        .iter()
        .map(|&v| with(&|p| p.sigma0 = v))
        .collect();
    assert!(
        by_sigma0.windows(2).all(|w| w[1] > w[0]),
        "passive stress vs sigma0 = 0.16, 0.3, 1.0 MPa: {by_sigma0:?}"
    );
}

/// Activated stress at 20 % strain (activation 1, pulled at 5 mm/s): rises
/// with kc and with d (paper Fig 12, over its ranges).
#[test]
fn activated_trends_of_the_paper() {
    let d = specimen(12, 1, Volumetric::NodalAverage);
    let with = |f: &dyn Fn(&mut Params)| {
        let mut p = Params::default();
        f(&mut p);
        pulled_stress(&d, &p, 1.0, 0.20)
    };
    let by_kc: Vec<f64> = [4.0, 5.0, 5.88]
        .iter()
        .map(|&v| with(&|p| p.kc = v))
        .collect();
    assert!(
        by_kc.windows(2).all(|w| w[1] > w[0]),
        "activated stress vs kc = 4, 5, 5.88: {by_kc:?}"
    );
    let by_d: Vec<f64> = [1.1, 1.5, 1.8]
        .iter()
        .map(|&v| with(&|p| p.d = v))
        .collect();
    assert!(
        by_d.windows(2).all(|w| w[1] > w[0]),
        "activated stress vs d = 1.1, 1.5, 1.8: {by_d:?}"
    );
}

/// The muscle pulled passively to `strain` (as [`pulled_stress`]) and its
/// final evaluation.
fn pulled(d: &Arc<Discretization>, p: &Params, strain: f64) -> hill_muscle::fe::muscle::Evaluation {
    let (mut m, _) = Muscle::isometric(d.clone(), p, L0, 0.0).unwrap();
    let n = (strain / 0.01).round() as usize;
    let mut last = None;
    for i in 1..=n {
        let r = m
            .advance(p, L0 * (1.0 + 0.01 * i as f64), 0.1, &|_| 0.0)
            .unwrap_or_else(|e| panic!("step {i}: {e}"));
        last = Some(r.solution.evaluation);
        m = r.muscle;
    }
    last.unwrap()
}

/// Issue 3 verification item 3, at 20 % strain with D = 1e-9: the volume
/// the formulation constrains (each element's mean nodal volume ratio J) is
/// within 1e-3 of 1 in every element whose centroid lies more than 1 mm from
/// the end faces' rims, and in every element not touching a rim on these
/// meshes; the elements where it is not are under 0.1 % of the volume, and
/// the whole specimen's volume is within 1e-4. At the rims — where a clamped
/// face meets the free surface at about 105° — the nearly incompressible
/// solution has a corner singularity (p = 2 (J − 1) / D ∝ r^−0.45, docs/fe.md),
/// so no pointwise bound on J − 1 holds there under refinement. The test
/// shows that: the largest rim deviation grows from the 12 × 2 to the
/// 16 × 3 (default) to the 24 × 4 mesh, while the bounds above hold on each.
#[test]
fn volume_is_conserved_except_at_the_clamped_rims_where_the_pressure_is_singular() {
    let p = Params::default();
    let mut rim_max = Vec::new();
    for res in [
        Resolution {
            n_axial: 12,
            n_radial: 2,
        },
        LUMPED,
        Resolution {
            n_axial: 24,
            n_radial: 4,
        },
    ] {
        let d = graded(res, LUMPED_GRADING, Volumetric::NodalAverage);
        let ev = pulled(&d, &p, 0.20);
        let v = d.volume_ratio_spread(&ev, 1e-3, 1e-3);
        let whole = (ev.volume / d.reference_volume() - 1.0).abs();
        eprintln!(
            "{}x{}: {v:?}, whole volume {whole:.2e}",
            res.n_axial, res.n_radial
        );
        assert!(
            v.beyond < 1e-3,
            "{res:?}: |J - 1| = {:e} more than 1 mm from the rims",
            v.beyond
        );
        assert!(
            v.elsewhere < 1e-3,
            "{res:?}: |J - 1| = {:e} in an element not touching a rim",
            v.elsewhere
        );
        assert!(
            v.share_over < 1e-3,
            "{res:?}: |J - 1| > 1e-3 in {:e} of the volume",
            v.share_over
        );
        assert!(whole < 1e-4, "{res:?}: |V/V0 - 1| = {whole:e}");
        rim_max.push(v.touching_a_rim);
    }
    assert!(
        rim_max.windows(2).all(|w| w[1] > w[0]),
        "the rim deviation does not grow under refinement: {rim_max:?}"
    );
}
