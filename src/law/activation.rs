//! Activation dynamics (paper eq 9–10, MODEL_NOTES "Activation").
//!
//! Eq 9–10 is first-order dynamics da/dt = S (u − a) for a square command u.

/// Activation level after a step of length `h` from level `a0`, for the
/// command u(τ) = u0 + u_dot τ over the step (exact solution of
/// da/dt = S (u − a), paper eq 9–10 as MODEL_NOTES "Activation" states them):
/// a(h) = u0 + u_dot h − u_dot/S + (a0 − u0 + u_dot/S) e^(−S h).
/// With `u_dot = 0` this is a(h) = u0 + (a0 − u0) e^(−S h) (MODEL_NOTES).
/// `decay` is e^(−S h) (see [`Decay`]). Returns the level (clamped to
/// [0, 1]) and ∂a(h)/∂u0 = 1 − e^(−S h).
pub fn activation_step(a0: f64, u0: f64, u_dot: f64, s: f64, h: f64, decay: f64) -> (f64, f64) {
    let e = decay;
    let a = if u_dot == 0.0 {
        u0 + (a0 - u0) * e
    } else {
        let r = u_dot / s;
        u0 + u_dot * h - r + (a0 - u0 + r) * e
    };
    let d = 1.0 - e;
    if a < 0.0 {
        (0.0, 0.0)
    } else if a > 1.0 {
        (1.0, 0.0)
    } else {
        (a, d)
    }
}

/// The activation level τ into a step and ∂a/∂u0 (MODEL_NOTES "Activation"
/// and "Co-simulation conventions": the command u(τ) = u0 + u_dot τ holds over
/// the step, and a command stays in [0, 1]). The command is clamped at every
/// τ, not only at the end: with `u_dot` pushing it out of [0, 1] it rises (or
/// falls) linearly until it reaches the bound at τ* = (bound − u0)/u_dot and
/// is held there ([`clamped_step`]). With the dynamics, the exact solution of
/// da/dt = S (u(τ) − a) over τ (`decay` = e^(−S τ) when the command stays
/// inside); without them (a = u), the clamped command itself (∂a/∂u0 = 0
/// where clamped; `decay` unused). Every substep of a step reads its level
/// here, as the whole step would.
pub fn level_at(
    dynamics: bool,
    a0: f64,
    u0: f64,
    u_dot: f64,
    s: f64,
    tau: f64,
    decay: f64,
) -> (f64, f64) {
    if dynamics {
        return match command_bound(u0, u_dot, tau) {
            Some((bound, reach)) => clamped_step(a0, u0, u_dot, s, tau, bound, reach),
            None => activation_step(a0, u0, u_dot, s, tau, decay),
        };
    }
    let a = u0 + tau * u_dot;
    if (0.0..=1.0).contains(&a) {
        (a, 1.0)
    } else {
        (a.clamp(0.0, 1.0), 0.0)
    }
}

/// The bound of [0, 1] the command u0 + u_dot τ reaches within `tau`, and
/// when (τ* ≥ 0); `None` when it stays inside over the whole interval.
fn command_bound(u0: f64, u_dot: f64, tau: f64) -> Option<(f64, f64)> {
    let bound = if u_dot > 0.0 {
        1.0
    } else if u_dot < 0.0 {
        0.0
    } else {
        return None;
    };
    let reach = ((bound - u0) / u_dot).max(0.0);
    (reach < tau).then_some((bound, reach))
}

/// The level τ into a step whose command reaches `bound` at τ* = `reach`
/// (< τ) and is held there: [`activation_step`] with the linear command over
/// [0, τ*], then with the command held at the bound over [τ*, τ]:
/// a(τ) = bound + (a(τ*) − bound) e^(−S (τ − τ*)). Its derivative with
/// respect to u0 is e^(−S (τ − τ*)) ∂a(τ*)/∂u0: the terms through τ*
/// cancel, since a is continuous in time at τ* and da/dt = S (bound − a)
/// on both sides.
fn clamped_step(
    a0: f64,
    u0: f64,
    u_dot: f64,
    s: f64,
    tau: f64,
    bound: f64,
    reach: f64,
) -> (f64, f64) {
    let (a1, d1) = activation_step(a0, u0, u_dot, s, reach, (-s * reach).exp());
    let held = (-s * (tau - reach)).exp();
    let a = bound + (a1 - bound) * held;
    (a.clamp(0.0, 1.0), d1 * held)
}

/// The decay factor e^(−S h) of [`activation_step`] for one (S, h). A model
/// keeps the last one: a co-simulation usually repeats its step size, so the
/// exponential is evaluated once instead of every step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decay {
    pub s: f64,
    pub h: f64,
    pub value: f64,
}

impl Decay {
    /// e^(−S h), the decay of a(t+h) = u + (a(t) − u) e^(−S h) (MODEL_NOTES
    /// "Activation"; 1 − h_t(t + h, t) of paper eq 10).
    pub fn new(s: f64, h: f64) -> Decay {
        Decay {
            s,
            h,
            value: (-s * h).exp(),
        }
    }

