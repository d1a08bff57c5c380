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
//! pennation angle, or only past the tendon's rupture strain
//! ([`Tendon::max_strain`]), is an error, never a clamped force.

use super::params::{ParamError, TendonParamId, TENDON_PARAMETERS};
use super::pennation::{Pennated, Pennation, MIN_COS};
use super::tendon::{Tendon, RUPTURE_STRAIN_RATIO};
use super::uniaxial::Uniaxial;

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

impl MuscleForce {
    /// The axial force of a muscle of rest length `l0` and cross-section
    /// `area` in the uniaxial state `u` at λ = L_M/L0: F_M = P area (P the
    /// nominal stress on the rest section) and dF_M/dL_M = (dP/dλ) area/L0.
    pub fn of_uniaxial(u: &Uniaxial, area: f64, l0: f64) -> MuscleForce {
        MuscleForce {
            force: u.nominal_stress() * area,
            stiffness: u.dnominal_dlambda() * area / l0,
        }
    }
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
    /// The equilibrium needs a tendon strain of at least `strain`, past the
    /// tendon's rupture strain `max_strain` ([`Tendon::max_strain`]).
    TendonRupture { strain: f64, max_strain: f64 },
    /// The iteration cap was reached.
    NoConvergence { lo: f64, hi: f64 },
    /// The root is resolved to the precision of L_M at `fibre_length` with
    /// the residual `residual` (N) still beyond [`DISCONTINUITY`] of the
    /// force scale: the muscle's force jumps there (a step map that changes
    /// between nearby end lengths), and no fibre length balances the tendon.
    Discontinuous { fibre_length: f64, residual: f64 },
}

impl<E> EquilibriumError<E> {
    /// Why no equilibrium was returned, for a message that names the path;
    /// `Err` with the muscle's own failure.
    pub fn reason(self) -> Result<String, E> {
        Ok(match self {
            EquilibriumError::Muscle { error, .. } => return Err(error),
            EquilibriumError::LargestAngle {
                min_fibre_length, ..
            } => format!(
                "the equilibrium needs fibres shorter than {min_fibre_length} m, past the largest \
                 pennation angle (cos alpha >= {MIN_COS}); a longer path or a smaller \
                 pennation_angle is needed"
            ),
            EquilibriumError::NoRoot { bound, residual } => format!(
                "no equilibrium of tendon and muscle for fibre lengths the law can evaluate \
                 (F_M cos alpha - F_T = {residual:e} N at fibre length {bound} m)"
            ),
            EquilibriumError::TendonRupture { strain, max_strain } => format!(
                "the equilibrium needs a tendon strain of {strain} or more, past the tendon's \
                 rupture strain {max_strain} ({RUPTURE_STRAIN_RATIO} tendon_strain_at_F0); a \
                 shorter path or a larger tendon_strain_at_F0 is needed"
            ),
            EquilibriumError::NoConvergence { lo, hi } => {
                format!("the equilibrium did not converge (fibre length in [{lo}, {hi}] m)")
            }
            EquilibriumError::Discontinuous {
                fibre_length,
                residual,
            } => format!(
                "the muscle's force jumps at fibre length {fibre_length} m (F_M cos alpha - F_T = \
                 {residual:e} N there, the root resolved to rounding): no fibre length balances \
                 the tendon; a shorter step may"
            ),
        })
    }
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

/// The trust length for a muscle whose evaluation is expensive far from
/// the root (the FE step): before the root is bracketed no move exceeds
/// this fraction of L_M ([`solve_equilibrium`]'s `trust`).
pub const TRUST: f64 = 0.1;

/// Consecutive failed evaluations, each halving the step back toward the
/// last evaluable fibre length, after which the failure is the answer: the
/// evaluable range then ends within 2⁻¹⁶ of the first failed step from it.
/// Also the bound of consecutive good points that approach a failed length
/// with the root on its side ([`solve_equilibrium`]).
pub const MAX_HALVINGS: u32 = 16;

/// The largest residual, relative to max(F0, |F_T|), of a root resolved to
/// the precision of L_M (a Newton correction below 4 ulp, or a bracket that
/// narrow) beyond the tendon's own resolution there (its stiffness times
/// 8 ulp of L_M): more is a jump of F_M(L_M) across the root, refused
/// ([`EquilibriumError::Discontinuous`]) rather than returned as a
/// balance. Not a multiple of the tolerance: the FE force's absolute floor
/// is above its relative tolerance where σ0 A is tiny (1.4e-10 N at
/// σ0 = 1 Pa, 1.5e-7 F0), while the jumps that matter, between step maps
/// with different substep counts, are of order 1e-3 F0.
pub const DISCONTINUITY: f64 = 1e-6;

/// The tolerance of the equilibrium's residual F_M cos α − F_T.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tolerance {
    /// A fixed tolerance (N): for a muscle whose force is exact to rounding
    /// (the 1D law), so that nothing grows with the force.
    Fixed(f64),
    /// `rtol` × max(F0, |F_T|) ([`Unit::equilibrium_tolerance`]): for a
    /// muscle whose force is itself solved to a tolerance relative to
    /// max(F0, |F_M|) (the FE solve).
    Scaled(f64),
}

