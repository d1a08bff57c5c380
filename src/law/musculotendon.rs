//! The musculotendon unit's equilibrium (MODEL_NOTES "Musculotendon unit"):
//! a muscle of fibre length L_M at pennation α in series with a tendon, on a
//! path of length ℓ = L_T + L_M cos α, in equilibrium when
//! F_T(ℓ − L_M cos α) = F_M(L_M) cos α.
//!
//! Entry points: [`UnitParams`] (the unit's parameters, from
//! [`TENDON_PARAMETERS`]), [`Unit`] (the tendon and pennation of a muscle of
//! given `L0` and F0) and [`solve_equilibrium`], which finds L_M for a path
//! length given the muscle's force and stiffness at the end of a step ending
//! at any L_M (a closure: the 1D muscle's step or the FE muscle's), and
//! returns the tendon force with its derivatives (the series stiffness of
//! tendon and muscle through the pennation). Any muscle provides the
//! closure; nothing here knows which.
//!
//! Invariants: the returned fibre length is the last one the closure was
//! evaluated at, so the caller's last muscle step is the accepted one; the
//! residual there is below the tolerance (or at the resolution of L_M in
//! binary64, reported in [`Equilibrium::residual`]); a root that does not
//! exist in the muscle's evaluable range, or only past the largest
//! pennation angle, is an error, never a clamped force.

use super::params::{ParamError, TendonParamId, TENDON_PARAMETERS};
use super::pennation::{Pennated, Pennation};
use super::tendon::Tendon;

/// The musculotendon unit's parameters (SI units; MODEL_NOTES
/// "Musculotendon unit"; names, defaults and ranges in
/// [`TENDON_PARAMETERS`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitParams {
    /// L_TS (m).
    pub tendon_slack_length: f64,
    /// ε0, the tendon strain at F0.
    pub tendon_strain_at_f0: f64,
    /// α0 (rad), the pennation angle at fibre length L0.
    pub pennation_angle: f64,
    /// A compliant tendon (Thelen's curve); false: rigid, of length L_TS.
    pub compliant_tendon: bool,
}

impl Default for UnitParams {
    /// The table's defaults, with a compliant tendon.
    fn default() -> Self {
        let mut p = UnitParams {
            tendon_slack_length: 0.0,
            tendon_strain_at_f0: 0.0,
            pennation_angle: 0.0,
            compliant_tendon: true,
        };
        for info in &TENDON_PARAMETERS {
            *p.get_mut(info.id) = info.default;
        }
        p
    }
}

impl UnitParams {
    /// Value of one parameter (no equation).
    pub fn get(&self, id: TendonParamId) -> f64 {
        match id {
            TendonParamId::TendonSlackLength => self.tendon_slack_length,
            TendonParamId::TendonStrainAtF0 => self.tendon_strain_at_f0,
            TendonParamId::PennationAngle => self.pennation_angle,
        }
    }

    fn get_mut(&mut self, id: TendonParamId) -> &mut f64 {
        match id {
            TendonParamId::TendonSlackLength => &mut self.tendon_slack_length,
            TendonParamId::TendonStrainAtF0 => &mut self.tendon_strain_at_f0,
            TendonParamId::PennationAngle => &mut self.pennation_angle,
        }
    }

    /// Set one parameter after checking it against its range; on error
    /// `self` is unchanged (no equation).
    pub fn set(&mut self, id: TendonParamId, value: f64) -> Result<(), ParamError> {
        let info = TENDON_PARAMETERS
            .iter()
            .find(|p| p.id == id)
            .expect("every TendonParamId has a row");
        if !info.range.contains(value) {
            return Err(ParamError {
                name: info.name,
                value,
                range: info.range,
            });
        }
        *self.get_mut(id) = value;
        Ok(())
    }

    /// The path length with the fibres at rest length `l0` and the tendon at
    /// its slack length, L_TS + L0 cos α0 (MODEL_NOTES "Musculotendon
    /// unit"): a musculotendon model's path input until one is set.
    pub fn rest_path(&self, l0: f64) -> f64 {
        self.tendon_slack_length + l0 * self.pennation_angle.cos()
    }

    /// Every parameter in its range; the first offender in table order.
    pub fn validate(&self) -> Result<(), ParamError> {
        let mut copy = *self;
        TENDON_PARAMETERS
            .iter()
            .try_for_each(|info| copy.set(info.id, self.get(info.id)))
    }
}

/// The tendon and pennation of one muscle: what the equilibrium needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    pub tendon: Tendon,
    pub pennation: Pennation,
    pub compliant: bool,
}

