//! Force-velocity relation f_v (paper eq 12 as restated in MODEL_NOTES "Hill fibre").

use super::components::Components;

/// f_v(λ̇m) and d f_v / d λ̇m (paper eq 12 as restated in MODEL_NOTES
/// "Hill fibre"), with x = λ̇m / λ̇_m^min (x > 0 when shortening):
/// - shortening (λ̇m ≤ 0): f_v = (1 − x) / (1 + k_c x), and 0 for x ≥ 1;
/// - lengthening (λ̇m > 0): f_v = d − (d − 1)(1 + x) / (1 − k_e k_c x).
///
/// f_v(0) = 1, f_v is non-decreasing in λ̇m and tends to d + (d − 1)/(k_e k_c).
#[inline]
pub fn force_velocity(
    lambda_dot_m: f64,
    lambda_dot_min: f64,
    kc: f64,
    ke: f64,
    d: f64,
) -> (f64, f64) {
    let x = lambda_dot_m / lambda_dot_min;
    let dx = 1.0 / lambda_dot_min;
    if lambda_dot_m <= 0.0 {
        if x >= 1.0 {
            (0.0, 0.0)
        } else {
            let den = 1.0 + kc * x;
            // d/dx (1 − x)/(1 + kc x) = −(1 + kc)/(1 + kc x)²
            ((1.0 - x) / den, -(1.0 + kc) / (den * den) * dx)
        }
    } else {
        let kk = ke * kc;
        let den = 1.0 - kk * x;
        // d/dx (1 + x)/(1 − kk x) = (1 + kk)/(1 − kk x)²
        (
            d - (d - 1.0) * (1.0 + x) / den,
            -(d - 1.0) * (1.0 + kk) / (den * den) * dx,
        )
    }
}

/// [`force_velocity`] with only the branches of eq 12 that `L` includes
/// ([`Components::FV_SHORTENING`], [`Components::FV_LENGTHENING`]): an absent
/// branch is replaced by its value at λ̇m = 0, f_v = 1 (df_v = 0). That keeps
/// f_v continuous and non-decreasing, so the CE–SEE residual of MODEL_NOTES
/// "Hill fibre" stays monotone with a unique root; a scene whose root lies on
/// an absent branch is told so by its FMU (the step is discarded). With both
/// branches this is [`force_velocity`] (the same code, bit for bit).
#[inline]
pub fn force_velocity_with<L: Components>(
    lambda_dot_m: f64,
    lambda_dot_min: f64,
    kc: f64,
    ke: f64,
    d: f64,
) -> (f64, f64) {
    if branch_included::<L>(lambda_dot_m) {
        force_velocity(lambda_dot_m, lambda_dot_min, kc, ke, d)
    } else {
        (1.0, 0.0)
    }
}

/// Whether the branch of eq 12 that λ̇m lies on (shortening λ̇m ≤ 0,
/// lengthening λ̇m > 0) is included in `L`.
#[inline]
pub fn branch_included<L: Components>(lambda_dot_m: f64) -> bool {
    if lambda_dot_m <= 0.0 {
        L::FV_SHORTENING
    } else {
        L::FV_LENGTHENING
    }
}

/// [`force_velocity_curvature`] of [`force_velocity_with`]: 0 on an absent
/// branch (f_v = 1 there).
#[inline]
pub fn force_velocity_curvature_with<L: Components>(
    lambda_dot_m: f64,
    lambda_dot_min: f64,
    kc: f64,
    ke: f64,
    d: f64,
) -> f64 {
    if branch_included::<L>(lambda_dot_m) {
        force_velocity_curvature(lambda_dot_m, lambda_dot_min, kc, ke, d)
    } else {
        0.0
    }
}

/// d²f_v/dλ̇m² of [`force_velocity`] (the second derivative of paper eq 12 in
/// the form of MODEL_NOTES "Hill fibre"; for the CE–SEE solve's error estimate):
/// shortening, d²/dx² (1 − x)/(1 + k_c x) = 2 k_c (1 + k_c)/(1 + k_c x)³ (0 for
/// x ≥ 1); lengthening, −(d − 1) d²/dx² (1 + x)/(1 − K x) = −(d − 1) 2 K (1 + K)/(1 − K x)³
/// with K = k_e k_c; divided by (λ̇_m^min)².
pub fn force_velocity_curvature(
    lambda_dot_m: f64,
    lambda_dot_min: f64,
    kc: f64,
    ke: f64,
    d: f64,
) -> f64 {
    let x = lambda_dot_m / lambda_dot_min;
    let scale = 1.0 / (lambda_dot_min * lambda_dot_min);
    if lambda_dot_m <= 0.0 {
        if x >= 1.0 {
            0.0
        } else {
            let den = 1.0 + kc * x;
            2.0 * kc * (1.0 + kc) / (den * den * den) * scale
        }
    } else {
        let kk = ke * kc;
        let den = 1.0 - kk * x;
        -(d - 1.0) * 2.0 * kk * (1.0 + kk) / (den * den * den) * scale
    }
}

