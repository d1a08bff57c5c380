//! The Hill fibre: contractile element (CE) in series with the series elastic
//! element (SEE), in parallel with the parallel element (PE)
//! (MODEL_NOTES "Hill fibre"; paper eq 4, 6–23 and 26).
//!
//! The fibre's nominal stress is W = ∂U_f/∂λ̄f = σ_s + σ_p. σ_s depends on the
//! SEE stretch λs, a history variable found by the CE–SEE step solve:
//!
//! (1 + k) λ̄f = λm + k λs,  λ̇m = (λm(t+h) − λm(t)) / h,
//! R(λs) = σ_s(λs) − σ0 a f_λ(λ̄f) f_v(λ̇m) = 0.
//!
//! This module solves R in the new SEE stretch λs(t+h) directly (equivalent to
//! the increment Δλs of MODEL_NOTES). R is non-decreasing in λs, and the root
//! lies in [1, λs_max] with σ_s(λs_max) = σ0 a f_λ f_v,max, so it is found by a
//! bracketed, safeguarded Newton iteration on any input. f_λ is evaluated at
//! the end-of-step fibre stretch λ̄f(t+h) (MODEL_NOTES allows this; the paper
//! uses λ̄f(t)), which makes the step map a function of the end state only.

use super::components::{Components, FullLaw};
use super::force_length::force_length;
use super::force_velocity::{
    force_velocity_branch, force_velocity_curvature_with, force_velocity_with,
};
use super::parallel_element::pe_stress;
use super::params::Params;
use super::root_finding::{safeguarded_newton, RootError};
use super::series_element::{see_stiffness, see_stress, see_stretch_for_stress};

/// History of one fibre at the start of a step: the SEE and CE stretches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreHistory {
    pub lambda_s: f64,
    pub lambda_m: f64,
}

/// Series kinematics (MODEL_NOTES "Hill fibre"): the CE stretch
/// λm = (1 + k) λ̄f − k λs.
#[inline]
pub fn ce_stretch(k: f64, lambda_f: f64, lambda_s: f64) -> f64 {
    (1.0 + k) * lambda_f - k * lambda_s
}

/// Estimated local error of one backward-Euler step of the CE–SEE update
/// over a piece of length `hs`, as SEE stress [Pa] (MODEL_NOTES "Hill
/// fibre"; the substep control of both models). The CE stretch obeys
/// λ̇m = r(t, λm); backward Euler's local error is (hs/2)(r(end) −
/// r(start)) + O(hs³), its difference from the trapezoidal rule. With λ̄f
/// given, λs errs by that over k, and σ_s by σ_s' = alpha (σ_s + beta)
/// times that, taken at `cap`, the largest SEE stress the CE can hold over
/// the piece (f_v,max σ0 a): an error of λm stays in the state and turns
/// into this much stress once the SEE is stretched that far. σ_s stays
/// within [0, cap], so no estimate exceeds `cap`.
pub fn backward_euler_error(p: &Params, cap: f64, rate_start: f64, rate_end: f64, hs: f64) -> f64 {
    let estimate =
        see_stiffness(cap, p.alpha, p.beta) * hs / (2.0 * p.k) * (rate_end - rate_start).abs();
    estimate.min(cap)
}

impl FibreHistory {
    /// Whether the series kinematics (MODEL_NOTES "Hill fibre") describe a real
    /// fibre: both element stretches finite and > 0. The law itself stays
    /// defined when λm = (1 + k) λ̄f − k λs ≤ 0 (only λ̇m enters f_v), but a
    /// contractile element of non-positive length is not a muscle: with a large
    /// k this happens as soon as λ̄f < k λs / (1 + k). The error names the bound.
    pub fn check_physical(&self, k: f64, lambda_f: f64) -> Result<(), String> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if ok(self.lambda_m) && ok(self.lambda_s) {
            Ok(())
        } else {
            Err(format!(
                "the contractile element would have a non-positive length: CE stretch \
                 (1 + k) * fibre_stretch - k * see_stretch = {:e} with k = {k}, fibre stretch {lambda_f} \
                 and SEE stretch {} (the fibre stretch must exceed k * see_stretch / (1 + k) = {})",
                self.lambda_m,
                self.lambda_s,
                k * self.lambda_s / (1.0 + k)
            ))
        }
    }

    /// Unloaded fibre at its rest length: λs = λm = 1.
    pub const REST: FibreHistory = FibreHistory {
        lambda_s: 1.0,
        lambda_m: 1.0,
    };
}

/// How the CE stretch rate is obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FibreRate {
    /// λ̇m = 0: isometric equilibrium (initialization, MODEL_NOTES
    /// "Co-simulation conventions"). σ_s = σ0 a f_λ, solved in closed form.
    Isometric,
    /// A step of length h > 0 from the history: λ̇m = (λm(t+h) − λm(t)) / h.
    Step { h: f64 },
}