impl Unit {
    /// The unit of a muscle of rest fibre length `l0` (m) and maximum
    /// isometric force `f0` = σ0 · area (N) (MODEL_NOTES "Musculotendon
    /// unit").
    pub fn new(p: &UnitParams, l0: f64, f0: f64) -> Self {
        Unit {
            tendon: Tendon {
                slack_length: p.tendon_slack_length,
                strain_at_f0: p.tendon_strain_at_f0,
                f0,
            },
            pennation: Pennation::new(l0, p.pennation_angle),
            compliant: p.compliant_tendon,
        }
    }
}

/// The muscle at the end of a step ending at one fibre length: its axial
/// force F_M (N) and dF_M/dL_M (N/m) of the step map, history fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MuscleForce {
    pub force: f64,
    pub stiffness: f64,
}

/// The solved equilibrium (MODEL_NOTES "Musculotendon unit") and its
/// implicit derivatives. "F̃" below is a change of the muscle's force at
/// fixed L_M (through activation or history), so that a caller chains
/// d/d(activation) as dF_M/da|_{L_M} times the `_dforce` entries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equilibrium {
    /// L_M (m): the closure's last evaluation.
    pub fibre_length: f64,
    pub pennation: Pennated,
    /// The muscle at L_M (the closure's last value).
    pub muscle: MuscleForce,
    /// ε = (ℓ − L_M cos α)/L_TS − 1 (0 for a rigid tendon).
    pub tendon_strain: f64,
    /// F_T (N): F0 f_T(ε) for a compliant tendon, F_M cos α for a rigid one.
    pub tendon_force: f64,
    /// dL_M/dℓ at fixed F̃.
    pub dfibre_dpath: f64,
    /// dL_M/dF̃ at fixed ℓ (m/N).
    pub dfibre_dforce: f64,
    /// dF_T/dℓ: tendon and muscle in series through the pennation (N/m).
    pub stiffness: f64,
    /// dF_T/dF̃ at fixed ℓ.
    pub dforce_dforce: f64,
    /// F_M cos α − F_T at L_M (N; 0 for a rigid tendon).
    pub residual: f64,
    /// Evaluations of the closure.
    pub evaluations: u32,
}

/// Why the equilibrium could not be solved.
#[derive(Clone, Debug, PartialEq)]
pub enum EquilibriumError<E> {
    /// The closure failed at `fibre_length`.
    Muscle { fibre_length: f64, error: E },
    /// The root lies at fibres shorter than the largest pennation angle
    /// allows (cos α < `pennation::MIN_COS`): the path is too short for the
    /// unit (a rigid tendon) or the muscle still pulls there.
    LargestAngle { path: f64, min_fibre_length: f64 },
    /// No root in the fibre lengths the muscle can evaluate: the residual
    /// F_M cos α − F_T keeps the sign `residual` (N) at the bound `bound`.
    NoRoot { bound: f64, residual: f64 },
    /// The iteration cap was reached.
    NoConvergence { lo: f64, hi: f64 },
}

/// One point of the iteration: L_M, the pennation and muscle there, the
/// residual F_M cos α − F_T and its slope, and the tendon's force and
/// stiffness.
#[derive(Clone, Copy)]
struct Point {
    x: f64,
    pen: Pennated,
    muscle: MuscleForce,
    r: f64,
    dr: f64,
    strain: f64,
    ft: f64,
    kt: f64,
}

