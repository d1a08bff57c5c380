//! The 1D Hill reduction: the 3D law in homogeneous uniaxial stress
//! (MODEL_NOTES "The 1D Hill reduction").
//!
//! A prism with fibres along axis 1 is stretched by λ = L / L0 along the axis
//! and by μ on both lateral axes: F = diag(λ, μ, μ), J = λ μ². The lateral
//! faces are traction-free, σ22 = σ33 = 0, which fixes μ. Everything here is
//! evaluated through [`LawPoint`] — the same stress and consistent tangent the
//! 3D element uses — so the reduction is the 3D law, not a separate formula:
//!
//! - residual τ22(μ) = 0 (τ = J σ), solved by Newton with
//!   ∂τ22/∂μ = [δτ for g = diag(0, 1/μ, 1/μ)]_22 (consistent tangent, CE–SEE
//!   solve inside), with a bracketed bisection fallback;
//! - force F = σ11 A0 μ² = τ11 A0 / λ, nominal stress P = τ11 / λ, Cauchy
//!   stress σ11 = τ11 / J;
//! - total derivatives with respect to λ and the activation level a from the
//!   implicit function theorem on τ22 = 0.
//!
//! Incompressible limit (D → 0): μ = λ^(−1/2) and P = 2 U_I' (λ − λ⁻²) + W.

use nalgebra::{Matrix3, Vector3};

use super::hill_fibre::{FibreHistory, FibreRate};
use super::params::Params;
use super::stress::LawPoint;

/// The uniaxial state at the end of a step.
#[derive(Clone, Debug)]
pub struct Uniaxial {
    /// Axial stretch λ = L / L0.
    pub lambda: f64,
    /// Lateral stretch μ (σ22 = 0).
    pub mu: f64,
    /// The law at F = diag(λ, μ, μ).
    pub point: LawPoint,
    /// Axial Kirchhoff stress τ11.
    pub tau11: f64,
    /// Total derivatives of (μ, τ11, λ̄f, λs) with respect to λ, lateral
    /// equilibrium and the CE–SEE solve included (history fixed).
    pub d_dlambda: Sensitivity,
    /// The same with respect to the activation level a at fixed λ.
    pub d_dactivation: Sensitivity,
    /// Newton iterations of the lateral solve.
    pub iterations: u32,
}

/// Total derivatives of the uniaxial state with respect to one driver.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sensitivity {
    pub mu: f64,
    pub tau11: f64,
    pub lambda_f: f64,
    pub lambda_s: f64,
}

/// The lateral solve failed (only with non-physical inputs).
#[derive(Clone, Debug, PartialEq)]
pub struct UniaxialError(pub String);

impl Uniaxial {
    /// Nominal (engineering) stress P = F / A0 = τ11 / λ.
    pub fn nominal_stress(&self) -> f64 {
        self.tau11 / self.lambda
    }

    /// Axial Cauchy stress σ11 = τ11 / J.
    pub fn cauchy_stress(&self) -> f64 {
        self.tau11 / self.point.j
    }

    /// dP/dλ (total): (dτ11/dλ) / λ − τ11 / λ².
    pub fn dnominal_dlambda(&self) -> f64 {
        self.d_dlambda.tau11 / self.lambda - self.tau11 / (self.lambda * self.lambda)
    }

    /// dP/da (total) at fixed λ.
    pub fn dnominal_dactivation(&self) -> f64 {
        self.d_dactivation.tau11 / self.lambda
    }

    /// Total derivative of the Cauchy stress σ11 = τ11 / (λ μ²) along `s`,
    /// with `dlambda` = dλ along the same driver (1 for λ, 0 for a).
    pub fn dcauchy(&self, s: &Sensitivity, dlambda: f64) -> f64 {
        let (l, m) = (self.lambda, self.mu);
        let dj = m * m * dlambda + 2.0 * l * m * s.mu;
        s.tau11 / self.point.j - self.tau11 * dj / (self.point.j * self.point.j)
    }
}

