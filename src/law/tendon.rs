//! The tendon in series with the muscle: Thelen's (2003) force-strain curve
//! (MODEL_NOTES "Musculotendon unit").
//!
//! Entry points: [`tendon_curve`] (the normalized curve f_T(ε) and its slope)
//! and [`Tendon`] (a tendon of slack length L_TS and maximum isometric force
//! F0: force and stiffness at a tendon length). Invariants: f_T = 0 for ε ≤ 0
//! (a slack tendon carries nothing, in compression too), f_T is continuous
//! and non-decreasing, and its slope is continuous to 7.06e-4 relative at the
//! toe's end ε_toe (Thelen's rounded constants; the test says the figure).
//! The curve is the tendon's only up to its rupture strain
//! [`Tendon::max_strain`]: a musculotendon unit refuses an equilibrium that
//! needs more.

/// Force at the end of the toe region, as a fraction of F0 (Thelen 2003).
pub const F_TOE: f64 = 0.33;
/// Exponential shape factor of the toe region (Thelen 2003).
pub const K_TOE: f64 = 3.0;
/// ε_toe / ε0: where the toe region ends (Thelen 2003).
pub const TOE_STRAIN_RATIO: f64 = 0.609;
/// k_lin ε0: the linear region's slope times ε0 (Thelen 2003).
pub const LINEAR_SLOPE_TIMES_STRAIN: f64 = 1.712;

/// ε_max / ε0: the strain at which the tendon ruptures, in units of its
/// strain at F0. Tendons fail at strains of about 8–10 % (Butler, Grood,
/// Noyes & Zernicke 1978, "Biomechanics of ligaments and tendons", Exerc.
/// Sport Sci. Rev. 6: 125–181); with Thelen's (2003) ε0 = 0.04, the
/// default, 2.5 ε0 = 0.10 is the upper end of that range. Scaled with ε0,
/// the bound is one point of the normalized curve for every tendon:
/// f_T(2.5 ε0) = 1.712 (2.5 − 0.609) + 0.33 = 3.567 F0.
pub const RUPTURE_STRAIN_RATIO: f64 = 2.5;

/// Thelen's normalized tendon force f_T(ε) = F_T / F0 and its slope
/// df_T/dε at strain `eps`, for the strain at F0 `eps0` (MODEL_NOTES
/// "Musculotendon unit"): 0 for ε ≤ 0 (slack);
/// F_toe (e^(k_toe ε/ε_toe) − 1)/(e^(k_toe) − 1) for 0 < ε ≤ ε_toe;
/// k_lin (ε − ε_toe) + F_toe above, with ε_toe = 0.609 ε0, k_lin = 1.712/ε0.
#[inline]
pub fn tendon_curve(eps: f64, eps0: f64) -> (f64, f64) {
    let eps_toe = TOE_STRAIN_RATIO * eps0;
    if eps <= 0.0 {
        (0.0, 0.0)
    } else if eps <= eps_toe {
        let scale = F_TOE / K_TOE.exp_m1();
        let rate = K_TOE / eps_toe;
        let e = (rate * eps).exp();
        (scale * (e - 1.0), scale * rate * e)
    } else {
        let k_lin = LINEAR_SLOPE_TIMES_STRAIN / eps0;
        (k_lin * (eps - eps_toe) + F_TOE, k_lin)
    }
}

/// A tendon: slack length L_TS (m), strain at F0 ε0, and the muscle's
/// maximum isometric force F0 = σ0 · area (N) that scales its curve
/// (MODEL_NOTES "Musculotendon unit").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tendon {
    pub slack_length: f64,
    pub strain_at_f0: f64,
    pub f0: f64,
}

impl Tendon {
    /// Strain ε = L_T / L_TS − 1 at tendon length `length` (MODEL_NOTES
    /// "Musculotendon unit").
    #[inline]
    pub fn strain(&self, length: f64) -> f64 {
        length / self.slack_length - 1.0
    }

    /// The largest strain the tendon takes, ε_max = [`RUPTURE_STRAIN_RATIO`]
    /// ε0 (its rupture strain); a longer tendon is no equilibrium of the
    /// unit.
    #[inline]
    pub fn max_strain(&self) -> f64 {
        RUPTURE_STRAIN_RATIO * self.strain_at_f0
    }

