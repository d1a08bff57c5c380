//! The quasi-static equilibrium solve of the FE muscle: Newton's method with
//! a factorised tangent that is reused across iterations and steps while it
//! still converges fast (issue 3, "Formulation and solver").
//!
//! # Why reuse the tangent
//!
//! Forming and factorising the tangent of the default mesh costs about 20
//! residual evaluations; over a 1 ms step of a muscle the tangent changes by
//! ~1e-3 relative. So each iteration solves with the factorisation of a
//! tangent K̃ formed at an earlier configuration (the *anchor*, possibly
//! several steps old) — modified Newton, which converges linearly with rate
//! ρ ≈ ‖K̃⁻¹(K − K̃)‖ — and the tangent is formed afresh at the current
//! iterate when that stops paying: when an iteration contracts the residual
//! by less than [`REFRESH_CONTRACTION`], when the step needs more than
//! [`REFRESH_ITERATIONS`] iterations, or when a stale correction does not
//! decrease the residual at all. With a tangent formed at the current iterate
//! the iteration is Newton's method with a backtracking line search (as
//! before this reuse).
//!
//! # Predictor
//!
//! The step starts from x_n + s Δx_n + v (ΔL − s ΔL_n) + w (Δa − s Δa_n):
//! the last step's increment Δx_n extrapolated to the new step (s = h/h_n),
//! corrected to first order for the part of the input change the
//! extrapolation does not predict, with the anchor's sensitivities v = ∂x/∂L
//! (the moved face pulled by a unit length, the interior following) and
//! w = ∂x/∂a. Without a last step (after initialization) it is
//! x_n + v ΔL + w Δa, the linearised response of the last equilibrium.
//!
//! # Convergence at the predictor
//!
//! The convergence test needs the contraction θ of the iteration, which a
//! step measures with the correction at its first trial x₁ = x₀ + Δx₀:
//! θ = ‖Δx̄₁‖/‖Δx₀‖, then x₁ is accepted when Δx̄₁/(1 − θ) is within the
//! tolerance. On smooth input that is most steps (on the default mesh's
//! passive pull the predictor's Δx₀ is below 1e-10 of the specimen's size in
//! 80 % of the steps, below 1e-9 in 99.8 %), and the
//! solve for Δx̄₁ only measures θ. So the first trial may take its θ from the
//! last steps' measurement with the same reused tangent ([`Contraction`]):
//! at most [`CONTRACTION_STEPS`] steps old, at most [`REFRESH_CONTRACTION`],
//! and doubled (the reused tangent drifts slowly between steps: θ grows by
//! ~0.005 per 1 ms step of the pull). x₁ is then accepted when its estimated
//! error θ/(1 − θ)·Δx₀ is within the tolerance — the iterate the full test
//! accepts in most steps, one linear solve sooner; every
//! [`CONTRACTION_STEPS`]-th step at the latest measures θ again.
//! (Accepting x₀ by Δx₀/(1 − θ) instead would save the residual too, but
//! leaves errors near the tolerance in the increments the predictor
//! extrapolates, and its corrections then grow past it: no gain, measured.)
//!
//! # Pressures
//!
//! When the displacement formulation's Newton fails on a step (below), it is
//! tried once more carrying the nodal pressures p_a as unknowns beside the
//! positions — Newton's method on the mixed problem (forces with pressures
//! p, constraint U_J'(J_a) = p_a), condensed. Because U_J = (J − 1)²/D is
//! quadratic the condensed right-hand side is the displacement residual; the
//! mixed iteration differs only in the pressure it carries:
//! p ← p + α (U_J'(J) + U_J'' ΔJ(Δx) − p), the linearised constraint's (ΔJ linear in Δx,
//! [`Discretization::linearised_pressures`]), instead of U_J'(J(x + αΔx)),
//! which holds the second-order volume change of the correction times 2/D —
//! with D = 1e-9, a correction straining the rims by 1 % changes the volume
//! by ~1e-4 at second order, a pressure error of ~2e5 Pa against stresses of
//! kPa. That pressure enters the tangent's initial-stress part (p̄ v (∇N ⊗
//! ∇N − ∇N ⊗ ∇N)); carried as the volume ratios', it spoils the Newton
//! direction after a large correction, and the convergence radius shrinks
//! with D (a 5 % length jump from rest: 9.6 s of failed attempts,
//! continuation and substeps at D = 1e-9; with this fallback 2.1 s and 139
//! linear solves, 22 of them in the attempt with the pressures as
//! unknowns). It is the fallback, not the first choice: on the
//! small increments of ordinary steps the displacement iteration converges
//! as fast or faster (a 2-iteration step stays a 2-iteration step), so every
//! step it solves is solved exactly as before. The equilibrium is the same:
//! at convergence p = U_J'(J) to the tolerance, and the tangents the FMU's
//! derivatives use are formed at converged states with the volume ratios'
//! pressures.
//!
//! # Determinism
//!
//! What an iteration does depends only on (x, the anchor, the inputs); the
//! factorisation is a function of the anchor (positions, activation level,
//! start history and rate mode) alone. The anchor is part of the muscle's
//! state, so a state saved and restored — even in another process, which
//! rebuilds the factorisation from the anchor — continues bit for bit.