/// Which smooth piece of f_v (paper eq 12, MODEL_NOTES "Hill fibre") a CE rate
/// lies on: 0 lengthening (λ̇m > 0), 1 shortening slower than the maximum rate
/// (x < 1), 2 faster (x ≥ 1, f_v = 0). f_v has kinks between them.
/// (x < 1 ⇔ λ̇m > λ̇_m^min, as λ̇_m^min < 0: compared without a division.)
pub fn force_velocity_branch(lambda_dot_m: f64, lambda_dot_min: f64) -> u8 {
    if lambda_dot_m > 0.0 {
        0
    } else if lambda_dot_m > lambda_dot_min {
        1
    } else {
        2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIN: f64 = -17.0;

    fn fv(r: f64) -> (f64, f64) {
        force_velocity(r, MIN, 5.0, 5.0, 1.5)
    }

    #[test]
    fn isometric_value_is_one_on_both_sides() {
        assert_eq!(fv(0.0).0, 1.0);
        assert!((fv(1e-12).0 - 1.0).abs() < 1e-12);
        assert!((fv(-1e-12).0 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn monotone_and_bounded_with_limits() {
        let fmax = 1.5 + 0.5 / 25.0;
        let mut prev = -1.0;
        for i in 0..=4000 {
            let r = -30.0 + 60.0 * i as f64 / 4000.0;
            let (f, df) = fv(r);
            assert!(f >= prev - 1e-15, "not monotone at {r}");
            assert!(df >= 0.0);
            assert!((0.0..=fmax).contains(&f));
            prev = f;
        }
        assert_eq!(fv(MIN).0, 0.0);
        assert_eq!(fv(2.0 * MIN).0, 0.0);
        assert!((fv(1e9).0 - fmax).abs() < 1e-6);
    }

    /// Every (k_c, k_e, d) of `sets` at 200 rates λ̇m across both branches
    /// (−16.5 … 23.5 1/s, beside the maximum shortening rate `MIN`), away
    /// from the kink at λ̇m = 0.
    fn on_the_rate_grid(sets: &[(f64, f64, f64)], mut check: impl FnMut(f64, f64, f64, f64)) {
        for &(kc, ke, d) in sets {
            for i in 0..200 {
                let r = -16.5 + 40.0 * (i as f64 + 0.5) / 200.0;
                if r.abs() >= 1e-3 {
                    check(kc, ke, d, r);
                }
            }
        }
    }

    #[allow(clippy::approx_constant)] // 3.14 is the paper's lower bound of k_e, not π
    const SETS: [(f64, f64, f64); 3] = [(5.0, 5.0, 1.5), (4.0, 3.14, 1.1), (5.88, 7.56, 1.8)];

    #[test]
    fn derivative_matches_finite_differences() {
        on_the_rate_grid(
            &[SETS[0], SETS[1], SETS[2], (5.0, 5.0, 1.0)],
            |kc, ke, d, r| {
                let h = 1e-6;
                let f = |r| force_velocity(r, MIN, kc, ke, d).0;
                let fd = (f(r + h) - f(r - h)) / (2.0 * h);
                let an = force_velocity(r, MIN, kc, ke, d).1;
                assert!(
                    (fd - an).abs() < 1e-6 * (1.0 + an.abs()),
                    "r={r} fd={fd} an={an}"
                );
            },
        );
    }

    /// [`force_velocity_curvature`] is the derivative of eq 12's first
    /// derivative, on both branches, away from the kinks at λ̇m = 0 and at
    /// the maximum shortening rate (and 0 beyond it).
    #[test]
    fn curvature_matches_finite_differences() {
        let mut lengthening = 0;
        on_the_rate_grid(&SETS, |kc, ke, d, r| {
            let h = 1e-5;
            let df = |r| force_velocity(r, MIN, kc, ke, d).1;
            let fd = (df(r + h) - df(r - h)) / (2.0 * h);
            let an = force_velocity_curvature(r, MIN, kc, ke, d);
            assert!(
                (fd - an).abs() < 1e-6 * an.abs().max(1e-3),
                "r={r} fd={fd} an={an} (kc={kc}, ke={ke}, d={d})"
            );
            lengthening += usize::from(r > 0.0 && an < 0.0);
        });
        assert!(lengthening > 100, "{lengthening}");
        for &(kc, ke, d) in &SETS {
            assert_eq!(force_velocity_curvature(1.5 * MIN, MIN, kc, ke, d), 0.0);
        }
    }
}