/// The fibre's response at the end of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreResponse {
    /// Fibre nominal stress W = σ_s + σ_p.
    pub w: f64,
    /// Consistent derivative dW/dλ̄f through the CE–SEE solve (history fixed).
    pub dw_dlambda: f64,
    /// ∂W/∂a at fixed λ̄f through the CE–SEE solve.
    pub dw_dactivation: f64,
    /// dλs/dλ̄f through the CE–SEE solve (history fixed).
    pub dls_dlambda: f64,
    /// ∂λs/∂a at fixed λ̄f.
    pub dls_dactivation: f64,
    /// ∂λs/∂λm(t): how the step's SEE stretch moves with the CE stretch of the
    /// history (the start of the step), at fixed λ̄f and a. Chains the
    /// derivatives through a sequence of steps (a step cut into substeps).
    /// 0 for the isometric solve.
    pub dls_dhistory: f64,
    /// ∂W/∂λm(t) at fixed λ̄f and a.
    pub dw_dhistory: f64,
    /// SEE (= CE) nominal stress σ_s.
    pub sigma_see: f64,
    /// PE nominal stress σ_p.
    pub sigma_pe: f64,
    /// History at the end of the step (commit it only when the step is accepted).
    pub history: FibreHistory,
    /// CE stretch rate λ̇m over the step (0 for the isometric solve).
    pub lambda_dot_m: f64,
    /// Iterations of the CE–SEE solve (0 when solved in closed form).
    pub iterations: u32,
    /// The rate mode the response was computed for.
    pub rate: FibreRate,
}

impl FibreResponse {
    /// The response at λ̄f + `dlambda_f` to first order, history fixed: every
    /// value moves along its consistent derivative (the CE–SEE root moves by
    /// dλs/dλ̄f · dλ̄f; σ_s' = α (σ_s + β), eq 31). Used to apply a Newton
    /// correction of ~1e-9 without re-solving (error O(dλ̄f²)).
    pub fn moved_to(&self, p: &Params, dlambda_f: f64) -> FibreResponse {
        if dlambda_f == 0.0 {
            return *self;
        }
        let dls = self.dls_dlambda * dlambda_f;
        let dsigma_see = see_stiffness(self.sigma_see, p.alpha, p.beta) * dls;
        let dlm = (1.0 + p.k) * dlambda_f - p.k * dls;
        FibreResponse {
            w: self.w + self.dw_dlambda * dlambda_f,
            // σ_s(λs ≥ 1) ≥ 0: the first-order value may dip below 0 by
            // round-off when σ_s ≈ 0.
            sigma_see: (self.sigma_see + dsigma_see).max(0.0),
            sigma_pe: self.sigma_pe + (self.dw_dlambda * dlambda_f - dsigma_see),
            history: FibreHistory {
                lambda_s: self.history.lambda_s + dls,
                lambda_m: self.history.lambda_m + dlm,
            },
            lambda_dot_m: match self.rate {
                FibreRate::Isometric => 0.0,
                FibreRate::Step { h } => self.lambda_dot_m + dlm / h,
            },
            ..*self
        }
    }
}

/// Fibre nominal stress W(λ̄f) = σ_s + σ_p (paper eq 26, with σ_s of eq 7 and
/// σ_p of eq 22–23) at the end of a step, with the CE–SEE solve σ_s = σ_c
/// (eq 8; the residual R of MODEL_NOTES "Hill fibre", which replaces the
/// paper's eq 13–21) and its consistent derivatives.
///
/// Derivatives at the root, from R(λs, λ̄f, a) = 0:
/// R_λs = σ_s' + σ0 a f_λ f_v' k / h,
/// R_λf = −σ0 a f_λ' f_v − σ0 a f_λ f_v' (1 + k) / h,  R_a = −σ0 f_λ f_v,
/// R_λm(t) = σ0 a f_λ f_v' / h,
/// dλs/dλ̄f = −R_λf / R_λs,  dλs/da = −R_a / R_λs,  dλs/dλm(t) = −R_λm(t) / R_λs,
/// dW/dλ̄f = σ_s' dλs/dλ̄f + σ_p',  ∂W/∂a = σ_s' dλs/da,  ∂W/∂λm(t) = σ_s' dλs/dλm(t).
pub fn fibre_response(
    p: &Params,
    lambda_f: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
) -> FibreResponse {
    fibre_response_with::<FullLaw>(p, lambda_f, activation, hist, rate)
}