use std::fmt;
use std::sync::{Arc, OnceLock};

use crate::fe::assembly::Factor;
use crate::fe::muscle::{Discretization, Evaluation};
use crate::law::{FibreHistory, FibreRate, Params};

/// Newton iterations per (sub)step before it counts as not converged.
pub const MAX_NEWTON_ITERATIONS: usize = 25;
/// Default tolerance of the convergence test ([`StepInput::tolerance`],
/// `Discretization::converged`): the solution's error estimate moves no
/// node by more than this × the specimen's size and the force by no more than this × the
/// larger of |F| and σ0 A.
pub const RESIDUAL_TOLERANCE: f64 = 1e-10;
/// A correction below this × the specimen's size is at the rounding level of
/// its positions (8 ulps): converged whatever the contraction.
pub const ROUNDING_CORRECTION: f64 = 8.0 * f64::EPSILON;
/// The factorisations one step of the default mesh may spend, over all its
/// attempts ([`Budget`]).
pub const BUDGET_FACTORIZATIONS: usize = 400;
/// Largest number of parts [`Discretization::solve_step_continued`] splits
/// a step's input change into.
pub const MAX_CONTINUATION: usize = 8;
/// Smallest line-search step before a Newton iteration counts as failed.
const MIN_LINE_SEARCH: f64 = 1.0 / 256.0;
/// A reused tangent whose iteration contracts the correction by less than
/// this (θ = ‖Δx̄‖/‖Δx‖ > c) is formed afresh at the next iterate.
pub const REFRESH_CONTRACTION: f64 = 0.25;
/// A step that has taken this many iterations with a reused tangent forms it
/// afresh.
pub const REFRESH_ITERATIONS: usize = 4;
/// Steps a measured contraction of a reused tangent may stand in for the
/// contraction of later steps with that tangent (module docs, "Convergence
/// at the predictor").
pub const CONTRACTION_STEPS: usize = 4;

/// Where a tangent was formed: enough to form it again, bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct Anchor {
    /// Node positions, flattened.
    pub x: Vec<f64>,
    /// Activation level.
    pub activation: f64,
    /// Element fibre histories at the start of the step it was formed in.
    pub start: Vec<FibreHistory>,
    /// Rate mode of that step.
    pub rate: FibreRate,
    /// The nodal pressures of the tangent's initial-stress part, when they
    /// are the iteration's own (module docs, "Pressures"); `None`: those of
    /// the nodal volume ratios at `x`.
    pub pressure: Option<Vec<f64>>,
}

/// A factorised tangent with the sensitivities the predictor uses.
pub struct Tangent {
    pub factor: Factor,
    /// v = ∂x/∂L: K_ff v_f = −K_fp δ, δ the moved face's unit axial motion
    /// (1 at those dofs).
    pub d_length: Vec<f64>,
    /// w = ∂x/∂a at fixed length: K_ff w_f = −(∂R/∂a)_f.
    pub d_activation: Vec<f64>,
    /// K δ on the free dofs (0 on the prescribed ones): how the reaction
    /// force changes with the free dofs (K symmetric).
    pub d_force: Vec<f64>,
}

/// An anchor and, formed on first use, its factorised tangent (shared by
/// every copy of the muscle state that has this anchor).
pub struct TangentCache {
    pub anchor: Anchor,
    built: OnceLock<Result<Tangent, String>>,
}

impl fmt::Debug for TangentCache {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TangentCache")
            .field("activation", &self.anchor.activation)
            .field("rate", &self.anchor.rate)
            .field("built", &self.built.get().map(|r| r.is_ok()))
            .finish()
    }
}

impl TangentCache {
    /// An anchor whose tangent is formed when first needed.
    pub fn new(anchor: Anchor) -> TangentCache {
        TangentCache {
            anchor,
            built: OnceLock::new(),
        }
    }

    /// The factorised tangent at the anchor (formed on first call).
    pub fn tangent(&self, disc: &Discretization, p: &Params) -> Result<&Tangent, String> {
        self.built
            .get_or_init(|| form_tangent(disc, p, &self.anchor))
            .as_ref()
            .map_err(|e| e.clone())
    }
}

/// Form, factorise and differentiate the tangent at `anchor`.
fn form_tangent(disc: &Discretization, p: &Params, anchor: &Anchor) -> Result<Tangent, String> {
    let ev = disc.evaluate_tangent(
        p,
        &anchor.x,
        anchor.activation,
        &anchor.start,
        anchor.rate,
        anchor.pressure.as_deref(),
    )?;
    let values = ev.tangent.as_ref().expect("tangent requested");
    let factor = disc.pattern.factorize(values)?;
    let (d_length, d_activation, d_force) = disc.sensitivities(&ev, &factor);
    Ok(Tangent {
        factor,
        d_length,
        d_activation,
        d_force,
    })
}

/// One committed (sub)step's increments.
#[derive(Clone, Debug, PartialEq)]
pub struct Increment {
    /// x_n − x_{n−1}.
    pub dx: Vec<f64>,
    /// Its length change, activation-level change and step length.
    pub dl: f64,
    pub da: f64,
    pub h: f64,
}

