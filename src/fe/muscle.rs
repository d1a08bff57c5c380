//! Time stepping of the FE muscle: the quasi-static equilibrium of its
//! [`Discretization`] at the end of each step, the CE–SEE history of every
//! element advanced over the step (`FibreRate::Step { h }`, backward Euler
//! as in the 1D model) and committed only when the step converges. Inertia
//! is neglected (as in the paper).
//!
//! Entry points: [`Muscle::isometric`] (initialization: the length ramped,
//! then the muscle relaxed to the isometric equilibrium at the activation
//! level, the level's ramp where that fails); [`Muscle::advance`] (one step: each (sub)step solved by
//! [`crate::fe::newton`], retried by continuation in its inputs and then in
//! 2, 4, … [`MAX_SUBSTEPS`] substeps); [`Muscle::advance_controlled`] (the
//! step in pieces whose CE–SEE error estimate meets a tolerance,
//! [`crate::step_control`]); [`Muscle::advance_pieces`] (the same pieces
//! again: the smooth step map the derivatives differentiate).
//!
//! Invariant: a step that fails returns `Err` and changes nothing (every
//! method takes `&self` and returns the new state).

use std::sync::Arc;

pub use crate::fe::discretization::{
    Discretization, ElementState, Ends, Evaluation, VolumeRatioSpread, Volumetric,
};
use crate::fe::newton::{Budget, Solution, Solved, StepInput, RESIDUAL_TOLERANCE};
use crate::fe::tangent::{Anchor, Increment, TangentCache, Trend};
use crate::law::force_length::force_length;
use crate::law::hill_fibre::backward_euler_error;
use crate::law::{FibreHistory, FibreRate, Params};
use crate::step_control::{self, MAX_CONTROLLED_TRIES};

/// Largest number of substeps a step is split into before it is refused.
pub const MAX_SUBSTEPS: usize = 64;
/// Substep counts up to which a failed (sub)step is retried by continuation
/// ([`Discretization::solve_step_continued`]) before it is split further.
const CONTINUED_SUBSTEPS: usize = 2;
/// The level change over a substep above which it is retried by
/// continuation at any substep count, where time cannot split it
/// ([`unsplittable_jump`]): with S·h ≫ 1 a jump of the command moves the
/// level within the first substep however many there are; continuation in
/// the level can split it.
const CONTINUED_LEVEL_CHANGE: f64 = 0.25;
/// Whether substeps in time cannot split the level's change over the
/// substep from `start` to `start + length` of a step of length `step`
/// ([`CONTINUED_LEVEL_CHANGE`]): even cut into the pieces of `step` /
/// [`MAX_SUBSTEPS`], one of them changes the level by more than that
/// (S·h ≫ 1). Where the pieces split it, a larger substep count is cheaper
/// than continuation in the level: the activation onset of a 100 ms step
/// at S = 50 (level 0 → 0.99) took 235 factorisations continued at 1–8
/// substeps, 87 plain at 4–16.
fn unsplittable_jump(activation: &dyn Fn(f64) -> f64, step: f64, start: f64, length: f64) -> bool {
    let piece = step / MAX_SUBSTEPS as f64;
    let pieces = ((length / piece).round() as usize).clamp(1, MAX_SUBSTEPS);
    (0..pieces).any(|k| {
        let t0 = start + k as f64 * piece;
        (activation(t0 + piece) - activation(t0)).abs() > CONTINUED_LEVEL_CHANGE
    })
}

/// Steps of 1 ms over which [`Muscle::isometric`]'s relaxation raises the
/// activation level before holding it.
pub(crate) const RELAX_RAMP: usize = 8;
/// Factor by which the relaxation's step grows after the level's ramp
/// (pseudo-time: only the steady state counts).
const RELAX_GROWTH: f64 = 4.0;
/// Largest CE move of a relaxation step (max |Δλm| over the elements)
/// after which the relaxation first tries the rate-free solve from its
/// state; after a failed try, the next waits for a move 10× smaller.
const RELAX_TRY_BELOW: f64 = 1e-2;
/// The rate-free solve that ends the relaxation converges to this fraction
/// of the muscle's tolerance (when it can), so that the equilibrium does not
/// depend on where the relaxation stopped by more than about the tolerance.
const RELAX_FINAL_TOLERANCE: f64 = 0.1;
/// Increments of the isometric activation ramp at initialization before it
/// turns to relaxation ([`Muscle::isometric`]).
const ACTIVATION_RAMP: usize = 4;

