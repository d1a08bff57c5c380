//! The step map of the 1D muscle and its error control: the state at the
//! end of a step from the committed one (`Muscle1D::solve_step`), solved in
//! pieces on a dyadic grid of the step, each one backward-Euler step of the
//! CE–SEE update (MODEL_NOTES "Hill fibre") inside the uniaxial solve
//! (MODEL_NOTES "The 1D Hill reduction"), with the total sensitivities of the
//! end state to the inputs chained through the pieces. Whether a piece is
//! accepted and how much the next grows or a rejected one shrinks is
//! [`crate::step_control`]'s policy on [`piece_error`]'s estimate; this file
//! only places the pieces on the grid. A piece's end stretch is prescribed
//! (linear over the step) or, through the [`PieceEnd`] hook, solved with the
//! piece (the musculotendon unit's equilibrium). Paths without a CE–SEE solve: a
//! muscle without the contractile element (`solve_passive`) and
//! a step at rest (`solve_rest`), bit for bit the general path's
//! one piece.

use super::error::Discard;
use super::muscle::Muscle1D;
use super::outputs::{IN_ACTIVATION, IN_LENGTH, N_IN};
use super::predictor::Predictor;
use crate::law::force_length::force_length;
use crate::law::force_velocity::branch_included;
use crate::law::hill_fibre::{backward_euler_error, ce_stretch};
use crate::law::uniaxial::Sensitivity;
use crate::law::{solve_uniaxial_with, Components, FibreHistory, FibreRate, Params, Uniaxial};
use crate::step_control::{self, MAX_CONTROLLED_TRIES};

/// Estimated local error of the backward-Euler CE–SEE update over a piece of
/// length `hs`, as SEE stress, Pa. `start` is the piece's start: the CE
/// rate of the piece before it and the activation level; `u` and `a` the
/// solution at the piece's end, `stretch_rate` the stretch rate λ̇ over it.
///
/// The CE stretch λm obeys the ODE λ̇m = r(t, λm) defined by
/// σ_s(λs) = σ0 a f_λ f_v(λ̇m) with λs = ((1 + k) λ̄f − λm)/k; each piece
/// takes one backward-Euler step of it. The local error of backward Euler is
/// (hs/2)(r(end) − r(start)) + O(hs³) (its difference from the trapezoidal
/// rule). The rate at the end is the piece's backward-Euler rate; the rate at
/// the start is the previous piece's, which satisfies the ODE at the start
/// exactly. λ̄f is given, so the error of λs is that of λm over k, and of
/// σ_s, σ_s' = alpha (σ_s + beta) times that. The special cases:
/// - the CE can carry nothing at the end (σ0 a f_λ = 0): σ_s = 0 there,
///   exactly as in the exact solution: no error;
/// - the SEE ends the piece slack (σ_s = 0 with σ0 a f_λ > 0: the fibre
///   shortens faster than the CE can, lambda_dot_min): exact if it is still
///   slack at the end, i.e. if the CE rate the kinematics ask for there,
///   (1 + k) dλ̄f/dt = (1 + k) (dλ̄f/dλ) λ̇ (`stretch_rate` = λ̇ over the
///   piece), is still below lambda_dot_min. If not — the shortening stopped
///   inside the piece, as when the volume takes up the length change — the
///   SEE has taken up load again by the end, and the error is estimated as
///   below with that kinematic rate in place of the backward-Euler one;
/// - a piece that starts from a slack SEE takes the rate the kinematics set
///   there ((1 + k) dλ̄f/dt, below lambda_dot_min) as its start rate: where
///   the SEE takes up load inside the piece the estimate is large, and the
///   piece is cut until that moment is resolved (the rate is continuous
///   there when λ̄f(t) is smooth);
/// - σ_s stays within [0, f_v,max σ0 a], so no error exceeds that range.
pub fn piece_error(
    p: &Params,
    start: (f64, f64),
    u: &Uniaxial,
    a: f64,
    stretch_rate: f64,
    hs: f64,
) -> f64 {
    let (start_rate, start_a) = start;
    let f = &u.fibre;
    let mut rate = f.lambda_dot_m;
    if f.sigma_see == 0.0 {
        let drive = p.sigma0 * a * force_length(u.lambda_f, p.lambda_opt).0;
        if drive == 0.0 {
            return 0.0;
        }
        let kinematic = (1.0 + p.k) * u.d_dlambda.lambda_f * stretch_rate;
        if kinematic <= p.lambda_dot_min {
            return 0.0;
        }
        rate = kinematic;
    }
    // The largest SEE stress the CE can hold over the piece.
    let cap = p.fv_max() * p.sigma0 * a.max(start_a);
    backward_euler_error(p, cap, start_rate, rate, hs)
}

