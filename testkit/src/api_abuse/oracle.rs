//! The oracle: the outcome the standard or the documented contract fixes
//! for a call, from its arguments, the variable table and the state before.

use super::*;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Expect {
    Reject,
    Accept,
    Unknown,
}

pub(crate) use Expect::{Accept, Reject, Unknown};

/// Arrays of one call: any NULL pointer with `n > 0`, or an impossible
/// length, must be refused.
pub(crate) fn arrays_bad(n: usize, ptrs: &[Ptr], len: Len) -> bool {
    len == Len::Impossible || (n > 0 && ptrs.contains(&Ptr::Null))
}

/// The outcome the standard / the layer's contract fixes for `call` in the
/// state `pre`, as far as it is simple to tell.
pub(crate) fn expect(call: &Call, pre: &LayerState, f: &Fmu) -> Expect {
    if call.comp() != Comp::Valid || !call.meta().1.contains(pre.fmi_state) {
        return Reject;
    }
    let state = pre.fmi_state;
    let settable = |vr: u32| var(vr).is_some_and(|v| settable_in(v, state));
    match call {
        Call::Setup {
            tol_def,
            tol,
            start,
            stop_def,
            stop,
            ..
        } => {
            if !start.is_finite()
                || (*stop_def != 0 && !(stop.is_finite() && stop >= start))
                || (*tol_def != 0 && !(tol.is_finite() && *tol >= 0.0))
            {
                Reject
            } else {
                Accept
            }
        }
        Call::Enter(_) | Call::Terminate(_) | Call::Reset(_) => Accept,
        Call::Exit(_) | Call::Cancel(_) => Unknown,
        Call::Logging { cats, ptr, len, .. } => {
            if arrays_bad(cats.len(), &[*ptr], *len)
                || cats.iter().any(|c| !matches!(c, Cat::Known(_)))
            {
                Reject
            } else {
                Accept
            }
        }
        Call::SetReal { vrs, ptrs, len, .. } => {
            if arrays_bad(vrs.len(), ptrs, *len)
                || vrs.iter().any(|&vr| !is_real(vr) || !settable(vr))
            {
                Reject
            } else if vrs.is_empty() {
                Accept
            } else {
                Unknown
            }
        }
        Call::SetInteger {
            vrs,
            vals,
            ptrs,
            len,
            ..
        } => {
            // Integer parameters are range-checked against their declared
            // min/max (docs/reference/bad-input.md); there are no Integer inputs.
            if arrays_bad(vrs.len(), ptrs, *len)
                || vrs.iter().any(|&vr| !is_int(vr) || !settable(vr))
                || vrs.iter().zip(vals).any(|(&vr, v)| {
                    let (lo, hi) = int_range(vr);
                    !(lo..=hi).contains(v)
                })
            {
                Reject
            } else {
                Accept
            }
        }
        Call::SetString { vrs, ptrs, len, .. } => {
            // Neither model has String variables.
            if arrays_bad(vrs.len(), ptrs, *len) || !vrs.is_empty() {
                Reject
            } else {
                Accept
            }
        }
        Call::SetBoolean { vrs, ptrs, len, .. } => {
            if arrays_bad(vrs.len(), ptrs, *len)
                || vrs.iter().any(|&vr| !is_bool(vr) || !settable(vr))
            {
                Reject
            } else {
                Accept
            }
        }
        Call::Get {
            ty, vrs, ptrs, len, ..
        } => {
            let type_ok = |vr: u32| match ty {
                Ty::Real => is_real(vr),
                Ty::Boolean => is_bool(vr),
                Ty::Integer => is_int(vr),
                Ty::String => false,
            };
            if arrays_bad(vrs.len(), ptrs, *len) || !vrs.iter().all(|&vr| type_ok(vr)) {
                Reject
            } else if state == FmiState::InitializationMode
                && (*ty == Ty::Real || (*ty == Ty::Integer && vrs.iter().any(|&vr| computed(vr))))
            {
                Unknown // may compute the initial values, which may fail
            } else {
                Accept
            }
        }
        Call::GetState { out, .. } => match out {
            StateOut::Slot(_) => Accept,
            _ => Reject,
        },
        Call::FreeState { out, .. } => match out {
            StateOut::Slot(_) | StateOut::NullPtr => Accept,
            _ => Reject,
        },
        Call::SetState { st, .. } => match st {
            StateIn::Slot(k) if !f.slots[*k].is_null() => Accept,
            _ => Reject,
        },
        Call::StateSize { st, null, .. } => match st {
            StateIn::Slot(k) if !f.slots[*k].is_null() && !null => Accept,
            _ => Reject,
        },
        // Decided at resolution.
        Call::Serialize { .. } | Call::Deserialize { .. } | Call::Step { .. } => Unknown,
        Call::DirDeriv {
            unknowns,
            knowns,
            dv,
            ptrs,
            len,
            ..
        } => {
            let bad_arrays = *len == Len::Impossible
                || (!unknowns.is_empty() && (ptrs[0] == Ptr::Null || ptrs[3] == Ptr::Null))
                || (!knowns.is_empty() && (ptrs[1] == Ptr::Null || ptrs[2] == Ptr::Null));
            // A seed must be finite (docs/reference/bad-input.md).
            if bad_arrays
                || dv.iter().any(|v| !v.is_finite())
                || !unknowns
                    .iter()
                    .all(|&vr| is_real_with(vr, Causality::Output))
                || !knowns.iter().all(|&vr| {
                    is_real_with(vr, Causality::Input)
                        || (state == FmiState::InitializationMode
                            && is_real_with(vr, Causality::Parameter))
                })
                || (knowns.iter().any(|&vr| is_real_with(vr, Causality::Input))
                    && !unknowns
                        .iter()
                        .all(|vr| table().differentiated.contains(vr)))
            {
                Reject
            } else if state == FmiState::InitializationMode && !unknowns.is_empty() {
                Unknown
            } else {
                Accept
            }
        }
        Call::SetInputDer {
            vrs,
            orders,
            vals,
            ptrs,
            len,
            ..
        } => {
            if arrays_bad(vrs.len(), ptrs, *len)
                || !vrs.iter().all(|&vr| is_real_with(vr, Causality::Input))
                || orders.iter().any(|&o| o != 1)
                || vals.iter().any(|v| !v.is_finite())
            {
                Reject
            } else {
                Accept
            }
        }
        Call::GetOutputDer { vrs, ptrs, len, .. } => {
            // maxOutputDerivativeOrder = 0: any request is an error.
            if arrays_bad(vrs.len(), ptrs, *len) || !vrs.is_empty() {
                Reject
            } else {
                Accept
            }
        }
        Call::Status { kind, null, .. } => {
            if *null || !(0..=3).contains(kind) {
                Reject
            } else {
                Accept
            }
        }
    }
}

/// `fmi2DoStep`'s expected outcome (module docs, property 3).
pub(crate) fn step_expect(tc: f64, h: f64, pre: &LayerState) -> Expect {
    let t = pre.time;
    if !(h.is_finite() && h > 0.0 && tc.is_finite()) {
        return Reject;
    }
    let tol = api::time_tolerance(t, h);
    if t.is_finite() && (tc - t).abs() > 2.0 * tol {
        return Reject;
    }
    if !(tc + h).is_finite() || !api::step_resolved(tc, h) {
        return Reject;
    }
    if let Some(stop) = pre.stop_time {
        if tc + h > stop + 2.0 * tol {
            return Reject;
        }
    }
    // Well inside the tolerance (a tenth of it): accepted for sure.
    let drift_ok = t.is_finite() && (tc - t).abs() <= 0.1 * tol;
    let stop_ok = match pre.stop_time {
        Some(s) => tc + h <= s,
        None => true,
    };
    if drift_ok && stop_ok {
        Accept
    } else {
        Unknown
    }
}