/// The equilibrium at path length `path` (MODEL_NOTES "Musculotendon
/// unit"), for fibre lengths within `range` (the muscle's evaluable ones),
/// starting from `guess`; `muscle(L_M)` is the muscle's force and stiffness
/// at the end of the step ending at L_M.
///
/// Rigid tendon: L_M cos α = ℓ − L_TS in closed form ([`Pennation::fibre_length_of`]),
/// one evaluation, F_T = F_M cos α. Compliant: the residual
/// R(L_M) = F_M(L_M) cos α − F_T(ℓ − L_M cos α), increasing where F_M is
/// (F_T falls as L_M grows), is solved by a bracketed, safeguarded Newton
/// iteration: from the guess, Newton steps while they stay inside the
/// bracket (and, once both ends are known, at most half the step before
/// last); else the bracket is bisected, or — with an end still unknown —
/// the search steps outward, doubling, toward the range's bound. Converged
/// when |R| ≤ `tol` (N), or when the Newton correction is below 4 ulp of
/// L_M. A slack tendon (F_T = 0) gives the root F_M = 0.
///
/// Derivatives (implicit function theorem on R = 0, with R_L = dR/dL_M =
/// k_M + k_T / cos α, k_M = d(F_M cos α)/dL_M, k_T = dF_T/dL_T):
/// dL_M/dℓ = k_T / R_L, dL_M/dF̃ = −cos α / R_L, dF_T/dℓ = k_T k_M / R_L
/// (the series stiffness), dF_T/dF̃ = k_T / R_L. Rigid: dL_M/dℓ = cos α, dF_T/dℓ = k_M cos α, dF_T/dF̃ = cos α.
pub fn solve_equilibrium<E, F>(
    unit: &Unit,
    path: f64,
    range: (f64, f64),
    guess: f64,
    tol: f64,
    mut muscle: F,
) -> Result<Equilibrium, EquilibriumError<E>>
where
    F: FnMut(f64) -> Result<MuscleForce, E>,
{
    let pen = &unit.pennation;
    let tendon = &unit.tendon;
    let min_fibre = pen.min_fibre_length();
    if !unit.compliant {
        let x = pen.fibre_length_of(path - tendon.slack_length).ok_or(
            EquilibriumError::LargestAngle {
                path,
                min_fibre_length: min_fibre,
            },
        )?;
        let m = muscle(x).map_err(|error| EquilibriumError::Muscle {
            fibre_length: x,
            error,
        })?;
        let p = pen.at(x);
        let k_m = m.stiffness * p.cos + m.force * p.dcos;
        return Ok(Equilibrium {
            fibre_length: x,
            pennation: p,
            muscle: m,
            tendon_strain: 0.0,
            tendon_force: m.force * p.cos,
            dfibre_dpath: p.cos,
            dfibre_dforce: 0.0,
            stiffness: k_m * p.cos,
            dforce_dforce: p.cos,
            residual: 0.0,
            evaluations: 1,
        });
    }
    let mut evaluations = 0u32;
    let mut eval = |x: f64| -> Result<Point, EquilibriumError<E>> {
        evaluations += 1;
        let m = muscle(x).map_err(|error| EquilibriumError::Muscle {
            fibre_length: x,
            error,
        })?;
        let p = pen.at(x);
        let (ft, kt) = tendon.force(path - p.projection);
        Ok(Point {
            x,
            pen: p,
            muscle: m,
            r: m.force * p.cos - ft,
            dr: m.stiffness * p.cos + m.force * p.dcos + kt * p.dprojection,
            strain: tendon.strain(path - p.projection),
            ft,
            kt,
        })
    };
    let (mut lo_bound, mut hi_bound) = (range.0.max(min_fibre), range.1);
    let (mut lo, mut hi) = (lo_bound, hi_bound);
    let (mut lo_known, mut hi_known) = (false, false);
    let mut x = guess.clamp(lo_bound, hi_bound);
    // The last two steps (the progress test) and the outward search's step.
    let (mut dx, mut dx_old) = (hi - lo, hi - lo);
    let mut reach = 1e-3 * x;
    // 200: bisection of the evaluable range to 1 ulp takes ~60.
    // The last point the muscle could evaluate.
    let mut good: Option<f64> = None;
    for _ in 0..200 {
        let pt = match eval(x) {
            Ok(pt) => pt,
            // The muscle cannot be evaluated at x (its law overflows, or its
            // step fails, past some fibre length): the evaluable range ends
            // between the last good point and x. Move that bound of the
            // range to x and halve the step, until x is within 4 ulp of
            // the good point, where the failure is the answer.
            Err(e) => match good {
                Some(g) if (x - g).abs() > 4.0 * f64::EPSILON * x.abs() => {
                    if x > g {
                        hi_bound = x;
                        if !hi_known {
                            hi = x;
                        }
                    } else {
                        lo_bound = x;
                        if !lo_known {
                            lo = x;
                        }
                    }
                    reach = 0.25 * (x - g).abs();
                    x = 0.5 * (g + x);
                    continue;
                }
                _ => return Err(e),
            },
        };
        good = Some(x);
        let step = pt.r / pt.dr;
        let newton_ok = pt.dr > 0.0 && step.is_finite();
        if pt.r.abs() <= tol || (newton_ok && step.abs() <= 4.0 * f64::EPSILON * x) {
            return Ok(finish(pt, evaluations));
        }
        if pt.r < 0.0 {
            lo = x;
            lo_known = true;
        } else {
            hi = x;
            hi_known = true;
        }
        if lo_known && hi_known && hi - lo <= 4.0 * f64::EPSILON * hi {
            // The root is resolved in binary64: this point is as good as any.
            return Ok(finish(pt, evaluations));
        }
        let newton = x - step;
        let bracketed = lo_known && hi_known;
        let next = if newton_ok
            && newton > lo
            && newton < hi
            && (!bracketed || (2.0 * step).abs() <= dx_old.abs())
        {
            newton
        } else if bracketed {
            0.5 * (lo + hi)
        } else if pt.r < 0.0 {
            // Search upward toward the range's top.
            if x >= hi_bound {
                return Err(EquilibriumError::NoRoot {
                    bound: hi_bound,
                    residual: pt.r,
                });
            }
            reach = (2.0 * reach).max(2.0 * step.abs());
            (x + reach).min(hi_bound)
        } else {
            if x <= lo_bound {
                return Err(if lo_bound == min_fibre {
                    EquilibriumError::LargestAngle {
                        path,
                        min_fibre_length: min_fibre,
                    }
                } else {
                    EquilibriumError::NoRoot {
                        bound: lo_bound,
                        residual: pt.r,
                    }
                });
            }
            reach = (2.0 * reach).max(2.0 * step.abs());
            (x - reach).max(lo_bound)
        };
        dx_old = dx;
        dx = next - x;
        x = next;
    }
    Err(EquilibriumError::NoConvergence { lo, hi })
}