/// The law at F = diag(λ, μ, μ) with fibres along axis 1.
fn evaluate(
    p: &Params,
    lambda: f64,
    mu: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
) -> LawPoint {
    let f = Matrix3::from_diagonal(&Vector3::new(lambda, mu, mu));
    LawPoint::new(p, &f, &Vector3::x(), activation, hist, rate)
}

/// δτ of `pt` along δF = diag(δλ, δμ, δμ), i.e. g = diag(δλ/λ, δμ/μ, δμ/μ).
fn variation(pt: &LawPoint, lambda: f64, mu: f64, dl: f64, dm: f64) -> Matrix3<f64> {
    let g = Matrix3::from_diagonal(&Vector3::new(dl / lambda, dm / mu, dm / mu));
    pt.kirchhoff_variation(&g)
}

/// Solve the uniaxial state at stretch `lambda` (MODEL_NOTES "The 1D Hill
/// reduction", lateral stretch from σ22 = 0), starting the lateral Newton
/// iteration from `mu_guess` (pass the previous step's μ scaled by
/// √(λ_prev/λ), or λ^(−1/2) when there is none).
pub fn solve_uniaxial(
    p: &Params,
    lambda: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
    mu_guess: f64,
) -> Result<Uniaxial, UniaxialError> {
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(UniaxialError(format!(
            "axial stretch {lambda} must be finite and > 0"
        )));
    }
    let residual = |mu: f64| -> (LawPoint, f64, f64) {
        let pt = evaluate(p, lambda, mu, activation, hist, rate);
        let tau22 = pt.kirchhoff()[(1, 1)];
        let slope = variation(&pt, lambda, mu, 0.0, 1.0)[(1, 1)];
        (pt, tau22, slope)
    };
    let mut mu = if mu_guess.is_finite() && mu_guess > 0.0 {
        mu_guess
    } else {
        lambda.sqrt().recip()
    };
    // Newton with a step limiter, the common path (2–4 iterations from a warm start).
    let mut iterations = 0u32;
    let mut converged: Option<LawPoint> = None;
    while iterations < 30 {
        iterations += 1;
        let (pt, r, dr) = residual(mu);
        let step = r / dr;
        if !(step.is_finite() && dr > 0.0) {
            break;
        }
        // Quadratic convergence: accept the point whose Newton correction is at
        // the round-off level of μ. Beyond 8 iterations accept a correction at
        // 1e-11 (floating-point noise of a stiff bulk term).
        let tol = if iterations <= 8 { 4e-15 } else { 1e-11 };
        if step.abs() <= tol * mu {
            converged = Some(pt);
            break;
        }
        mu -= step.clamp(-0.3 * mu, 0.3 * mu);
    }
    let (point, mu) = match converged {
        Some(pt) => (pt, mu),
        None => bisect_lateral(p, lambda, activation, hist, rate, &mut iterations)?,
    };
    Ok(finish(point, lambda, mu, iterations))
}