/// Number of past increments the predictor extrapolates from: the
/// increment's rate is extrapolated by the polynomial through the last
/// [`TREND_LENGTH`] rates (quadratic: the positions to third order).
pub const TREND_LENGTH: usize = 3;

/// The contraction θ = ‖Δx̄‖/‖Δx‖ of the reused tangent's iteration, as last
/// measured, and how many steps ago (0: in the last step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contraction {
    pub theta: f64,
    pub age: usize,
}

impl Contraction {
    /// The θ a step may test convergence at its first correction with
    /// (module docs, "Convergence at the predictor"): twice the measured
    /// one, when that is recent and small enough.
    fn stand_in(self) -> Option<f64> {
        (self.age < CONTRACTION_STEPS && self.theta <= REFRESH_CONTRACTION)
            .then_some(2.0 * self.theta)
    }
}

/// The last steps' increments, most recent first (at most
/// [`TREND_LENGTH`]), and the contraction of the tangent they were solved
/// with.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trend {
    pub increments: Vec<Increment>,
    /// The contraction of the tangent of the last step's solution (`None`:
    /// not measured since it was formed).
    pub contraction: Option<Contraction>,
}

impl Trend {
    /// The trend with `inc` as the most recent increment, solved with a
    /// tangent of contraction `contraction`.
    pub fn push(&self, inc: Increment, contraction: Option<Contraction>) -> Trend {
        let mut increments = Vec::with_capacity(TREND_LENGTH);
        increments.push(inc);
        increments.extend(self.increments.iter().take(TREND_LENGTH - 1).cloned());
        Trend {
            increments,
            contraction,
        }
    }

    /// Weights c_i such that the increment of a new step of length `h` is
    /// predicted as Σ c_i Δ_i (Δ_i the i-th most recent increment): the rates
    /// Δ_i / h_i, taken at the middle of their steps, extrapolated by their
    /// interpolating polynomial to the middle of the new step, times h. Uses
    /// the longest run of recent steps whose lengths are within a factor 2
    /// of each other and of h (variable-step extrapolation stays well
    /// conditioned); empty when there is none.
    pub fn weights(&self, h: f64) -> Vec<f64> {
        let mut m = 0;
        let mut prev = h;
        for inc in &self.increments {
            if !(inc.h > 0.0 && (0.5..=2.0).contains(&(inc.h / prev))) {
                break;
            }
            prev = inc.h;
            m += 1;
        }
        // Midpoints of the past steps, relative to the end of the last one.
        let mut nodes = Vec::with_capacity(m);
        let mut end = 0.0;
        for inc in &self.increments[..m] {
            nodes.push(end - 0.5 * inc.h);
            end -= inc.h;
        }
        let target = 0.5 * h;
        (0..m)
            .map(|i| {
                let lagrange: f64 = (0..m)
                    .filter(|&j| j != i)
                    .map(|j| (target - nodes[j]) / (nodes[i] - nodes[j]))
                    .product();
                lagrange * h / self.increments[i].h
            })
            .collect()
    }
}

/// A converged equilibrium.
#[derive(Clone, Debug)]
pub struct Solution {
    pub x: Vec<f64>,
    pub evaluation: Evaluation,
    /// Newton corrections (linear solves) taken.
    pub iterations: usize,
    /// Residual evaluations (without tangent).
    pub residuals: usize,
    /// Tangents formed and factorised.
    pub factorizations: usize,
}

impl Solution {
    /// This equilibrium with the work of the solves that led to it (e.g. the
    /// earlier stages of an initialization) added to its counts.
    pub fn with_counts_added(
        self,
        iterations: usize,
        factorizations: usize,
        residuals: usize,
    ) -> Self {
        Solution {
            iterations: self.iterations + iterations,
            factorizations: self.factorizations + factorizations,
            residuals: self.residuals + residuals,
            ..self
        }
    }
}

/// One (sub)step's problem.
pub struct StepInput<'a> {
    /// Positions of the last equilibrium.
    pub x: &'a [f64],
    /// Its length and the step's end length.
    pub length_start: f64,
    pub length: f64,
    /// Activation level at the start and end of the step.
    pub activation_start: f64,
    pub activation: f64,
    /// Fibre histories at the start of the step and the rate mode.
    pub start: &'a [FibreHistory],
    pub rate: FibreRate,
    /// The last steps' increments (`None`: predict from the sensitivities
    /// alone).
    pub trend: Option<&'a Trend>,
    /// The convergence test's tolerance ([`RESIDUAL_TOLERANCE`]).
    pub tolerance: f64,
    /// The work the whole step may still spend.
    pub budget: &'a Budget,
}

/// A bound on the work of one step, shared by all its attempts
/// (substeps, continuation, fallbacks): so that a step the solver cannot do
/// ends in an error after bounded work rather than after an unbounded
/// search. Counted, not timed, so the outcome is deterministic.
#[derive(Debug)]
pub struct Budget {
    solves: std::cell::Cell<usize>,
    factorizations: std::cell::Cell<usize>,
}