/// The tolerance [`MAX_CONTROLLED_TRIES`] is sized for (the FMUs' default
/// `substep_tolerance`, relative to sigma0).
const BOUND_TOLERANCE: f64 = 1e-3;

/// Largest factor by which a tighter tolerance raises the work bound (reached
/// at a tolerance of about 1e-6).
const MAX_BOUND_FACTOR: f64 = 32.0;

/// The work bound of one step at relative tolerance `rtol`: the number of
/// tries after which the rest of the step is one piece. Backward Euler's
/// local error is second order in the piece length, so the pieces a
/// trajectory needs grow as rtol^(−1/2): [`MAX_CONTROLLED_TRIES`] at
/// [`BOUND_TOLERANCE`] and above, scaled by (BOUND_TOLERANCE/rtol)^(1/2) below
/// it (at most [`MAX_BOUND_FACTOR`] times), so that a tighter tolerance
/// keeps the bound as far above the need as the default does instead of
/// leaving the step's rest uncontrolled.
pub(crate) fn max_tries(rtol: f64) -> u32 {
    let factor = (BOUND_TOLERANCE / rtol).sqrt();
    if factor > 1.0 {
        (f64::from(MAX_CONTROLLED_TRIES) * factor.min(MAX_BOUND_FACTOR)) as u32
    } else {
        MAX_CONTROLLED_TRIES
    }
}

/// How many halvings bring a piece within `factor` (< 1) of its length:
/// the smallest n with 2^(−n) ≤ factor (a reduction placed on the dyadic
/// grid).
fn halvings(factor: f64) -> u32 {
    let mut n = 0;
    let mut f = 1.0;
    while f > factor && n < 64 {
        f *= 0.5;
        n += 1;
    }
    n
}

/// How many doublings fit in `factor` (≥ 0): the largest n with 2^n ≤ factor
/// (a growth placed on the dyadic grid).
fn doublings(factor: f64) -> u32 {
    let mut n = 0;
    let mut f = 2.0;
    while f <= factor && n < 64 {
        f *= 2.0;
        n += 1;
    }
    n
}

/// Σ cᵢ sᵢ over the terms with cᵢ ≠ 0: the chain rule through a piece.
pub(crate) fn combine(terms: &[(&Sensitivity, f64)]) -> Sensitivity {
    let mut r = Sensitivity::default();
    for &(s, c) in terms {
        if c != 0.0 {
            r.q += c * s.q;
            r.j += c * s.j;
            r.mu += c * s.mu;
            r.tau11 += c * s.tau11;
            r.lambda_f += c * s.lambda_f;
            r.lambda_s += c * s.lambda_s;
        }
    }
    r
}

/// A solved step (`Muscle1D::solve_step`): the state at its end, the level
/// and ∂a/∂u there, the total sensitivities of the end state with respect to
/// the inputs (activation, length), the end stretch's total derivatives
/// with respect to them, and the solver counts.
pub(crate) struct Stepped {
    pub(crate) u: Uniaxial,
    pub(crate) a: f64,
    pub(crate) da_du: f64,
    pub(crate) sens: [Sensitivity; N_IN],
    pub(crate) dlambda: [f64; N_IN],
    pub(crate) stats: StepStatistics,
}

/// Where a piece of the step ends: the hook that lets a step's end stretch
/// be solved with the muscle's response (the musculotendon unit's
/// equilibrium, [`super::musculotendon`]) instead of prescribed. The plain
/// muscle's [`Prescribed`] end is not coupled: its pieces are exactly the
/// step map of the module docs.
pub(crate) trait PieceEnd {
    /// Whether the end stretch depends on the muscle's response.
    const COUPLED: bool;
    /// The stretch at the end of the piece from fraction `from` to `frac`
    /// of the step (`last`: the step's end): the prescribed one from the
    /// step's start stretch `lambda`, or (coupled) the solve's first guess
    /// from the piece's start stretch `lambda`.
    fn stretch(&self, lambda: f64, from: f64, frac: f64, last: bool) -> f64;
    /// A coupled piece: the piece's law `law(λ)` (its uniaxial solve ending
    /// at λ) evaluated where the end condition holds, starting from
    /// `guess`; the last evaluation is the one returned.
    fn solve<F>(&self, frac: f64, last: bool, guess: f64, law: F) -> Result<Solved, Discard>
    where
        F: FnMut(f64) -> Result<Uniaxial, Discard>;
}