/// [`fibre_response`] with the components `L` includes ([`Components`]):
/// without the parallel element σ_p = 0; without the contractile and series
/// elements the fibre is the parallel element alone, W = σ_p, with σ_s = 0
/// and λs = 1 in closed form (MODEL_NOTES "Hill fibre": the CE carries
/// nothing) — the same values, bit for bit, as the complete law's at
/// activation 0, except the derivatives with respect to the activation and
/// the history, which are 0 here (there is no activation to vary).
pub fn fibre_response_with<L: Components>(
    p: &Params,
    lambda_f: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
) -> FibreResponse {
    let (sigma_pe, dsigma_pe) = if L::PARALLEL {
        pe_stress(lambda_f, p.sigma0, p.a_pe)
    } else {
        (0.0, 0.0)
    };
    if !L::CONTRACTILE {
        let lambda_m = ce_stretch(p.k, lambda_f, 1.0);
        return FibreResponse {
            w: sigma_pe,
            dw_dlambda: dsigma_pe,
            dw_dactivation: 0.0,
            dls_dlambda: 0.0,
            dls_dactivation: 0.0,
            dls_dhistory: 0.0,
            dw_dhistory: 0.0,
            sigma_see: 0.0,
            sigma_pe,
            history: FibreHistory {
                lambda_s: 1.0,
                lambda_m,
            },
            lambda_dot_m: match rate {
                FibreRate::Isometric => 0.0,
                FibreRate::Step { h } => (lambda_m - hist.lambda_m) / h,
            },
            iterations: 0,
            rate,
        };
    }
    let (f_l, df_l) = force_length(lambda_f, p.lambda_opt);
    let drive = p.sigma0 * activation * f_l; // σ0 a f_λ
    let (sol, lambda_dot_m, dls_df, dls_da, dls_dh) = match rate {
        FibreRate::Isometric => {
            // σ_s(λs) = σ0 a f_λ with f_v(0) = 1; dσ_s/dλs = α (σ_s + β) (eq 31).
            let sigma = drive.max(0.0);
            let sol = SeeSolution {
                lambda_s: see_stretch_for_stress(sigma, p.alpha, p.beta),
                sigma,
                dsigma: see_stiffness(sigma, p.alpha, p.beta),
                fv: 1.0,
                dfv: 0.0,
                iterations: 0,
            };
            let (dls_df, dls_da) = (
                p.sigma0 * activation * df_l / sol.dsigma,
                p.sigma0 * f_l / sol.dsigma,
            );
            (sol, 0.0, dls_df, dls_da, 0.0)
        }
        FibreRate::Step { h } => {
            let sol = step_solve::<L>(p, lambda_f, drive, hist, h);
            let r_ls = sol.dsigma + drive * sol.dfv * p.k / h;
            let r_lf = -p.sigma0 * activation * df_l * sol.fv - drive * sol.dfv * (1.0 + p.k) / h;
            let r_a = -p.sigma0 * f_l * sol.fv;
            let r_h = drive * sol.dfv / h;
            let rate = (ce_stretch(p.k, lambda_f, sol.lambda_s) - hist.lambda_m) / h;
            (sol, rate, -r_lf / r_ls, -r_a / r_ls, -r_h / r_ls)
        }
    };
    FibreResponse {
        w: sol.sigma + sigma_pe,
        dw_dlambda: sol.dsigma * dls_df + dsigma_pe,
        dw_dactivation: sol.dsigma * dls_da,
        dls_dlambda: dls_df,
        dls_dactivation: dls_da,
        dls_dhistory: dls_dh,
        dw_dhistory: sol.dsigma * dls_dh,
        sigma_see: sol.sigma,
        sigma_pe,
        history: FibreHistory {
            lambda_s: sol.lambda_s,
            lambda_m: ce_stretch(p.k, lambda_f, sol.lambda_s),
        },
        lambda_dot_m,
        iterations: sol.iterations,
        rate,
    }
}

/// What a residual needs of the fibre at the end of a step (no
/// derivatives): [`fibre_stress`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreStress {
    /// Fibre nominal stress W = σ_s + σ_p.
    pub w: f64,
    /// SEE (= CE) nominal stress σ_s.
    pub sigma_see: f64,
    /// History at the end of the step.
    pub history: FibreHistory,
}

/// The stress part of [`fibre_response`] (MODEL_NOTES "Hill fibre", paper
/// eq 4, 6–23, 26): the same CE–SEE solve, hence the same W, σ_s and
/// history, without the consistent derivatives. When the CE can carry
/// nothing (σ0 a f_λ ≤ 0) it is σ_s = 0, λs = 1 in closed form.
pub fn fibre_stress(
    p: &Params,
    lambda_f: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
) -> FibreStress {
    let (sigma_pe, _) = pe_stress(lambda_f, p.sigma0, p.a_pe);
    let (f_l, _) = force_length(lambda_f, p.lambda_opt);
    let drive = p.sigma0 * activation * f_l; // σ0 a f_λ
    let (sigma, lambda_s) = if drive <= 0.0 {
        // σ_s(1) = β (e⁰ − 1) = 0 exactly, as in the solves below.
        (0.0, 1.0)
    } else {
        match rate {
            FibreRate::Isometric => (drive, see_stretch_for_stress(drive, p.alpha, p.beta)),
            FibreRate::Step { h } => {
                let sol = step_solve::<FullLaw>(p, lambda_f, drive, hist, h);
                (sol.sigma, sol.lambda_s)
            }
        }
    };
    FibreStress {
        w: sigma + sigma_pe,
        sigma_see: sigma,
        history: FibreHistory {
            lambda_s,
            lambda_m: ce_stretch(p.k, lambda_f, lambda_s),
        },
    }
}