impl Budget {
    /// Work allowed for one step of `disc`: [`BUDGET_FACTORIZATIONS`]
    /// tangent factorisations and ten linear solves per factorisation on a
    /// mesh the size of the default one (1,887 dofs: about 4 s at most), more
    /// on smaller meshes in proportion to the factorisation's cost
    /// (∝ dofs^1.5 for these slender meshes), at most 50 times more.
    pub fn for_step(disc: &Discretization) -> Budget {
        let dofs = 3.0 * disc.n_nodes() as f64;
        let scale = (1887.0 / dofs).powf(1.5).clamp(1.0, 50.0);
        let factorizations = (BUDGET_FACTORIZATIONS as f64 * scale) as usize;
        Budget {
            solves: std::cell::Cell::new(10 * factorizations),
            factorizations: std::cell::Cell::new(factorizations),
        }
    }

    fn charge(cell: &std::cell::Cell<usize>, what: &str) -> Result<(), String> {
        match cell.get() {
            0 => Err(format!("the step's work limit is spent ({what})")),
            n => {
                cell.set(n - 1);
                Ok(())
            }
        }
    }
}

/// A solved (sub)step: the equilibrium and the tangent to use next.
pub struct Solved {
    pub solution: Solution,
    pub cache: Arc<TangentCache>,
    /// The contraction of that tangent's iteration (`None`: not measured
    /// since it was formed).
    pub contraction: Option<Contraction>,
}

impl Discretization {
    /// Solve one (sub)step (module docs): with a trend and a tangent to
    /// reuse, the extrapolating predictor and `Self::iterate`; else, or
    /// when that fails, `Self::robust`.
    pub fn solve_step(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        cache: Option<Arc<TangentCache>>,
    ) -> Result<Solved, String> {
        let h = match input.rate {
            FibreRate::Step { h } => h,
            FibreRate::Isometric => 0.0,
        };
        let weights = input.trend.map_or(Vec::new(), |t| t.weights(h));
        let mut spent = Counts::default();
        let mut first_error = None;
        if let (Some(c), Some(tr), false) = (&cache, input.trend, weights.is_empty()) {
            match self.extrapolated(p, input, tr, &weights, c.clone(), &mut spent) {
                Ok(s) => return Ok(s),
                Err(e) => first_error = Some(e),
            }
        }
        self.robust(p, input, spent).map_err(|e| match first_error {
            Some(f) => format!("{e} (from the extrapolated start: {f})"),
            None => e,
        })
    }

    /// [`Self::solve_step`], and when it fails, continuation: the same step
    /// (same start history, same rate mode — the same backward-Euler step of
    /// the CE–SEE law) solved as a sequence of 2, 4, … [`MAX_CONTINUATION`]
    /// problems whose end length and activation level go linearly from the
    /// step's start values to its end values, each solution the start of the
    /// next. The equilibrium at the end values does not depend on that path
    /// (the step map is a function of the end state and the start history):
    /// the path only guides Newton, e.g. across an activation jump, which
    /// substeps in time cannot split when S·h ≫ 1.
    pub fn solve_step_continued(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        cache: Option<Arc<TangentCache>>,
    ) -> Result<Solved, String> {
        let first = match self.solve_step(p, input, cache) {
            Ok(s) => return Ok(s),
            Err(e) => e,
        };
        let mut last = String::new();
        let mut m = 2;
        while m <= MAX_CONTINUATION {
            let mut x = input.x.to_vec();
            let mut cache = None;
            let mut counts = (0, 0, 0);
            let mut solved = None;
            for i in 1..=m {
                let (u0, u) = ((i - 1) as f64 / m as f64, i as f64 / m as f64);
                let along = |a: f64, b: f64, t: f64| a + (b - a) * t;
                let part = StepInput {
                    x: &x,
                    length_start: along(input.length_start, input.length, u0),
                    length: along(input.length_start, input.length, u),
                    activation_start: along(input.activation_start, input.activation, u0),
                    activation: along(input.activation_start, input.activation, u),
                    start: input.start,
                    rate: input.rate,
                    trend: None,
                    tolerance: input.tolerance,
                    budget: input.budget,
                };
                match self.solve_step(p, &part, cache.take()) {
                    Ok(s) => {
                        counts.0 += s.solution.iterations;
                        counts.1 += s.solution.residuals;
                        counts.2 += s.solution.factorizations;
                        x = s.solution.x.clone();
                        cache = Some(s.cache.clone());
                        solved = Some(s);
                    }
                    Err(e) => {
                        last = e;
                        solved = None;
                        break;
                    }
                }
            }
            if let Some(s) = solved {
                return Ok(Solved {
                    solution: Solution {
                        iterations: counts.0,
                        residuals: counts.1,
                        factorizations: counts.2,
                        ..s.solution
                    },
                    cache: s.cache,
                    contraction: s.contraction,
                });
            }
            m *= 2;
        }
        Err(format!(
            "{first}; by continuation in {MAX_CONTINUATION} parts: {last}"
        ))
    }