/// A coupled piece's end ([`PieceEnd::solve`]): the solve there, and how its
/// stretch moves with the length input at fixed muscle response
/// (`dlambda_dinput`, d λ/d input) and with the muscle's axial Kirchhoff
/// stress at fixed stretch (`dlambda_dtau`, d λ/d τ11).
pub(crate) struct Solved {
    pub(crate) u: Uniaxial,
    pub(crate) dlambda_dinput: f64,
    pub(crate) dlambda_dtau: f64,
}

/// The plain muscle's end: the stretch moves linearly to `lambda_end`.
pub(crate) struct Prescribed(pub(crate) f64);

impl PieceEnd for Prescribed {
    const COUPLED: bool = false;

    #[inline(always)]
    fn stretch(&self, lambda: f64, _from: f64, frac: f64, last: bool) -> f64 {
        if last {
            self.0
        } else {
            lambda + (self.0 - lambda) * frac
        }
    }

    #[inline(always)]
    fn solve<F>(&self, _frac: f64, _last: bool, guess: f64, mut law: F) -> Result<Solved, Discard>
    where
        F: FnMut(f64) -> Result<Uniaxial, Discard>,
    {
        Ok(Solved {
            u: law(guess)?,
            dlambda_dinput: 0.0,
            dlambda_dtau: 0.0,
        })
    }
}

/// Solver counts of the last completed step (or of the initialization), for
/// diagnostics such as the stability matrix (`cargo run --release --example
/// stability`). Not part of the muscle's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepStatistics {
    /// Substeps the step was solved in (1: in one piece; see the module
    /// docs).
    pub substeps: u32,
    /// Substeps tried and rejected by the error estimate (their solves are
    /// counted in the iterations below).
    pub rejected_substeps: u32,
    /// Newton iterations of the lateral solve, summed over the substeps
    /// (each one evaluation of the law; a count above 100 in one solve means
    /// the bracketed fallback ran).
    pub lateral_iterations: u32,
    /// Iterations of the CE–SEE solve, summed over every evaluation of the law.
    pub ce_iterations: u32,
    /// The step was taken at rest ([`Muscle1D::set_rest_shortcut`]):
    /// activation command and level exactly 0, no CE–SEE solve, one piece.
    pub at_rest: bool,
}

impl<C: Components> Muscle1D<C> {
    /// The step from the committed state to stretch `lambda_end` over `h`,
    /// in substeps whose size the error estimate of the CE–SEE update
    /// controls ([`piece_error`]). Within the step the stretch moves linearly
    /// to `lambda_end` (the co-simulation convention) and the activation level
    /// follows [`Self::level`]; each substep is the backward-Euler step of
    /// MODEL_NOTES over its own length. The first try is the whole step. A
    /// substep whose estimate exceeds `substep_tolerance`·sigma0 is tried
    /// again shorter, and after an accepted one the next may be longer, by
    /// [`step_control`]'s policy (h_new = h · 0.9 (tol/err)^(1/2), the
    /// controller of a first-order method), rounded down to the dyadic sizes
    /// h/2^k that fit the dyadic grid of the step, so that the substeps tile the step exactly and are piecewise
    /// constant in the inputs (the step map is then smooth between switches
    /// of the pattern, and its partial derivatives — chained through the
    /// substeps — are those of the map). After [`max_tries`] tries (the work bound,
    /// [`MAX_CONTROLLED_TRIES`] at the default tolerance) the rest
    /// of the step is taken in one piece (backward Euler is stable for any
    /// length: the result stays bounded, only less accurate). `a_end` is the
    /// level at the end of the step. Changes nothing (the caller commits).
    #[inline(always)]
    pub(crate) fn solve_step(
        &self,
        h: f64,
        lambda_end: f64,
        a_end: (f64, f64),
    ) -> Result<Stepped, Discard> {
        self.solve_step_to(h, &Prescribed(lambda_end), a_end)
    }