impl Unit {
    /// The equilibrium's tolerance (N) on its residual F_M cos α − F_T where
    /// the tendon carries `tendon_force`: `rtol` × max(F0, |F_T|). A muscle
    /// solved to a tolerance relative to max(F0, |F_M|), with
    /// |F_M| cos α ≤ max(F0, |F_T|) at the root, then keeps a fixed margin
    /// below it at every force the tendon can carry.
    pub fn equilibrium_tolerance(&self, rtol: f64, tendon_force: f64) -> f64 {
        rtol * self.tendon.f0.max(tendon_force.abs())
    }

    /// The tolerance `tol` (N) where the tendon carries `tendon_force`.
    fn tolerance_at(&self, tol: Tolerance, tendon_force: f64) -> f64 {
        match tol {
            Tolerance::Fixed(t) => t,
            Tolerance::Scaled(rtol) => self.equilibrium_tolerance(rtol, tendon_force),
        }
    }
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
/// iteration: from the guess, Newton steps while they stay strictly inside
/// the bracket (and, once both ends are known, at most half the step before
/// last); else the bracket is bisected, or — with an end still unknown —
/// the search steps outward, doubling, toward the range's bound. Before
/// the bracket is known, with `trust` = Some(f) (a muscle expensive to
/// evaluate far from the root: the FE step), no move exceeds f L_M or
/// twice the last move, and with R > 0 none goes below the fibre length at
/// which the tendon alone carries the muscle's present force; with `None`
/// (an evaluation costs the same anywhere: the 1D law) the search is
/// unbounded. Converged
/// when |R| ≤ `tol` ([`Tolerance`], at the point's F_T), or when the
/// Newton correction is below 4 ulp of L_M. A slack tendon (F_T = 0) gives
/// the root F_M = 0. The tendon strain falls as L_M grows, so a root that
/// needs more than the rupture strain ([`Tendon::max_strain`]) is refused
/// as soon as it is known: before any evaluation when the strain exceeds it
/// at the longest evaluable fibres, or at a point with R > 0 (the root is
/// shorter) and a strain past it, or at the converged point itself (at the
/// resolution of L_M its R may be below −tol).
///
/// Where the muscle cannot be evaluated (its closure fails), the evaluable
/// lengths end between the last good point and the failed one: no later
/// trial goes to or past a failed length (the evaluable lengths are taken
/// to be an interval), the step back is halved toward
/// the good point at most [`MAX_HALVINGS`] times in a row, at most as many
/// good points in a row approach a failed end with the root on its side
/// (each then the failure is the answer), and a failed first trial is retried once at a fallback point (the rigid tendon's
/// fibre length, else the middle of the range) before the failure is
/// returned.
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
    tol: Tolerance,
    trust: Option<f64>,
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
    let near = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(b.abs());
    // The evaluable range: its ends, and whether each is a failed length
    // (never tried again) or the range given.
    let (mut lo_bound, mut hi_bound) = (range.0.max(min_fibre), range.1);
    let (mut lo_failed, mut hi_failed) = (false, false);
    // The bracket: the ends with R < 0 (lo) and R > 0 (hi) once known.
    let rupture = |strain: f64| EquilibriumError::TendonRupture {
        strain,
        max_strain: tendon.max_strain(),
    };
    if lo_bound <= hi_bound {
        let least = tendon.strain(path - pen.at(hi_bound).projection);
        if least > tendon.max_strain() {
            return Err(rupture(least));
        }
    }
    let (mut lo, mut hi) = (lo_bound, hi_bound);
    let (mut lo_known, mut hi_known) = (false, false);
    let mut x = guess.clamp(lo_bound, hi_bound);
    // The last two steps (the progress test) and the outward search's step.
    let (mut dx, mut dx_old) = (hi - lo, hi - lo);
    let mut reach = 1e-3 * x;
    // The last point the muscle could evaluate, the errors at the failed
    // ends of the range, whether the fallback was tried, the failures in a
    // row.
    let mut good: Option<f64> = None;
    let (mut lo_error, mut hi_error) = (None, None);
    let mut fallback_tried = false;
    let mut halvings = 0u32;
    // Moves in a row toward a failed end: failed trials after a good point,
    // and good points with the root on the side of a failed end.
    let mut approaches = 0u32;
    let mut last_move = 0.0f64;
    // Newton steps that fall short: the residual before the last move when
    // that was a Newton step, and the factor the next Newton step takes.
    let mut newton_from: Option<f64> = None;
    let mut boost = 1.0f64;
    // 200: bisection of the evaluable range to 1 ulp takes ~60.
    for _ in 0..200 {
        let pt = match eval(x) {
            Ok(pt) => pt,
            Err(e) => {
                // The evaluable range ends between the last good point (or
                // the fallback) and x: x becomes that end of the range.
                let toward = match good {
                    Some(g) => g,
                    None if !fallback_tried => {
                        fallback_tried = true;
                        let rigid = pen
                            .fibre_length_of(path - tendon.slack_length)
                            .map(|l| l.clamp(lo_bound, hi_bound));
                        match rigid {
                            Some(l) if !near(l, x) => l,
                            _ => 0.5 * (lo_bound + hi_bound),
                        }
                    }
                    // The fallback failed too: the first trial's failure.
                    None => return Err(hi_error.or(lo_error).unwrap_or(e)),
                };
                halvings += 1;
                // A halving move toward a failed end (below).
                if good.is_some() {
                    approaches += 1;
                }
                if near(x, toward) || halvings > MAX_HALVINGS || approaches > MAX_HALVINGS {
                    return Err(e);
                }
                if x > toward {
                    hi_bound = x;
                    hi_failed = true;
                    hi = hi.min(x);
                    hi_error = Some(e);
                } else {
                    lo_bound = x;
                    lo_failed = true;
                    lo = lo.max(x);
                    lo_error = Some(e);
                }
                reach = 0.25 * (x - toward).abs();
                x = if good.is_some() {
                    0.5 * (toward + x)
                } else {
                    toward
                };
                continue;
            }
        };
        good = Some(x);
        halvings = 0;
        if pt.strain > tendon.max_strain() && pt.r >= -unit.tolerance_at(tol, pt.ft) {
            return Err(rupture(pt.strain));
        }
        let step = pt.r / pt.dr;
        let newton_ok = pt.dr > 0.0 && step.is_finite();
        if pt.r.abs() <= unit.tolerance_at(tol, pt.ft) {
            return accept(pt, evaluations, tendon);
        }
        if newton_ok && step.abs() <= 4.0 * f64::EPSILON * x {
            return resolved(unit, tol, pt, evaluations);
        }
        if pt.r < 0.0 {
            lo = x;
            lo_known = true;
        } else {
            hi = x;
            hi_known = true;
        }
        let failed_end = (lo_failed && lo == lo_bound) || (hi_failed && hi == hi_bound);
        if lo_known && hi_known && hi - lo <= 4.0 * f64::EPSILON * hi && !failed_end {
            // The root is resolved in binary64: this point is as good as any
            // (unless an end of the bracket is a failed length: below).
            return resolved(unit, tol, pt, evaluations);
        }
        // The trials' interval: the bracket's known ends, else the
        // evaluable range's, never a failed length.
        let top = if hi_known { hi.min(hi_bound) } else { hi_bound };
        let bottom = if lo_known { lo.max(lo_bound) } else { lo_bound };
        // The root on the side of a failed end of the trials' interval: the
        // search toward it moves at most halfway there, and so does the
        // bisection. After MAX_HALVINGS such moves in a row (failed trials
        // included) the evaluable lengths are taken to end here, as after as
        // many failed halvings: the failure is the answer (not some fifty
        // moves to its last ulp).
        let toward_hi = pt.r < 0.0 && hi_failed && top == hi_bound;
        let toward_lo = pt.r > 0.0 && lo_failed && bottom == lo_bound;
        approaches = if toward_hi || toward_lo {
            approaches + 1
        } else {
            0
        };
        if approaches > MAX_HALVINGS {
            let failure = if toward_hi {
                hi_error.take()
            } else {
                lo_error.take()
            };
            if let Some(e) = failure {
                return Err(e);
            }
        }
        // A Newton step that left more than half of the residual, its sign
        // unchanged, came from a slope far too large (a stale one: the FE
        // unit's secant is not formed below its force resolution, and a
        // slope 100 times too large would take hundreds of trials): each
        // such step in a row doubles the next. Overshooting brackets the
        // root, and the bracket bounds every later step.
        boost = match newton_from {
            Some(r0) if r0.signum() == pt.r.signum() && pt.r.abs() > 0.5 * r0.abs() => 2.0 * boost,
            _ => 1.0,
        };
        let newton = x - boost * step;
        let bracketed = lo_known && hi_known;
        if bracketed && top - bottom <= 4.0 * f64::EPSILON * top {
            // The bracket ends at a failed length within rounding of the
            // last point: the failure is the answer.
            let failure = if hi_failed && top == hi_bound {
                hi_error.take()
            } else if lo_failed && bottom == lo_bound {
                lo_error.take()
            } else {
                None
            };
            return match failure {
                Some(e) => Err(e),
                None => resolved(unit, tol, pt, evaluations),
            };
        }
        let newton_taken = newton_ok
            && newton > bottom
            && newton < top
            && (!bracketed || (2.0 * boost * step).abs() <= dx_old.abs());
        newton_from = newton_taken.then_some(pt.r);
        let next = if newton_taken {
            newton
        } else if bracketed {
            0.5 * (bottom + top)
        } else if pt.r < 0.0 {
            // Search upward toward the range's top (short of a failed one).
            if hi_failed && near(x, hi_bound) {
                // The range ends here at a failure: it is the answer.
                if let Some(e) = hi_error.take() {
                    return Err(e);
                }
            }
            if x >= hi_bound {
                return Err(EquilibriumError::NoRoot {
                    bound: hi_bound,
                    residual: pt.r,
                });
            }
            reach = (2.0 * reach).max(2.0 * step.abs());
            let cap = if hi_failed {
                0.5 * (x + hi_bound)
            } else {
                hi_bound
            };
            (x + reach).min(cap)
        } else {
            if lo_failed && near(x, lo_bound) {
                if let Some(e) = lo_error.take() {
                    return Err(e);
                }
            }
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
            let cap = if lo_failed {
                0.5 * (x + lo_bound)
            } else {
                lo_bound
            };
            (x - reach).max(cap)
        };
        // Before the root is bracketed no trial moves further than the
        // trust length: a tenth of L_M, or twice the last move (so that a
        // far root is still reached in a few doublings). A Newton or search
        // step from a stale slope (a slack tendon has none of its own)
        // would otherwise evaluate the muscle far from the root.
        let Some(fraction) = trust else {
            dx_old = dx;
            dx = next - x;
            x = next;
            continue;
        };
        let next = if bracketed {
            next
        } else {
            let reach = (fraction * x).max(2.0 * last_move);
            next.clamp(x - reach, x + reach)
        };
        // R > 0: the root is shorter, where the tendon is longer and
        // stiffer. No trial goes below the fibre length at which the tendon
        // alone carries the muscle's present force F_M cos α: from a slack
        // tendon (k_T = 0) Newton's step and the outward search would
        // otherwise leap to the range's end.
        let next = match (
            pt.r > 0.0,
            tendon_balance(unit, path, pt.muscle.force * pt.pen.cos),
        ) {
            (true, Some(xt)) if xt < x && next < xt && xt > bottom => xt,
            _ => next,
        };
        dx_old = dx;
        dx = next - x;
        last_move = dx.abs();
        x = next;
    }
    Err(EquilibriumError::NoConvergence { lo, hi })
}