    /// The fast path: the last steps' increments extrapolated, corrected to
    /// first order for the input change they do not predict with the reused
    /// tangent's sensitivities (module docs), then `Self::iterate`.
    fn extrapolated(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        trend: &Trend,
        weights: &[f64],
        cache: Arc<TangentCache>,
        spent: &mut Counts,
    ) -> Result<Solved, String> {
        let mut x = input.x.to_vec();
        let (mut pl, mut pa) = (0.0, 0.0);
        for (inc, &c) in trend.increments.iter().zip(weights) {
            for (xi, di) in x.iter_mut().zip(&inc.dx) {
                *xi += c * di;
            }
            pl += c * inc.dl;
            pa += c * inc.da;
        }
        let cl = input.length - input.length_start - pl;
        let ca = input.activation - input.activation_start - pa;
        let t = spent.tangent(&cache, self, p, input.budget)?;
        for ((xi, v), w) in x.iter_mut().zip(&t.d_length).zip(&t.d_activation) {
            *xi += v * cl + w * ca;
        }
        self.apply_prescribed(&mut x, input.length);
        self.iterate(
            p,
            input,
            x,
            cache,
            Mode::Reuse,
            Merit::Natural,
            Pressures::VolumeRatios,
            trend.contraction,
            spent,
        )
    }

    /// −R on the free dofs, 0 on the prescribed ones.
    fn free_negated(&self, forces: &[f64]) -> Vec<f64> {
        forces
            .iter()
            .zip(&self.pattern.prescribed)
            .map(|(f, &pr)| if pr { 0.0 } else { -f })
            .collect()
    }

