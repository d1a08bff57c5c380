//! Safeguarded Newton iteration for increasing scalar functions with a bracket.

/// Why a bracketed solve failed.
#[derive(Clone, Debug, PartialEq)]
pub enum RootError {
    /// f(lo) > 0 or f(hi) < 0, or a non-finite value.
    NotBracketed {
        lo: f64,
        hi: f64,
        f_lo: f64,
        f_hi: f64,
    },
    /// The iteration cap was reached (not expected with a valid bracket: the
    /// bracket at least halves every second iteration).
    NoConvergence { lo: f64, hi: f64 },
}

/// A converged root.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Root {
    pub x: f64,
    /// f'(x) at the returned root (for implicit derivatives).
    pub slope: f64,
    pub iterations: u32,
}

/// Root of a non-decreasing `f` (returning value and derivative) in `[lo, hi]`
/// with f(lo) ≤ 0 ≤ f(hi), starting from `x0`. A Newton step is taken when
/// it stays strictly inside the current bracket, the derivative is positive
/// and finite, and it is at most half the step before last (the progress test
/// of the classic "rtsafe"); otherwise the bracket is bisected. So the bracket
/// at least halves every second iteration and the iteration converges for any
/// input (at worst like bisection), at Newton's rate near the root. Converged when the Newton correction is below `xtol` (the
/// correction is applied, leaving an error of O(xtol²)), or f(x) = 0, or the
/// bracket is narrower than `xtol`.
/// Used by the CE–SEE solve (MODEL_NOTES "Hill fibre": "a safeguarded
/// Newton (bracket + bisection fallback), never a bare Newton").
pub fn safeguarded_newton<F>(
    mut f: F,
    mut lo: f64,
    mut hi: f64,
    x0: f64,
    xtol: f64,
) -> Result<Root, RootError>
where
    F: FnMut(f64) -> (f64, f64),
{
    let mut x = if x0 > lo && x0 < hi {
        x0
    } else {
        0.5 * (lo + hi)
    };
    let mut iterations = 0u32;
    // The last two steps, for the progress test.
    let (mut dx, mut dx_old) = (hi - lo, hi - lo);
    let mut checked_lo = false;
    let mut checked_hi = false;
    // 200 iterations: a bisection halves ~1 to below 1e-16 within 60, so the
    // cap is never reached with a valid bracket; it only guards the loop.
    while iterations < 200 {
        iterations += 1;
        let (r, dr) = f(x);
        if !r.is_finite() {
            // Treat a non-finite value as lying above the root (overflowing
            // exponentials grow with x); shrink from above.
            hi = x;
            x = 0.5 * (lo + hi);
            continue;
        }
        if r == 0.0 {
            return Ok(Root {
                x,
                slope: dr,
                iterations,
            });
        }
        if r < 0.0 {
            lo = x;
            checked_lo = true;
        } else {
            hi = x;
            checked_hi = true;
        }
        let step = r / dr;
        let newton = x - step;
        // Converged: a Newton correction below `xtol` is applied and accepted
        // (its own error is O(step²)). Checked before the bracket test, since a
        // correction below the rounding of x lands on the bracket end.
        if dr > 0.0 && dr.is_finite() && step.abs() <= xtol {
            return Ok(Root {
                x: newton.clamp(lo, hi),
                slope: dr,
                iterations,
            });
        }
        let step_ok = dr > 0.0
            && dr.is_finite()
            && newton > lo
            && newton < hi
            && (2.0 * step).abs() <= dx_old.abs();
        if hi - lo <= xtol {
            // The bracket is resolved; confirm it really brackets a root.
            if !checked_lo || !checked_hi {
                let (f_lo, _) = f(lo);
                let (f_hi, _) = f(hi);
                if f_lo > 0.0 || f_hi < 0.0 {
                    return Err(RootError::NotBracketed { lo, hi, f_lo, f_hi });
                }
            }
            return Ok(Root {
                x: 0.5 * (lo + hi),
                slope: dr,
                iterations,
            });
        }
        dx_old = dx;
        if step_ok {
            dx = step;
            x = newton;
        } else {
            dx = 0.5 * (hi - lo);
            x = lo + dx;
        }
    }
    Err(RootError::NoConvergence { lo, hi })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converges_on_smooth_and_kinked_functions() {
        let r =
            safeguarded_newton(|x| (x * x * x - 2.0, 3.0 * x * x), 0.0, 2.0, 1.9, 1e-15).unwrap();
        assert!((r.x - 2f64.cbrt()).abs() < 1e-14);
        // A kinked, nearly flat-then-steep function where bare Newton overshoots.
        let f = |x: f64| {
            if x < 1.0 {
                (1e-6 * (x - 1.0) - 1e-9, 1e-6)
            } else {
                (1e6 * (x - 1.0) - 1e-9, 1e6)
            }
        };
        let r = safeguarded_newton(f, -10.0, 10.0, -9.0, 1e-15).unwrap();
        assert!((r.x - (1.0 + 1e-15)).abs() < 1e-13, "{}", r.x);
        assert!(r.iterations < 200);
    }

    #[test]
    fn a_correction_below_rounding_converges_at_once() {
        // x0 is the root to the last bit: the correction rounds away, and the
        // iteration must stop there, not bisect a bracket that cannot shrink.
        let root = 1.605_818_543_921_715_2_f64;
        let f = |x: f64| (3.4e8 * (x - root) - 5e-9, 3.4e8);
        let r = safeguarded_newton(f, 1.0, 1.7, root, 1e-15).unwrap();
        assert!(r.iterations <= 2, "{} iterations", r.iterations);
    }

    #[test]
    fn an_infinite_slope_is_not_convergence() {
        // f' overflows to +∞ far above the root: r/f' = 0 there must not be
        // taken for a converged correction.
        let f = |x: f64| (x - 0.25, if x > 0.9 { f64::INFINITY } else { 1.0 });
        let r = safeguarded_newton(f, 0.0, 1.0, 0.95, 1e-12).unwrap();
        assert!((r.x - 0.25).abs() < 1e-12, "{}", r.x);
    }

    #[test]
    fn slow_newton_progress_falls_back_to_bisection() {
        // Steep exponential, started high in a valid bracket: Newton creeps
        // down by ~1/α per step (≈ 700 steps from x = 69); the progress test
        // must bisect instead.
        let f = |x: f64| ((10.0 * x).exp() - 2.0, 10.0 * (10.0 * x).exp());
        let r = safeguarded_newton(f, 0.0, 70.0, 69.0, 1e-14).unwrap();
        assert!((r.x - 2f64.ln() / 10.0).abs() < 1e-13, "{}", r.x);
        assert!(r.iterations < 100, "{} iterations", r.iterations);
    }

    #[test]
    fn zero_derivative_falls_back_to_bisection() {
        // A step function: no usable derivative anywhere.
        let f = |x: f64| (if x < 0.3 { -1.0 } else { 1.0 }, 0.0);
        let r = safeguarded_newton(f, 0.0, 1.0, 0.9, 1e-12).unwrap();
        assert!((r.x - 0.3).abs() < 1e-11);
    }

    #[test]
    fn reports_a_bad_bracket() {
        let r = safeguarded_newton(|x| (x + 5.0, 1.0), 0.0, 1.0, 0.5, 1e-12);
        assert!(matches!(r, Err(RootError::NotBracketed { .. })));
    }
}