/// The SEE stretch of a step with the curve values at it.
struct SeeSolution {
    lambda_s: f64,
    /// σ_s(λs) and dσ_s/dλs.
    sigma: f64,
    dsigma: f64,
    /// f_v(λ̇m) and df_v/dλ̇m.
    fv: f64,
    dfv: f64,
    iterations: u32,
}

/// The CE–SEE step solve: the root of R(λs) = σ_s(λs) − drive · f_v(λ̇m(λs))
/// in [1, λs_max] with drive = σ0 a f_λ (MODEL_NOTES "Hill fibre"). Newton's
/// method from the warm start first; the bracketed safeguarded iteration when
/// that does not settle. The last Newton correction δ is applied to first
/// order together with the curve values of the last evaluation, once its
/// estimated error C δ² is below 1e-15 (fast path, |δ| ≤ 1e-6) or |δ| ≤ 1e-12
/// (bracketed path), which saves re-evaluating them.
fn step_solve<L: Components>(
    p: &Params,
    lambda_f: f64,
    drive: f64,
    hist: &FibreHistory,
    h: f64,
) -> SeeSolution {
    let ce_rate = |ls: f64| (ce_stretch(p.k, lambda_f, ls) - hist.lambda_m) / h;
    let evaluate = |ls: f64| {
        let (sigma, dsigma) = see_stress(ls, p.alpha, p.beta);
        let (fv, dfv) = force_velocity_with::<L>(ce_rate(ls), p.lambda_dot_min, p.kc, p.ke, p.d);
        SeeSolution {
            lambda_s: ls,
            sigma,
            dsigma,
            fv,
            dfv,
            iterations: 0,
        }
    };
    if drive <= 0.0 {
        // The CE carries nothing: σ_s = 0, λs = 1 (MODEL_NOTES "Hill fibre"),
        // no solve. σ_s(1) = β (e⁰ − 1) = 0 and σ_s'(1) = α β e⁰ = α β
        // (eq 7, 31) in closed form: the same numbers as evaluating eq 7 at
        // λs = 1, without the exponential (test
        // `zero_drive_is_the_closed_form_of_eq_7_at_rest`). f_v at the rate
        // of a slack SEE is still needed: ∂λs/∂a (the activation derivative
        // of the step) is σ0 f_λ f_v / σ_s'.
        let (fv, dfv) = force_velocity_with::<L>(ce_rate(1.0), p.lambda_dot_min, p.kc, p.ke, p.d);
        return SeeSolution {
            lambda_s: 1.0,
            sigma: 0.0,
            dsigma: p.alpha * p.beta,
            fv,
            dfv,
            iterations: 0,
        };
    }
    let residual_of =
        |e: &SeeSolution| (e.sigma - drive * e.fv, e.dsigma + drive * e.dfv * p.k / h);
    // Fast path: Newton's method from the warm start (the history's λs, or a
    // caller's prediction put there: R depends on the history through λm(t)
    // alone). R is strictly increasing, so a correction below tolerance with
    // R' > 0 can only be at its unique root. Anything else — a step below
    // λs = 1, a non-finite value, no convergence in 3 iterations — goes to the
    // bracketed iteration below.
    // The root lies below 1 + drive f_v,max / (α β) (σ_s(λs) ≥ α β (λs − 1)):
    // an iterate beyond it has left the region where the fast path is safe
    // (σ_s' may overflow there, making any correction look converged).
    let beyond = 1.0 + drive * p.fv_max() / (p.alpha * p.beta);
    let mut x = hist.lambda_s.max(1.0);
    let k_over_h = p.k / h;
    for iteration in 1..=3u32 {
        if x > beyond {
            break;
        }
        let e = evaluate(x);
        let (r, dr) = residual_of(&e);
        let step = r / dr;
        if !(r.is_finite() && dr.is_finite() && dr > 0.0) {
            break;
        }
        let next = x - step;
        // Applying the correction δ to first order leaves an error of about
        // C δ² with C = |R''| / (2 R'), R'' = α σ_s' − drive f_v'' (k/h)²
        // (σ_s'' = α σ_s', eq 31), valid while x and x − δ lie on the same
        // smooth piece of f_v. The two terms of R'' can cancel, so C is bounded
        // by their absolute values (which also bounds the first-order errors
        // of σ_s and f_v moved in `accept`). Accept when C δ² ≤ 1e-15.
        if step.abs() <= 1e-6 && next > 1.0 {
            let rate = ce_rate(x);
            let same_piece = force_velocity_branch(rate, p.lambda_dot_min)
                == force_velocity_branch(ce_rate(next), p.lambda_dot_min);
            let curvature =
                force_velocity_curvature_with::<L>(rate, p.lambda_dot_min, p.kc, p.ke, p.d);
            let r2 = p.alpha * e.dsigma.abs() + drive * curvature.abs() * k_over_h * k_over_h;
            if same_piece && r2 / (2.0 * dr) * step * step <= 1e-15 {
                return accept(e, next, iteration, k_over_h);
            }
        }
        x = next;
        if x <= 1.0 {
            break;
        }
    }
    // Upper end of the bracket: σ_s(hi) = drive f_v,max, so R(hi) ≥ 0. (The
    // log-free bound 1 + drive f_v,max / (α β) is valid too but so loose that
    // Newton overshoots into overflow and bisects for up to ~140 iterations.)
    let hi = see_stretch_for_stress(drive * p.fv_max(), p.alpha, p.beta);
    let mut last = evaluate(1.0);
    let residual = |ls: f64| {
        last = evaluate(ls);
        residual_of(&last)
    };
    let (ls, iterations) = match safeguarded_newton(residual, 1.0, hi, hist.lambda_s, 1e-12) {
        Ok(root) => (root.x, 3 + root.iterations),
        // [1, hi] brackets the root by construction (R(1) = −drive f_v ≤ 0,
        // R(hi) ≥ 0); keep the edge that is closer.
        Err(RootError::NotBracketed { lo, hi, f_lo, f_hi }) => {
            (if f_lo.abs() < f_hi.abs() { lo } else { hi }, 200)
        }
        // Not expected (the bracket halves at least every second iteration).
        Err(RootError::NoConvergence { lo, hi }) => (0.5 * (lo + hi), 200),
    };
    // At λs = 1 (the CE-free edge) evaluate afresh so that σ_s is exactly 0;
    // likewise when the iteration ended by bisection.
    if (ls - last.lambda_s).abs() <= 1e-12 && ls > 1.0 {
        accept(last, ls, iterations, p.k / h)
    } else {
        SeeSolution {
            iterations,
            ..evaluate(ls)
        }
    }
}