    /// Newton's method with the tangent of `cache` — reused while it
    /// contracts ([`Mode::Reuse`]) or formed at every iterate
    /// ([`Mode::Fresh`]). From the iterate x with correction Δx = −K̃⁻¹R(x),
    /// a trial x + αΔx is accepted when
    /// - ([`Merit::Natural`], affine-covariant, Deuflhard) its simplified
    ///   correction Δx̄ = −K̃⁻¹R(x + αΔx) is smaller, θ = ‖Δx̄‖/‖Δx‖ ≤ 1 − α/4,
    ///   and Δx̄ is then the next correction. The test is in the corrections,
    ///   not in the residual: with D = 1e-9 the residual after a step is
    ///   dominated by the pressure of its second-order volume change, 2/D
    ///   times an O(‖∇Δx‖²) term — large in any residual norm, but a small
    ///   correction, as K̃ carries the same 2/D;
    /// - ([`Merit::Residual`]) the residual's norm decreases,
    ///   ‖R(x + αΔx)‖ ≤ (1 − 10⁻⁴ α) ‖R(x)‖ — the classic damped Newton, which
    ///   finds its way from starts the natural test rejects.
    ///
    /// With [`Mode::Reuse`] the tangent is formed afresh at the current
    /// iterate when θ exceeds [`REFRESH_CONTRACTION`], after
    /// [`REFRESH_ITERATIONS`] iterations with a reused tangent, or when a
    /// reused tangent fails the test; with a tangent formed at the iterate,
    /// α is halved down to [`MIN_LINE_SEARCH`]. Convergence:
    /// [`Self::converged`]; at the first correction with the contraction
    /// `known` of the reused tangent from earlier steps (module docs,
    /// "Convergence at the predictor").
    #[allow(clippy::too_many_arguments)]
    fn iterate(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        mut x: Vec<f64>,
        mut cache: Arc<TangentCache>,
        mode: Mode,
        merit: Merit,
        pressures: Pressures,
        known: Option<Contraction>,
        spent: &mut Counts,
    ) -> Result<Solved, String> {
        let (activation, start, rate) = (input.activation, input.start, input.rate);
        let form = |x: &[f64], pressure: &Option<Vec<f64>>| {
            Arc::new(TangentCache::new(Anchor {
                x: x.to_vec(),
                activation,
                start: start.to_vec(),
                rate,
                pressure: pressure.clone(),
            }))
        };
        // With the pressures as unknowns (module docs, "Pressures"): from
        // the last equilibrium's, linearised over the predictor's increment.
        let mut pressure = match pressures {
            Pressures::VolumeRatios => None,
            Pressures::Unknowns => {
                let increment: Vec<f64> = x.iter().zip(input.x).map(|(a, b)| a - b).collect();
                Some(self.linearised_pressures(p, input.x, &increment)?.1)
            }
        };
        let mut ev = self.evaluate(p, &x, activation, start, rate, false)?;
        spent.residuals += 1;
        // The start histories with the SEE stretch of the latest evaluation:
        // the CE–SEE solves' warm start (λs of the history enters only as
        // that; the law reads λm(t)), nearly exact between iterates.
        let mut warm = start.to_vec();
        let warm_from = |w: &mut Vec<FibreHistory>, e: &Evaluation| {
            for (h, el) in w.iter_mut().zip(&e.elements) {
                h.lambda_s = el.history.lambda_s;
            }
        };
        warm_from(&mut warm, &ev);
        if mode == Mode::Fresh {
            cache = form(&x, &pressure);
        }
        let mut t = spent.tangent(&cache, self, p, input.budget)?;
        let mut dx = self.free_negated(&ev.forces);
        t.factor.solve_in_place(&mut dx);
        spent.solve(input.budget)?;
        // The contraction measured in this step, whether the tangent was
        // formed at the current iterate, how often it has been reused.
        let mut theta: Option<f64> = None;
        let mut fresh = mode == Mode::Fresh;
        let mut reused = 0;
        let mut refresh = false;
        let mut iterations = 0;
        // The contraction of `cache`'s tangent over a step: measured at
        // the first trial of a step with the tangent it came with (later
        // trials measure Newton's contraction near the solution, not the
        // tangent's over a step); the earlier steps' until then, none for a
        // tangent formed here.
        let mut incoming = mode == Mode::Reuse;
        let mut contraction = known.filter(|_| incoming);
        loop {
            if self.converged(p, &ev, &dx, theta, t, input.tolerance) {
                return Ok(spent.solved(x, ev, cache, contraction));
            }
            if iterations == MAX_NEWTON_ITERATIONS {
                return Err(format!(
                    "no convergence in {MAX_NEWTON_ITERATIONS} Newton iterations (correction {:e} m, residual {:e} N)",
                    max_abs(&dx),
                    self.residual_norm(&ev.forces)
                ));
            }
            iterations += 1;
            if (refresh || mode == Mode::Fresh) && !fresh {
                cache = form(&x, &pressure);
                contraction = None;
                incoming = false;
                t = spent.tangent(&cache, self, p, input.budget)?;
                let previous = norm2(&dx);
                dx = self.free_negated(&ev.forces);
                t.factor.solve_in_place(&mut dx);
                spent.solve(input.budget)?;
                // Across a tangent change the contraction is the ratio of
                // the new correction to the last one.
                theta = theta.map(|_| norm2(&dx) / previous);
                fresh = true;
                reused = 0;
            }
            let norm = norm2(&dx);
            let r2 = self.residual_norm2(&ev.forces);
            // Before its first trial this step has not measured θ: the
            // earlier steps' may stand in for it (module docs, "Convergence
            // at the predictor"); `contraction` is `None` once the tangent is
            // formed afresh.
            let stand_in = if theta.is_none() && pressure.is_none() && merit == Merit::Natural {
                contraction.and_then(Contraction::stand_in)
            } else {
                None
            };
            let mut alpha = 1.0;
            let accepted = loop {
                let trial: Vec<f64> = x.iter().zip(&dx).map(|(a, d)| a + alpha * d).collect();
                let evaluated = self.evaluate(p, &trial, activation, &warm, rate, false);
                spent.residuals += 1;
                if let Ok(e) = evaluated {
                    warm_from(&mut warm, &e);
                    if let Some(th) = stand_in.filter(|_| alpha == 1.0) {
                        if self.error_within(p, &e, &dx, th / (1.0 - th), t, input.tolerance) {
                            let aged = contraction.map(|c| Contraction {
                                age: c.age + 1,
                                ..c
                            });
                            return Ok(spent.solved(trial, e, cache, aged));
                        }
                    }
                    let decreased = match merit {
                        Merit::Residual => {
                            self.residual_norm2(&e.forces) <= (1.0 - 1e-4 * alpha) * r2
                        }
                        Merit::Natural => true,
                    };
                    if decreased {
                        let mut next = self.free_negated(&e.forces);
                        t.factor.solve_in_place(&mut next);
                        spent.solve(input.budget)?;
                        let th = norm2(&next) / norm;
                        if merit == Merit::Residual || th <= 1.0 - 0.25 * alpha {
                            break Some((trial, e, next, th));
                        }
                    }
                }
                if !fresh {
                    break None;
                }
                alpha *= 0.5;
                if alpha < MIN_LINE_SEARCH {
                    return Err(format!(
                        "Newton: no decrease along the Newton direction (correction {norm:e} m, residual {r2:e} N)"
                    ));
                }
            };
            refresh = match accepted {
                Some((trial, e, next, th)) => {
                    // The mixed update p ← p + α (U_J'(J) + U_J'' ΔJ(Δx) − p) at
                    // x, for the step αΔx taken.
                    if let Some(pressure) = pressure.as_mut() {
                        let step: Vec<f64> = trial.iter().zip(&x).map(|(a, b)| a - b).collect();
                        let (current, predicted) = self.linearised_pressures(p, &x, &step)?;
                        for ((pi, q), c) in pressure.iter_mut().zip(&predicted).zip(&current) {
                            *pi = q + (1.0 - alpha) * (*pi - c);
                        }
                    }
                    x = trial;
                    ev = e;
                    dx = next;
                    if theta.is_none() && incoming {
                        contraction = Some(Contraction { theta: th, age: 0 });
                    }
                    theta = Some(th);
                    reused = if fresh { 0 } else { reused + 1 };
                    fresh = false;
                    th > REFRESH_CONTRACTION || reused >= REFRESH_ITERATIONS
                }
                // A reused tangent that fails the test: form it here.
                None => true,
            };
        }
    }

    /// The convergence test at evaluation `ev` with the correction Δx there
    /// (module docs): Δx is at the rounding level of the positions
    /// ([`ROUNDING_CORRECTION`]), or the tangent's contraction θ ≤ 1/2 has been measured in
    /// this step, so that the remaining error is about ‖Δx‖/(1 − θ), and by
    /// that estimate no node is more than tol · ℓ from the solution (ℓ the
    /// specimen's size, [`Discretization::size`]) and the
    /// reaction force not more than tol · max(|F|, σ0 A) from its value
    /// there (its change (K̃ δ)·Δx: K̃ δ is the tangent's moved-face row
    /// sum; σ0 A is the muscle's maximum isometric force on its mean
    /// section).
    fn converged(
        &self,
        p: &Params,
        ev: &Evaluation,
        dx: &[f64],
        theta: Option<f64>,
        t: &Tangent,
        tolerance: f64,
    ) -> bool {
        // A correction at the rounding level of the positions (a few ulps):
        // nothing representable is left to correct.
        if max_abs(dx) <= ROUNDING_CORRECTION * self.size() {
            return true;
        }
        match theta {
            Some(th) if th <= 0.5 => self.error_within(p, ev, dx, 1.0 / (1.0 - th), t, tolerance),
            _ => false,
        }
    }

