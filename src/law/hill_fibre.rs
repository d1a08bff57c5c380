//! The Hill fibre: contractile element (CE) in series with the series elastic
//! element (SEE), in parallel with the parallel element (PE)
//! (MODEL_NOTES "Hill fibre", paper eq 5–23).
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

use super::force_length::force_length;
use super::force_velocity::force_velocity;
use super::parallel_element::pe_stress;
use super::params::Params;
use super::root_finding::{safeguarded_newton, RootError};
use super::series_element::{see_stress, see_stretch_for_stress};

/// History of one fibre at the start of a step: the SEE and CE stretches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreHistory {
    pub lambda_s: f64,
    pub lambda_m: f64,
}

impl FibreHistory {
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
}

/// Fibre nominal stress W(λ̄f) at the end of a step, with the CE–SEE solve and
/// its consistent derivatives (MODEL_NOTES "Hill fibre").
///
/// Derivatives at the root, from R(λs, λ̄f, a) = 0:
/// R_λs = σ_s' + σ0 a f_λ f_v' k / h,
/// R_λf = −σ0 a f_λ' f_v − σ0 a f_λ f_v' (1 + k) / h,  R_a = −σ0 f_λ f_v,
/// dλs/dλ̄f = −R_λf / R_λs,  dλs/da = −R_a / R_λs,
/// dW/dλ̄f = σ_s' dλs/dλ̄f + σ_p',  ∂W/∂a = σ_s' dλs/da.
pub fn fibre_response(
    p: &Params,
    lambda_f: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
) -> FibreResponse {
    let (sigma_pe, dsigma_pe) = pe_stress(lambda_f, p.sigma0, p.a_pe);
    let (f_l, df_l) = force_length(lambda_f, p.lambda_opt);
    let drive = p.sigma0 * activation * f_l; // σ0 a f_λ
    let ce_stretch = |lambda_s: f64| (1.0 + p.k) * lambda_f - p.k * lambda_s;

    let (lambda_s, lambda_dot_m, iterations, dls_df, dls_da) = match rate {
        FibreRate::Isometric => {
            // σ_s(λs) = σ0 a f_λ with f_v(0) = 1.
            let ls = see_stretch_for_stress(drive.max(0.0), p.alpha, p.beta);
            let (_, ds) = see_stress(ls, p.alpha, p.beta);
            (
                ls,
                0.0,
                0,
                p.sigma0 * activation * df_l / ds,
                p.sigma0 * f_l / ds,
            )
        }
        FibreRate::Step { h } => {
            let rate_of = |ls: f64| (ce_stretch(ls) - hist.lambda_m) / h;
            let fv = |ls: f64| force_velocity(rate_of(ls), p.lambda_dot_min, p.kc, p.ke, p.d);
            let ls = if drive > 0.0 {
                let hi = see_stretch_for_stress(drive * p.fv_max(), p.alpha, p.beta);
                let residual = |ls: f64| {
                    let (s, ds) = see_stress(ls, p.alpha, p.beta);
                    let (f, df) = fv(ls);
                    (s - drive * f, ds + drive * df * p.k / h)
                };
                match safeguarded_newton(residual, 1.0, hi, hist.lambda_s, 1e-12) {
                    Ok(root) => (root.x, root.iterations),
                    // The bracket [1, hi] is valid by construction (R(1) = −drive·f_v ≤ 0,
                    // R(hi) = drive (f_v,max − f_v) ≥ 0); keep the edge that is closer.
                    Err(RootError::NotBracketed { lo, hi, f_lo, f_hi }) => {
                        (if f_lo.abs() < f_hi.abs() { lo } else { hi }, 200)
                    }
                }
            } else {
                // The CE carries nothing: σ_s = 0, λs = 1.
                (1.0, 0)
            };
            let (ls, iterations) = ls;
            let (_, ds) = see_stress(ls, p.alpha, p.beta);
            let (f, df) = fv(ls);
            let r_ls = ds + drive * df * p.k / h;
            let r_lf = -p.sigma0 * activation * df_l * f - drive * df * (1.0 + p.k) / h;
            let r_a = -p.sigma0 * f_l * f;
            (ls, rate_of(ls), iterations, -r_lf / r_ls, -r_a / r_ls)
        }
    };
    let (sigma_see, dsigma_see) = see_stress(lambda_s, p.alpha, p.beta);
    FibreResponse {
        w: sigma_see + sigma_pe,
        dw_dlambda: dsigma_see * dls_df + dsigma_pe,
        dw_dactivation: dsigma_see * dls_da,
        dls_dlambda: dls_df,
        dls_dactivation: dls_da,
        sigma_see,
        sigma_pe,
        history: FibreHistory {
            lambda_s,
            lambda_m: ce_stretch(lambda_s),
        },
        lambda_dot_m,
        iterations,
    }
}

#[cfg(test)]
mod tests {
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

    fn check_derivatives(p: &Params, lf: f64, a: f64, hist: &FibreHistory, rate: FibreRate) {
        let r = fibre_response(p, lf, a, hist, rate);
        let e = 1e-7;
        let wp = fibre_response(p, lf + e, a, hist, rate).w;
        let wm = fibre_response(p, lf - e, a, hist, rate).w;
        let fd = (wp - wm) / (2.0 * e);
        let scale = r.dw_dlambda.abs().max(1e3);
        assert!(
            (fd - r.dw_dlambda).abs() < 1e-5 * scale,
            "dW/dλ: fd {fd} vs {} at lf={lf} a={a} {rate:?}",
            r.dw_dlambda
        );
        let ea = 1e-7;
        let (ap, am) = ((a + ea).min(1.0), (a - ea).max(0.0));
        let fd_a = (fibre_response(p, lf, ap, hist, rate).w
            - fibre_response(p, lf, am, hist, rate).w)
            / (ap - am);
        let scale = r.dw_dactivation.abs().max(1e3);
        assert!(
            (fd_a - r.dw_dactivation).abs() < 1e-5 * scale,
            "dW/da: fd {fd_a} vs {} at lf={lf} a={a} {rate:?}",
            r.dw_dactivation
        );
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
            let rr = lf / p.lambda_opt;
            let near_fl_kink = [0.4, 0.6, 1.4, 1.6].iter().any(|k| (rr - k).abs() < 1e-4);
            let dl = (1.0 + p.k) * 1e-6 / h;
            let near_fv_kink = r.lambda_dot_m.abs() < 10.0 * dl
                || (r.lambda_dot_m - p.lambda_dot_min).abs() < 10.0 * dl;
            if near_fl_kink || near_fv_kink {
                continue;
            }
            check_derivatives(&p, lf, a, &hist, FibreRate::Step { h });
            check_derivatives(&p, lf, a, &hist, FibreRate::Isometric);
            checked += 1;
        }
        assert!(checked > 200, "only {checked} points checked");
    }
}