/// The muscle's state between steps (shared discretization + per-instance
/// fields): what [`Muscle::advance`] reads and commits.
#[derive(Clone, Debug)]
pub struct Muscle {
    pub disc: Arc<Discretization>,
    /// Converged positions, flattened.
    pub x: Vec<f64>,
    /// Committed fibre history per element.
    pub history: Vec<FibreHistory>,
    /// Muscle length of the converged state.
    pub length: f64,
    /// The tangent the next step starts with ([`crate::fe::newton`]).
    pub tangent: Option<Arc<TangentCache>>,
    /// The last steps' increments, for the predictor.
    pub trend: Trend,
    /// The solver's convergence test ([`StepInput::tolerance`]).
    pub tolerance: f64,
}

/// Result of [`Muscle::advance`].
#[derive(Clone, Debug)]
pub struct Advance {
    pub muscle: Muscle,
    /// The last substep's converged solution.
    pub solution: Solution,
    /// Its starting history, rate and end activation level (what its
    /// tangent is formed with).
    pub start: Vec<FibreHistory>,
    pub rate: FibreRate,
    pub activation: f64,
    /// Newton iterations summed over the substeps.
    pub iterations: usize,
    /// Tangents formed and factorised, summed over the substeps.
    pub factorizations: usize,
    /// Residual evaluations, summed over the substeps.
    pub residuals: usize,
    /// Substeps taken, summed over the pieces.
    pub substeps: usize,
    /// The step's pieces: the time each ends at (the last at h) and the
    /// equal substeps it took ([`Muscle::advance_pieces`] takes the same
    /// again); one piece unless the time error was controlled.
    pub pieces: Vec<(f64, usize)>,
}

impl Muscle {
    /// The muscle at rest (reference positions, unloaded history).
    pub fn at_rest(disc: Arc<Discretization>) -> Muscle {
        let x = disc.reference_positions();
        let n = disc.n_elements();
        let l0 = disc.l0;
        Muscle {
            disc,
            x,
            history: vec![FibreHistory::REST; n],
            length: l0,
            tangent: None,
            trend: Trend::default(),
            tolerance: RESIDUAL_TOLERANCE,
        }
    }

    /// Isometric equilibrium at `length` and activation level `activation`
    /// (initialization, MODEL_NOTES "Co-simulation conventions"): the
    /// passive equilibrium at `length` (`Self::isometric_ramp` from rest),
    /// then, for an active muscle, the level raised to `activation` by
    /// relaxation (`Self::relax_isometric`); when that fails, by the same
    /// ramp as the length's at that length. (The rate-free ramp of the level
    /// mostly fails at L0 and takes tens of factorisations where it
    /// succeeds; the relaxation reaches every case of the tests and benches
    /// in fewer.) The solution's counts are those of every
    /// converged solve of the way there (the passive ramp, then the
    /// relaxation steps and the final solve, or the level's ramp; attempts
    /// that failed and were retried are not counted).
    pub fn isometric(
        disc: Arc<Discretization>,
        p: &Params,
        length: f64,
        activation: f64,
    ) -> Result<(Muscle, Solution), String> {
        let rest = Muscle::at_rest(disc);
        let (passive, s) = rest.isometric_ramp(p, length, 0.0, 0.0, MAX_SUBSTEPS)?;
        if activation == 0.0 {
            return Ok((passive, s));
        }
        let (active, a) = match passive.relax_isometric(p, activation) {
            Ok(done) => done,
            Err(relax) => passive
                .isometric_ramp(p, length, 0.0, activation, ACTIVATION_RAMP)
                .map_err(|ramp| {
                    format!("relaxing to it at the activation level held: {relax}; {ramp}")
                })?,
        };
        Ok((
            active,
            a.with_counts_added(s.iterations, s.factorizations, s.residuals),
        ))
    }

