//! Tests of the musculotendon equilibrium on a synthetic monotone muscle:
//! the residual, the hard cases, the derivatives, and the safeguards
//! (fallback, failed regions, halving cap, trust length, rupture strain).

use super::*;

const L0: f64 = 0.05;
const F0: f64 = 100.0;
const TOL: f64 = 1e-10 * F0;
const FIXED: Tolerance = Tolerance::Fixed(TOL);

/// A synthetic monotone muscle: F_M = F0 (a + e^(5 (L/L0 − 1)) − 1),
/// zero at L/L0 = 1 + ln(1 − a)/5 (a < 1), negative below.
fn synthetic(a: f64) -> impl FnMut(f64) -> Result<MuscleForce, ()> {
    move |l: f64| {
        let e = (5.0 * (l / L0 - 1.0)).exp();
        Ok(MuscleForce {
            force: F0 * (a + e - 1.0),
            stiffness: F0 * 5.0 * e / L0,
        })
    }
}

fn unit(eps0: f64, alpha0: f64, compliant: bool) -> Unit {
    let p = UnitParams {
        tendon_slack_length: 0.04,
        tendon_strain_at_f0: eps0,
        pennation_angle: alpha0,
        compliant_tendon: compliant,
    };
    Unit::new(&p, L0, F0)
}

fn solve(u: &Unit, path: f64, a: f64) -> Result<Equilibrium, EquilibriumError<()>> {
    solve_equilibrium(u, path, (0.1 * L0, 5.0 * L0), L0, FIXED, None, synthetic(a))
}

/// A muscle that cannot be evaluated past a fibre length (its law
/// overflows there): a root below it is found however far the
/// outward search overshoots into the failing lengths; a root beyond
/// it is the muscle's error near the end of the evaluable lengths.
#[test]
fn a_muscle_that_fails_past_a_length_is_searched_below_it() {
    let u = unit(0.04, 0.0, true);
    let failing = |limit: f64| {
        let mut m = synthetic(0.0);
        move |l: f64| if l > limit { Err(()) } else { m(l) }
    };
    let path = 0.04 * 1.05 + 1.3 * L0;
    let free = solve(&u, path, 0.0).unwrap();
    for limit in [1.02, 1.5, 3.0].map(|k| k * free.fibre_length) {
        let eq = solve_equilibrium(
            &u,
            path,
            (0.1 * L0, 5.0 * L0),
            0.5 * L0,
            FIXED,
            None,
            failing(limit),
        )
        .unwrap();
        assert!(eq.residual.abs() <= TOL, "{limit}: {}", eq.residual);
        assert!((eq.fibre_length - free.fibre_length).abs() <= 1e-12 * L0);
    }
    let below = 0.9 * free.fibre_length;
    let mut trials = Vec::new();
    let r = solve_equilibrium(
        &u,
        path,
        (0.1 * L0, 5.0 * L0),
        0.5 * L0,
        FIXED,
        None,
        watched(0.0, |l| l > below, &mut trials),
    );
    // The failure at the end of the approach, MAX_HALVINGS moves (failed
    // trials and good points) after the first failed trial: a failed
    // length, within 1e-4 L0 of the limit here (4.0e-5 L0; the moves are
    // halvings and Newton steps, so no power of two bounds it).
    let first = trials.iter().position(|&l| l > below).unwrap();
    assert!(
        trials.len() - first <= MAX_HALVINGS as usize + 1,
        "{trials:?}"
    );
    match r {
        Err(EquilibriumError::Muscle { fibre_length, .. }) => {
            assert!(
                fibre_length > below && fibre_length - below <= 1e-4 * L0,
                "{fibre_length}: {trials:?}"
            )
        }
        other => panic!("{:?}", other.map(|e| e.fibre_length)),
    }
}