    /// `cached` when it is for (S, h), else a new one: the same factor
    /// e^(−S h) as [`Decay::new`] (MODEL_NOTES "Activation"; paper eq 10).
    pub fn for_step(cached: Option<Decay>, s: f64, h: f64) -> Decay {
        match cached {
            Some(d) if d.s == s && d.h == h => d,
            _ => Decay::new(s, h),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_held_input_and_composable() {
        // One step of 0.1 s equals ten steps of 0.01 s (exactness), and the
        // rise from 0 with u = 1 is 1 − e^(−S t).
        let s = 50.0;
        let mut a = 0.0;
        for _ in 0..10 {
            a = activation_step(a, 1.0, 0.0, s, 0.01, f64::exp(-s * 0.01)).0;
        }
        let one = activation_step(0.0, 1.0, 0.0, s, 0.1, f64::exp(-s * 0.1)).0;
        assert!((a - one).abs() < 1e-14);
        assert!((one - (1.0 - (-5.0f64).exp())).abs() < 1e-15);
        // Huge S h: lands on the command, no overshoot.
        assert_eq!(
            activation_step(0.3, 0.7, 0.0, 1e5, 1.0, f64::exp(-1e5 * 1.0)).0,
            0.7
        );
    }

    #[test]
    fn linear_input_matches_fine_integration() {
        let (s, a0, u0, ud, h) = (50.0, 0.2, 0.1, 3.0, 0.2);
        let n = 200_000;
        let dt = h / n as f64;
        let mut a = a0;
        for i in 0..n {
            // Exact update for the input held at its midpoint value.
            let u = u0 + ud * (i as f64 + 0.5) * dt;
            a = u + (a - u) * (-s * dt).exp();
        }
        let exact = activation_step(a0, u0, ud, s, h, f64::exp(-s * h)).0;
        assert!((a - exact).abs() < 1e-9, "{a} vs {exact}");
    }

    #[test]
    fn decay_is_reused_only_for_the_same_step() {
        let d = Decay::new(50.0, 1e-3);
        assert_eq!(d.value, f64::exp(-50.0 * 1e-3));
        assert_eq!(Decay::for_step(Some(d), 50.0, 1e-3), d);
        assert_eq!(
            Decay::for_step(Some(d), 50.0, 2e-3).value,
            f64::exp(-50.0 * 2e-3)
        );
        assert_eq!(
            Decay::for_step(Some(d), 60.0, 1e-3).value,
            f64::exp(-60.0 * 1e-3)
        );
        assert_eq!(Decay::for_step(None, 50.0, 1e-3), d);
    }

    #[test]
    fn derivative_wrt_command() {
        let (a, da) = activation_step(0.2, 0.5, 0.0, 50.0, 0.01, f64::exp(-50.0 * 0.01));
        let h = 1e-7;
        let fd = (activation_step(0.2, 0.5 + h, 0.0, 50.0, 0.01, f64::exp(-50.0 * 0.01)).0 - a) / h;
        assert!((fd - da).abs() < 1e-7);
    }

    /// A command pushed out of [0, 1] by its derivative is held at the
    /// bound from the moment it reaches it: the level equals a fine
    /// integration of da/dt = S (clamp(u0 + u_dot t) − a), never more than a
    /// command of 1 (or less than one of 0) can give, and its derivative
    /// with respect to u0 is the finite difference's.
    #[test]
    fn a_command_driven_out_of_the_unit_interval_is_held_at_its_bound() {
        let s = 50.0;
        let fine = |a0: f64, u0: f64, ud: f64, h: f64| {
            let n = 200_000;
            let dt = h / n as f64;
            let mut a = a0;
            for i in 0..n {
                let u = (u0 + ud * (i as f64 + 0.5) * dt).clamp(0.0, 1.0);
                a = u + (a - u) * (-s * dt).exp();
            }
            a
        };
        let level = |a0, u0, ud, h: f64| level_at(true, a0, u0, ud, s, h, (-s * h).exp());
        // At the bound already: the held command's solution, 1 − e^(−S h)
        // from rest (the unclamped line gave 1.0).
        let (a, da) = level(0.0, 1.0, 1000.0, 0.01);
        assert!((a - (1.0 - (-0.5f64).exp())).abs() < 1e-15, "{a}");
        assert_eq!(da, 0.0);
        // Reaching the bound inside the step, upward and downward.
        for (a0, u0, ud, h) in [
            (0.2, 0.5, 100.0, 0.01),
            (0.9, 0.4, -100.0, 0.02),
            (0.0, 0.1, 1e3, 1e-3),
        ] {
            let (a, da) = level(a0, u0, ud, h);
            let want = fine(a0, u0, ud, h);
            assert!((a - want).abs() < 1e-9, "{a} vs {want}");
            let d = 1e-7;
            let fd = (level(a0, u0 + d, ud, h).0 - level(a0, u0 - d, ud, h).0) / (2.0 * d);
            assert!((fd - da).abs() < 1e-6, "d/du0 {da} vs {fd}");
        }
        // A command of 0 pushed down from level 0.2 decays, held at 0.
        let (a, _) = level(0.2, 0.0, -1000.0, 0.01);
        assert!((a - 0.2 * (-0.5f64).exp()).abs() < 1e-15, "{a}");
        // Staying inside: the unclamped formula, bit for bit.
        assert_eq!(
            level(0.2, 0.5, 10.0, 0.01),
            activation_step(0.2, 0.5, 10.0, s, 0.01, (-s * 0.01f64).exp())
        );
    }
}
