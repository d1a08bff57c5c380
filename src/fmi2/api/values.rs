//! Getting and setting variable values (FMI 2.0 spec, section 2.1.7).

use super::*;

/// `fmi2GetReal` (FMI 2.0 spec, section 2.1.7). In initialization mode,
/// reading a computed variable after a set first runs
/// [`Model::initialize`].
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn get_real<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2GetReal";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let out = out_slice(&inst.log, F, "value", value, nvr)?;
            get_values(inst, F, vrs, out, Kind::Real, |m, id| m.get_real(id))
        })
    }
}

/// `fmi2GetInteger` (FMI 2.0 spec, section 2.1.7).
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn get_integer<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    const F: &str = "fmi2GetInteger";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let out = out_slice(&inst.log, F, "value", value, nvr)?;
            get_values(inst, F, vrs, out, Kind::Integer, |m, id| m.get_integer(id))
        })
    }
}

/// `fmi2GetBoolean` (FMI 2.0 spec, section 2.1.7).
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn get_boolean<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    const F: &str = "fmi2GetBoolean";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let out = out_slice(&inst.log, F, "value", value, nvr)?;
            get_values(inst, F, vrs, out, Kind::Boolean, |m, id| {
                if m.get_boolean(id) {
                    fmi2True
                } else {
                    fmi2False
                }
            })
        })
    }
}

/// `fmi2GetString` (FMI 2.0 spec, section 2.1.7). The models have no String
/// variables: every value reference is an error (`nvr == 0` is fine).
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn get_string<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2String,
) -> fmi2Status {
    const F: &str = "fmi2GetString";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let out = out_slice(&inst.log, F, "value", value, nvr)?;
            get_values(inst, F, vrs, out, Kind::String, |_, _| std::ptr::null())
        })
    }
}

/// `fmi2SetReal` (FMI 2.0 spec, section 2.1.7). Which variables may be set
/// in which state: [`settable_in`](super::rules::settable_in). The model checks the value; a refused
/// value is logged with the variable name, the value and the model's
/// message (which states the valid range), and nothing is changed.
/// `SetOutcome::Warning` gives `fmi2Warning`; its message is logged, and
/// with `log_once` only the first time per instance and variable (until
/// `fmi2Reset`). Warnings of a vector set that is rejected later are not
/// logged (the values did not stick).
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn set_real<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2SetReal";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            set_values(inst, F, vrs, vals, Kind::Real, show_real, |m, id, v| {
                m.set_real(id, v)
            })
        })
    }
}

/// `fmi2SetInteger` (FMI 2.0 spec, section 2.1.7); as [`set_real`].
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn set_integer<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    const F: &str = "fmi2SetInteger";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            set_values(
                inst,
                F,
                vrs,
                vals,
                Kind::Integer,
                |v| v.to_string(),
                |m, id, v| m.set_integer(id, v),
            )
        })
    }
}

/// `fmi2SetBoolean` (FMI 2.0 spec, section 2.1.7); as [`set_real`]. Any
/// non-zero value is true.
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn set_boolean<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    const F: &str = "fmi2SetBoolean";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            set_values(inst, F, vrs, vals, Kind::Boolean, show_bool, |m, id, v| {
                m.set_boolean(id, v != fmi2False)
            })
        })
    }
}

/// `fmi2SetString` (FMI 2.0 spec, section 2.1.7). No String variables:
/// every value reference is an error (`nvr == 0` is fine).
///
/// # Safety
/// `c` a live instance; `vr` and `value` `nvr` elements each.
pub unsafe fn set_string<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2String,
) -> fmi2Status {
    const F: &str = "fmi2SetString";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_VALUES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            set_values(inst, F, vrs, vals, Kind::String, cstr_lossy, |_, _, _| {
                Err(ModelError("String variables are not supported".into()))
            })
        })
    }
}

// ---------------------------------------------------------------------------
// FMU states (FMI 2.0 spec, section 2.1.8)
// ---------------------------------------------------------------------------