    /// From this isometric equilibrium at activation level `activation`, the
    /// one at `length` and the same level: a length ramp at the level held
    /// (`Self::isometric_ramp`, continuation along this equilibrium's
    /// branch), to the tolerance the cold path ends at ([`Self::isometric`]:
    /// `RELAX_FINAL_TOLERANCE` × the tolerance when active, when it can).
    /// What a family of nearby lengths costs after its first member (the
    /// musculotendon unit's initialization): a few solves instead of a
    /// passive ramp and a relaxation. The counts are this ramp's.
    pub fn isometric_near(
        &self,
        p: &Params,
        length: f64,
        activation: f64,
    ) -> Result<(Muscle, Solution), String> {
        let start = Muscle {
            trend: Trend::default(),
            ..self.clone()
        };
        let ramp = |m: &Muscle| m.isometric_ramp(p, length, activation, activation, MAX_SUBSTEPS);
        if activation == 0.0 {
            return ramp(&start);
        }
        let tight = Muscle {
            tolerance: start.tolerance * RELAX_FINAL_TOLERANCE,
            ..start.clone()
        };
        match ramp(&tight) {
            Ok((done, s)) => Ok((
                Muscle {
                    tolerance: start.tolerance,
                    ..done
                },
                s,
            )),
            Err(_) => ramp(&start),
        }
    }

    /// From this isometric equilibrium (at activation level `from`), the
    /// isometric equilibrium at `length` and activation level `activation`:
    /// length and level approached together in 1, 2, 4, … `max_increments`
    /// increments (path-independent: the isometric fibre has no rate, so the
    /// increments only guide Newton).
    fn isometric_ramp(
        &self,
        p: &Params,
        length: f64,
        from: f64,
        activation: f64,
        max_increments: usize,
    ) -> Result<(Muscle, Solution), String> {
        let disc = &self.disc;
        let a0 = from;
        let mut last_error = String::new();
        let mut n = 1;
        while n <= max_increments {
            let mut x = self.x.clone();
            let mut cache = None;
            let mut result = None;
            let (mut iterations, mut factorizations, mut residuals) = (0, 0, 0);
            for i in 1..=n {
                // Each increment is a step's worth of work.
                let budget = Budget::for_step(disc);
                let at = |i: usize| (i as f64 / n as f64, (i - 1) as f64 / n as f64);
                let (u, u0) = at(i);
                let input = StepInput {
                    x: &x,
                    length_start: self.length + (length - self.length) * u0,
                    length: self.length + (length - self.length) * u,
                    activation_start: a0 + (activation - a0) * u0,
                    activation: a0 + (activation - a0) * u,
                    start: &self.history,
                    rate: FibreRate::Isometric,
                    trend: None,
                    tolerance: self.tolerance,
                    budget: &budget,
                };
                match disc.solve_step(p, &input, cache.take()) {
                    Ok(s) => {
                        iterations += s.solution.iterations;
                        residuals += s.solution.residuals;
                        factorizations += s.solution.factorizations;
                        x = s.solution.x.clone();
                        cache = Some(s.cache);
                        result = Some(s.solution);
                    }
                    Err(e) => {
                        last_error = e;
                        result = None;
                        break;
                    }
                }
            }
            if let Some(s) = result {
                let history = s.evaluation.elements.iter().map(|e| e.history).collect();
                return Ok((
                    Muscle {
                        disc: disc.clone(),
                        x: s.x.clone(),
                        history,
                        length,
                        tangent: cache,
                        trend: Trend::default(),
                        tolerance: self.tolerance,
                    },
                    Solution {
                        iterations,
                        residuals,
                        factorizations,
                        ..s
                    },
                ));
            }
            n *= 2;
        }
        Err(format!(
            "no isometric equilibrium at length {length} m and activation level {activation} in up to {max_increments} increments: {last_error}"
        ))
    }