    /// The strain at which the tendon carries `force` (N) > 0: the inverse
    /// of [`tendon_curve`], ε_toe/k_toe · ln(1 + f (e^k_toe − 1)/F_toe) for
    /// f = F/F0 ≤ F_toe, ε_toe + (f − F_toe)/k_lin above (MODEL_NOTES
    /// "Musculotendon unit").
    pub fn strain_at(&self, force: f64) -> f64 {
        let (eps0, f) = (self.strain_at_f0, force / self.f0);
        let eps_toe = TOE_STRAIN_RATIO * eps0;
        if f <= F_TOE {
            eps_toe / K_TOE * (f * K_TOE.exp_m1() / F_TOE).ln_1p()
        } else {
            eps_toe + (f - F_TOE) * eps0 / LINEAR_SLOPE_TIMES_STRAIN
        }
    }

    /// Force F_T = F0 f_T(ε) (N) and stiffness dF_T/dL_T (N/m) at tendon
    /// length `length` (MODEL_NOTES "Musculotendon unit"; ε as
    /// [`Tendon::strain`]).
    #[inline]
    pub fn force(&self, length: f64) -> (f64, f64) {
        let (f, df) = tendon_curve(self.strain(length), self.strain_at_f0);
        (self.f0 * f, self.f0 * df / self.slack_length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slack_carries_nothing_and_f0_is_reached_near_eps0() {
        for eps0 in [1e-4, 0.04, 0.1] {
            for eps in [-1.0, -1e-3, 0.0] {
                assert_eq!(tendon_curve(eps, eps0), (0.0, 0.0));
            }
            // 1.712 (1 − 0.609) + 0.33 = 0.999392 at ε0.
            let (f, _) = tendon_curve(eps0, eps0);
            assert!((f - 0.999392).abs() < 1e-12, "{f}");
        }
    }

    #[test]
    fn the_rupture_strain_is_ten_percent_at_the_default_and_3_567_f0() {
        let t = |eps0| Tendon {
            slack_length: 0.2,
            strain_at_f0: eps0,
            f0: 1.0,
        };
        assert!((t(0.04).max_strain() - 0.10).abs() < 1e-15);
        for eps0 in [1e-4, 0.04, 1.0] {
            let (f, _) = tendon_curve(t(eps0).max_strain(), eps0);
            assert!((f - 3.567392).abs() < 1e-12, "{f}");
        }
    }

    #[test]
    fn strain_at_inverts_the_curve() {
        let t = Tendon {
            slack_length: 0.2,
            strain_at_f0: 0.04,
            f0: 800.0,
        };
        for eps in [1e-6, 0.003, 0.0243, 0.03, 0.1] {
            let f = t.force(t.slack_length * (1.0 + eps)).0;
            let back = t.strain_at(f);
            assert!((back - eps).abs() <= 1e-12, "{eps}: {back}");
        }
    }

    #[test]
    fn value_and_slope_are_continuous_at_the_toe_end() {
        for eps0 in [1e-6, 1e-4, 0.04, 1.0] {
            let eps_toe = TOE_STRAIN_RATIO * eps0;
            let below = tendon_curve(eps_toe, eps0);
            let above = tendon_curve(eps_toe * (1.0 + 1e-15), eps0);
            let value_jump = (above.0 - below.0).abs();
            assert!(value_jump < 1e-12, "value jump {value_jump:e}");
            // Thelen's rounded constants: toe slope 0.99 e³/((e³ − 1) 0.609)
            // = 1.71079/ε0 against k_lin = 1.712/ε0, a relative jump of 7.06e-4.
            let slope_jump = (above.1 - below.1).abs() / above.1;
            assert!(slope_jump < 1e-3, "slope jump {slope_jump:e}");
            assert!(
                (slope_jump - 7.06e-4).abs() < 1e-6,
                "slope jump {slope_jump:e}"
            );
        }
    }

    #[test]
    fn slope_matches_finite_differences() {
        let eps0 = 0.04;
        for eps in [1e-5, 0.003, 0.012, 0.0243, 0.03, 0.05, 0.2] {
            let d = 1e-7 * eps0;
            let fd = (tendon_curve(eps + d, eps0).0 - tendon_curve(eps - d, eps0).0) / (2.0 * d);
            let (_, slope) = tendon_curve(eps, eps0);
            assert!(
                (fd - slope).abs() <= 1e-6 * slope,
                "ε {eps}: {fd} vs {slope}"
            );
        }
        let t = Tendon {
            slack_length: 0.2,
            strain_at_f0: 0.04,
            f0: 800.0,
        };
        for lt in [0.2005, 0.203, 0.21] {
            let d = 1e-9;
            let fd = (t.force(lt + d).0 - t.force(lt - d).0) / (2.0 * d);
            let k = t.force(lt).1;
            assert!((fd - k).abs() <= 1e-5 * k, "{fd} vs {k}");
        }
    }
}