    /// [`Self::solve_step`] with the pieces' ends given by `ends`: for a
    /// coupled end ([`PieceEnd::COUPLED`]) each piece's end stretch is
    /// solved with the piece's law, and the chain rule through the piece
    /// takes its stretch's dependence on the inputs, the level and the
    /// history (d λ_j = dλ/d input + dλ/dτ11 · ∂τ11/∂(a, λm) at fixed λ).
    /// A coupled end takes the general path (no shortcuts: those are for
    /// a prescribed stretch).
    #[inline(always)]
    pub(crate) fn solve_step_to<E: PieceEnd>(
        &self,
        h: f64,
        ends: &E,
        a_end: (f64, f64),
    ) -> Result<Stepped, Discard> {
        let lambda_end = ends.stretch(self.lambda, 0.0, 1.0, true);
        if !C::CONTRACTILE && !E::COUPLED {
            return self.solve_passive(h, lambda_end);
        }
        // At rest — command 0 (not rising) and level 0, so the level is 0
        // throughout the step — the CE carries nothing (σ0 a f_λ = 0): no
        // CE–SEE solve and an error estimate of exactly 0, hence one piece.
        if !E::COUPLED
            && self.rest_shortcut.0
            && self.command == 0.0
            && self.command_rate <= 0.0
            && self.activation_level == 0.0
            && a_end.0 == 0.0
        {
            return self.solve_rest(h, lambda_end, a_end.1);
        }
        // Positions within the step in units of h / 2^FINEST.
        const FINEST: u32 = 40;
        const WHOLE: u64 = 1 << FINEST;
        let p = &self.params;
        let tol = self.substep_tolerance * p.sigma0;
        let (lambda0, a0) = (self.lambda, self.activation_level);
        let mut stats = StepStatistics::default();
        // The start of the current piece: position in the step, stretch,
        // level, fibre history, CE rate and the last accepted solve.
        let (mut pos, mut lam, mut a) = (0u64, lambda0, a0);
        let (mut hist, mut rate) = (self.history, self.ce_rate);
        // The last accepted piece: (q, λs) at its start and end, its length.
        let mut prev: Option<([f64; 2], [f64; 2], f64)> = None;
        // d λm / d(input) of the history (the start of the piece): how the
        // earlier pieces made it depend on this step's inputs.
        let mut chain = [0.0; 2];
        // The piece is h / 2^level long.
        let mut level = 0u32;
        let mut tries = 0u32;
        let bound = max_tries(self.substep_tolerance);
        loop {
            tries += 1;
            let forced = tries >= bound;
            let end = if forced {
                WHOLE
            } else {
                pos + (WHOLE >> level)
            };
            let last = end == WHOLE;
            let frac = end as f64 / WHOLE as f64;
            let hs_j = if forced {
                h - h * (pos as f64 / WHOLE as f64)
            } else {
                h / (1u64 << level) as f64
            };
            // Prescribed: linear over the whole step; coupled: the guess
            // from the piece's start.
            let from = if E::COUPLED { lam } else { lambda0 };
            let lam_j = ends.stretch(from, pos as f64 / WHOLE as f64, frac, last);
            let (a_j, da_du_j) = if last {
                a_end
            } else {
                let tau = h * frac;
                self.level(tau, (-p.s * tau).exp())
            };
            let (dl, da) = (lam_j - lam, a_j - a);
            // Starting points only (they change the cost, not the result).
            let (q_guess, ls_guess) = match &prev {
                None => (
                    Predictor::predict(&self.predict.q, self.q, dl, da, hs_j),
                    Predictor::predict(&self.predict.lambda_s, hist.lambda_s, dl, da, hs_j),
                ),
                // Linear in time from the last piece.
                Some((x0, x1, hp)) => {
                    let r = hs_j / hp;
                    (x1[0] + (x1[0] - x0[0]) * r, x1[1] + (x1[1] - x0[1]) * r)
                }
            };
            let start = FibreHistory {
                // The CE–SEE solve's starting point (module docs of hill_fibre).
                lambda_s: ls_guess.max(1.0),
                lambda_m: hist.lambda_m,
            };
            let law = |lam_j: f64| {
                solve_uniaxial_with::<C>(
                    p,
                    lam_j,
                    a_j,
                    &start,
                    FibreRate::Step { h: hs_j },
                    q_guess,
                )
                .map_err(|e| {
                    Discard::Unsolvable(self.unsolvable_step(
                        lam_j * self.l0,
                        lam_j - lam,
                        hs_j,
                        &e.0,
                    ))
                })
            };
            let Solved {
                u,
                dlambda_dinput,
                dlambda_dtau,
            } = ends.solve(frac, last, lam_j, law)?;
            // A coupled end settles where its condition holds.
            let (lam_j, dl) = if E::COUPLED {
                (u.lambda, u.lambda - lam)
            } else {
                (lam_j, dl)
            };
            stats.lateral_iterations = stats.lateral_iterations.saturating_add(u.iterations);
            stats.ce_iterations = stats.ce_iterations.saturating_add(u.ce_iterations);
            // Without the CE the step map has no history: one piece, exact.
            let err = if C::CONTRACTILE {
                piece_error(p, (rate, a), &u, a_j, dl / hs_j, hs_j)
            } else {
                0.0
            };
            // A piece of h/2^FINEST is taken whatever its estimate (an event
            // faster than that, like a SEE snapping slack, is not resolved by
            // shorter pieces), and so is one that cannot be halved in binary64
            // (a step of a few ulps).
            // Without substeps every step is one piece.
            let acceptable = step_control::accepted(err, tol) || !self.adaptive_substeps;
            if !forced && level < FINEST && hs_j * 0.5 >= f64::MIN_POSITIVE && !acceptable {
                // Too large (or not finite): the same start, a shorter piece,
                // at least half as long.
                stats.rejected_substeps += 1;
                // A reduction is at most 0.9: at least one halving.
                level += match step_control::reduction(err, tol) {
                    Some(factor) => halvings(factor),
                    None => 4,
                };
                level = level.min(FINEST);
                continue;
            }
            u.fibre
                .history
                .check_physical(p.k, u.lambda_f)
                .map_err(|e| Discard::Unsolvable(format!("length = {} m: {e}", lam_j * self.l0)))?;
            // Chain rule through the piece: its state depends on the inputs
            // through its stretch (d λ_j/dL = frac/L0), its level (∂a_j/∂u)
            // and the history's CE stretch (`chain`).
            self.check_fv_branch(&u)?;
            let mut drivers = [[da_du_j, 0.0], [0.0, frac / self.l0]];
            let mut sens = [Sensitivity::default(); 2];
            for c in [IN_ACTIVATION, IN_LENGTH] {
                if c == IN_ACTIVATION && !C::ACTIVATION_INPUT {
                    continue; // no activation input: no such partial
                }
                if E::COUPLED {
                    // The end stretch moves with the input, and with the
                    // muscle's stress through the level and the history.
                    let dtau =
                        u.d_dactivation.tau11 * drivers[c][0] + u.d_dhistory.tau11 * chain[c];
                    let dinput = if c == IN_LENGTH { dlambda_dinput } else { 0.0 };
                    drivers[c][1] = dinput + dlambda_dtau * dtau;
                }
                sens[c] = combine(&[
                    (&u.d_dactivation, drivers[c][0]),
                    (&u.d_dlambda, drivers[c][1]),
                    (&u.d_dhistory, chain[c]),
                ]);
                chain[c] = ce_stretch(p.k, sens[c].lambda_f, sens[c].lambda_s);
            }
            stats.substeps += 1;
            if last {
                return Ok(Stepped {
                    u,
                    a: a_j,
                    da_du: da_du_j,
                    sens,
                    dlambda: [drivers[0][1], drivers[1][1]],
                    stats,
                });
            }
            // The next piece: as much longer as the policy allows (at most
            // 4x: two doublings) and the grid of its size admits (its start
            // a multiple of it).
            let mut next = level.saturating_sub(doublings(step_control::growth(err, tol)));
            while next < level && end % (WHOLE >> next) != 0 {
                next += 1;
            }
            level = next;
            (pos, lam, a) = (end, lam_j, a_j);
            (hist, rate) = (u.fibre.history, u.fibre.lambda_dot_m);
            if !rate.is_finite() {
                rate = if rate.is_nan() {
                    0.0
                } else {
                    rate.clamp(-f64::MAX, f64::MAX)
                };
            }
            let (q0, ls0) = match prev {
                Some((_, x1, _)) => (x1[0], x1[1]),
                None => (self.q, self.history.lambda_s),
            };
            prev = Some(([q0, ls0], [u.q, u.fibre.history.lambda_s], hs_j));
        }
    }

