//! The tangent the equilibrium solve reuses ([`crate::fe::newton`]) and the
//! predictor's record of the last steps.
//!
//! Each Newton iteration solves with the factorisation of a tangent K̃
//! formed at an earlier configuration, its [`Anchor`] (possibly several
//! steps old): modified Newton, which converges linearly with rate
//! ρ ≈ ‖K̃⁻¹(K − K̃)‖, while forming and factorising the tangent costs many
//! residual evaluations and the tangent changes little over a step. A
//! [`TangentCache`] holds an anchor and, formed on first use, its
//! factorised [`Tangent`] with the sensitivities the predictor uses; a
//! [`Trend`] holds the last steps' [`Increment`]s and the measured
//! [`Contraction`] of the reused tangent.
//!
//! Invariant: the factorisation is a function of the anchor (positions,
//! activation level, start history, rate mode, pressures) alone. The anchor
//! is part of the muscle's state, so a state saved and restored — even in
//! another process, which forms the factorisation again from the anchor —
//! continues bit for bit.

use std::fmt;
use std::sync::OnceLock;

use crate::fe::assembly::Factor;
use crate::fe::discretization::Discretization;
use crate::law::{FibreHistory, FibreRate, Params};

/// A reused tangent whose iteration contracts the correction by less than
/// this (θ = ‖Δx̄‖/‖Δx‖ > c) is formed afresh at the next iterate.
pub const REFRESH_CONTRACTION: f64 = 0.25;
/// Steps a measured contraction of a reused tangent may stand in for the
/// contraction of later steps with that tangent ([`crate::fe::newton`],
/// "Convergence at the predictor").
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
    /// are the iteration's own ([`crate::fe::newton`], "Pressures"); `None`: those of
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

    /// Whether the tangent has been formed.
    pub(crate) fn is_built(&self) -> bool {
        self.built.get().is_some()
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
    let factor = disc.pattern.factorize_direction(values)?;
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
    /// ([`crate::fe::newton`], "Convergence at the predictor"): twice the measured
    /// one, when that is recent and small enough.
    pub(crate) fn stand_in(self) -> Option<f64> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