/// A muscle that records where it was evaluated and checks that no
/// evaluation goes to or past a length that failed on the far side of
/// the last good point; `fails(l)` says where it cannot be evaluated.
fn watched<'a>(
    a: f64,
    fails: impl Fn(f64) -> bool + 'a,
    trials: &'a mut Vec<f64>,
) -> impl FnMut(f64) -> Result<MuscleForce, ()> + 'a {
    let mut m = synthetic(a);
    let (mut good, mut below, mut above) = (None, f64::NEG_INFINITY, f64::INFINITY);
    move |l: f64| {
        assert!(
            below < l && l < above,
            "{l} in a failed region ({below}, {above})"
        );
        trials.push(l);
        if fails(l) {
            match good {
                Some(g) if l > g => above = above.min(l),
                Some(_) => below = below.max(l),
                None => {}
            }
            Err(())
        } else {
            good = Some(l);
            m(l)
        }
    }
}

/// A first trial the muscle cannot evaluate is retried at the fallback
/// (the rigid tendon's fibre length) before the failure is returned.
#[test]
fn a_failed_first_trial_is_retried_at_a_fallback() {
    let u = unit(0.04, 0.0, true);
    let path = 0.04 * 1.05 + 1.3 * L0;
    let free = solve(&u, path, 0.0).unwrap();
    let cut = 0.5 * (0.5 * L0 + free.fibre_length);
    let mut trials = Vec::new();
    let eq = solve_equilibrium(
        &u,
        path,
        (0.1 * L0, 5.0 * L0),
        0.5 * L0,
        FIXED,
        None,
        watched(0.0, |l| l < cut, &mut trials),
    )
    .unwrap();
    assert!((eq.fibre_length - free.fibre_length).abs() <= 1e-12 * L0);
    assert!(trials[1] > cut, "{trials:?}");
    // Failing everywhere: the first trial's failure.
    let mut trials = Vec::new();
    let r = solve_equilibrium(
        &u,
        path,
        (0.1 * L0, 5.0 * L0),
        0.5 * L0,
        FIXED,
        None,
        watched(0.0, |_| true, &mut trials),
    );
    match r {
        Err(EquilibriumError::Muscle { fibre_length, .. }) => {
            assert_eq!(fibre_length, 0.5 * L0)
        }
        other => panic!("{:?}", other.map(|e| e.fibre_length)),
    }
    assert_eq!(trials.len(), 2);
}

/// Failures in a window anywhere around the root: no trial returns to
/// or past a failed length (checked by [`watched`]), and the solve
/// either converges or returns the muscle's failure.
#[test]
fn no_trial_returns_into_a_region_that_failed() {
    let u = unit(0.04, 0.3, true);
    let path = 0.04 * 1.05 + 1.3 * L0;
    let free = solve(&u, path, 0.3).unwrap();
    let root = free.fibre_length;
    for guess in [0.5 * L0, 0.9 * root, 1.1 * root, 3.0 * L0] {
        for (c, w) in [
            (0.98, 0.01),
            (1.02, 0.01),
            (1.0, 1e-4),
            (0.95, 0.03),
            (1.05, 0.03),
            (1.3, 0.2),
            (0.7, 0.2),
        ] {
            let (a, b) = ((c - w) * root, (c + w) * root);
            let mut trials = Vec::new();
            let r = solve_equilibrium(
                &u,
                path,
                (0.1 * L0, 5.0 * L0),
                guess,
                FIXED,
                None,
                watched(0.3, |l| a < l && l < b, &mut trials),
            );
            match r {
                Ok(eq) => assert!(
                    (eq.fibre_length - root).abs() <= 1e-12 * L0,
                    "{guess} ({a}, {b}): {} {:?}",
                    eq.fibre_length,
                    trials
                ),
                // The window between the guess and the root, or
                // around the root: the evaluable lengths end there.
                Err(EquilibriumError::Muscle { .. }) => {
                    assert!(a < guess.max(root) && guess.min(root) < b)
                }
                Err(e) => panic!("{guess} ({a}, {b}): {e:?} {trials:?}"),
            }
        }
    }
}

