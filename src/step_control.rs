//! Step-size control of the CE–SEE update, one policy for both muscles.
//!
//! A step is integrated in pieces, each one backward-Euler step of the CE–SEE
//! update (MODEL_NOTES "Hill fibre") whose local error is estimated by
//! [`crate::law::hill_fibre::backward_euler_error`]. Backward Euler's local
//! error is second order in the piece length h, so the length that would meet
//! the tolerance is h √(tol/err); the policy takes [`SAFETY`] of that:
//! - a piece is accepted when its estimate is within the tolerance
//!   ([`accepted`]: a NaN estimate is not);
//! - after an accepted piece the next may grow by [`growth`], at most
//!   [`MAX_GROWTH`];
//! - a rejected piece is tried again shorter by [`reduction`], at most
//!   [`SAFETY`], or by the model's own floor when the estimate is not finite;
//! - after [`MAX_CONTROLLED_TRIES`] tries the rest of the step is one piece
//!   (the 1D muscle grows that bound below its default tolerance:
//!   `crate::muscle1d::step::max_tries`).
//!
//! The muscles only place the pieces: the 1D muscle on a dyadic grid of the
//! step (`crate::muscle1d`), the FE muscle continuously with a floor of 1/4
//! per rejection (`crate::fe`).

/// Fraction of the tolerance-meeting length a new piece is given.
pub const SAFETY: f64 = 0.9;

/// Largest growth of a piece over the one accepted before it.
pub const MAX_GROWTH: f64 = 4.0;

/// Most tries (accepted and rejected pieces) of one error-controlled step
/// before the rest of the step is taken in one piece: the work bound of the
/// substep control. A bound that binds leaves the error uncontrolled, so it
/// sits far above what the grid of docs/stability.md needs: an FE element
/// whose CE yields under fast lengthening (f_v near its plateau) needs pieces
/// of ~10 µs, hundreds in a 0.1 s step.
pub const MAX_CONTROLLED_TRIES: u32 = 10_000;

/// Whether a piece with estimated local error `err` meets `tol` (false for a
/// NaN estimate).
pub fn accepted(err: f64, tol: f64) -> bool {
    err <= tol
}

/// The factor SAFETY √(tol/err) that would bring the estimate to the
/// tolerance (+∞ for a zero estimate).
pub fn factor(err: f64, tol: f64) -> f64 {
    SAFETY * (tol / err).sqrt()
}

/// How much longer the piece after an accepted one may be: [`factor`] capped
/// at [`MAX_GROWTH`] (the cap for a zero estimate).
pub fn growth(err: f64, tol: f64) -> f64 {
    if err > 0.0 {
        factor(err, tol).min(MAX_GROWTH)
    } else {
        MAX_GROWTH
    }
}

/// How much shorter a rejected piece is tried again: [`factor`], at most
/// [`SAFETY`]; `None` when the estimate is not finite (the model then cuts
/// by its own floor).
pub fn reduction(err: f64, tol: f64) -> Option<f64> {
    err.is_finite().then(|| factor(err, tol).min(SAFETY))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The policy's three answers on the cases that matter: an estimate at,
    /// above and below the tolerance, a zero and a non-finite one.
    #[test]
    fn the_policy_accepts_grows_and_shrinks_by_the_square_root_law() {
        assert!(accepted(1e-3, 1e-3));
        assert!(!accepted(1.1e-3, 1e-3));
        assert!(!accepted(f64::NAN, 1e-3));
        // Four times the tolerance: half the length, times the safety.
        assert_eq!(factor(4e-3, 1e-3), 0.45);
        assert_eq!(reduction(4e-3, 1e-3), Some(0.45));
        // Just above the tolerance: a little under the safety; the cap
        // holds whatever the estimate.
        assert!(reduction(1.0000001e-3, 1e-3).unwrap() < SAFETY);
        assert_eq!(reduction(0.5e-3, 1e-3), Some(SAFETY));
        assert_eq!(reduction(f64::INFINITY, 1e-3), None);
        assert_eq!(reduction(f64::NAN, 1e-3), None);
        // A hundredth of the tolerance: 9x, capped at 4x.
        assert_eq!(growth(1e-5, 1e-3), MAX_GROWTH);
        assert_eq!(growth(0.0, 1e-3), MAX_GROWTH);
        assert!((growth(2.5e-4, 1e-3) - 1.8).abs() < 1e-15);
    }
}
