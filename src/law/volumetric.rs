//! Volumetric penalty U_J(J) (MODEL_NOTES "Energy and stress").

/// U_J = (J − 1)² / D (paper eq 5; MODEL_NOTES "Energy and stress").
pub fn volumetric_energy(j: f64, d_comp: f64) -> f64 {
    (j - 1.0) * (j - 1.0) / d_comp
}

/// (U_J', U_J'') = (2 (J − 1) / D, 2 / D): U_J' is paper eq 27 (MODEL_NOTES
/// "Energy and stress"), the hydrostatic pressure p of eq 30's U_J' I term;
/// U_J'' is its derivative in J (for the tangent).
#[inline]
pub fn volumetric_derivatives(j: f64, d_comp: f64) -> (f64, f64) {
    (2.0 * (j - 1.0) / d_comp, 2.0 / d_comp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        let d = 1e-6;
        for j in [0.9, 1.0, 1.05] {
            let h = 1e-6;
            let fd = (volumetric_energy(j + h, d) - volumetric_energy(j - h, d)) / (2.0 * h);
            let (p, dp) = volumetric_derivatives(j, d);
            assert!((fd - p).abs() < 1e-6 * (1.0 + p.abs()) + 1e-2);
            let p_of = |j| volumetric_derivatives(j, d).0;
            let fd2 = (p_of(j + h) - p_of(j - h)) / (2.0 * h);
            assert!((fd2 - dp).abs() < 1e-6 * dp, "U_J'': fd {fd2} vs {dp}");
        }
    }
}
