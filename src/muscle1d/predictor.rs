//! The solvers' starting points for the next step of the 1D muscle: a
//! prediction of q = J^(1/3) and of the SEE stretch λs. Only the cost of a
//! step depends on it, never the converged result.

use crate::law::Uniaxial;

/// Prediction of a solved quantity x (q or λs) for the next step:
/// x + s_λ Δλ + s_a Δa + (2 ẋ_h − ẋ_h,prev) h, where s are the total
/// sensitivities of the last solve and ẋ_h is the history-driven rate of the
/// last step (its change not explained by Δλ and Δa, per unit time),
/// extrapolated linearly from the step before. A smooth input is predicted to
/// O(h³) and a jump in λ or a to first order (the iterations it saves are in
/// BENCHMARKS.md). Only the solvers' starting points depend on it, not the
/// converged result.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Predictor {
    /// (dq/dλ, dq/da, history rate of q, the step before's)
    pub(crate) q: [f64; 4],
    /// (dλs/dλ, dλs/da, history rate of λs, the step before's)
    pub(crate) lambda_s: [f64; 4],
}

impl Predictor {
    /// The prediction of x after a change `dlambda` of the stretch and `da`
    /// of the level over `h`, from the coefficients `s` of x.
    pub(crate) fn predict(s: &[f64; 4], x: f64, dlambda: f64, da: f64, h: f64) -> f64 {
        // The history rate extrapolated linearly from the last two steps.
        x + s[0] * dlambda + s[1] * da + (2.0 * s[2] - s[3]) * h
    }

    /// The predictor after a step (h, Δλ, Δa, Δq, Δλs) that ended at `u`
    /// (`None`: initialization, no history rate yet).
    pub(crate) fn after(&self, u: &Uniaxial, step: Option<(f64, f64, f64, f64, f64)>) -> Predictor {
        // Only a solver's starting point: a rate that overflows (a step of a
        // few ulps) is dropped rather than committed.
        let rate = |s: &[f64; 4], dx: f64, dl: f64, da: f64, h: f64| {
            let r = (dx - s[0] * dl - s[1] * da) / h;
            if r.is_finite() {
                r
            } else {
                0.0
            }
        };
        let (rq, rls) = match step {
            Some((h, dl, da, dq, dls)) => (
                rate(&self.q, dq, dl, da, h),
                rate(&self.lambda_s, dls, dl, da, h),
            ),
            None => (0.0, 0.0),
        };
        let (pq, pls) = match step {
            Some(_) => (self.q[2], self.lambda_s[2]),
            None => (0.0, 0.0),
        };
        Predictor {
            q: [
                u.d_dlambda.q,
                u.d_dactivation.q,
                rq,
                if step.is_some() { pq } else { rq },
            ],
            lambda_s: [
                u.d_dlambda.lambda_s,
                u.d_dactivation.lambda_s,
                rls,
                if step.is_some() { pls } else { rls },
            ],
        }
    }
}