/// A muscle that fails just past the good point it started from: the
/// step back is halved at most [`MAX_HALVINGS`] times in a row.
#[test]
fn the_step_halving_is_capped() {
    let u = unit(0.04, 0.0, true);
    let path = 0.04 * 1.05 + 1.3 * L0;
    let start = 0.5 * L0;
    let mut trials = Vec::new();
    let r = solve_equilibrium(
        &u,
        path,
        (0.1 * L0, 5.0 * L0),
        start,
        FIXED,
        None,
        watched(0.0, |l| l > start * (1.0 + 1e-13), &mut trials),
    );
    assert!(matches!(r, Err(EquilibriumError::Muscle { .. })));
    assert_eq!(trials.len() as u32, 2 + MAX_HALVINGS, "{trials:?}");
}

/// A root beyond the lengths the muscle can evaluate, above or below them:
/// at most [`MAX_HALVINGS`] moves in a row approach the failed end (failed
/// trials halving back, good points at most halfway there), then its
/// failure is the answer — not some fifty halfway moves to its last ulp.
#[test]
fn the_approach_to_a_failed_end_is_capped() {
    let u = unit(0.04, 0.0, true);
    let path = 0.04 * 1.05 + 1.3 * L0;
    let root = solve(&u, path, 0.0).unwrap().fibre_length;
    // (failing above `limit` or below it, guesses).
    for (above, limit) in [(true, 0.9 * root), (false, 1.1 * root)] {
        for guess in [
            0.5 * L0,
            limit * (1.0 - 1e-3),
            limit * (1.0 + 1e-3),
            3.0 * L0,
        ] {
            let fails = |l: f64| if above { l > limit } else { l < limit };
            let mut trials = Vec::new();
            let r = solve_equilibrium(
                &u,
                path,
                (0.1 * L0, 5.0 * L0),
                guess,
                FIXED,
                None,
                watched(0.0, fails, &mut trials),
            );
            match r {
                Err(EquilibriumError::Muscle { fibre_length, .. }) => {
                    assert!(fails(fibre_length), "{fibre_length}")
                }
                other => panic!("{:?}", other.map(|e| e.fibre_length)),
            }
            // From the first failure on: the failures halving back and
            // the good points approaching, MAX_HALVINGS moves in all (and
            // the fallback after a failed first trial).
            let first = trials.iter().position(|&l| fails(l)).unwrap();
            let after = (trials.len() - first) as u32;
            assert!(
                after <= MAX_HALVINGS + 2,
                "{above} {guess}: {after} trials after the first failure: {trials:?}"
            );
        }
    }
}

/// A path whose equilibrium needs the tendon past its rupture strain
/// is refused: before any evaluation when even the longest evaluable
/// fibres leave it there, else once a point shows it.
#[test]
fn a_tendon_past_its_rupture_strain_is_refused() {
    let u = unit(0.04, 0.3, true);
    let range = (0.1 * L0, 5.0 * L0);
    let mut n = 0;
    let r = solve_equilibrium(&u, 100.0, range, L0, FIXED, None, |l| {
        n += 1;
        synthetic(0.0)(l)
    });
    match r {
        Err(EquilibriumError::TendonRupture { strain, max_strain }) => {
            assert!(
                strain > max_strain && (max_strain - 0.1).abs() < 1e-15,
                "{strain}"
            )
        }
        other => panic!("{:?}", other.map(|e| e.tendon_force)),
    }
    assert_eq!(n, 0);
    // Paths around the one whose equilibrium is at the rupture strain.
    let at_rupture = |path: f64| solve(&u, path, 1.0).map(|e| e.tendon_strain);
    let (mut lo, mut hi) = (0.09, 0.2);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        match at_rupture(mid) {
            Ok(_) => lo = mid,
            Err(EquilibriumError::TendonRupture { .. }) => hi = mid,
            Err(e) => panic!("{e:?}"),
        }
    }
    let eq = solve(&u, lo, 1.0).unwrap();
    assert!(
        eq.tendon_strain <= 0.1 && eq.tendon_strain > 0.1 - 1e-9,
        "{}",
        eq.tendon_strain
    );
    assert!(eq.tendon_force > 3.56 * F0, "{}", eq.tendon_force);
    // A rigid tendon has no strain and no such bound.
    assert!(solve(&unit(0.04, 0.3, false), 0.13, 1.0).is_ok());
}