/// The solution at `ls` from the evaluation `e` at a nearby point (one
/// accepted Newton correction away) of the CE–SEE step solve (MODEL_NOTES
/// "Hill fibre"): σ_s (paper eq 7, slope eq 31) and f_v (eq 12) moved to
/// first order, with dλ̇m/dλs = −k/h = −`k_over_h` from the series kinematics
/// (1 + k) λ̄f = λm + k λs.
fn accept(e: SeeSolution, ls: f64, iterations: u32, k_over_h: f64) -> SeeSolution {
    let delta = ls - e.lambda_s;
    SeeSolution {
        lambda_s: ls,
        // σ_s(λs > 1) > 0; the first-order value may fall below 0 by round-off
        // (~1e-10 Pa) next to λs = 1.
        sigma: (e.sigma + e.dsigma * delta).max(0.0),
        fv: e.fv - e.dfv * k_over_h * delta,
        iterations,
        ..e
    }
}

#[cfg(test)]
mod tests {
    use super::super::force_velocity::force_velocity;
    use super::*;

    fn residual(p: &Params, lf: f64, a: f64, hist: &FibreHistory, h: f64, ls: f64) -> f64 {
        let lm = (1.0 + p.k) * lf - p.k * ls;
        let (fl, _) = force_length(lf, p.lambda_opt);
        let (fv, _) = force_velocity((lm - hist.lambda_m) / h, p.lambda_dot_min, p.kc, p.ke, p.d);
        see_stress(ls, p.alpha, p.beta).0 - p.sigma0 * a * fl * fv
    }