    /// The isometric equilibrium at this length and activation level
    /// `activation` as the steady state of the rate-dependent muscle held at
    /// that length and level (from this state): the level raised over
    /// `RELAX_RAMP` steps of 1 ms, then held in steps of the CE–SEE law with
    /// growing length h = 4 ms, 16 ms, … (`RELAX_GROWTH`) until the
    /// contractile elements stop moving (every |Δλm| below 1e-12), then the
    /// isometric solve from there (`Self::isometric_solve`); that solve is
    /// tried early, once a step moves them by at most `RELAX_TRY_BELOW`
    /// (then at each 10× smaller move), and ends the relaxation when it
    /// converges. In steady state λ̇m = 0, f_v = 1 and σ_s = σ0 a f_λ: the
    /// isometric equilibrium. Why: with the fibres of the clamped specimen
    /// partly on the descending limb of f_λ (negative active stiffness), the
    /// rate-free isometric problem can defeat Newton's method from the
    /// passive state, while the force-velocity relation regularises the
    /// rate-dependent one. The counts are summed over the relaxation steps
    /// and the final solve.
    ///
    /// The pseudo-time steps use the force-velocity constants (k_c, k_e, d,
    /// λ̇m^min) at their defaults, not the muscle's: the steady state does
    /// not depend on them (f_v = 1), and the path to it must not either, so
    /// that the initial state is a function of the parameters it depends on
    /// (the final solve stops within its tolerance of where it starts).
    fn relax_isometric(&self, p: &Params, activation: f64) -> Result<(Muscle, Solution), String> {
        let default = Params::default();
        let pseudo = Params {
            kc: default.kc,
            ke: default.ke,
            d: default.d,
            lambda_dot_min: default.lambda_dot_min,
            ..*p
        };
        let mut m = self.clone();
        let mut h = 1e-3;
        let mut steps = 0;
        let (mut iterations, mut factorizations, mut residuals) = (0, 0, 0);
        let mut try_below = RELAX_TRY_BELOW;
        // The level is raised over the first RELAX_RAMP steps (pseudo-time:
        // only the steady state counts), then held while h grows RELAX_GROWTH×.
        while h <= 1e6 {
            let (a0, a1) = if steps < RELAX_RAMP {
                let at = |k: usize| activation * k as f64 / RELAX_RAMP as f64;
                (at(steps), at(steps + 1))
            } else {
                (activation, activation)
            };
            let r = m.advance(&pseudo, m.length, h, &|tau| a0 + (a1 - a0) * tau / h)?;
            steps += 1;
            iterations += r.iterations;
            factorizations += r.factorizations;
            residuals += r.residuals;
            let moved = r
                .solution
                .evaluation
                .elements
                .iter()
                .zip(&m.history)
                .fold(0.0f64, |d, (e, old)| {
                    d.max((e.history.lambda_m - old.lambda_m).abs())
                });
            m = r.muscle;
            if steps < RELAX_RAMP {
                continue;
            }
            if moved <= 1e-12 {
                break;
            }
            if moved <= try_below {
                try_below = moved / 10.0;
                if let Ok((done, s)) = m.isometric_solve(p, activation) {
                    return Ok((
                        done,
                        s.with_counts_added(iterations, factorizations, residuals),
                    ));
                }
            }
            h *= RELAX_GROWTH;
        }
        let (done, s) = m
            .isometric_solve(p, activation)
            .map_err(|e| format!("after {steps} relaxation steps: {e}"))?;
        Ok((
            done,
            s.with_counts_added(iterations, factorizations, residuals),
        ))
    }

    /// The exact isometric equilibrium at activation level `activation`
    /// from this (relaxed) state: a level ramp of one increment (the level
    /// is already there) at `RELAX_FINAL_TOLERANCE` × the tolerance, or at
    /// the tolerance when that does not converge.
    fn isometric_solve(&self, p: &Params, activation: f64) -> Result<(Muscle, Solution), String> {
        let m = self.clone();
        let relaxed = Muscle {
            tangent: Some(Arc::new(TangentCache::new(Anchor {
                x: m.x.clone(),
                activation,
                start: m.history.clone(),
                rate: FibreRate::Isometric,
                pressure: None,
            }))),
            trend: Trend::default(),
            ..m
        };
        let tight = Muscle {
            tolerance: relaxed.tolerance * RELAX_FINAL_TOLERANCE,
            ..relaxed.clone()
        };
        match tight.isometric_ramp(p, relaxed.length, activation, activation, 1) {
            Ok((done, s)) => Ok((
                Muscle {
                    tolerance: relaxed.tolerance,
                    ..done
                },
                s,
            )),
            Err(_) => relaxed.isometric_ramp(p, relaxed.length, activation, activation, 1),
        }
    }

    /// Advance over a step of length `h` to muscle length `length`, the
    /// activation level following `activation(τ)` for τ in [0, h] (exact
    /// dynamics). Tries 1, 2, 4, … [`MAX_SUBSTEPS`] substeps (length linear
    /// in τ, [`Self::advance_in`]); `Err` with the last failure when none
    /// converges (self unchanged).
    pub fn advance(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
    ) -> Result<Advance, String> {
        self.advance_from(p, length, h, activation, 1)
    }

