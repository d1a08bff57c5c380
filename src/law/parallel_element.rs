//! Parallel elastic element (PE), paper eq 22–23 (eq 28 with A = 4).

/// σ_p(λ̄f) = σ0 A (λ̄f − 1)² for λ̄f > 1, else 0 (paper eq 22–23; MODEL_NOTES
/// "Energy and stress"), and its derivative dσ_p/dλ̄f = 2 σ0 A (λ̄f − 1).
#[inline]
pub fn pe_stress(lambda_f: f64, sigma0: f64, a_pe: f64) -> (f64, f64) {
    if lambda_f > 1.0 {
        let e = lambda_f - 1.0;
        (sigma0 * a_pe * e * e, 2.0 * sigma0 * a_pe * e)
    } else {
        (0.0, 0.0)
    }
}

/// Normalised PE force f_PE = σ_p / σ0 = A (λ̄f − 1)² for λ̄f > 1, else 0
/// (paper eq 23, plotted in Fig 3).
pub fn pe_force_normalised(lambda_f: f64, a_pe: f64) -> f64 {
    pe_stress(lambda_f, 1.0, a_pe).0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slack_below_rest_quadratic_above() {
        assert_eq!(pe_stress(0.8, 7e5, 4.0), (0.0, 0.0));
        assert_eq!(pe_stress(1.0, 7e5, 4.0), (0.0, 0.0));
        let (s, ds) = pe_stress(1.2, 7e5, 4.0);
        assert!((s - 7e5 * 4.0 * 0.04).abs() < 1e-6);
        assert!((ds - 2.0 * 7e5 * 4.0 * 0.2).abs() < 1e-6);
        assert!((pe_force_normalised(1.5, 4.0) - 1.0).abs() < 1e-12);
    }
}