    /// The lateral solve of a step at zero drive (activation 0, MODEL_NOTES
    /// "Hill fibre" with σ0 a f_λ = 0) to `lambda_end`, from the committed
    /// history and the predicted q: what [`Self::solve_passive`] and
    /// [`Self::solve_rest`] share, so that both give the general path's one
    /// piece bit for bit.
    #[inline(always)]
    fn solve_at_zero_drive(&self, h: f64, lambda_end: f64) -> Result<Uniaxial, Discard> {
        let q_guess = Predictor::predict(&self.predict.q, self.q, lambda_end - self.lambda, 0.0, h);
        solve_uniaxial_with::<C>(
            &self.params,
            lambda_end,
            0.0,
            &self.history,
            FibreRate::Step { h },
            q_guess,
        )
        .map_err(|e| {
            Discard::Unsolvable(self.unsolvable_step(
                lambda_end * self.l0,
                lambda_end - self.lambda,
                h,
                &e.0,
            ))
        })
    }

    /// The step of a muscle without the contractile element: the fibre is the
    /// parallel element alone, so the state at the end of the step depends
    /// on the end stretch only (no history, no activation: MODEL_NOTES "Hill
    /// fibre" with σ0 a f_λ = 0) — one lateral solve on the passive law, no
    /// substeps (the error estimate of the CE–SEE update is exactly 0), no
    /// SEE predictor, no activation or history sensitivities. The lateral
    /// solve starts from the same predicted q as the general path's one
    /// piece, so the result is the complete law's at activation 0, bit for
    /// bit (tests/scenes.rs).
    #[inline(always)]
    fn solve_passive(&self, h: f64, lambda_end: f64) -> Result<Stepped, Discard> {
        let u = self.solve_at_zero_drive(h, lambda_end)?;
        let stats = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: 0,
            at_rest: true,
        };
        let sens = [
            Sensitivity::default(),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        Ok(Stepped {
            u,
            a: 0.0,
            da_du: 0.0,
            sens,
            dlambda: [0.0, 1.0 / self.l0],
            stats,
        })
    }

