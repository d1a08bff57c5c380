//! The equilibrium solve of one (sub)step of the FE muscle: Newton's method
//! on R(x) = 0 at the free degrees of freedom of a [`Discretization`], with a
//! factorised tangent reused across iterations and steps while it still
//! contracts fast ([`crate::fe::tangent`]) and formed afresh at the current
//! iterate when it stops paying: when an iteration contracts the correction
//! by less than [`REFRESH_CONTRACTION`], after [`REFRESH_ITERATIONS`]
//! iterations unless its contraction reaches the tolerance within
//! [`REFRESH_REACH`] more, or when a stale correction does not decrease the
//! residual.
//! With a tangent formed at the iterate it is Newton's method with a
//! backtracking line search.
//!
//! Entry points: [`Discretization::solve_step`], and
//! [`Discretization::solve_step_continued`] (the same, then continuation in
//! the step's inputs), for a [`StepInput`] within a [`Budget`].
//!
//! Invariants: the result is an equilibrium to [`StepInput::tolerance`] of
//! the specimen's size and force scale (`Discretization::converged`), or
//! `Err`; a step's work is bounded by its [`Budget`] (counted, not timed, so
//! the outcome is deterministic); what an iteration does depends only on
//! (x, the anchor, the inputs).
//!
//! # Predictor
//!
//! The step starts from x_n + s Δx_n + v (ΔL − s ΔL_n) + w (Δa − s Δa_n):
//! the last step's increment Δx_n extrapolated to the new step (s = h/h_n,
//! [`Trend::weights`]), corrected to first order for the part of the input
//! change the extrapolation does not predict, with the anchor's
//! sensitivities v = ∂x/∂L (the moved face pulled by a unit length, the
//! interior following) and w = ∂x/∂a. Without a last step (after
//! initialization) it is x_n + v ΔL + w Δa, the linearised response of the
//! last equilibrium.
//!
//! # Convergence at the predictor
//!
//! The convergence test needs the contraction θ of the iteration, which a
//! step measures with the correction at its first trial x₁ = x₀ + Δx₀:
//! θ = ‖Δx̄₁‖/‖Δx₀‖, then x₁ is accepted when Δx̄₁/(1 − θ) is within the
//! tolerance. On smooth input the solve for Δx̄₁ mostly only measures θ, so
//! the first trial may take its θ from the last steps' measurement with the
//! same reused tangent ([`Contraction`]): at most [`CONTRACTION_STEPS`]
//! steps old, at most [`REFRESH_CONTRACTION`], and doubled (the reused
//! tangent drifts slowly between steps). x₁ is then accepted when its
//! estimated error θ/(1 − θ)·Δx₀ is within the tolerance; every
//! [`CONTRACTION_STEPS`]-th step at the latest measures θ again. (Accepting
//! x₀ by Δx₀/(1 − θ) instead leaves errors near the tolerance in the
//! increments the predictor extrapolates, whose corrections then grow past
//! it.)
//!
//! # Pressures
//!
//! Newton's method on the mixed problem carries the nodal pressures p_a
//! as unknowns beside the positions (forces with pressures p, constraint
//! U_J'(J_a) = p_a), condensed. As U_J = (J − 1)²/D is quadratic the
//! condensed right-hand side is the displacement residual; the iteration
//! differs only in the pressure of the tangent's initial-stress part:
//! p ← p + α (U_J'(J) + U_J'' ΔJ(Δx) − p), the linearised constraint's
//! ([`Discretization::linearised_pressures`]), instead of U_J'(J(x + αΔx)),
//! which holds 2/D times the second-order volume change of the correction,
//! spoils the Newton direction after a large correction and shrinks the
//! convergence radius with D. The equilibrium is the same (at convergence
//! p = U_J'(J) to the tolerance).
//!
//! A step reuses its tangent with the pressures it was formed with; when it
//! forms a tangent afresh, it switches to the mixed iteration. Its
//! pressures then start from the last equilibria's U_J'(J), extrapolated
//! with the predictor's weights (the pressures vary smoothly in time) —
//! not from U_J'(J) at the predicted positions: a sum of increments that
//! each kept the volume preserves it only to first order, and 2/D times
//! that second-order volume change (a 1 % strain increment: ~10⁵ Pa) would
//! make the fresh tangent useless; large steps then took tens of Newton
//! iterations. Without a last step (`Self::robust`), the mixed iteration
//! from the linearised response comes first (its pressures the linearised
//! problem's), the displacement iteration is the fallback.
//!
//! # Stalls
//!
//! Newton's method with a tangent formed at every iterate, started outside
//! its region of convergence (an activation jump inside a step, a large
//! length change against the predictor), can creep: each line search
//! accepts α ≈ 1/32 with θ ≈ 0.99, and the attempt spends all of its
//! [`MAX_NEWTON_ITERATIONS`] iterations, one factorisation each, before the
//! fallbacks (the linearised start, damped Newton, continuation) that reach
//! the equilibrium in a few. [`STALL_ITERATIONS`] fresh-tangent iterations
//! in a row with STALL_CONTRACTION < θ ≤ 1 end the attempt early. Damped
//! Newton (the residual merit), which is meant to creep, is never cut. The
//! equilibrium a step converges to is the same to the tolerance; only the
//! path to it changes, and only on steps that stall.
//!
//! # Natural test failing
//!
//! Where the tangent is far from the Jacobian along the correction (an
//! indefinite tangent of a slack, shortening muscle; the mixed iteration's
//! pressures far from U_J'(J)), no α of a fresh tangent's line search may
//! pass the natural test while the residual does decrease. The attempt then
//! continues as damped Newton (the residual merit) from its iterate with
//! the first trial of that search the residual merit accepts — what the
//! damped-Newton fallback would do with the same tangent — instead of
//! ending and leaving the fallbacks to form their tangents again from the
//! linearised start. Only when no trial decreases the residual either does
//! the attempt fail. The equilibrium is the same to the tolerance.
//!
//! # Rounding floor
//!
//! With a very small compressibility (D = 1e-12 1/Pa: volumetric
//! stiffness 2/D) the residual of an iterate rounds at ~1e-7 N, the
//! stiffness times the positions' rounding, above the force tolerance of
//! a small specimen. Near the solution the residual is then noise: no
//! trial of a fresh tangent's line search decreases it, and θ measured on
//! noise says nothing. Where that happens and Newton's correction from the
//! tangent formed there (the error to first order) is within the
//! tolerance, the force part allowed the reaction's rounding level
//! ε ℓ Σ|K̃ δ| where that is larger, the iterate is the solution
//! (`Discretization::within_rounding`). Elsewhere the search's failure is
//! an error, as before; nothing else changes.
//!
//! [`CONTRACTION_STEPS`]: crate::fe::tangent::CONTRACTION_STEPS