    /// [`Self::advance`] trying `first`, 2 `first`, … up to [`MAX_SUBSTEPS`]
    /// substeps (`first` one of [`Self::advance`]'s counts, a power of
    /// two): what keeps several end lengths of one step on the same map
    /// (the musculotendon unit's trials).
    pub fn advance_from(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        first: usize,
    ) -> Result<Advance, String> {
        let mut last_error = String::new();
        let mut n = first.max(1);
        while n <= MAX_SUBSTEPS {
            match self.advance_in(p, length, h, activation, n, Budget::for_step(&self.disc)) {
                Ok(done) => return Ok(done),
                Err(e) => last_error = e,
            }
            n *= 2;
        }
        Err(format!(
            "the step to length {length} m did not converge, even in {MAX_SUBSTEPS} substeps: {last_error}"
        ))
    }

    /// The step of [`Self::advance`] in exactly `n` equal substeps (length
    /// linear in τ, the level `activation(τ)` at each substep's ends);
    /// `Err` with the failure of the first substep that does not converge.
    /// With `n` fixed this is a smooth map of the step's inputs, which
    /// the directional derivatives of a substepped step differentiate. All
    /// substeps share `budget` ([`Budget::for_step`] for a step).
    pub fn advance_in(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        n: usize,
        budget: Budget,
    ) -> Result<Advance, String> {
        let disc = &self.disc;
        let mut last_error = String::new();
        let hs = h / n as f64;
        let mut x = self.x.clone();
        let mut hist = self.history.clone();
        let mut cache = self.tangent.clone();
        let mut trend = self.trend.clone();
        let mut l_prev = self.length;
        let mut iterations = 0;
        let mut factorizations = 0;
        let mut residuals = 0;
        let mut done = None;
        for i in 1..=n {
            let tau = h * i as f64 / n as f64;
            let l = self.length + (length - self.length) * i as f64 / n as f64;
            let rate = FibreRate::Step { h: hs };
            let a_start = activation(h * (i - 1) as f64 / n as f64);
            let a_end = activation(tau);
            let input = StepInput {
                x: &x,
                length_start: l_prev,
                length: l,
                activation_start: a_start,
                activation: a_end,
                start: &hist,
                rate,
                trend: Some(&trend),
                tolerance: self.tolerance,
                budget: &budget,
            };
            // Continuation (a path in the inputs, same physics) on the
            // whole step and its halves, and on a substep that takes a
            // jump of the level; finer substeps in time without it, so
            // that a hopeless step ends in bounded work.
            let jump = (a_end - a_start).abs() > CONTINUED_LEVEL_CHANGE
                && unsplittable_jump(activation, h, tau - hs, hs);
            let solved = if n <= CONTINUED_SUBSTEPS || jump {
                disc.solve_step_continued(p, &input, cache.take())
            } else {
                disc.solve_step(p, &input, cache.take())
            };
            match solved {
                Ok(Solved {
                    solution: s,
                    cache: c,
                    contraction,
                }) => {
                    iterations += s.iterations;
                    factorizations += s.factorizations;
                    residuals += s.residuals;
                    let new_hist: Vec<FibreHistory> =
                        s.evaluation.elements.iter().map(|e| e.history).collect();
                    if let Some((e, err)) =
                        s.evaluation
                            .elements
                            .iter()
                            .enumerate()
                            .find_map(|(e, el)| {
                                el.history
                                    .check_physical(p.k, el.lambda_f)
                                    .err()
                                    .map(|m| (e, m))
                            })
                    {
                        last_error = format!("element {e}: {err}");
                        done = None;
                        break;
                    }
                    trend = trend.push(
                        Increment {
                            dx: s.x.iter().zip(&x).map(|(a, b)| a - b).collect(),
                            dl: l - l_prev,
                            da: a_end - a_start,
                            h: hs,
                        },
                        contraction,
                    );
                    x = s.x.clone();
                    l_prev = l;
                    cache = Some(c);
                    let start = std::mem::replace(&mut hist, new_hist);
                    done = Some((s, start, rate, a_end));
                }
                Err(e) => {
                    last_error = e;
                    done = None;
                    break;
                }
            }
        }
        if let Some((solution, start, rate, activation)) = done {
            return Ok(Advance {
                muscle: Muscle {
                    disc: disc.clone(),
                    x,
                    history: hist,
                    length,
                    tangent: cache,
                    trend,
                    tolerance: self.tolerance,
                },
                solution,
                start,
                rate,
                activation,
                iterations,
                factorizations,
                residuals,
                substeps: n,
                pieces: vec![(h, n)],
            });
        }
        Err(last_error)
    }
}

