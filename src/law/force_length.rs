//! Active force-length relation f_λ (paper eq 11, MODEL_NOTES "Hill fibre").

/// f_λ(λ̄f) and its derivative d f_λ / d λ̄f, with r = λ̄f / λ_opt (eq 11):
/// 0 (r < 0.4); 9 (r − 0.4)² (0.4 ≤ r < 0.6); 1 − 4 (1 − r)² (0.6 ≤ r < 1.4);
/// 9 (r − 1.6)² (1.4 ≤ r < 1.6); 0 (r ≥ 1.6). Continuous, kinks at r = 0.6, 1.4.
pub fn force_length(lambda_f: f64, lambda_opt: f64) -> (f64, f64) {
    let r = lambda_f / lambda_opt;
    let (f, dfdr) = if !(0.4..1.6).contains(&r) {
        (0.0, 0.0)
    } else if r < 0.6 {
        (9.0 * (r - 0.4) * (r - 0.4), 18.0 * (r - 0.4))
    } else if r < 1.4 {
        (1.0 - 4.0 * (1.0 - r) * (1.0 - r), 8.0 * (1.0 - r))
    } else {
        (9.0 * (r - 1.6) * (r - 1.6), 18.0 * (r - 1.6))
    };
    (f, dfdr / lambda_opt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn support_peak_and_continuity() {
        let lo = 1.05;
        assert_eq!(force_length(0.39 * lo, lo).0, 0.0);
        assert_eq!(force_length(1.61 * lo, lo).0, 0.0);
        assert!((force_length(lo, lo).0 - 1.0).abs() < 1e-15);
        for r in [0.4, 0.6, 1.4, 1.6] {
            let x = r * lo;
            let below = force_length(x * (1.0 - 1e-12), lo).0;
            let above = force_length(x * (1.0 + 1e-12), lo).0;
            assert!((below - above).abs() < 1e-9, "jump at r = {r}");
        }
        // 0.6 and 1.4 take the value 0.36 on both pieces.
        assert!((force_length(0.6 * lo, lo).0 - 0.36).abs() < 1e-12);
        assert!((force_length(1.4 * lo, lo).0 - 0.36).abs() < 1e-12);
    }

    #[test]
    fn derivative_matches_finite_differences_away_from_kinks() {
        let lo = 1.05;
        for i in 0..400 {
            let x = 0.3 + 1.5 * (i as f64 + 0.5) / 400.0;
            let r = x / lo;
            if [0.4, 0.6, 1.4, 1.6].iter().any(|k| (r - k).abs() < 1e-4) {
                continue;
            }
            let h = 1e-7;
            let fd = (force_length(x + h, lo).0 - force_length(x - h, lo).0) / (2.0 * h);
            assert!((fd - force_length(x, lo).1).abs() < 1e-6, "x = {x}");
        }
    }
}