use std::sync::Arc;

use crate::fe::discretization::{Discretization, Evaluation};
use crate::fe::tangent::{Anchor, Contraction, Tangent, TangentCache, Trend, REFRESH_CONTRACTION};
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
/// A step that has taken this many iterations with a reused tangent forms it
/// afresh.
pub const REFRESH_ITERATIONS: usize = 4;
/// ... unless its contraction θ reaches the tolerance within this many
/// more iterations (the error estimate θ^k/(1 − θ) × the correction).
pub const REFRESH_REACH: usize = 2;
/// An iteration with a tangent formed at its iterate that contracts the
/// correction by no more than this (STALL_CONTRACTION < θ ≤ 1: a line search
/// cut to a small α, or a residual barely decreasing) makes no progress
/// toward Newton's region of convergence.
pub const STALL_CONTRACTION: f64 = 0.9;
/// After this many such iterations in a row the attempt is given up for the
/// next fallback (module docs, "Stalls").
pub const STALL_ITERATIONS: usize = 3;

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
    /// mesh the size of the default one (1,887 dofs), more
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

    /// [`Self::for_step`] with no factorisation: a solve that only reuses
    /// the tangent it is given.
    pub fn without_factorizations(disc: &Discretization) -> Budget {
        let b = Budget::for_step(disc);
        b.factorizations.set(0);
        b
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
            Pressures::OnRefresh,
            trend.contraction,
            Some((trend, weights)),
            spent,
        )
    }

    /// The nodal pressures U_J'(J_a) of the last equilibria x_n, x_{n−1}, …
    /// (x_{n−i} = x_{n−i+1} − Δx_i from the trend's increments) extrapolated
    /// to the new step with the predictor's weights: p_n + Σ c_i (p_{n−i+1}
    /// − p_{n−i}).
    fn extrapolated_pressures(
        &self,
        p: &Params,
        x_n: &[f64],
        trend: &Trend,
        weights: &[f64],
    ) -> Result<Vec<f64>, String> {
        let zero = vec![0.0; x_n.len()];
        let mut x = x_n.to_vec();
        let mut later = self.linearised_pressures(p, &x, &zero)?.0;
        let mut guess = later.clone();
        for (inc, &c) in trend.increments.iter().zip(weights) {
            for (xi, d) in x.iter_mut().zip(&inc.dx) {
                *xi -= d;
            }
            let earlier = self.linearised_pressures(p, &x, &zero)?.0;
            for ((g, l), e) in guess.iter_mut().zip(&later).zip(&earlier) {
                *g += c * (l - e);
            }
            later = earlier;
        }
        Ok(guess)
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
    ///   finds its way from starts the natural test rejects. A natural
    ///   search with a fresh tangent that no α passes continues with this
    ///   merit (module docs, "Natural test failing").
    ///
    /// With [`Mode::Reuse`] the tangent is formed afresh at the current
    /// iterate when θ exceeds [`REFRESH_CONTRACTION`], after
    /// [`REFRESH_ITERATIONS`] iterations with a reused tangent (unless θ
    /// reaches the tolerance within [`REFRESH_REACH`] more), or when a
    /// reused tangent fails the test; with a tangent formed at the iterate,
    /// α is halved down to [`MIN_LINE_SEARCH`]. Convergence:
    /// [`Self::converged`]; at the first correction with the contraction
    /// `known` of the reused tangent from earlier steps (module docs,
    /// "Convergence at the predictor"). With [`Pressures::OnRefresh`] the
    /// pressures become unknowns when the tangent is first formed here,
    /// predicted from `history` (the trend and the predictor's weights)
    /// when given.
    #[allow(clippy::too_many_arguments)]
    fn iterate(
        &self,
        p: &Params,
        input: &StepInput<'_>,
        mut x: Vec<f64>,
        mut cache: Arc<TangentCache>,
        mode: Mode,
        mut merit: Merit,
        pressures: Pressures,
        known: Option<Contraction>,
        history: Option<(&Trend, &[f64])>,
        spent: &mut Counts,
    ) -> Result<Solved, String> {
        let predictor = x.clone();
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
            Pressures::VolumeRatios | Pressures::OnRefresh => None,
            Pressures::Unknowns => {
                let increment: Vec<f64> = x.iter().zip(input.x).map(|(a, b)| a - b).collect();
                Some(self.linearised_pressures(p, input.x, &increment)?.1)
            }
        };
        let mut ev = self.evaluate(p, &x, activation, start, rate, false)?;
        spent.residual(self);
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
        spent.solve(self, input.budget)?;
        // The contraction measured in this step, whether the tangent was
        // formed at the current iterate, how often it has been reused.
        let mut theta: Option<f64> = None;
        let mut fresh = mode == Mode::Fresh;
        let mut reused = 0;
        let mut refresh = false;
        let mut iterations = 0;
        // Fresh-tangent iterations in a row that made no progress (module
        // docs, "Stalls").
        let mut stalled = 0;
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
                // Switching to the pressures as unknowns (module docs,
                // "Pressures"): the last equilibria's extrapolated like the
                // positions, linearised over the iterate's move from the
                // predictor; without a trend, the last equilibrium's
                // linearised over the whole increment.
                if pressures == Pressures::OnRefresh && pressure.is_none() {
                    let from = |a: &[f64], b: &[f64]| -> Vec<f64> {
                        a.iter().zip(b).map(|(a, b)| a - b).collect()
                    };
                    pressure = Some(match history {
                        Some((trend, weights)) => {
                            let guess = self.extrapolated_pressures(p, input.x, trend, weights)?;
                            let (at, moved) =
                                self.linearised_pressures(p, &predictor, &from(&x, &predictor))?;
                            guess
                                .iter()
                                .zip(at.iter().zip(&moved))
                                .map(|(g, (a, m))| g + m - a)
                                .collect()
                        }
                        None => self.linearised_pressures(p, input.x, &from(&x, input.x))?.1,
                    });
                }
                cache = form(&x, &pressure);
                contraction = None;
                incoming = false;
                t = spent.tangent(&cache, self, p, input.budget)?;
                let previous = norm2(&dx);
                dx = self.free_negated(&ev.forces);
                t.factor.solve_in_place(&mut dx);
                spent.solve(self, input.budget)?;
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
            // With the natural test and a fresh tangent: the first trial of
            // this search that decreases the residual (the residual merit's
            // choice), should no trial pass the natural test.
            let mut descent = None;
            let accepted = loop {
                let trial: Vec<f64> = x.iter().zip(&dx).map(|(a, d)| a + alpha * d).collect();
                let evaluated = self.evaluate(p, &trial, activation, &warm, rate, false);
                spent.residual(self);
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
                    let armijo = self.residual_norm2(&e.forces) <= (1.0 - 1e-4 * alpha) * r2;
                    if merit == Merit::Natural || armijo {
                        let mut next = self.free_negated(&e.forces);
                        t.factor.solve_in_place(&mut next);
                        spent.solve(self, input.budget)?;
                        let th = norm2(&next) / norm;
                        if merit == Merit::Residual || th <= 1.0 - 0.25 * alpha {
                            break Some((trial, e, next, th));
                        }
                        if fresh && armijo && descent.is_none() {
                            descent = Some((alpha, trial, e, next, th));
                        }
                    }
                }
                if !fresh {
                    break None;
                }
                alpha *= 0.5;
                if alpha < MIN_LINE_SEARCH {
                    // The natural test fails along the whole search: damped
                    // Newton from here, its trial already evaluated (module
                    // docs, "Natural test failing").
                    if let Some((a, trial, e, next, th)) = descent.take() {
                        merit = Merit::Residual;
                        alpha = a;
                        break Some((trial, e, next, th));
                    }
                    // No trial decreases the residual along a correction
                    // from a tangent formed here that is itself within the
                    // tolerance: the residual is at the rounding level of its
                    // evaluation (with D = 1e-12 the volumetric forces round
                    // at ~1e-7 N), and Newton's correction, the error to first
                    // order, says the iterate is converged (module docs,
                    // "Rounding floor").
                    if self.within_rounding(p, &ev, &dx, t, input.tolerance) {
                        return Ok(spent.solved(x, ev, cache, contraction));
                    }
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
                    stalled = if merit == Merit::Natural
                        && fresh
                        && th > STALL_CONTRACTION
                        && th <= 1.0
                    {
                        stalled + 1
                    } else {
                        0
                    };
                    if stalled == STALL_ITERATIONS {
                        return Err(format!(
                            "Newton stalls: {STALL_ITERATIONS} iterations in a row contract the correction by no more than {STALL_CONTRACTION} (correction {:e} m, residual {:e} N)",
                            max_abs(&next),
                            self.residual_norm(&e.forces)
                        ));
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
                    // By count only when the contraction would not reach
                    // the tolerance within REFRESH_REACH more solves, each
                    // far cheaper than a tangent and its factorisation.
                    let within_reach = || {
                        let left = th.powi(REFRESH_REACH as i32) / (1.0 - th);
                        self.error_within(p, &ev, &dx, left, t, input.tolerance)
                    };
                    th > REFRESH_CONTRACTION || (reused >= REFRESH_ITERATIONS && !within_reach())
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

    /// Whether Newton's correction Δx from a tangent formed at `ev`, along
    /// which no trial decreases the residual, is within the tolerance: no
    /// node moved by more than tol · ℓ, the reaction force by no more than
    /// tol · max(|F|, σ0 A) or, where that is finer, its rounding level
    /// ε ℓ Σ|K̃ δ| (its change when every position moves by ε ℓ, the
    /// representation error of positions within ℓ; with D = 1e-12 some
    /// 1e-8 of σ0 A). Module docs, "Rounding floor".
    fn within_rounding(
        &self,
        p: &Params,
        ev: &Evaluation,
        dx: &[f64],
        t: &Tangent,
        tolerance: f64,
    ) -> bool {
        let floor = f64::EPSILON * self.size() * t.d_force.iter().map(|k| k.abs()).sum::<f64>();
        let df: f64 = t.d_force.iter().zip(dx).map(|(k, d)| k * d).sum();
        let scale = self
            .reaction(&ev.forces)
            .abs()
            .max(p.sigma0 * self.mean_area());
        df.abs() <= (tolerance * scale).max(floor) && max_abs(dx) <= tolerance * self.size()
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
    /// tangent reuse): with the pressures as unknowns, then with the volume
    /// ratios' (module docs, "Pressures").
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
        spent.residual(self);
        let mut dx = self.free_negated(&r.forces);
        t.factor.solve_in_place(&mut dx);
        spent.solve(self, input.budget)?;
        let dl = input.length - input.length_start;
        let mut x = input.x.to_vec();
        for ((xi, d), v) in x.iter_mut().zip(&dx).zip(&t.d_length) {
            *xi += d + v * dl;
        }
        self.apply_prescribed(&mut x, input.length);
        // The mixed iteration (natural test, then damped Newton), and when
        // both fail the same from the same start with the volume ratios'
        // pressures (module docs, "Pressures"), sharing the start's tangent.
        let order = [Pressures::Unknowns, Pressures::VolumeRatios];
        let mut tried = spent;
        let mut failures = Vec::new();
        for pressures in order {
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
                    None,
                    &mut tried,
                ) {
                    Ok(s) => return Ok(s),
                    Err(e) => failures.push(e),
                }
            }
        }
        Err(match failures.as_slice() {
            [.., first, _, second] => {
                format!("{second} (with the {} first: {first})", order[0].name())
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
    /// Those of a reused tangent until it is formed afresh, then
    /// [`Pressures::Unknowns`].
    OnRefresh,
}

impl Pressures {
    /// How an error message names them.
    fn name(self) -> &'static str {
        match self {
            Pressures::VolumeRatios => "volume ratios' pressures",
            Pressures::Unknowns | Pressures::OnRefresh => "pressures as unknowns",
        }
    }
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
        if !cache.is_built() {
            Budget::charge(&budget.factorizations, "factorisations")?;
            self.factorizations += 1;
            disc.work.factorization();
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

    /// Count (and charge to `budget`) a linear solve with `disc`.
    fn solve(&mut self, disc: &Discretization, budget: &Budget) -> Result<(), String> {
        Budget::charge(&budget.solves, "solves")?;
        self.solves += 1;
        disc.work.solve();
        Ok(())
    }

    /// Count a residual evaluation of `disc`.
    fn residual(&mut self, disc: &Discretization) {
        self.residuals += 1;
        disc.work.residual();
    }
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}
