//! Series elastic element (SEE), paper eq 6–7, 29 and 31 (MODEL_NOTES "Hill fibre").

/// σ_s(λs) = β (exp(α (λs − 1)) − 1) and dσ_s/dλs = α β exp(α (λs − 1))
/// (paper eq 7 = eq 29; eq 6 is its recurrence form, the exact integral of
/// dσ/dλ = α (σ + β), eq 31; MODEL_NOTES "Hill fibre").
#[inline]
pub fn see_stress(lambda_s: f64, alpha: f64, beta: f64) -> (f64, f64) {
    let e = (alpha * (lambda_s - 1.0)).exp();
    (beta * (e - 1.0), alpha * beta * e)
}

/// SEE stiffness from its stress, dσ_s/dλs = α (σ_s + β) (eq 31).
#[inline]
pub fn see_stiffness(sigma: f64, alpha: f64, beta: f64) -> f64 {
    alpha * (sigma + beta)
}

/// Inverse of [`see_stress`]: the SEE stretch carrying nominal stress σ ≥ 0,
/// λs = 1 + ln(1 + σ/β)/α (paper eq 7 solved for λs; MODEL_NOTES "Hill fibre").
#[inline]
pub fn see_stretch_for_stress(sigma: f64, alpha: f64, beta: f64) -> f64 {
    1.0 + (sigma / beta).ln_1p() / alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_at_rest_inverse_and_derivative() {
        assert_eq!(see_stress(1.0, 10.0, 1e3).0, 0.0);
        for s in [0.0, 1.0, 1e3, 7e5, 1e7] {
            let l = see_stretch_for_stress(s, 10.0, 1e3);
            assert!((see_stress(l, 10.0, 1e3).0 - s).abs() <= 1e-9 * (1.0 + s));
        }
        let l = 1.3;
        let h = 1e-7;
        let fd = (see_stress(l + h, 10.0, 1e3).0 - see_stress(l - h, 10.0, 1e3).0) / (2.0 * h);
        assert!((fd / see_stress(l, 10.0, 1e3).1 - 1.0).abs() < 1e-7);
        // eq 31: dσ/dλ = α (σ + β)
        let (s, ds) = see_stress(l, 10.0, 1e3);
        assert!((ds - see_stiffness(s, 10.0, 1e3)).abs() < 1e-9 * ds);
    }
}
