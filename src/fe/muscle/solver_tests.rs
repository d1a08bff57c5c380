//! Tests of the equilibrium solve ([`crate::fe::newton`]) through the
//! muscle's steps: every step ends in an equilibrium to the tolerance, the
//! reused tangent and the pressures' fallback do what they are for, and a
//! tangent formed again from its anchor continues bit for bit.

use super::*;
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::work::Work;

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn specimen(n_axial: usize, n_radial: usize) -> Arc<Discretization> {
    Arc::new(
        Discretization::fusiform_graded(
            0.05,
            crate::specimen::MEAN_AREA,
            Resolution { n_axial, n_radial },
            Grading::axial(0.9),
            FibreLayout::Axial,
            Ends::Clamped,
        )
        .unwrap(),
    )
}

/// The Newton correction at a converged step with a tangent formed there:
/// (max |Δx| / L0, |δF| / max(|F|, σ0 A)) — how far the solution is from
/// the equilibrium, independently of how it was reached.
fn distance_to_equilibrium(d: &Discretization, p: &Params, r: &Advance) -> (f64, f64) {
    let ev = &r.solution.evaluation;
    let level = r.activation;
    let cache = TangentCache::new(Anchor {
        x: r.solution.x.clone(),
        activation: level,
        start: r.start.clone(),
        rate: r.rate,
        pressure: None,
    });
    let t = cache.tangent(d, p).unwrap();
    let mut dx: Vec<f64> = ev
        .forces
        .iter()
        .zip(&d.pattern.prescribed)
        .map(|(f, &pr)| if pr { 0.0 } else { -f })
        .collect();
    t.factor.solve_in_place(&mut dx);
    let df: f64 = t.d_force.iter().zip(&dx).map(|(k, x)| k * x).sum();
    let scale = d.reaction(&ev.forces).abs().max(p.sigma0 * d.mean_area());
    (max_abs(&dx) / d.l0, df.abs() / scale)
}

/// [`distance_to_equilibrium`] of the isometric initialization of `d` at
/// `length` and activation level `level`.
fn isometric_distance(d: &Arc<Discretization>, p: &Params, length: f64, level: f64) -> (f64, f64) {
    let (m, s) = Muscle::isometric(d.clone(), p, length, level).unwrap();
    let r = Advance {
        muscle: m.clone(),
        solution: s,
        start: m.history.clone(),
        rate: FibreRate::Isometric,
        activation: level,
        iterations: 0,
        factorizations: 0,
        residuals: 0,
        substeps: 1,
        pieces: vec![],
    };
    distance_to_equilibrium(d, p, &r)
}

