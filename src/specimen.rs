//! The paper's test specimen (MODEL_NOTES "The 3D muscle"), shared by both
//! variants: the FE mesh is built on it, and the 1D FMU's default `area` is
//! its mean cross-section V0/L0, so both give the same stress scale.
//!
//! A solid of revolution of length L about the long axis with the radius
//! profile r(x) = r_end + (r_mid − r_end) sin(π x / L), 0 ≤ x ≤ L: diameter
//! 0.9 cm at the two end faces and 1.75 cm at the middle, smooth in between
//! (the paper gives only the two diameters; this profile is our choice).

use std::f64::consts::PI;

/// Rest length L0 \[m\].
pub const LENGTH: f64 = 0.05;
/// Radius of the end faces \[m\] (diameter 0.9 cm).
pub const END_RADIUS: f64 = 0.0045;
/// Radius at the middle \[m\] (diameter 1.75 cm).
pub const MID_RADIUS: f64 = 0.00875;

/// Volume of the fusiform solid in closed form (∫ sin = 2L/π,
/// ∫ sin² = L/2, Δ = r_mid − r_end):
/// V0 = π [ r_end² L + 2 r_end Δ (2L/π) + Δ² L/2 ].
pub const fn fusiform_volume(length: f64, r_end: f64, r_mid: f64) -> f64 {
    let d = r_mid - r_end;
    PI * (r_end * r_end * length + 2.0 * r_end * d * (2.0 * length / PI) + d * d * length / 2.0)
}

/// Volume V0 of the specimen \[m³\] (≈ 8.4245e-6).
pub const VOLUME: f64 = fusiform_volume(LENGTH, END_RADIUS, MID_RADIUS);
/// Mean cross-section V0 / L0 \[m²\] (≈ 1.6849e-4).
pub const MEAN_AREA: f64 = VOLUME / LENGTH;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volume_matches_quadrature() {
        // Composite Simpson on π r(x)².
        let n = 2000;
        let h = LENGTH / n as f64;
        let area = |x: f64| {
            let r = END_RADIUS + (MID_RADIUS - END_RADIUS) * (PI * x / LENGTH).sin();
            PI * r * r
        };
        let mut s = area(0.0) + area(LENGTH);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * area(i as f64 * h);
        }
        let simpson = s * h / 3.0;
        assert!(
            (simpson - VOLUME).abs() < 1e-12 * VOLUME,
            "{simpson} vs {VOLUME}"
        );
        assert!((MEAN_AREA - 1.6849e-4).abs() < 1e-8);
    }
}