/// The equilibrium at a converged point, or the tendon's rupture where its
/// strain there is past [`Tendon::max_strain`]: a root at the resolution of
/// L_M may have R < −tol (the root a little longer), and is still past
/// rupture.
/// [`accept`] for a point at a root resolved to the precision of L_M: its
/// residual within [`DISCONTINUITY`] of the force scale (or the tolerance,
/// if larger) plus the tendon's resolution there, else
/// [`EquilibriumError::Discontinuous`].
fn resolved<E>(
    unit: &Unit,
    tol: Tolerance,
    pt: Point,
    evaluations: u32,
) -> Result<Equilibrium, EquilibriumError<E>> {
    let resolution = (pt.kt * pt.pen.dprojection).abs() * 8.0 * f64::EPSILON * pt.x;
    let scale = unit.tendon.f0.max(pt.ft.abs());
    if pt.r.abs() > (DISCONTINUITY * scale).max(unit.tolerance_at(tol, pt.ft)) + resolution {
        return Err(EquilibriumError::Discontinuous {
            fibre_length: pt.x,
            residual: pt.r,
        });
    }
    accept(pt, evaluations, &unit.tendon)
}

fn accept<E>(
    pt: Point,
    evaluations: u32,
    tendon: &Tendon,
) -> Result<Equilibrium, EquilibriumError<E>> {
    if pt.strain > tendon.max_strain() {
        return Err(EquilibriumError::TendonRupture {
            strain: pt.strain,
            max_strain: tendon.max_strain(),
        });
    }
    Ok(finish(pt, evaluations))
}