/// Convergence at the predictor ([`crate::fe::newton`] docs): on a smooth passive pull
/// more than a third of the steps are accepted after one linear solve
/// (without the stand-in a step takes one only when its first correction
/// is at the rounding level; here 95 of 200 take one, 378 solves in
/// all), the earlier steps' contraction
/// standing in, and every step is still an
/// equilibrium to the tolerance (the bound of
/// `reused_tangent_converges_to_the_equilibrium`); a length jump after
/// those steps, where the stale contraction says nothing, is not
/// accepted on it: it too ends at an equilibrium.
#[test]
fn a_measured_contraction_stands_in_only_where_it_holds() {
    let p = Params::default();
    let d = specimen(8, 2);
    let h = 1e-3;
    let (mut m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let tol = 10.0 * RESIDUAL_TOLERANCE;
    let steps = 200;
    let (mut solves, mut one_solve) = (0, 0);
    for k in 1..=steps {
        let r = m
            .advance(&p, 0.05 * (1.0 + 1e-4 * k as f64), h, &|_| 0.0)
            .unwrap();
        let (dx, df) = distance_to_equilibrium(&d, &p, &r);
        assert!(dx < tol && df < tol, "step {k}: |dx|/L0 {dx:e}, dF {df:e}");
        solves += r.iterations;
        one_solve += usize::from(r.iterations == 1);
        m = r.muscle;
    }
    assert!(
        one_solve > steps / 3 && solves < 2 * steps,
        "{one_solve} one-solve steps, {solves} solves in {steps} steps"
    );
    assert!(m.trend.contraction.is_some());
    let r = m.advance(&p, 0.05 * 1.05, h, &|_| 0.0).unwrap();
    let (dx, df) = distance_to_equilibrium(&d, &p, &r);
    assert!(
        r.iterations > 1 && dx < tol && df < tol,
        "jump: {} solves, |dx|/L0 {dx:e}, dF {df:e}",
        r.iterations
    );
}

/// The tangent formed with the pressures of the nodal volume ratios at x
/// given explicitly is the plain tangent, bit for bit; and the
/// linearised pressures are the first-order change of those pressures:
/// against central differences of U_J'(J_a(x + ε d)).
#[test]
fn pressures_as_unknowns_are_consistent_with_the_volume_ratios() {
    let p = Params::default();
    let d = specimen(6, 1);
    let (m, _) = Muscle::isometric(d.clone(), &p, 0.052, 0.3).unwrap();
    let x = m.x.clone();
    let rate = FibreRate::Step { h: 1e-3 };
    let dir: Vec<f64> = (0..x.len())
        .map(|i| {
            if d.pattern.prescribed[i] {
                0.0
            } else {
                ((i * 7919) % 13) as f64 / 13.0 - 0.5
            }
        })
        .collect();
    let (current, _) = d.linearised_pressures(&p, &x, &vec![0.0; x.len()]).unwrap();
    let plain = d.evaluate(&p, &x, 0.3, &m.history, rate, true).unwrap();
    let given = d
        .evaluate_tangent(&p, &x, 0.3, &m.history, rate, Some(&current))
        .unwrap();
    assert_eq!(plain.tangent, given.tangent);
    assert_eq!(plain.forces, given.forces);
    let eps = 1e-7;
    let at = |t: f64| -> Vec<f64> {
        let xt: Vec<f64> = x.iter().zip(&dir).map(|(a, b)| a + t * b).collect();
        d.linearised_pressures(&p, &xt, &vec![0.0; x.len()])
            .unwrap()
            .0
    };
    let (plus, minus) = (at(eps), at(-eps));
    let scaled: Vec<f64> = dir.iter().map(|v| eps * v).collect();
    let (_, predicted) = d.linearised_pressures(&p, &x, &scaled).unwrap();
    let scale = plus
        .iter()
        .zip(&minus)
        .fold(0.0_f64, |s, (a, b)| s.max((a - b).abs()));
    assert!(scale > 0.0);
    for a in 0..current.len() {
        let fd = 0.5 * (plus[a] - minus[a]);
        let lin = predicted[a] - current[a];
        assert!(
            (fd - lin).abs() <= 1e-6 * scale,
            "node {a}: {lin:e} vs {fd:e}"
        );
    }
}

/// A stiff case for the solver: a 5 % length jump in one step from rest
/// at D = 1e-9 (bulk modulus 2 GPa against a shear stiffness of ~20 kPa)
/// on the graded default mesh. With only the volume ratios' pressures in
/// the tangent every attempt failed and continuation took 439 linear
/// solves (the second-order volume change of each correction, times 2/D,
/// spoils the tangent's initial-stress part); with the fallback that
/// carries the pressures as unknowns ([`crate::fe::newton`], "Pressures") the step
/// converges without continuation or substeps, in 139 solves counting
/// the failed displacement attempts before it (asserted: at most 200,
/// under half the continuation's). The result is the equilibrium
/// of the same problem: the same force as the step reached in 50
/// increments of 0.1 %.
#[test]
fn a_length_jump_from_rest_converges_in_few_iterations() {
    let p = Params::default();
    let d = specimen(16, 3);
    let h = 0.1;
    let (m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let jump = m.advance(&p, 0.0525, h, &|_| 0.0).unwrap();
    assert!(
        jump.iterations <= 200 && jump.substeps == 1,
        "{} linear solves, {} substeps",
        jump.iterations,
        jump.substeps
    );
    let mut slow = m;
    for k in 1..=50 {
        slow = slow
            .advance(&p, 0.05 * (1.0 + 0.001 * k as f64), h / 50.0, &|_| 0.0)
            .unwrap()
            .muscle;
    }
    let force = |x: &[f64]| {
        let ev = d
            .evaluate(&p, x, 0.0, &slow.history, FibreRate::Step { h }, false)
            .unwrap();
        d.reaction(&ev.forces)
    };
    let (fj, fs) = (d.reaction(&jump.solution.evaluation.forces), force(&slow.x));
    assert!(fj > 1.0 && (fj - fs).abs() <= 1e-6 * fj, "{fj} vs {fs}");
}

/// The paper's activated elongation (MODEL_NOTES "Experiments"), on a
/// small mesh: activated at rest length for 0.1 s (u = 1), then pulled
/// at 5 mm/s, 1 ms steps. Every step's result is an equilibrium to the
/// tolerance — the Newton correction with a tangent formed at the result
/// moves no node by more than 10 × the tolerance × L0 and the force by
/// no more than 10 × the tolerance × max(|F|, σ0 A) — and in the pull
/// the reused tangent carries most steps (factorisations in fewer than
/// a quarter of them).
#[test]
fn reused_tangent_converges_to_the_equilibrium() {
    let p = Params::default();
    let d = specimen(6, 1);
    let h = 1e-3;
    let (mut m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let level = |t: f64| 1.0 - (-p.s * t).exp();
    let (hold, pull): (usize, usize) = (100, 60);
    let mut pull_factorizations = 0;
    for k in 0..hold + pull {
        let t0 = k as f64 * h;
        let l = 0.05 + 0.005 * h * (k + 1).saturating_sub(hold) as f64;
        let r = m.advance(&p, l, h, &|tau| level(t0 + tau)).unwrap();
        if k >= hold {
            pull_factorizations += r.factorizations;
        }
        let (dx, df) = distance_to_equilibrium(&d, &p, &r);
        let tol = 10.0 * RESIDUAL_TOLERANCE;
        assert!(dx < tol && df < tol, "step {k}: |dx|/L0 {dx:e}, dF {df:e}");
        m = r.muscle;
    }
    assert!(
        pull_factorizations < pull / 4,
        "{pull_factorizations} factorisations in {pull} steps of the pull"
    );
}

/// Initialization at full activation, D = 1e-9, on a graded 6 × 1 mesh:
/// the isometric ramp cannot reach it (fibres of the clamped specimen on
/// the descending limb of f_λ), the relaxation does, and the result is
/// the isometric equilibrium: the Newton correction of the rate-free
/// problem with a tangent formed there is within the tolerance. Its
/// counts are the whole initialization's: the passive ramp's, at least
/// one iteration per relaxation step, and the final solve's.
#[test]
fn isometric_initialization_at_full_activation_relaxes_to_the_equilibrium() {
    let p = Params::default();
    let d = specimen(6, 1);
    let (m, s) = Muscle::isometric(d.clone(), &p, 0.05, 1.0).unwrap();
    let (_, passive) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let ramp = RELAX_RAMP;
    assert!(
        s.iterations > passive.iterations + ramp && s.factorizations > passive.factorizations,
        "initialization counted {} iterations, {} factorisations; the passive ramp alone {}, {}",
        s.iterations,
        s.factorizations,
        passive.iterations,
        passive.factorizations
    );
    let r = Advance {
        muscle: m.clone(),
        solution: s,
        start: m.history.clone(),
        rate: FibreRate::Isometric,
        activation: 1.0,
        iterations: 0,
        factorizations: 0,
        residuals: 0,
        substeps: 1,
        pieces: vec![],
    };
    let (dx, df) = distance_to_equilibrium(&d, &p, &r);
    let tol = 10.0 * RESIDUAL_TOLERANCE;
    assert!(dx < tol && df < tol, "|dx|/L0 {dx:e}, dF {df:e}");
    // Active: the force is of the order of sigma0 times the section.
    let f = d.reaction(&r.solution.evaluation.forces);
    assert!(f > 0.5 * p.sigma0 * d.mean_area(), "force {f} N");
}

/// The extremes of the activated initialization, level 1 at 0.7 L0 and
/// 1.3 L0 on a graded 8 × 2 mesh (D = 1e-9): each ends in the isometric
/// equilibrium (the rate-free problem's Newton correction with a tangent
/// formed there within the tolerance).
#[test]
fn isometric_initialization_at_extreme_lengths_is_an_equilibrium() {
    let p = Params::default();
    let d = specimen(8, 2);
    for stretch in [0.7, 1.3] {
        let (dx, df) = isometric_distance(&d, &p, 0.05 * stretch, 1.0);
        let tol = 10.0 * RESIDUAL_TOLERANCE;
        assert!(
            dx < tol && df < tol,
            "{stretch} L0: |dx|/L0 {dx:e}, dF {df:e}"
        );
    }
}

/// With D = 1e-12 the volumetric forces round at ~1e-7 N, above the
/// force tolerance of a small specimen (1e-10 σ0 A, 3e-8 N at the
/// musculotendon scene's area 8.919e-4 m² on L0 = 0.05 m): relaxed at 0.3
/// and 1.2 L0, the isometric initialization of that squat specimen ends
/// where no trial of a fresh tangent decreases the residual. Accepted at
/// that rounding floor ([`crate::fe::newton`], "Rounding floor"; refused
/// before, as "no isometric equilibrium"), it is an equilibrium to the
/// bound of the extreme lengths above.
#[test]
fn isometric_initialization_with_d_1e_12_ends_at_the_rounding_floor() {
    let p = Params {
        d_comp: 1e-12,
        ..Params::default()
    };
    let d = crate::fe::step_map::squat_specimen();
    for stretch in [0.3, 1.2] {
        let (dx, df) = isometric_distance(&d, &p, 0.05 * stretch, 0.0);
        let tol = 10.0 * RESIDUAL_TOLERANCE;
        assert!(
            dx < tol && df < tol,
            "{stretch} L0: |dx|/L0 {dx:e}, dF {df:e}"
        );
    }
}

/// An activation jump 0 → 1 within one 10 ms step (no activation
/// dynamics: the level is 1 over the whole step) at rest length, which
/// drives the contractile elements to their maximum shortening speed
/// (the kink of f_v at x = 1): the step completes (by continuation and
/// substeps) and ends in an equilibrium.
#[test]
fn an_activation_jump_completes_in_an_equilibrium() {
    let p = Params::default();
    let d = specimen(6, 1);
    let (m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let r = m.advance(&p, 0.05, 1e-2, &|_| 1.0).unwrap();
    let (dx, df) = distance_to_equilibrium(&d, &p, &r);
    let tol = 10.0 * RESIDUAL_TOLERANCE;
    assert!(dx < tol && df < tol, "|dx|/L0 {dx:e}, dF {df:e}");
}

/// An activation jump 0 → 1 with fast dynamics (S = 1e5/s: the level
/// reaches 1 within the first substep of any count) in one 10 ms step on
/// a squat, very compressible specimen (L0 5 cm, area 8.9 cm², D = 1e-4,
/// alpha = 1000, graded 0.9 × 0.6) at 1.05 L0: the substep that holds the
/// jump is continued in the level whatever the substep count (without
/// that, no count up to 64 converged), and the step ends in an
/// equilibrium.
#[test]
fn a_fast_activation_jump_on_a_squat_compressible_specimen_completes() {
    let p = Params {
        d_comp: 1e-4,
        alpha: 1000.0,
        s: 1e5,
        ..Params::default()
    };
    let d = crate::fe::step_map::squat_specimen();
    let (m, _) = Muscle::isometric(d.clone(), &p, 0.0525, 0.0).unwrap();
    let h = 1e-2;
    let r = m
        .advance(&p, 0.0525, h, &|tau| 1.0 - (-p.s * tau).exp())
        .unwrap();
    let (dx, df) = distance_to_equilibrium(&d, &p, &r);
    let tol = 10.0 * RESIDUAL_TOLERANCE;
    assert!(dx < tol && df < tol, "|dx|/L0 {dx:e}, dF {df:e}");
    assert_eq!(r.activation, 1.0);
}

/// The discretization's ledger counts every attempt: a smooth step that
/// converges at its first attempt spends exactly what it reports; an
/// activated length jump of 40 % in one 10 ms step, whose first attempts
/// fail before continuation converges, spends more than its converged
/// attempts report (42 factorisations against 23).
#[test]
fn the_ledger_counts_the_failed_attempts_too() {
    let p = Params::default();
    let d = specimen(6, 1);
    let (m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let reported = |r: &Advance| Work {
        residuals: r.residuals,
        factorizations: r.factorizations,
        solves: r.iterations,
    };
    let before = d.work.work();
    let smooth = m.advance(&p, 0.05 * 1.001, 1e-3, &|_| 0.0).unwrap();
    let spent = d.work.work() - before;
    assert_eq!(spent, reported(&smooth));
    let before = d.work.work();
    let jump = m.advance(&p, 0.03, 1e-2, &|_| 1.0).unwrap();
    let (spent, reported) = (d.work.work() - before, reported(&jump));
    assert!(
        spent.factorizations > reported.factorizations
            && spent.solves > reported.solves
            && spent.residuals > reported.residuals,
        "ledger {spent:?}, step {reported:?}"
    );
}

/// The factorisation is a function of the anchor: a muscle whose cached
/// tangent is dropped and formed again from the anchor alone (what a
/// state restored in another process does) continues bit for bit.
#[test]
fn a_tangent_formed_again_from_its_anchor_continues_bit_for_bit() {
    let p = Params::default();
    let d = specimen(6, 1);
    let h = 1e-3;
    let (mut m, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let pull = |k: usize| 0.05 * (1.0 + 0.003 * k as f64);
    for k in 1..=20 {
        m = m.advance(&p, pull(k), h, &|_| 0.6).unwrap().muscle;
    }
    let restored = Muscle {
        tangent: m
            .tangent
            .as_ref()
            .map(|c| Arc::new(TangentCache::new(c.anchor.clone()))),
        ..m.clone()
    };
    assert!(m.tangent.is_some() && !m.trend.increments.is_empty());
    let (mut a, mut b) = (m, restored);
    for k in 21..=40 {
        let ra = a.advance(&p, pull(k), h, &|_| 0.6).unwrap();
        let rb = b.advance(&p, pull(k), h, &|_| 0.6).unwrap();
        assert_eq!(ra.solution.x, rb.solution.x, "step {k}");
        assert_eq!(ra.solution.evaluation.forces, rb.solution.evaluation.forces);
        assert_eq!(ra.iterations, rb.iterations);
        a = ra.muscle;
        b = rb.muscle;
    }
}

/// Large steps (module docs of [`crate::fe::newton`], "Pressures"): a
/// passive pull at 5 mm/s in steps of 100 ms (a 1 % strain increment per
/// step, D = 1e-9, the stiff case) and, the extreme, the activated muscle
/// (level 1) stretched to 1.3 L0 and released in steps of 50 ms, each step
/// an equilibrium to the tolerance. The pull's smooth steps, once the
/// predictor has a trend, take few Newton iterations and factorisations
/// (with the displacement iteration's fresh tangent at the predictor they
/// took 7–10 solves and 3 factorisations, and tens near rest).
#[test]
fn large_smooth_steps_take_few_newton_iterations() {
    let p = Params::default();
    let d = specimen(8, 2);
    let tol = 10.0 * RESIDUAL_TOLERANCE;
    let (rest, _) = Muscle::isometric(d.clone(), &p, 0.05, 0.0).unwrap();
    let h = 0.1;
    let mut m = rest.clone();
    let (mut solves, mut factorizations) = (0, 0);
    for k in 1..=16 {
        let r = m
            .advance(&p, 0.05 + 0.005 * h * k as f64, h, &|_| 0.0)
            .unwrap();
        let (dx, df) = distance_to_equilibrium(&d, &p, &r);
        assert!(
            dx < tol && df < tol,
            "pull step {k}: |dx|/L0 {dx:e}, dF {df:e}"
        );
        if k > 4 {
            solves += r.iterations;
            factorizations += r.factorizations;
        }
        m = r.muscle;
    }
    assert!(
        solves <= 7 * 12 && factorizations <= 2 * 12,
        "{solves} solves, {factorizations} factorisations in 12 steps of 100 ms"
    );
    let h = 0.05;
    let level = |t: f64| 1.0 - (-p.s * t).exp();
    let mut m = rest;
    for k in 0..24 {
        let t0 = k as f64 * h;
        let up = (k + 1).min(23 - k.min(23)) as f64 / 12.0;
        let l = 0.05 * (1.0 + 0.3 * up.min(1.0));
        let r = m.advance(&p, l, h, &|tau| level(t0 + tau)).unwrap();
        let (dx, df) = distance_to_equilibrium(&d, &p, &r);
        assert!(
            dx < tol && df < tol,
            "activated step {k}: |dx|/L0 {dx:e}, dF {df:e}"
        );
        m = r.muscle;
    }
}

/// The activated initialization is a function of the parameters its steady
/// state depends on (λ̇m = 0, f_v = 1): changing a force-velocity constant
/// (k_c, k_e, d, λ̇m^min) leaves the initial positions bit for bit, at L0
/// (the relaxation) and 1.1 L0, as the model descriptions declare.
#[test]
fn the_activated_initialization_does_not_depend_on_the_force_velocity_law() {
    let d = specimen(4, 1);
    for length in [0.05, 0.055] {
        let p = Params::default();
        let (m, _) = Muscle::isometric(d.clone(), &p, length, 0.5).unwrap();
        let changes: [fn(&mut Params); 4] = [
            |q| q.kc *= 1.5,
            |q| q.ke *= 1.5,
            |q| q.d *= 1.1,
            |q| q.lambda_dot_min *= 2.0,
        ];
        for change in changes {
            let mut q = p;
            change(&mut q);
            let (n, _) = Muscle::isometric(d.clone(), &q, length, 0.5).unwrap();
            assert!(
                n.x.iter()
                    .zip(&m.x)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "length {length}: the initial positions moved with a force-velocity constant"
            );
        }
    }
}

/// Continuation in the level beyond two substeps is for jumps that time
/// cannot split (S·h ≫ 1): at S = 1e5 a 10 ms step's level jumps within
/// its finest substep; at S = 50 the 100 ms step's onset (0 → 0.99) falls
/// below a quarter per piece at 16 substeps and more.
#[test]
fn only_jumps_finer_than_the_finest_substep_are_continued() {
    let rise = |s: f64| move |tau: f64| 1.0 - (-s * tau).exp();
    let fast = rise(1e5);
    assert!(unsplittable_jump(&fast, 1e-2, 0.0, 1e-2 / 8.0));
    assert!(unsplittable_jump(&fast, 1e-2, 0.0, 1e-2 / 64.0));
    let slow = rise(50.0);
    for n in [4, 8, 16] {
        assert!(!unsplittable_jump(&slow, 0.1, 0.0, 0.1 / n as f64), "{n}");
    }
    // A jump later in the step is found where it is.
    let late = |tau: f64| if tau > 0.05 { 1.0 } else { 0.0 };
    assert!(unsplittable_jump(&late, 0.1, 0.0375, 0.025));
    assert!(!unsplittable_jump(&late, 0.1, 0.0, 0.025));
}

/// The activation onset of a 100 ms step of the stretch and release
/// (fe_realtime) on the default mesh: splittable in time, so it is solved
/// in more substeps rather than continued at every count. Continued at 4
/// and 8 substeps it spent 235 factorisations over all attempts; now 87.
#[test]
fn a_splittable_onset_in_a_large_step_is_not_continued_at_every_count() {
    use crate::fe::mesh::{LUMPED, LUMPED_GRADING};
    use crate::specimen::{LENGTH, MEAN_AREA};
    let p = Params::default();
    let d = crate::fe::step_map::discretization(
        None,
        LENGTH,
        MEAN_AREA,
        LUMPED,
        LUMPED_GRADING,
        FibreLayout::Axial,
    )
    .unwrap();
    let (m, _) = Muscle::isometric(d.clone(), &p, LENGTH, 0.0).unwrap();
    let h = 0.1;
    let m = m.advance(&p, LENGTH * 1.01, h, &|_| 0.0).unwrap().muscle;
    let before = d.work.work();
    let onset = m
        .advance(&p, LENGTH * 1.02, h, &|tau| 1.0 - (-p.s * tau).exp())
        .unwrap();
    let spent = d.work.work() - before;
    assert!(
        spent.factorizations <= 150,
        "{} factorisations over all attempts ({} substeps)",
        spent.factorizations,
        onset.substeps
    );
}