/// The shortest piece of an error-controlled step, as a fraction of the
/// step: such a piece is accepted whatever its estimate (a jump of the
/// rates — an activation jump with S h ≫ 1, the start of a length ramp —
/// is not resolved further). 2⁻²⁰, not the 1D model's 2⁻⁴⁰: the
/// estimate's rates are differences of solved fibre stretches over the
/// piece, and the equilibrium solve leaves them uncertain by up to its
/// tolerance (~1e-10), which over a piece of h 2⁻²⁰ is a rate of at most
/// ~1e-4/h — small against the CE rates the estimate compares — where
/// over h 2⁻⁴⁰ it would be ~100/h and pollute the next piece's estimate.
pub const FINEST_PIECE: f64 = 1.0 / (1u64 << 20) as f64;

/// The most a rejected piece is shortened by at once (and by how much when
/// its estimate is not finite): the FE muscle's floor of the reduction of
/// [`crate::step_control`].
pub const REDUCTION_FLOOR: f64 = 0.25;

impl Muscle {
    /// The CE rates λ̇m per element of a committed (sub)step that started
    /// from `start` and took `h` (0 for an isometric one): the rates the
    /// next piece's error estimate starts from.
    pub fn ce_rates(&self, start: &[FibreHistory], h: Option<f64>) -> Vec<f64> {
        match h {
            Some(h) => self
                .history
                .iter()
                .zip(start)
                .map(|(e, s)| (e.lambda_m - s.lambda_m) / h)
                .collect(),
            None => vec![0.0; self.history.len()],
        }
    }

    /// Estimated local error of the CE–SEE update over the piece `piece`
    /// taken from this muscle, as SEE stress [Pa]: the largest over the
    /// elements of [`crate::law::hill_fibre::backward_euler_error`], with
    /// the rates `rates` at the piece's start and its backward-Euler rates
    /// at the end (returned, for the next piece); `levels` the activation
    /// level at the piece's ends. No error where the CE can carry nothing
    /// at the end (σ0 a f_λ = 0: σ_s = 0 exactly), nor where the SEE is
    /// slack at both ends (λs ≤ 1: the CE follows the kinematics, no ODE).
    pub fn piece_error(
        &self,
        p: &Params,
        piece: &Advance,
        rates: &[f64],
        levels: (f64, f64),
    ) -> (f64, Vec<f64>) {
        let h = match piece.rate {
            FibreRate::Step { h } => h,
            FibreRate::Isometric => return (0.0, vec![0.0; rates.len()]),
        };
        let cap = p.fv_max() * p.sigma0 * levels.0.max(levels.1);
        let end_rates = piece.muscle.ce_rates(&piece.start, Some(h));
        let mut worst = 0.0f64;
        for (((e, before), &r0), &r1) in piece
            .solution
            .evaluation
            .elements
            .iter()
            .zip(&self.history)
            .zip(rates)
            .zip(&end_rates)
        {
            let drive = p.sigma0 * levels.1 * force_length(e.lambda_f, p.lambda_opt).0;
            let slack = e.history.lambda_s <= 1.0 && before.lambda_s <= 1.0;
            if drive == 0.0 || slack {
                continue;
            }
            // NaN propagates (max ignores it): make it the worst.
            let err = backward_euler_error(p, cap, r0, r1, h);
            worst = if err.is_nan() {
                f64::INFINITY
            } else {
                worst.max(err)
            };
        }
        (worst, end_rates)
    }

