//! Isotropic matrix energy U_I(Ī1) (MODEL_NOTES "Energy and stress").

/// U_I = c (exp(b (Ī1 − 3)) − 1) (paper eq 3; MODEL_NOTES "Energy and stress").
pub fn matrix_energy(i1_bar: f64, b: f64, c: f64) -> f64 {
    c * (b * (i1_bar - 3.0)).exp_m1()
}

/// (U_I', U_I'') = (b c exp(b (Ī1 − 3)), b² c exp(b (Ī1 − 3))): U_I' is paper
/// eq 25 (MODEL_NOTES "Energy and stress"), U_I'' its derivative in Ī1 (for the
/// tangent, `super::stress` module docs).
#[inline]
pub fn matrix_derivatives(i1_bar: f64, b: f64, c: f64) -> (f64, f64) {
    let e = b * c * (b * (i1_bar - 3.0)).exp();
    (e, b * e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        for i1 in [3.0, 3.01, 3.2] {
            let h = 1e-6;
            let fd1 = (matrix_energy(i1 + h, 23.46, 379.0) - matrix_energy(i1 - h, 23.46, 379.0))
                / (2.0 * h);
            let (d1, d2) = matrix_derivatives(i1, 23.46, 379.0);
            assert!((fd1 / d1 - 1.0).abs() < 1e-8);
            let fd2 = (matrix_derivatives(i1 + h, 23.46, 379.0).0
                - matrix_derivatives(i1 - h, 23.46, 379.0).0)
                / (2.0 * h);
            assert!((fd2 / d2 - 1.0).abs() < 1e-8);
        }
        assert_eq!(matrix_energy(3.0, 23.46, 379.0), 0.0);
    }
}