    /// Whether an error estimated as `factor` × the correction Δx moves no
    /// node by more than tol · ℓ and the reaction force (by (K̃ δ)·Δx) by no
    /// more than tol · max(|F|, σ0 A) at `ev` ([`Self::converged`]).
    fn error_within(
        &self,
        p: &Params,
        ev: &Evaluation,
        dx: &[f64],
        factor: f64,
        t: &Tangent,
        tolerance: f64,
    ) -> bool {
        let df: f64 = t.d_force.iter().zip(dx).map(|(k, d)| k * d).sum();
        let scale = self
            .reaction(&ev.forces)
            .abs()
            .max(p.sigma0 * self.mean_area());
        factor * df.abs() <= tolerance * scale && factor * max_abs(dx) <= tolerance * self.size()
    }

    /// The linearised response of the last equilibrium x_n as a start, with
    /// the tangent formed there (at the level the step starts from, an
    /// equilibrium's: positive definite where the state is stable) and the
    /// residual at the new level and rate: x_f = x_n,f + v_f ΔL −
    /// K_ff⁻¹ R_f(x_n). (Moving the face alone would start from pressures of
    /// order (ΔL/L)·2/D next to it; the tangent at the new level but old
    /// positions is indefinite when the level rises: fibre tension not yet
    /// balanced by pressure.) From it, `Self::iterate` with the natural
    /// test, and when that fails the damped Newton method (the solver before
    /// tangent reuse).
    fn robust(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        mut spent: Counts,
    ) -> Result<Solved, String> {
        let (activation, start, rate) = (input.activation, input.start, input.rate);
        let cache = Arc::new(TangentCache::new(Anchor {
            x: input.x.to_vec(),
            activation: input.activation_start,
            start: start.to_vec(),
            rate,
            pressure: None,
        }));
        let t = spent.tangent(&cache, self, p, input.budget)?;
        let r = self.evaluate(p, input.x, activation, start, rate, false)?;
        spent.residuals += 1;
        let mut dx = self.free_negated(&r.forces);
        t.factor.solve_in_place(&mut dx);
        spent.solve(input.budget)?;
        let dl = input.length - input.length_start;
        let mut x = input.x.to_vec();
        for ((xi, d), v) in x.iter_mut().zip(&dx).zip(&t.d_length) {
            *xi += d + v * dl;
        }
        self.apply_prescribed(&mut x, input.length);
        // The displacement iteration (natural test, then damped Newton), and
        // when both fail the same from the same start with the pressures as
        // unknowns (module docs, "Pressures"), sharing the start's tangent.
        let mut tried = spent;
        let mut failures = Vec::new();
        for pressures in [Pressures::VolumeRatios, Pressures::Unknowns] {
            for (mode, merit) in [
                (Mode::Reuse, Merit::Natural),
                (Mode::Fresh, Merit::Residual),
            ] {
                match self.iterate(
                    p,
                    input,
                    x.clone(),
                    cache.clone(),
                    mode,
                    merit,
                    pressures,
                    None,
                    &mut tried,
                ) {
                    Ok(s) => return Ok(s),
                    Err(e) => failures.push(e),
                }
            }
        }
        Err(match failures.as_slice() {
            [.., volume_ratios, _, unknowns] => {
                format!("{unknowns} (with the volume ratios' pressures: {volume_ratios})")
            }
            _ => failures.concat(),
        })
    }

    /// Euclidean norm of the residual over the free dofs.
    fn residual_norm2(&self, forces: &[f64]) -> f64 {
        forces
            .iter()
            .zip(&self.pattern.prescribed)
            .filter(|(_, &p)| !p)
            .map(|(f, _)| f * f)
            .sum::<f64>()
            .sqrt()
    }

    /// Largest residual over the free dofs.
    fn residual_norm(&self, forces: &[f64]) -> f64 {
        forces
            .iter()
            .zip(&self.pattern.prescribed)
            .filter(|(_, &p)| !p)
            .fold(0.0, |m, (f, _)| m.max(f.abs()))
    }
}

/// Which nodal pressures [`Discretization::iterate`] forms its tangents
/// with (module docs, "Pressures").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pressures {
    /// U_J'(J_a) of the iterate: the displacement formulation's Newton.
    VolumeRatios,
    /// The iteration's own, updated by the linearised constraint.
    Unknowns,
}

/// Whether [`Discretization::iterate`] reuses its tangent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Reuse,
    Fresh,
}

/// The acceptance test of [`Discretization::iterate`]'s line search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Merit {
    Natural,
    Residual,
}

/// What a solve spent.
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    residuals: usize,
    solves: usize,
    factorizations: usize,
}