/// The equilibrium's outputs and implicit derivatives at a converged point
/// (see [`solve_equilibrium`]).
fn finish(pt: Point, evaluations: u32) -> Equilibrium {
    let k_m = pt.muscle.stiffness * pt.pen.cos + pt.muscle.force * pt.pen.dcos;
    let r_l = pt.dr;
    Equilibrium {
        fibre_length: pt.x,
        pennation: pt.pen,
        muscle: pt.muscle,
        tendon_strain: pt.strain,
        tendon_force: pt.ft,
        dfibre_dpath: pt.kt / r_l,
        dfibre_dforce: -pt.pen.cos / r_l,
        stiffness: pt.kt * k_m / r_l,
        dforce_dforce: pt.kt / r_l,
        residual: pt.r,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const L0: f64 = 0.05;
    const F0: f64 = 100.0;
    const TOL: f64 = 1e-10 * F0;

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
        solve_equilibrium(u, path, (0.1 * L0, 5.0 * L0), L0, TOL, synthetic(a))
    }

    /// A muscle that cannot be evaluated past a fibre length (its law
    /// overflows there): a root below it is found however far the
    /// outward search overshoots into the failing lengths; a root beyond
    /// it is the muscle's error at the end of the evaluable lengths.
    #[test]
    fn a_muscle_that_fails_past_a_length_is_searched_below_it() {
        let u = unit(0.04, 0.0, true);
        let failing = |limit: f64| {
            let mut m = synthetic(0.0);
            move |l: f64| if l > limit { Err(()) } else { m(l) }
        };
        let path = 0.04 * 1.5 + 1.3 * L0;
        let free = solve(&u, path, 0.0).unwrap();
        for limit in [1.02, 1.5, 3.0].map(|k| k * free.fibre_length) {
            let eq = solve_equilibrium(
                &u,
                path,
                (0.1 * L0, 5.0 * L0),
                0.5 * L0,
                TOL,
                failing(limit),
            )
            .unwrap();
            assert!(eq.residual.abs() <= TOL, "{limit}: {}", eq.residual);
            assert!((eq.fibre_length - free.fibre_length).abs() <= 1e-12 * L0);
        }
        let below = 0.9 * free.fibre_length;
        match solve_equilibrium(
            &u,
            path,
            (0.1 * L0, 5.0 * L0),
            0.5 * L0,
            TOL,
            failing(below),
        ) {
            Err(EquilibriumError::Muscle { fibre_length, .. }) => {
                assert!(
                    fibre_length > below && fibre_length - below <= 1e-12 * L0,
                    "{fibre_length}"
                )
            }
            other => panic!("{:?}", other.map(|e| e.fibre_length)),
        }
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

    #[test]
    fn the_residual_is_below_tolerance_over_stiffness_pennation_and_activation() {
        let mut worst: f64 = 0.0;
        let mut most = 0;
        for eps0 in [0.1, 0.04, 1e-2, 1e-3, 1e-4, 1e-6] {
            for alpha0 in [0.0, 0.5, 1.0] {
                for a in [0.0, 0.5, 1.0] {
                    for path in [0.07, 0.085, 0.09, 0.1, 0.12] {
                        let u = unit(eps0, alpha0, true);
                        let eq = solve(&u, path, a).unwrap();
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
        eprintln!("worst residual {worst:e} F0, at most {most} evaluations");
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
        let r = solve_equilibrium(&u, 0.03, (0.1 * L0, 5.0 * L0), L0, TOL, pulls);
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
}