    /// The step of [`Self::advance`] in pieces whose estimated local error
    /// of the CE–SEE update ([`Self::piece_error`]) stays below `tolerance`
    /// (SEE stress, Pa), by the policy of [`crate::step_control`]: the whole
    /// step first; a rejected piece is tried again shorter by
    /// [`step_control::reduction`], but by no less than [`REDUCTION_FLOOR`];
    /// after an accepted piece the next may grow by [`step_control::growth`].
    /// The pieces are placed continuously in the step. A piece of
    /// [`FINEST_PIECE`] h is accepted whatever its estimate, and after
    /// [`MAX_CONTROLLED_TRIES`] tries the rest of the step is one piece.
    /// Each piece is [`Self::advance`] over its part of
    /// the step (length linear in time, the level `activation(τ)`), with
    /// its own substeps when Newton needs them. `rates`: the CE rates at
    /// the step's start ([`Self::ce_rates`] of the last step). `Err` when a
    /// piece does not converge (self unchanged).
    pub fn advance_controlled(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        tolerance: f64,
        rates: &[f64],
    ) -> Result<Advance, String> {
        let at = |tau: f64| self.length + (length - self.length) * (tau / h).min(1.0);
        // The muscle the next piece starts from: self, then the last
        // accepted piece's.
        let mut accepted: Option<Muscle> = None;
        let mut rates = rates.to_vec();
        let (mut tau, mut hs) = (0.0, h);
        let (mut pieces, mut tries) = (Vec::new(), 0);
        let (mut iterations, mut factorizations, mut residuals, mut substeps) = (0, 0, 0, 0);
        loop {
            tries += 1;
            let last_try = tries >= MAX_CONTROLLED_TRIES;
            let end = if last_try || tau + hs >= h * (1.0 - 1e-12) {
                h
            } else {
                tau + hs
            };
            let piece_h = end - tau;
            let start = tau;
            let m = accepted.as_ref().unwrap_or(self);
            let piece = m.advance(p, at(end), piece_h, &|s| activation(start + s))?;
            iterations += piece.iterations;
            factorizations += piece.factorizations;
            residuals += piece.residuals;
            let levels = (activation(start), activation(end));
            let (err, end_rates) = m.piece_error(p, &piece, &rates, levels);
            let finest = piece_h <= FINEST_PIECE * h * (1.0 + 1e-9);
            if step_control::accepted(err, tolerance) || finest || last_try {
                substeps += piece.substeps;
                pieces.push((end, piece.substeps));
                rates = end_rates;
                hs = (piece_h * step_control::growth(err, tolerance)).max(FINEST_PIECE * h);
                tau = end;
                if end == h {
                    return Ok(Advance {
                        iterations,
                        factorizations,
                        residuals,
                        substeps,
                        pieces,
                        ..piece
                    });
                }
                accepted = Some(piece.muscle);
            } else {
                let shrink = step_control::reduction(err, tolerance)
                    .map_or(REDUCTION_FLOOR, |r| r.max(REDUCTION_FLOOR));
                hs = (piece_h * shrink).max(FINEST_PIECE * h);
            }
        }
    }

    /// The step in the pieces `pieces` ([`Advance::pieces`]: end times, the
    /// last `h`, and each piece's equal substeps), without error control:
    /// with the pieces fixed, a smooth map of the step's inputs, which the
    /// directional derivatives of a step in more than one substep
    /// differentiate.
    pub fn advance_pieces(
        &self,
        p: &Params,
        length: f64,
        h: f64,
        activation: &dyn Fn(f64) -> f64,
        pieces: &[(f64, usize)],
    ) -> Result<Advance, String> {
        let at = |tau: f64| self.length + (length - self.length) * (tau / h).min(1.0);
        let mut tau = 0.0;
        let mut done: Option<Advance> = None;
        for &(end, n) in pieces {
            let start = tau;
            let m = done.as_ref().map_or(self, |d| &d.muscle);
            let piece = m.advance_in(
                p,
                at(end),
                end - start,
                &|s| activation(start + s),
                n,
                Budget::for_step(&m.disc),
            )?;
            tau = end;
            done = Some(piece);
        }
        done.ok_or_else(|| "a step of no pieces".to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::mesh::{cylinder, FibreLayout, Resolution};
    use crate::law::{solve_uniaxial, Uniaxial};

    fn patch(n_axial: usize, n_radial: usize) -> Arc<Discretization> {
        Arc::new(
            Discretization::new(cylinder(0.01, 0.003, n_axial, n_radial), Ends::Sliding).unwrap(),
        )
    }

    /// The FE force on a sliding-end cylinder vs the 1D reduction's nominal
    /// stress × the cylinder's mesh cross-section (the inscribed polygon).
    fn area_of(d: &Discretization) -> f64 {
        d.reference_volume() / d.l0
    }

    #[test]
    fn homogeneous_patch_reproduces_the_uniaxial_reduction_passive() {
        let p = Params::default();
        let d = patch(3, 2);
        for stretch in [0.9, 1.05, 1.2] {
            let (_, s) = Muscle::isometric(d.clone(), &p, stretch * d.l0, 0.0).unwrap();
            let f = d.reaction(&s.evaluation.forces);
            let u: Uniaxial = solve_uniaxial(
                &p,
                stretch,
                0.0,
                &FibreHistory::REST,
                FibreRate::Isometric,
                1.0,
            )
            .unwrap();
            let f1 = u.nominal_stress() * area_of(&d);
            assert!(
                ((f - f1) / f1).abs() < 1e-6,
                "stretch {stretch}: FE {f} vs 1D {f1} (rel {:e})",
                (f - f1) / f1
            );
            // Homogeneous: every element has the same J and fibre stretch.
            let (jmin, jmax) = s
                .evaluation
                .elements
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), e| {
                    (a.min(e.j), b.max(e.j))
                });
            assert!((jmax - jmin) < 1e-9, "{jmin} {jmax}");
            assert!(((jmin - u.j) / u.j).abs() < 1e-8, "{jmin} vs {}", u.j);
        }
    }

