//! Constant-thickness pennation (Zajac 1989; MODEL_NOTES "Musculotendon
//! unit"): fibres of length L_M at angle α to the line of action, with
//! L_M sin α = L0 sin α0 = h (the muscle's thickness) held.
//!
//! Entry points: [`Pennation`] (from `L0` and α0), its [`Pennation::at`]
//! (cos α, the projection L_M cos α and their derivatives) and
//! [`Pennation::fibre_length_of`] (the inverse: the fibre length of a
//! projection, the rigid tendon's closed form).
//!
//! The largest angle: α may not reach 90° (the projection would stop
//! depending on L_M and the force along the path would vanish). The angle is
//! at most α_max with cos α_max = [`MIN_COS`] = 0.1 (84.3°), i.e. the fibre
//! length is at least h / sin α_max ([`Pennation::min_fibre_length`]). A
//! length below it is outside the model: [`Pennation::at`] is not evaluated
//! there, and an equilibrium that would need it is refused
//! (`musculotendon::EquilibriumError::LargestAngle`), never clamped silently.

/// The smallest cos α the unit admits (the largest angle, 84.3°).
pub const MIN_COS: f64 = 0.1;

/// The pennation of a muscle: its thickness h = L0 sin α0 (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pennation {
    pub height: f64,
}

/// The pennation at one fibre length L_M.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pennated {
    /// cos α = sqrt(1 − (h / L_M)²).
    pub cos: f64,
    /// α (rad).
    pub angle: f64,
    /// The fibres' projection on the line of action, L_M cos α (m).
    pub projection: f64,
    /// d(L_M cos α)/dL_M = 1 / cos α.
    pub dprojection: f64,
    /// d(cos α)/dL_M = h² / (L_M³ cos α) (1/m).
    pub dcos: f64,
}

impl Pennation {
    /// The pennation of fibres of rest length `l0` at angle `alpha0` (rad)
    /// there: h = L0 sin α0 (MODEL_NOTES "Musculotendon unit").
    pub fn new(l0: f64, alpha0: f64) -> Self {
        Pennation {
            height: l0 * alpha0.sin(),
        }
    }

    /// sin α_max = sqrt(1 − MIN_COS²).
    fn max_sin() -> f64 {
        (1.0 - MIN_COS * MIN_COS).sqrt()
    }

    /// The shortest fibre length, h / sin α_max, at the largest angle (0
    /// without pennation).
    pub fn min_fibre_length(&self) -> f64 {
        self.height / Self::max_sin()
    }

    /// The shortest projection L_M cos α, h cos α_max / sin α_max, at the
    /// largest angle (0 without pennation).
    pub fn min_projection(&self) -> f64 {
        self.height * MIN_COS / Self::max_sin()
    }

    /// The pennation at fibre length `l_m` ≥ [`Pennation::min_fibre_length`]
    /// (constant thickness, MODEL_NOTES "Musculotendon unit"):
    /// cos α = sqrt(1 − (h/L_M)²), projection sqrt(L_M² − h²), its slope
    /// L_M / sqrt(L_M² − h²) = 1/cos α, and d cos α/dL_M = h²/(L_M³ cos α).
    /// Without pennation (h = 0) exactly cos α = 1 and projection L_M.
    #[inline]
    pub fn at(&self, l_m: f64) -> Pennated {
        let h = self.height;
        if h == 0.0 {
            return Pennated {
                cos: 1.0,
                angle: 0.0,
                projection: l_m,
                dprojection: 1.0,
                dcos: 0.0,
            };
        }
        let sin = h / l_m;
        let cos = (1.0 - sin * sin).sqrt();
        Pennated {
            cos,
            angle: sin.asin(),
            projection: l_m * cos,
            dprojection: 1.0 / cos,
            dcos: sin * sin / (l_m * cos),
        }
    }

    /// The fibre length whose projection is `projection` (the inverse of
    /// [`Pennation::at`]'s projection): sqrt(p² + h²); `None` below the
    /// largest angle's projection. Without pennation exactly `projection`.
    pub fn fibre_length_of(&self, projection: f64) -> Option<f64> {
        if self.height == 0.0 {
            return (projection >= 0.0).then_some(projection);
        }
        // Compared on the fibre length: the projection of `min_fibre_length`
        // may round a few ulp below `min_projection`.
        let l_m = projection.hypot(self.height);
        (projection >= 0.0 && l_m >= self.min_fibre_length() * (1.0 - 4.0 * f64::EPSILON))
            .then_some(l_m.max(self.min_fibre_length()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        let pen = Pennation::new(0.1, 0.5);
        for l_m in [pen.min_fibre_length() * 1.001, 0.06, 0.1, 0.15] {
            let d = 1e-8;
            let (p, m) = (pen.at(l_m + d), pen.at(l_m - d));
            let x = pen.at(l_m);
            let fd_proj = (p.projection - m.projection) / (2.0 * d);
            let fd_cos = (p.cos - m.cos) / (2.0 * d);
            assert!(
                (fd_proj - x.dprojection).abs() < 1e-6 * x.dprojection,
                "{l_m}"
            );
            assert!((fd_cos - x.dcos).abs() < 1e-5 * x.dcos, "{l_m}");
            assert!((x.angle.cos() - x.cos).abs() < 1e-14);
            // Constant thickness.
            assert!((l_m * x.angle.sin() - pen.height).abs() < 1e-15);
        }
    }

    #[test]
    fn the_largest_angle_has_cos_min_and_the_inverse_holds() {
        let pen = Pennation::new(0.1, 1.0);
        let at_max = pen.at(pen.min_fibre_length());
        assert!((at_max.cos - MIN_COS).abs() < 1e-12, "{}", at_max.cos);
        assert!((at_max.projection - pen.min_projection()).abs() < 1e-15);
        assert_eq!(pen.fibre_length_of(pen.min_projection() * 0.999), None);
        for l_m in [pen.min_fibre_length(), 0.09, 0.1, 0.2] {
            let back = pen.fibre_length_of(pen.at(l_m).projection).unwrap();
            assert!((back - l_m).abs() < 1e-15, "{l_m}: {back}");
        }
    }

    #[test]
    fn zero_pennation_is_the_identity() {
        let pen = Pennation::new(0.05, 0.0);
        let x = pen.at(0.0437);
        assert_eq!(
            (x.cos, x.projection, x.dprojection, x.dcos),
            (1.0, 0.0437, 1.0, 0.0)
        );
        assert_eq!(pen.fibre_length_of(0.0437), Some(0.0437));
        assert_eq!(pen.min_fibre_length(), 0.0);
    }
}