/// The fibre length at which the tendon on path `path` carries
/// `force` (N): L_M cos α = ℓ − L_TS (1 + ε(F/F0)) ([`Tendon::strain_at`]);
/// `None` past the largest pennation angle or for no tension.
fn tendon_balance(unit: &Unit, path: f64, force: f64) -> Option<f64> {
    let t = &unit.tendon;
    if force.is_nan() || force <= 0.0 {
        return None;
    }
    let lt = t.slack_length * (1.0 + t.strain_at(force));
    unit.pennation.fibre_length_of(path - lt)
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

/// What a unit's next first trial extrapolates from (both units, MODEL_NOTES
/// "Musculotendon unit", the step's equilibrium): the mean rates of the
/// fibres' length (or stretch) and of the path over the last step, their
/// changes from the step before per time between the two steps' midpoints,
/// and that step's length `span` (s; 0 after initialization, when the rates
/// and their changes are 0). They change a step's cost, not its result
/// beyond the equilibrium's tolerance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepRates {
    pub fibre_rate: f64,
    pub path_rate: f64,
    pub fibre_accel: f64,
    pub path_accel: f64,
    pub span: f64,
}

impl StepRates {
    /// The rates after a step of length `h` that moved the fibres by
    /// `dfibre` and the path by `dpath`; `None` for a step so short that a
    /// change over it overflows (h = 5e-324): the next step then guesses as
    /// after initialization.
    pub fn after(&self, h: f64, dfibre: f64, dpath: f64) -> Option<StepRates> {
        let (fibre_rate, path_rate) = (dfibre / h, dpath / h);
        let (fibre_accel, path_accel) = if self.span > 0.0 {
            let mid = 0.5 * (h + self.span);
            (
                (fibre_rate - self.fibre_rate) / mid,
                (path_rate - self.path_rate) / mid,
            )
        } else {
            (0.0, 0.0)
        };
        let next = StepRates {
            fibre_rate,
            path_rate,
            fibre_accel,
            path_accel,
            span: h,
        };
        [fibre_rate, path_rate, fibre_accel, path_accel]
            .iter()
            .all(|x| x.is_finite())
            .then_some(next)
    }

    /// The change from `t0` to `t1` (s into the step) of a quantity whose
    /// rate was `rate` at the last step's midpoint and changes by `accel`
    /// per second: the integral of the rate extrapolated linearly.
    pub fn change(&self, rate: f64, accel: f64, t0: f64, t1: f64) -> f64 {
        (t1 - t0) * (rate + 0.5 * accel * (t0 + t1 + self.span))
    }

    /// The fibres' and the path's changes from `t0` to `t1`.
    pub fn changes(&self, t0: f64, t1: f64) -> (f64, f64) {
        (
            self.change(self.fibre_rate, self.fibre_accel, t0, t1),
            self.change(self.path_rate, self.path_accel, t0, t1),
        )
    }
}

#[cfg(test)]
mod tests;