#[test]
fn defaults_are_in_range_and_bad_values_are_refused() {
    let mut p = UnitParams::default();
    assert!(p.validate().is_ok());
    assert_eq!(p.tendon_strain_at_f0, 0.04);
    let before = p;
    for (id, v) in [
        (TendonParamId::TendonSlackLength, 0.0),
        (TendonParamId::TendonStrainAtF0, 0.0),
        (TendonParamId::PennationAngle, 1.2),
        (TendonParamId::PennationAngle, f64::NAN),
    ] {
        let e = p.set(id, v).unwrap_err();
        assert!(e.to_string().contains("must be"), "{e}");
        assert_eq!(p, before);
    }
}

/// The path beyond which the synthetic muscle's equilibrium needs the tendon
/// past its rupture strain: the tendon at ε_max carries F_r = F0 f_T(ε_max),
/// the fibres at L_r where F_M cos α = F_r (bisection: F_M cos α increases
/// with L_M), the path L_TS (1 + ε_max) + L_r cos α(L_r).
fn rupture_path(u: &Unit, a: f64) -> f64 {
    let t = &u.tendon;
    let f_r = t.force(t.slack_length * (1.0 + t.max_strain())).0;
    let mut m = synthetic(a);
    let mut pulls = |l: f64| m(l).unwrap().force * u.pennation.at(l).cos;
    let (mut lo, mut hi) = (u.pennation.min_fibre_length().max(0.1 * L0), 5.0 * L0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if pulls(mid) < f_r {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    t.slack_length * (1.0 + t.max_strain()) + u.pennation.at(lo).projection
}

#[test]
fn the_residual_is_below_tolerance_over_stiffness_pennation_and_activation() {
    let (mut worst, mut most, mut refused): (f64, u32, u32) = (0.0, 0, 0);
    for eps0 in [0.1, 0.04, 1e-2, 1e-3, 1e-4, 1e-6] {
        for alpha0 in [0.0, 0.5, 1.0] {
            for a in [0.0, 0.5, 1.0] {
                for path in [0.07, 0.085, 0.09, 0.1, 0.12] {
                    let u = unit(eps0, alpha0, true);
                    // Refused exactly where the equilibrium needs the
                    // tendon past its rupture strain (no path of the sweep
                    // lies within 1e-6 m of that bound).
                    let bound = rupture_path(&u, a);
                    assert!((path - bound).abs() > 1e-6, "{path} {bound}");
                    let past = path > bound;
                    let eq = match solve(&u, path, a) {
                        Ok(eq) => {
                            assert!(!past, "ε0 {eps0} α0 {alpha0} a {a} ℓ {path} > {bound}");
                            eq
                        }
                        Err(EquilibriumError::TendonRupture { strain, max_strain }) => {
                            assert!(past, "ε0 {eps0} α0 {alpha0} a {a} ℓ {path} <= {bound}");
                            assert!(strain > max_strain);
                            refused += 1;
                            continue;
                        }
                        Err(e) => panic!("{e:?}"),
                    };
                    let m = eq.muscle.force * eq.pennation.cos;
                    // The residual at the returned point, recomputed.
                    let ft = u.tendon.force(path - eq.pennation.projection).0;
                    assert_eq!(eq.residual, m - ft);
                    // Below tol, or at the resolution of L_M (ε0 = 1e-6:
                    // k_T ulp(L_M) ~ 1e-10 F0).
                    let resolution = 8.0 * f64::EPSILON * L0 * u.tendon.f0 * 1.712
                        / (eps0 * u.tendon.slack_length);
                    assert!(
                        eq.residual.abs() <= TOL.max(resolution),
                        "ε0 {eps0} α0 {alpha0} a {a} ℓ {path}: {:e}",
                        eq.residual
                    );
                    worst = worst.max(eq.residual.abs() / F0);
                    most = most.max(eq.evaluations);
                }
            }
        }
    }
    eprintln!(
        "worst residual {worst:e} F0, at most {most} evaluations, {refused} of 270 past \
         the rupture strain"
    );
    assert!(refused > 0 && refused < 135, "{refused}");
    assert!(most <= 30, "{most}");
}

#[test]
fn a_slack_tendon_leaves_the_muscle_at_zero_force() {
    for a in [0.0, 0.5] {
        for alpha0 in [0.0, 0.5] {
            // Shorter than tendon slack + the fibres at zero force.
            let u = unit(0.04, alpha0, true);
            let eq = solve(&u, 0.06, a).unwrap();
            assert_eq!(eq.tendon_force, 0.0);
            assert!(eq.tendon_strain < 0.0);
            assert!(
                eq.muscle.force.abs() <= TOL / eq.pennation.cos,
                "{:e}",
                eq.muscle.force
            );
            assert_eq!(eq.stiffness, 0.0);
            assert_eq!(eq.dfibre_dpath, 0.0);
        }
    }
}

/// A slope far too large (the FE unit's stale secant, 150 times the
/// muscle's) makes Newton's steps fall short, each leaving 99 % of the
/// residual: 930 trials from 500 tolerances off, past the 200 the solve
/// allows. Doubling the steps that fall short brackets the root in a few.
#[test]
fn a_slope_far_too_large_still_converges_in_few_trials() {
    for (a, path) in [(0.5, 0.06), (1.0, 0.1)] {
        let u = unit(0.04, 0.2, true);
        let exact = solve(&u, path, a).unwrap();
        let mut muscle = synthetic(a);
        let stale = |l: f64| {
            muscle(l).map(|m| MuscleForce {
                stiffness: 150.0 * m.stiffness,
                ..m
            })
        };
        // dR/dL_M at the root: dL_M/dF = −cos α / (dR/dL_M).
        let dr = -exact.pennation.cos / exact.dfibre_dforce;
        let guess = exact.fibre_length + 500.0 * TOL / dr;
        let eq =
            solve_equilibrium(&u, path, (0.1 * L0, 5.0 * L0), guess, FIXED, None, stale).unwrap();
        assert!(eq.residual.abs() <= TOL, "a = {a}: {:e}", eq.residual);
        assert!(eq.evaluations <= 30, "a = {a}: {} trials", eq.evaluations);
    }
}

#[test]
fn near_rigid_converges_to_rigid() {
    for alpha0 in [0.0, 0.5] {
        for a in [0.0, 1.0] {
            let path = 0.095;
            let rigid = solve(&unit(0.04, alpha0, false), path, a).unwrap();
            let mut errs = Vec::new();
            for eps0 in [1e-2, 1e-3, 1e-4] {
                let eq = solve(&unit(eps0, alpha0, true), path, a).unwrap();
                errs.push((eq.tendon_force - rigid.tendon_force).abs() / F0);
            }
            // First order in ε0: the tendon stretches by ~ε0 L_TS F_T/F0,
            // which the (stiff, 5 F0/L0) synthetic muscle feels; observed
            // ratios 9.3 and 9.9 per decade.
            assert!(errs[2] < 2e-3, "{errs:?}");
            assert!(
                errs[1] / errs[2] > 8.0 && errs[0] / errs[1] > 8.0,
                "{errs:?}"
            );
        }
    }
}

#[test]
fn the_largest_angle_is_refused() {
    // Rigid: a path shorter than L_TS + the smallest projection.
    let u = unit(0.04, 1.0, false);
    let short = u.tendon.slack_length + 0.5 * u.pennation.min_projection();
    assert!(matches!(
        solve(&u, short, 1.0),
        Err(EquilibriumError::LargestAngle { .. })
    ));
    // Compliant, with a muscle that pulls at every length.
    let u = unit(0.04, 1.0, true);
    let pulls = |_: f64| -> Result<MuscleForce, ()> {
        Ok(MuscleForce {
            force: F0,
            stiffness: 0.0,
        })
    };
    let r = solve_equilibrium(&u, 0.03, (0.1 * L0, 5.0 * L0), L0, FIXED, None, pulls);
    assert!(
        matches!(r, Err(EquilibriumError::LargestAngle { .. })),
        "{r:?}"
    );
    // At the largest angle, an equilibrium just inside it is found.
    let u = unit(0.04, 1.0, true);
    let eq = solve(&u, 0.0405, 0.0).unwrap();
    assert!(eq.pennation.cos >= crate::law::pennation::MIN_COS);
}

#[test]
fn derivatives_match_finite_differences_of_the_solve() {
    for (eps0, alpha0, compliant) in [
        (0.04, 0.0, true),
        (0.04, 0.5, true),
        (1e-4, 0.5, true),
        (0.04, 0.5, false),
    ] {
        let u = unit(eps0, alpha0, compliant);
        let (path, a) = (0.095, 0.7);
        let eq = solve(&u, path, a).unwrap();
        let d = 1e-7 * path;
        let f = |p| solve(&u, p, a).unwrap().tendon_force;
        let fd = (f(path + d) - f(path - d)) / (2.0 * d);
        assert!(
            (fd - eq.stiffness).abs() <= 1e-5 * eq.stiffness,
            "{fd} vs {}",
            eq.stiffness
        );
        let lf = |p| solve(&u, p, a).unwrap().fibre_length;
        let fd = (lf(path + d) - lf(path - d)) / (2.0 * d);
        assert!((fd - eq.dfibre_dpath).abs() <= 1e-5 * eq.dfibre_dpath.abs().max(1e-3));
        // A change of F_M at fixed L_M: through a.
        let da = 1e-6;
        let g = |a| solve(&u, path, a).unwrap();
        let (p, m) = (g(a + da), g(a - da));
        let fd_f = (p.tendon_force - m.tendon_force) / (2.0 * da);
        let fd_l = (p.fibre_length - m.fibre_length) / (2.0 * da);
        // dF_M/da at fixed L_M is F0.
        assert!(
            (fd_f - eq.dforce_dforce * F0).abs() <= 1e-5 * fd_f.abs(),
            "{fd_f}"
        );
        assert!((fd_l - eq.dfibre_dforce * F0).abs() <= 1e-5 * fd_l.abs().max(1e-9));
    }
}

/// A muscle whose force jumps across the root (a step map that changes
/// between nearby end lengths, e.g. its substep count): the root is
/// resolved to rounding with the jump left as the residual, which is
/// refused, not returned as a balance — with the exact slope and with a
/// secant through the jump; a jump within [`DISCONTINUITY`] of F0 (noise)
/// is a root.
#[test]
fn a_force_that_jumps_across_the_root_is_refused() {
    let u = unit(0.04, 0.0, true);
    let path = 0.04 * 1.05 + 1.3 * L0;
    let free = solve(&u, path, 0.0).unwrap();
    let at = free.fibre_length;
    for (jump, refused) in [(3.0, true), (1e-3, true), (0.5 * DISCONTINUITY * F0, false)] {
        for secant in [false, true] {
            let mut smooth = synthetic(0.0);
            let mut last: Option<(f64, f64)> = None;
            let muscle = |l: f64| -> Result<MuscleForce, ()> {
                let m = smooth(l)?;
                let force = m.force + if l > at { 0.5 * jump } else { -0.5 * jump };
                let stiffness = match last {
                    Some((l1, f1)) if secant && l != l1 => (force - f1) / (l - l1),
                    _ => m.stiffness,
                };
                last = Some((l, force));
                Ok(MuscleForce { force, stiffness })
            };
            let r = solve_equilibrium(&u, path, (0.1 * L0, 5.0 * L0), L0, FIXED, None, muscle);
            match r {
                Err(EquilibriumError::Discontinuous {
                    fibre_length,
                    residual,
                }) => {
                    assert!(refused, "jump {jump}: refused");
                    assert!((fibre_length - at).abs() <= 1e-12 * L0);
                    assert!(residual.abs() > TOL && residual.abs() <= jump);
                }
                Ok(eq) => {
                    assert!(!refused, "jump {jump}, secant {secant}: {eq:?}");
                    assert!(eq.residual.abs() <= jump);
                }
                Err(e) => panic!("jump {jump}, secant {secant}: {e:?}"),
            }
        }
    }
}