    /// The step at rest (see [`Self::solve_step`]): the general path's
    /// one piece without what cannot change it — the level within the step
    /// (0), the SEE predictor (the CE–SEE solve is not run at zero drive,
    /// so its starting point is not read), the error estimate (0), the
    /// f_v branch check (σ_s = 0). The same lateral solve from the same
    /// predicted q, hence the same result bit for bit (tests/scenes.rs,
    /// `the_rest_shortcut_changes_nothing`).
    fn solve_rest(&self, h: f64, lambda_end: f64, da_du: f64) -> Result<Stepped, Discard> {
        let p = &self.params;
        let u = self.solve_at_zero_drive(h, lambda_end)?;
        u.fibre
            .history
            .check_physical(p.k, u.lambda_f)
            .map_err(|e| {
                Discard::Unsolvable(format!("length = {} m: {e}", lambda_end * self.l0))
            })?;
        let stats = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: u.ce_iterations,
            at_rest: true,
        };
        let sens = [
            combine(&[(&u.d_dactivation, da_du)]),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        Ok(Stepped {
            u,
            a: 0.0,
            da_du,
            sens,
            dlambda: [0.0, 1.0 / self.l0],
            stats,
        })
    }

    /// Components without one of the f_v branches (eq 12) compute f_v = 1 on
    /// it ([`crate::law::force_velocity::force_velocity_with`]); a step whose
    /// CE–SEE root lies on the absent branch — the CE carrying force while
    /// moving faster than 1e-9 |lambda_dot_min| in that direction, where
    /// f_v would differ from 1 by more than ~1e-9 — is not what the muscle
    /// can compute: it is discarded ([`Discard::AbsentFvBranch`]). (Below
    /// that rate the round-off of an isometric hold stays inside.)
    fn check_fv_branch(&self, u: &Uniaxial) -> Result<(), Discard> {
        if !C::CONTRACTILE || (C::FV_SHORTENING && C::FV_LENGTHENING) {
            return Ok(());
        }
        let rate = u.fibre.lambda_dot_m;
        let p = &self.params;
        if u.fibre.sigma_see > 0.0
            && !branch_included::<C>(rate)
            && rate.abs() > 1e-9 * p.lambda_dot_min.abs()
        {
            return Err(Discard::AbsentFvBranch {
                rate,
                sigma_see: u.fibre.sigma_see,
            });
        }
        Ok(())
    }
}