/// Fallback: bracket the root of τ22(μ) (increasing in μ) and bisect.
fn bisect_lateral(
    p: &Params,
    lambda: f64,
    activation: f64,
    hist: &FibreHistory,
    rate: FibreRate,
    iterations: &mut u32,
) -> Result<(LawPoint, f64), UniaxialError> {
    let tau22 = |mu: f64| evaluate(p, lambda, mu, activation, hist, rate).kirchhoff()[(1, 1)];
    let mu0 = lambda.sqrt().recip();
    let (mut lo, mut hi) = (mu0, mu0);
    let mut n = 0;
    // `<` and `>` are false for NaN, so a NaN residual keeps expanding (bounded).
    while tau22(lo).partial_cmp(&0.0) != Some(std::cmp::Ordering::Less) {
        lo *= 0.5;
        n += 1;
        if n > 60 {
            return Err(UniaxialError(format!(
                "lateral stretch not bracketed below at axial stretch {lambda}"
            )));
        }
    }
    while tau22(hi).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        hi *= 2.0;
        n += 1;
        if n > 120 {
            return Err(UniaxialError(format!(
                "lateral stretch not bracketed above at axial stretch {lambda}"
            )));
        }
    }
    for _ in 0..200 {
        *iterations += 1;
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if tau22(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let mu = 0.5 * (lo + hi);
    Ok((evaluate(p, lambda, mu, activation, hist, rate), mu))
}

/// Total derivatives by the implicit function theorem on τ22(λ, μ, a) = 0.
fn finish(point: LawPoint, lambda: f64, mu: f64, iterations: u32) -> Uniaxial {
    let tau = point.kirchhoff();
    let dl = variation(&point, lambda, mu, 1.0, 0.0); // ∂τ/∂λ
    let dm = variation(&point, lambda, mu, 0.0, 1.0); // ∂τ/∂μ
    let da = point.kirchhoff_activation_derivative(); // ∂τ/∂a
    let mu_l = -dl[(1, 1)] / dm[(1, 1)];
    let mu_a = -da[(1, 1)] / dm[(1, 1)];
    // λ̄f = λ^(2/3) μ^(−2/3).
    let lf = point.lambda_f;
    let lf_l = lf * (2.0 / 3.0) * (1.0 / lambda - mu_l / mu);
    let lf_a = -lf * (2.0 / 3.0) * mu_a / mu;
    // λs(λ̄f, a) from the CE–SEE solve.
    let ls_lf = point.fibre.dls_dlambda;
    let ls_a = point.fibre.dls_dactivation;
    Uniaxial {
        lambda,
        mu,
        tau11: tau[(0, 0)],
        d_dlambda: Sensitivity {
            mu: mu_l,
            tau11: dl[(0, 0)] + dm[(0, 0)] * mu_l,
            lambda_f: lf_l,
            lambda_s: ls_lf * lf_l,
        },
        d_dactivation: Sensitivity {
            mu: mu_a,
            tau11: da[(0, 0)] + dm[(0, 0)] * mu_a,
            lambda_f: lf_a,
            lambda_s: ls_a + ls_lf * lf_a,
        },
        point,
        iterations,
    }
}

#[cfg(test)]
mod tests {
    use super::super::isotropic_matrix::matrix_derivatives;
    use super::super::volumetric::volumetric_derivatives;
    use super::*;

    fn solve(p: &Params, lambda: f64, a: f64, hist: &FibreHistory, rate: FibreRate) -> Uniaxial {
        solve_uniaxial(p, lambda, a, hist, rate, lambda.sqrt().recip()).unwrap()
    }

    #[test]
    fn matches_the_closed_form_of_model_notes() {
        // σ11 = (1/J)[2 U_I' (λ̄f² − Ī1/3) + (2/3) λ̄f W] + U_J',
        // σ22 = (1/J)[2 U_I' (μ̄² − Ī1/3) − (1/3) λ̄f W] + U_J' = 0.
        for d_comp in [1e-9, 1e-6, 1e-4] {
            let p = Params {
                d_comp,
                ..Params::default()
            };
            for &(lambda, a) in &[(1.0, 0.0), (1.2, 0.0), (0.8, 0.0), (1.1, 1.0), (0.9, 0.5)] {
                let u = solve(&p, lambda, a, &FibreHistory::REST, FibreRate::Isometric);
                let j = lambda * u.mu * u.mu;
                let lf = j.powf(-1.0 / 3.0) * lambda;
                let mb = j.powf(-1.0 / 3.0) * u.mu;
                let i1 = lf * lf + 2.0 * mb * mb;
                let (du, _) = matrix_derivatives(i1, p.b, p.c);
                let (uj, _) = volumetric_derivatives(j, p.d_comp);
                let w = u.point.fibre.w;
                let s11 = (2.0 * du * (lf * lf - i1 / 3.0) + 2.0 / 3.0 * lf * w) / j + uj;
                let s22 = (2.0 * du * (mb * mb - i1 / 3.0) - lf * w / 3.0) / j + uj;
                let scale = s11.abs().max(p.c);
                assert!(
                    s22.abs() < 1e-6 * scale,
                    "D={d_comp} λ={lambda}: σ22 = {s22}"
                );
                assert!(
                    (u.cauchy_stress() - s11).abs() < 1e-6 * scale,
                    "D={d_comp} λ={lambda}: {} vs {s11}",
                    u.cauchy_stress()
                );
                // The same as the 3D stress at F = diag(λ, μ, μ).
                let sig = u.point.cauchy();
                assert!((sig[(0, 0)] - u.cauchy_stress()).abs() <= 1e-12 * scale);
                assert!(sig[(2, 2)].abs() < 1e-6 * scale && sig[(0, 1)] == 0.0);
            }
        }
    }

    #[test]
    fn incompressible_limit() {
        // D → 0: μ = λ^(−1/2), P = 2 U_I' (λ − λ⁻²) + W.
        let p = Params {
            d_comp: 1e-13,
            ..Params::default()
        };
        for &(lambda, a) in &[(1.2, 0.0), (0.85, 0.0), (1.05, 1.0), (1.3, 0.3)] {
            let u = solve(&p, lambda, a, &FibreHistory::REST, FibreRate::Isometric);
            assert!(
                (u.mu - lambda.powf(-0.5)).abs() < 1e-7,
                "μ = {} at λ = {lambda}",
                u.mu
            );
            let i1 = lambda * lambda + 2.0 / lambda;
            let (du, _) = matrix_derivatives(i1, p.b, p.c);
            let w = crate::law::fibre_response(
                &p,
                lambda,
                a,
                &FibreHistory::REST,
                FibreRate::Isometric,
            )
            .w;
            let expect = 2.0 * du * (lambda - lambda.powi(-2)) + w;
            assert!(
                (u.nominal_stress() - expect).abs() < 1e-5 * expect.abs().max(p.c),
                "{} vs {expect}",
                u.nominal_stress()
            );
        }
    }

    #[test]
    fn volume_change_vanishes_linearly_with_compressibility() {
        // At λ = 1.5 the matrix stress is ~1e10 Pa, so J − 1 = D p / 2 is
        // visible even at D = 1e-12; it must shrink in proportion to D.
        let dev = |d_comp: f64| {
            let p = Params {
                d_comp,
                ..Params::default()
            };
            let u = solve(&p, 1.5, 0.3, &FibreHistory::REST, FibreRate::Isometric);
            (u.point.j - 1.0).abs()
        };
        let (e12, e13, e14) = (dev(1e-12), dev(1e-13), dev(1e-14));
        // Ratios tend to 10 (9.2 and 9.9 measured: the pressure itself still
        // depends on J at D = 1e-12).
        let (r1, r2) = (e12 / e13, e13 / e14);
        assert!(
            r1 > 9.0 && r1 < 10.0 && r2 > 9.8 && r2 < 10.05 && r2 > r1,
            "{e12} {e13} {e14}"
        );
    }

    #[test]
    fn stress_falls_as_compressibility_grows_and_rises_with_sigma0() {
        let at = |d_comp: f64, sigma0: f64| {
            let p = Params {
                d_comp,
                sigma0,
                ..Params::default()
            };
            solve(&p, 1.2, 0.0, &FibreHistory::REST, FibreRate::Isometric).nominal_stress()
        };
        let (s9, s6, s4) = (at(1e-9, 7e5), at(1e-6, 7e5), at(1e-4, 7e5));
        assert!(s9 > s6 && s6 > s4, "{s9} {s6} {s4}");
        assert!(at(1e-9, 1e6) > at(1e-9, 1.6e5));
    }

    #[test]
    fn total_derivatives_match_finite_differences() {
        let p = Params::default();
        let cases = [
            (1.1, 0.0, FibreHistory::REST, FibreRate::Isometric),
            (1.02, 0.7, FibreHistory::REST, FibreRate::Isometric),
            (
                1.08,
                0.9,
                FibreHistory {
                    lambda_s: 1.03,
                    lambda_m: 1.05,
                },
                FibreRate::Step { h: 1e-3 },
            ),
            (
                0.93,
                0.6,
                FibreHistory {
                    lambda_s: 1.05,
                    lambda_m: 0.95,
                },
                FibreRate::Step { h: 1e-2 },
            ),
        ];
        for (lambda, a, hist, rate) in cases {
            let u = solve(&p, lambda, a, &hist, rate);
            // 1e-5, not smaller: with a 2 GPa bulk modulus the lateral solve's
            // round-off (~1e-15 in μ) is ~1e-5 Pa of stress, which a step of
            // 1e-7 turns into a 1e-5 relative error of the difference quotient.
            let e = 1e-5;
            let up = solve(&p, lambda + e, a, &hist, rate);
            let um = solve(&p, lambda - e, a, &hist, rate);
            let fd = |f: fn(&Uniaxial) -> f64| (f(&up) - f(&um)) / (2.0 * e);
            let close = |fd: f64, an: f64, what: &str| {
                assert!(
                    (fd - an).abs() < 1e-5 * an.abs().max(fd.abs()).max(1e-3),
                    "{what}: fd {fd} vs {an} at λ={lambda} a={a}"
                );
            };
            close(fd(|u| u.nominal_stress()), u.dnominal_dlambda(), "dP/dλ");
            close(fd(|u| u.mu), u.d_dlambda.mu, "dμ/dλ");
            close(fd(|u| u.point.lambda_f), u.d_dlambda.lambda_f, "dλ̄f/dλ");
            close(
                fd(|u| u.point.fibre.history.lambda_s),
                u.d_dlambda.lambda_s,
                "dλs/dλ",
            );
            close(
                fd(|u| u.cauchy_stress()),
                u.dcauchy(&u.d_dlambda, 1.0),
                "dσ11/dλ",
            );
            if a > 0.0 {
                // dP/da can be ~1e-2 of P (fast lengthening), so the same
                // round-off needs a larger step here.
                let ea = 1e-4;
                let ap = solve(&p, lambda, a + ea, &hist, rate);
                let am = solve(&p, lambda, a - ea, &hist, rate);
                let fda = |f: fn(&Uniaxial) -> f64| (f(&ap) - f(&am)) / (2.0 * ea);
                close(
                    fda(|u| u.nominal_stress()),
                    u.dnominal_dactivation(),
                    "dP/da",
                );
                close(fda(|u| u.mu), u.d_dactivation.mu, "dμ/da");
                close(
                    fda(|u| u.point.fibre.history.lambda_s),
                    u.d_dactivation.lambda_s,
                    "dλs/da",
                );
                close(
                    fda(|u| u.cauchy_stress()),
                    u.dcauchy(&u.d_dactivation, 0.0),
                    "dσ11/da",
                );
            }
        }
    }

    #[test]
    fn stiff_and_extreme_cases_converge() {
        for d_comp in [1e-12, 1e-9, 1e-6, 1e-4] {
            for alpha in [10.0, 100.0, 1000.0] {
                let p = Params {
                    d_comp,
                    alpha,
                    ..Params::default()
                };
                for lambda in [0.3, 0.5, 0.8, 1.0, 1.3, 1.6, 2.0] {
                    for a in [0.0, 1.0] {
                        for rate in [
                            FibreRate::Isometric,
                            FibreRate::Step { h: 1e-6 },
                            FibreRate::Step { h: 0.1 },
                        ] {
                            let u = solve_uniaxial(&p, lambda, a, &FibreHistory::REST, rate, 1.0)
                                .unwrap();
                            let s = u.nominal_stress();
                            assert!(
                                s.is_finite() && u.mu.is_finite(),
                                "D={d_comp} α={alpha} λ={lambda}"
                            );
                            let lateral = u.point.kirchhoff()[(1, 1)];
                            assert!(
                                lateral.abs() <= 1e-6 * u.tau11.abs().max(p.c),
                                "D={d_comp} α={alpha} λ={lambda}: τ22 = {lateral}"
                            );
                            if lambda > 1.0 && a == 0.0 {
                                assert!(s > 0.0, "passive tension must be positive");
                            }
                        }
                    }
                }
            }
        }
        assert!(solve_uniaxial(
            &Params::default(),
            f64::NAN,
            0.0,
            &FibreHistory::REST,
            FibreRate::Isometric,
            1.0
        )
        .is_err());
        assert!(solve_uniaxial(
            &Params::default(),
            0.0,
            0.0,
            &FibreHistory::REST,
            FibreRate::Isometric,
            1.0
        )
        .is_err());
    }
}