    /// Active patch: a sequence of steps with the activation rising while
    /// the bar is stretched and released (CE–SEE history advancing in every
    /// element) gives the 1D reduction's force at every step.
    #[test]
    fn homogeneous_patch_reproduces_the_uniaxial_reduction_active() {
        let p = Params::default();
        let d = patch(2, 1);
        let (mut m, _) = Muscle::isometric(d.clone(), &p, d.l0, 0.0).unwrap();
        let mut hist = FibreHistory::REST;
        let mut q = 1.0;
        let h = 1e-3;
        let mut a_prev = 0.0;
        for (k, stretch) in [1.0, 1.02, 1.05, 1.08, 1.06, 1.03].into_iter().enumerate() {
            let a = (0.2 * (k + 1) as f64).min(1.0);
            let a0 = a_prev;
            let r = m
                .advance(&p, stretch * d.l0, h, &|tau| a0 + (a - a0) * tau / h)
                .unwrap();
            let f = d.reaction(&r.solution.evaluation.forces);
            let u = solve_uniaxial(&p, stretch, a, &hist, FibreRate::Step { h }, q).unwrap();
            let f1 = u.nominal_stress() * area_of(&d);
            assert!(
                ((f - f1) / f1).abs() < 1e-6,
                "step {k}: FE {f} vs 1D {f1} (rel {:e})",
                (f - f1) / f1
            );
            let e0 = r.solution.evaluation.elements[0];
            assert!((e0.history.lambda_s - u.fibre.history.lambda_s).abs() < 1e-9);
            hist = u.fibre.history;
            q = u.q;
            a_prev = a;
            m = r.muscle;
        }
    }

    #[test]
    fn force_derivatives_match_finite_differences() {
        let p = Params::default();
        let d = Arc::new(
            Discretization::fusiform(
                0.05,
                crate::specimen::MEAN_AREA,
                Resolution {
                    n_axial: 6,
                    n_radial: 1,
                },
                FibreLayout::Axial,
                Ends::Clamped,
            )
            .unwrap(),
        );
        let (m, _) = Muscle::isometric(d.clone(), &p, 0.05 * 1.1, 0.3).unwrap();
        let h = 1e-3;
        let step = |l: f64, a: f64| m.advance(&p, l, h, &|_| a).unwrap();
        let (l, a) = (0.05 * 1.12, 0.5);
        let base = step(l, a);
        let ev = d
            .evaluate(&p, &base.solution.x, a, &base.start, base.rate, true)
            .unwrap();
        let (dfdl, dfda) = d.force_derivatives(&ev).unwrap();
        let f = |s: &Advance| d.reaction(&s.solution.evaluation.forces);
        let el = 1e-7;
        let fd_l = (f(&step(l + el, a)) - f(&step(l - el, a))) / (2.0 * el);
        let ea = 1e-6;
        let fd_a = (f(&step(l, a + ea)) - f(&step(l, a - ea))) / (2.0 * ea);
        assert!(
            ((dfdl - fd_l) / fd_l).abs() < 1e-5,
            "dF/dL {dfdl} vs fd {fd_l}"
        );
        assert!(
            ((dfda - fd_a) / fd_a).abs() < 1e-5,
            "dF/da {dfda} vs fd {fd_a}"
        );
    }
}

#[cfg(test)]
mod solver_tests;
