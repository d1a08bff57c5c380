//! Finite differences for checking derivatives against the step map or the
//! initialization: second-order central and one-sided quotients, of a scalar
//! function or element-wise of sampled output vectors.

/// `(f(h) − f(−h)) / 2h`: the central difference at 0 of `f`, a function of
/// the displacement.
pub fn central(f: impl Fn(f64) -> f64, h: f64) -> f64 {
    (f(h) - f(-h)) / (2.0 * h)
}

/// Element-wise central differences `(plus − minus) / 2h` of outputs sampled
/// at `x + h` and `x − h`.
pub fn central_all(plus: &[f64], minus: &[f64], h: f64) -> Vec<f64> {
    plus.iter()
        .zip(minus)
        .map(|(p, m)| (p - m) / (2.0 * h))
        .collect()
}

/// Element-wise second-order one-sided differences
/// `(−3 f(x) + 4 f(x + h) − f(x + 2h)) / 2h`, where `x − h` is out of reach.
pub fn forward_all(f0: &[f64], f1: &[f64], f2: &[f64], h: f64) -> Vec<f64> {
    (0..f0.len())
        .map(|k| (-3.0 * f0[k] + 4.0 * f1[k] - f2[k]) / (2.0 * h))
        .collect()
}