impl Counts {
    /// The tangent of `cache`, counting (and charging to `budget`) its
    /// factorisation when it is formed here.
    fn tangent<'c>(
        &mut self,
        cache: &'c TangentCache,
        disc: &Discretization,
        p: &Params,
        budget: &Budget,
    ) -> Result<&'c Tangent, String> {
        if cache.built.get().is_none() {
            Budget::charge(&budget.factorizations, "factorisations")?;
            self.factorizations += 1;
        }
        cache.tangent(disc, p)
    }

    /// The converged solve at `x` (evaluated as `evaluation`) with what it
    /// spent.
    fn solved(
        &self,
        x: Vec<f64>,
        evaluation: Evaluation,
        cache: Arc<TangentCache>,
        contraction: Option<Contraction>,
    ) -> Solved {
        Solved {
            solution: Solution {
                x,
                evaluation,
                iterations: self.solves,
                residuals: self.residuals,
                factorizations: self.factorizations,
            },
            cache,
            contraction,
        }
    }

    /// Count (and charge to `budget`) a linear solve.
    fn solve(&mut self, budget: &Budget) -> Result<(), String> {
        Budget::charge(&budget.solves, "solves")?;
        self.solves += 1;
        Ok(())
    }
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::mesh::{FibreLayout, Grading, Resolution};
    use crate::fe::muscle::{Ends, Muscle};

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
    fn distance_to_equilibrium(
        d: &Discretization,
        p: &Params,
        r: &crate::fe::muscle::Advance,
    ) -> (f64, f64) {
        let ev = &r.solution.evaluation;
        let level = r.activation;
        let t = form_tangent(
            d,
            p,
            &Anchor {
                x: r.solution.x.clone(),
                activation: level,
                start: r.start.clone(),
                rate: r.rate,
                pressure: None,
            },
        )
        .unwrap();
        let mut dx = d.free_negated(&ev.forces);
        t.factor.solve_in_place(&mut dx);
        let df: f64 = t.d_force.iter().zip(&dx).map(|(k, x)| k * x).sum();
        let scale = d.reaction(&ev.forces).abs().max(p.sigma0 * d.mean_area());
        (max_abs(&dx) / d.l0, df.abs() / scale)
    }

    /// Convergence at the predictor (module docs): on a smooth passive pull
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
    /// carries the pressures as unknowns (module docs, "Pressures") the step
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
        let ramp = crate::fe::muscle::RELAX_RAMP;
        assert!(
            s.iterations > passive.iterations + ramp && s.factorizations > passive.factorizations,
            "initialization counted {} iterations, {} factorisations; the passive ramp alone {}, {}",
            s.iterations,
            s.factorizations,
            passive.iterations,
            passive.factorizations
        );
        let r = crate::fe::muscle::Advance {
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

    /// The extrapolation weights: exact for polynomials of the rate of
    /// degree < the number of increments, with constant and varying steps;
    /// none across a step-length jump beyond a factor 2.
    #[test]
    fn trend_weights_extrapolate_polynomial_rates_exactly() {
        let inc = |h: f64, dl: f64| Increment {
            dx: vec![],
            dl,
            da: 0.0,
            h,
        };
        // Constant steps: the classic (3, −3, 1).
        let t = Trend {
            increments: vec![inc(1e-3, 0.0), inc(1e-3, 0.0), inc(1e-3, 0.0)],
            contraction: None,
        };
        let w = t.weights(1e-3);
        for (a, b) in w.iter().zip([3.0, -3.0, 1.0]) {
            assert!((a - b).abs() < 1e-12, "{w:?}");
        }
        // Varying steps, a quadratic rate r(t) = 1 + 2t + 3t²: the increment
        // over [t0, t1] is its integral; the mean rates, taken at the step
        // midpoints, predict the new step's increment to O(h²) relative.
        let integral = |a: f64, b: f64| {
            let f = |t: f64| t + t * t + t * t * t;
            f(b) - f(a)
        };
        let hs = [0.011, 0.009, 0.012]; // most recent first
        let mut end = 0.0;
        let mut incs = Vec::new();
        for &h in &hs {
            incs.push(inc(h, integral(end - h, end)));
            end -= h;
        }
        let t = Trend {
            increments: incs,
            contraction: None,
        };
        let h = 0.01;
        let w = t.weights(h);
        assert_eq!(w.len(), 3);
        let predicted: f64 = w.iter().zip(&t.increments).map(|(c, i)| c * i.dl).sum();
        let exact = integral(0.0, h);
        assert!(
            (predicted - exact).abs() < 1e-4 * exact,
            "{predicted} vs {exact}"
        );
        // Without the variable-step nodes (constant-step weights) it is off
        // by far more.
        let naive = 3.0 * t.increments[0].dl - 3.0 * t.increments[1].dl + t.increments[2].dl;
        assert!(
            (naive - exact).abs() > 10.0 * (predicted - exact).abs(),
            "{naive} vs {predicted} vs {exact}"
        );
        // A jump in step length ends the usable history.
        let t = Trend {
            increments: vec![inc(1e-3, 0.0), inc(1e-2, 0.0)],
            contraction: None,
        };
        assert_eq!(t.weights(1e-3).len(), 1);
        assert!(t.weights(1e-1).is_empty());
    }
}