    /// Plain bisection on [1, 3] as an independent reference.
    fn bisection(p: &Params, lf: f64, a: f64, hist: &FibreHistory, h: f64) -> f64 {
        let (mut lo, mut hi) = (1.0, 3.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if residual(p, lf, a, hist, h, mid) < 0.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        0.5 * (lo + hi)
    }

    /// A deterministic pseudo-random sequence (xorshift), no extra crate.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    #[test]
    fn residual_is_monotone_in_see_stretch() {
        let p = Params::default();
        let mut rng = Rng(0x9e3779b97f4a7c15);
        for _ in 0..300 {
            let lf = rng.range(0.5, 1.6);
            let a = rng.range(0.0, 1.0);
            let h = 10f64.powf(rng.range(-6.0, -1.0));
            let hist = FibreHistory {
                lambda_s: rng.range(1.0, 1.2),
                lambda_m: rng.range(0.5, 1.6),
            };
            let mut prev = f64::NEG_INFINITY;
            for i in 0..=500 {
                let ls = 1.0 + 0.6 * i as f64 / 500.0;
                let r = residual(&p, lf, a, &hist, h, ls);
                assert!(r >= prev, "R not monotone at lf={lf} a={a} h={h} ls={ls}");
                prev = r;
            }
        }
    }

    /// Lower end of the paper's k_e range (not π).
    #[allow(clippy::approx_constant)]
    const KE_MIN: f64 = 3.14;

    #[test]
    fn step_solve_matches_bisection_on_random_and_extreme_inputs() {
        let mut rng = Rng(12345);
        for case in 0..3000 {
            // The paper's ranges (k_e from 3.14 to 7.56) and stiff SEEs.
            let p = Params {
                sigma0: rng.range(1.6e5, 1.0e6),
                kc: rng.range(4.0, 5.88),
                ke: rng.range(KE_MIN, 7.56),
                d: rng.range(1.0, 1.8),
                alpha: [10.0, 100.0, 1000.0][case % 3],
                ..Params::default()
            };
            let lf = rng.range(0.3, 2.0);
            let a = if case % 7 == 0 {
                1.0
            } else {
                rng.range(0.0, 1.0)
            };
            let h = 10f64.powf(rng.range(-7.0, 0.0));
            // History far from and near to the new state: length jumps in one step.
            let hist = FibreHistory {
                lambda_s: rng.range(1.0, 1.5),
                lambda_m: rng.range(0.2, 2.2),
            };
            let r = fibre_response(&p, lf, a, &hist, FibreRate::Step { h });
            let ls = r.history.lambda_s;
            assert!(ls.is_finite() && r.w.is_finite(), "case {case}");
            assert!(r.iterations < 200, "case {case}: no convergence");
            let reference = bisection(&p, lf, a, &hist, h);
            assert!(
                (ls - reference).abs() < 1e-12,
                "case {case}: {ls} vs bisection {reference}"
            );
            // Physical bounds: 0 ≤ σ_s ≤ σ0 a f_v,max.
            assert!(r.sigma_see >= 0.0);
            assert!(r.sigma_see <= p.sigma0 * a * p.fv_max() * (1.0 + 1e-12) + 1e-9);
        }
    }

    #[test]
    fn zero_drive_is_the_closed_form_of_eq_7_at_rest() {
        // With σ0 a f_λ = 0 the step is σ_s = 0, λs = 1 without a solve; the
        // closed form equals eq 7 and its slope evaluated at λs = 1 bit for
        // bit (what the solve returned before the shortcut).
        let mut rng = Rng(4242);
        for case in 0..2000 {
            let p = Params {
                alpha: rng.range(0.1, 1e3),
                beta: 10f64.powf(rng.range(-3.0, 9.0)),
                ..Params::default()
            };
            let lf = rng.range(0.3, 2.0);
            let h = 10f64.powf(rng.range(-7.0, 0.0));
            let hist = FibreHistory {
                lambda_s: 1.0,
                lambda_m: rng.range(0.2, 2.2),
            };
            // a = 0, or f_λ = 0 (r ≥ 1.6) with a > 0.
            let a = if case % 2 == 0 { 0.0 } else { 1.0 };
            let lf = if a > 0.0 { 1.7 * p.lambda_opt + lf } else { lf };
            let sol = step_solve::<FullLaw>(
                &p,
                lf,
                p.sigma0 * a * force_length(lf, p.lambda_opt).0,
                &hist,
                h,
            );
            let (sigma, dsigma) = see_stress(1.0, p.alpha, p.beta);
            let rate = (ce_stretch(p.k, lf, 1.0) - hist.lambda_m) / h;
            let (fv, dfv) = force_velocity(rate, p.lambda_dot_min, p.kc, p.ke, p.d);
            assert_eq!(sol.lambda_s.to_bits(), 1f64.to_bits());
            assert_eq!(sol.sigma.to_bits(), sigma.to_bits(), "case {case}");
            assert_eq!(sol.dsigma.to_bits(), dsigma.to_bits(), "case {case}");
            assert_eq!(sol.fv.to_bits(), fv.to_bits());
            assert_eq!(sol.dfv.to_bits(), dfv.to_bits());
            assert_eq!(sol.iterations, 0);
        }
    }

    #[test]
    fn isometric_solve_balances_see_and_ce() {
        let p = Params::default();
        for &(lf, a) in &[(1.0, 1.0), (1.05, 0.5), (0.7, 1.0), (1.8, 1.0), (1.0, 0.0)] {
            let r = fibre_response(&p, lf, a, &FibreHistory::REST, FibreRate::Isometric);
            let (fl, _) = force_length(lf, p.lambda_opt);
            assert!((r.sigma_see - p.sigma0 * a * fl).abs() < 1e-8 * p.sigma0);
            assert_eq!(
                r.history.lambda_m,
                (1.0 + p.k) * lf - p.k * r.history.lambda_s
            );
        }
    }

    #[test]
    fn long_isometric_hold_converges_to_the_isometric_solve() {
        let p = Params::default();
        let lf = 1.05;
        let mut hist = FibreHistory {
            lambda_s: 1.0,
            lambda_m: (1.0 + p.k) * lf - p.k,
        };
        for _ in 0..2000 {
            hist = fibre_response(&p, lf, 1.0, &hist, FibreRate::Step { h: 1e-3 }).history;
        }
        let iso = fibre_response(&p, lf, 1.0, &FibreHistory::REST, FibreRate::Isometric);
        assert!((hist.lambda_s - iso.history.lambda_s).abs() < 1e-10);
    }

    /// Whether λ̄f lies within the finite-difference reach (1e-4 in r) of a
    /// break of f_λ's pieces (r = λ̄f / λopt = 0.4, 0.6, 1.4, 1.6; paper eq 11).
    fn near_force_length_kink(p: &Params, lf: f64) -> bool {
        let r = lf / p.lambda_opt;
        [0.4, 0.6, 1.4, 1.6].iter().any(|k| (r - k).abs() < 1e-4)
    }

    /// How [`check_derivatives`] differentiates: central differences with
    /// step `step`, or (`richardson`) extrapolated from `step` and `step / 2`
    /// (their step² terms cancel), for the stiff cases where rounding
    /// forbids a small step.
    #[derive(Clone, Copy)]
    struct Fd {
        step: f64,
        richardson: bool,
    }

    /// The default: central differences, step 1e-7.
    const PLAIN: Fd = Fd {
        step: 1e-7,
        richardson: false,
    };
    /// The stiff lengthening cases (see their test).
    const STIFF: Fd = Fd {
        step: 1e-4,
        richardson: true,
    };

    impl Fd {
        fn of(self, g: &dyn Fn(f64) -> f64, x: f64) -> f64 {
            let central = |h: f64| (g(x + h) - g(x - h)) / (2.0 * h);
            if self.richardson {
                (4.0 * central(self.step / 2.0) - central(self.step)) / 3.0
            } else {
                central(self.step)
            }
        }
    }

    /// Differences `fd` in λ̄f, a and λm(t) of W and λs against the
    /// consistent derivatives of [`fibre_response`], to 1e-5 of the larger
    /// of the two (W's with a floor of 1e3 Pa, λs's of 1e-2). `a` stays
    /// inside (0, 1) by more than the step.
    fn check_derivatives(
        p: &Params,
        lf: f64,
        a: f64,
        hist: &FibreHistory,
        rate: FibreRate,
        fd: Fd,
    ) {
        let r = fibre_response(p, lf, a, hist, rate);
        let at = |lf: f64, a: f64, lm: f64| {
            let h = FibreHistory {
                lambda_m: lm,
                ..*hist
            };
            let out = fibre_response(p, lf, a, &h, rate);
            (out.w, out.history.lambda_s)
        };
        let lm = hist.lambda_m;
        let close = |fd: f64, an: f64, floor: f64, what: &str| {
            assert!(
                (fd - an).abs() < 1e-5 * an.abs().max(fd.abs()).max(floor),
                "{what}: fd {fd} vs {an} at lf={lf} a={a} {rate:?}"
            );
        };
        close(fd.of(&|x| at(x, a, lm).0, lf), r.dw_dlambda, 1e3, "dW/dλ");
        close(
            fd.of(&|x| at(lf, x, lm).0, a),
            r.dw_dactivation,
            1e3,
            "dW/da",
        );
        // The SEE stretch's derivatives, and both with respect to the CE
        // stretch of the history, λm(t) (what chains a step's substeps).
        close(
            fd.of(&|x| at(x, a, lm).1, lf),
            r.dls_dlambda,
            1e-2,
            "dλs/dλ",
        );
        close(
            fd.of(&|x| at(lf, x, lm).1, a),
            r.dls_dactivation,
            1e-2,
            "dλs/da",
        );
        close(
            fd.of(&|x| at(lf, a, x).1, lm),
            r.dls_dhistory,
            1e-2,
            "dλs/dλm(t)",
        );
        close(
            fd.of(&|x| at(lf, a, x).0, lm),
            r.dw_dhistory,
            1e3,
            "dW/dλm(t)",
        );
    }

    #[test]
    fn a_cold_start_far_from_the_root_converges_to_it() {
        // Regression: from λs = 1 during fast lengthening (f_v flat at its
        // maximum, R' ≈ α β) the first Newton step lands at λs ≈ 71, where
        // σ_s' overflows to +∞ and the correction R/R' = 0 used to be taken
        // for convergence (then σ_s = NaN, clamped to 0).
        let p = Params::default();
        let hist = FibreHistory {
            lambda_s: 1.0,
            lambda_m: 0.858_496_553_242_002_1,
        };
        for lf in [1.0275, 1.03] {
            let r = fibre_response(
                &p,
                lf,
                0.670_441_038_924_811,
                &hist,
                FibreRate::Step { h: 1e-4 },
            );
            let reference = bisection(&p, lf, 0.670_441_038_924_811, &hist, 1e-4);
            assert!(
                (r.history.lambda_s - reference).abs() < 1e-12,
                "{} vs {reference}",
                r.history.lambda_s
            );
            assert!(r.w.is_finite() && r.sigma_see > 0.0);
        }
    }

    #[test]
    fn moved_to_is_the_first_order_expansion() {
        // The error of the first-order move must shrink quadratically, and be
        // at round-off for the ~1e-9 moves the lateral solve applies.
        let p = Params::default();
        let hist = FibreHistory {
            lambda_s: 1.5,
            lambda_m: 0.9,
        };
        for rate in [FibreRate::Isometric, FibreRate::Step { h: 1e-3 }] {
            let r = fibre_response(&p, 1.05, 0.8, &hist, rate);
            let err = |d: f64| {
                let exact = fibre_response(&p, 1.05 + d, 0.8, &hist, rate);
                let moved = r.moved_to(&p, d);
                [
                    (moved.w - exact.w).abs(),
                    (moved.sigma_see - exact.sigma_see).abs(),
                    (moved.history.lambda_s - exact.history.lambda_s).abs(),
                    (moved.history.lambda_m - exact.history.lambda_m).abs(),
                ]
            };
            let (e5, e6, e9) = (err(1e-5), err(1e-6), err(-1e-9));
            for k in 0..4 {
                assert!(
                    e6[k] <= e5[k] / 50.0 + 1e-12,
                    "{rate:?} quantity {k}: {} then {}",
                    e5[k],
                    e6[k]
                );
            }
            assert!(
                e9[0] <= 1e-6 && e9[1] <= 1e-6 && e9[2] <= 1e-14 && e9[3] <= 1e-14,
                "{rate:?}: {e9:?}"
            );
        }
    }

    #[test]
    fn consistent_derivatives_match_finite_differences() {
        let p = Params::default();
        let mut rng = Rng(777);
        let mut checked = 0;
        for _ in 0..400 {
            let lf = rng.range(0.5, 1.6);
            let a = rng.range(0.05, 0.95);
            let h = 10f64.powf(rng.range(-5.0, -1.0));
            let hist = FibreHistory {
                lambda_s: rng.range(1.0, 1.2),
                lambda_m: (1.0 + p.k) * lf - p.k * 1.1 + rng.range(-0.05, 0.05),
            };
            // Skip points within the finite-difference reach of a kink
            // (f_λ at r = 0.4, 0.6, 1.4, 1.6; f_v at λ̇m = 0 and at x = 1).
            let r = fibre_response(&p, lf, a, &hist, FibreRate::Step { h });
            let near_fl_kink = near_force_length_kink(&p, lf);
            let dl = (1.0 + p.k) * 1e-6 / h;
            let near_fv_kink = r.lambda_dot_m.abs() < 10.0 * dl
                || (r.lambda_dot_m - p.lambda_dot_min).abs() < 10.0 * dl;
            if near_fl_kink || near_fv_kink {
                continue;
            }
            check_derivatives(&p, lf, a, &hist, FibreRate::Step { h }, PLAIN);
            check_derivatives(&p, lf, a, &hist, FibreRate::Isometric, PLAIN);
            checked += 1;
        }
        assert!(checked > 200, "only {checked} points checked");
    }

    /// The same checks on the lengthening branch of f_v (the paper's
    /// activated elongation), which the sampling above hardly reaches: the
    /// history's CE is shorter than the fibre's length now asks for, so the
    /// CE lengthens over the step. At the default alpha and at the stiff
    /// 100 and 1000 (the plateau's approach gets steeper), with the count
    /// of lengthening points asserted.
    #[test]
    fn consistent_derivatives_match_finite_differences_on_lengthening() {
        let mut rng = Rng(4242);
        for alpha in [10.0, 100.0, 1000.0] {
            let p = Params {
                alpha,
                ..Params::default()
            };
            let mut lengthening = 0;
            for _ in 0..600 {
                let lf = rng.range(0.8, 1.5);
                let a = rng.range(0.05, 0.95);
                let h = 10f64.powf(rng.range(-4.0, -1.0));
                let ls = rng.range(1.0, 1.1);
                let hist = FibreHistory {
                    lambda_s: ls,
                    lambda_m: (1.0 + p.k) * lf - p.k * ls - rng.range(0.02, 0.3),
                };
                if hist.lambda_m <= 0.0 {
                    continue;
                }
                let r = fibre_response(&p, lf, a, &hist, FibreRate::Step { h });
                let near_fl_kink = near_force_length_kink(&p, lf);
                let dl = (1.0 + p.k) * 1e-6 / h;
                if r.lambda_dot_m < 10.0 * dl || near_fl_kink {
                    continue;
                }
                // Steps of 1e-4 and 5e-5, Richardson-extrapolated: on this
                // branch at alpha = 1000 the derivatives are small against W
                // (2e2-3e3 against 3e5-1e6 Pa), and at a step of 1e-7 the
                // solve's rounding (~W · 1e-14 / step) reaches the 1e-5
                // tolerance (a probe: plain differences of dW/dλm(t) agree
                // to < 7e-7 at 1e-4 and drift to 5e-5 at 1e-6), while 1e-4
                // alone leaves a truncation error of 1.4e-4 in dλs/dλm(t).
                check_derivatives(&p, lf, a, &hist, FibreRate::Step { h }, STIFF);
                lengthening += 1;
            }
            assert!(
                lengthening > 100,
                "alpha {alpha}: only {lengthening} lengthening points"
            );
        }
    }
}
