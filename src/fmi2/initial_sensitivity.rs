//! Derivatives of the initial values with respect to parameters, for
//! `fmi2GetDirectionalDerivative` in Initialization Mode.
//!
//! FMI 2.0 spec, section 2.1.9: in Initialization Mode the unknowns are those
//! of `<InitialUnknowns>` and the knowns are the variables their
//! `dependencies` may name, section 2.2.8: the inputs and the variables with
//! `initial = "exact"`, so every (independent) parameter. A model gives the
//! derivatives with respect to its inputs itself
//! ([`Model::partial_derivative`]). With respect to a Real parameter the layer
//! differentiates the model's own initialization, which it can do for any
//! model without knowing what the model computes: on copies of the model, it
//! sets the parameter to nearby values ([`Model::set_real`]), runs
//! [`Model::initialize`] on each and reads the unknowns
//! ([`Model::get_real`]). A parameter that an unknown's `<InitialUnknowns>`
//! entry does not name has the derivative 0 there (the declared structure).

use super::model::{Model, SetOutcome};

/// The difference step δ relative to the parameter's value (absolute at a
/// value 0). With the Richardson combination below the truncation error is
/// O(δ⁴) (central) or O(δ³) (one-sided), while an initialization solved to a
/// relative tolerance ε adds ~ε/δ: the two balance near δ = ε^(1/5), 6e-4
/// for round-off (ε = 1e-16) and 1e-2 for a Newton tolerance of 1e-10.
/// 1e-3 serves both (tests/python/test_initial_parameter_derivatives.py
/// measures the result on every shipped FMU).
pub const RELATIVE_STEP: f64 = 1e-3;

/// Where the difference points lie around the parameter value p.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stencil {
    /// p ± δ and p ± δ/2.
    Central,
    /// p, p + sδ/2, p + sδ, p + 2sδ with s = ±1 (a bound within δ of p on
    /// the other side).
    OneSided(f64),
}

/// Step and stencil for a parameter at `p` with the declared range
/// [`min`, `max`]: the central stencil where p ± δ lie in the range, else the
/// one-sided stencil towards the side with room, δ shrunk to fit if needed.
fn stencil(p: f64, min: f64, max: f64) -> Result<(f64, Stencil), String> {
    let delta = RELATIVE_STEP * if p == 0.0 { 1.0 } else { p.abs() };
    if p - delta >= min && p + delta <= max {
        return Ok((delta, Stencil::Central));
    }
    let (room, side) = if max - p >= p - min {
        (max - p, 1.0)
    } else {
        (p - min, -1.0)
    };
    let delta = delta.min(room / 2.0);
    if delta > 0.0 && delta.is_finite() {
        Ok((delta, Stencil::OneSided(side)))
    } else {
        Err(format!(
            "its declared range [{min}, {max}] leaves no room for a difference step at {p}"
        ))
    }
}

/// ∂u/∂p at the current parameter value `p` for each of `unknowns`, by
/// differences of the initial values: central differences
/// D(δ) = (f(p+δ) − f(p−δ))/(2δ) at δ and δ/2, combined as
/// (4 D(δ/2) − D(δ))/3 (fourth order); next to a bound of the declared range
/// [`min`, `max`], the one-sided D(δ) = (−3 f(p) + 4 f(p+δ) − f(p+2δ))/(2δ)
/// combined the same way (third order). `model` is not changed.
pub fn initial_parameter_column<M: Model>(
    model: &M,
    param: M::Var,
    min: Option<f64>,
    max: Option<f64>,
    unknowns: &[M::Var],
) -> Result<Vec<f64>, String> {
    let p = model.get_real(param);
    let (delta, kind) = stencil(
        p,
        min.unwrap_or(f64::NEG_INFINITY),
        max.unwrap_or(f64::INFINITY),
    )?;
    let at = |x: f64| -> Result<Vec<f64>, String> {
        let mut m = model.clone();
        match m.set_real(param, x) {
            Ok(SetOutcome::Ok) => {}
            Ok(SetOutcome::Warning { message, .. }) => {
                return Err(format!(
                    "the difference step to {x} was adjusted: {message}"
                ))
            }
            Err(e) => return Err(format!("the difference step to {x} was refused: {}", e.0)),
        }
        m.initialize()
            .map_err(|e| format!("the initial values at {x} cannot be computed: {}", e.0))?;
        Ok(unknowns.iter().map(|&u| m.get_real(u)).collect())
    };
    let combine = |coarse: f64, fine: f64| (4.0 * fine - coarse) / 3.0;
    let column = match kind {
        Stencil::Central => {
            let (a, b) = (at(p + delta)?, at(p - delta)?);
            let (c, d) = (at(p + delta / 2.0)?, at(p - delta / 2.0)?);
            (0..unknowns.len())
                .map(|i| combine((a[i] - b[i]) / (2.0 * delta), (c[i] - d[i]) / delta))
                .collect()
        }
        Stencil::OneSided(s) => {
            let h = s * delta;
            let f0 = at(p)?;
            let (f1, f2, f4) = (at(p + h / 2.0)?, at(p + h)?, at(p + 2.0 * h)?);
            (0..unknowns.len())
                .map(|i| {
                    combine(
                        (-3.0 * f0[i] + 4.0 * f2[i] - f4[i]) / (2.0 * h),
                        (-3.0 * f0[i] + 4.0 * f1[i] - f2[i]) / h,
                    )
                })
                .collect()
        }
    };
    Ok(column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stencil_stays_inside_the_declared_range() {
        assert_eq!(stencil(2.0, 0.0, 10.0), Ok((2e-3, Stencil::Central)));
        assert_eq!(
            stencil(0.0, f64::NEG_INFINITY, f64::INFINITY),
            Ok((1e-3, Stencil::Central))
        );
        assert_eq!(stencil(0.0, 0.0, 1.0), Ok((1e-3, Stencil::OneSided(1.0))));
        assert_eq!(stencil(1.0, 0.0, 1.0), Ok((1e-3, Stencil::OneSided(-1.0))));
        // A range narrower than the step: shrunk so that p + 2δ is the bound.
        let (delta, kind) = stencil(1.0, 1.0, 1.0 + 1e-6).unwrap();
        assert_eq!(kind, Stencil::OneSided(1.0));
        assert!(1.0 + 2.0 * delta <= 1.0 + 1e-6 && delta > 4.9e-7, "{delta}");
        assert!(stencil(1.0, 1.0, 1.0).is_err());
    }
}
