//! Stepping and status queries (FMI 2.0 spec, sections 4.2.2 and 4.2.3).

use super::*;

/// `fmi2DoStep` (FMI 2.0 spec, section 4.2.2), synchronous. Rejected with
/// `fmi2Error` and no change: `communicationStepSize` not finite and > 0,
/// `currentCommunicationPoint` not finite or further than
/// [`time_tolerance`] from the FMU's time, a step the time cannot represent
/// there ([`step_resolved`]: the end time would not advance by the step
/// computed), or (with a defined stop time)
/// `tc + h` past `stopTime` by more than the tolerance. Then
/// [`Model::do_step`]:
/// - `Ok`: time = `tc + h`, `fmi2OK`;
/// - `Discard`: `fmi2Discard`, state `stepFailed`, model unchanged,
///   `fmi2LastSuccessfulTime` = `tc`; recover with `fmi2SetFMUstate`;
/// - `Error`: `fmi2Error`, state `error`.
///
/// `noSetFMUStatePriorToCurrentPoint` is not needed (nothing is buffered).
///
/// # Safety
/// `c` a live instance.
pub unsafe fn do_step<M: Model>(
    c: fmi2Component,
    current_communication_point: fmi2Real,
    communication_step_size: fmi2Real,
    _no_set_fmu_state_prior_to_current_point: fmi2Boolean,
) -> fmi2Status {
    const F: &str = "fmi2DoStep";
    let (tc, h) = (current_communication_point, communication_step_size);
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::DO_STEP, |inst| {
            let t = inst.layer.time;
            if !(h.is_finite() && h > 0.0) {
                inst.log.error(&format!(
                    "{F}: communicationStepSize = {h:?} must be finite and > 0"
                ));
                return Err(fmi2Error);
            }
            let tol = time_tolerance(t, h);
            if !tc.is_finite() || (tc - t).abs() > tol {
                inst.log.error(&format!(
                    "{F}: currentCommunicationPoint = {tc:?} does not match the FMU time {t:?} (tolerance {tol:e})"
                ));
                return Err(fmi2Error);
            }
            if !(tc + h).is_finite() {
                inst.log.error(&format!(
                    "{F}: the step from {tc:?} with communicationStepSize = {h:?} ends at {:?}, not a finite time",
                    tc + h
                ));
                return Err(fmi2Error);
            }
            if !step_resolved(tc, h) {
                inst.log.error(&format!(
                    "{F}: the step from {tc:?} with communicationStepSize = {h:?} ends at {:?}: binary64 \
                     cannot represent the time after this step to {}% of it here; use a larger step or an \
                     earlier start time",
                    tc + h,
                    STEP_RESOLUTION * 100.0
                ));
                return Err(fmi2Error);
            }
            if let Some(stop) = inst.layer.stop_time {
                if tc + h > stop + tol {
                    inst.log.error(&format!(
                        "{F}: the step to {:?} goes past stopTime = {stop:?}",
                        tc + h
                    ));
                    return Err(fmi2Error);
                }
            }
            match inst.model.do_step(tc, h) {
                Ok(()) => {
                    let l = &mut inst.layer;
                    l.time = tc + h;
                    l.last_successful_time = l.time;
                    l.last_step_status = fmi2OK;
                    inst.log.debug(LogCategory::All, || {
                        format!("{F}: tc = {tc:?}, h = {h:?} done")
                    });
                    Ok(fmi2OK)
                }
                Err(StepError::Discard(msg)) => {
                    let l = &mut inst.layer;
                    l.time = tc;
                    l.last_successful_time = tc;
                    l.last_step_status = fmi2Discard;
                    l.fmi_state = FmiState::StepFailed;
                    inst.log.discard(&format!(
                        "{F}: step from t = {tc:?} with h = {h:?} discarded: {msg}"
                    ));
                    Err(fmi2Discard)
                }
                Err(StepError::Error(msg)) => {
                    let l = &mut inst.layer;
                    l.last_step_status = fmi2Error;
                    l.fmi_state = FmiState::Error;
                    inst.log.error(&format!(
                        "{F}: step from t = {tc:?} with h = {h:?} failed: {msg}"
                    ));
                    Err(fmi2Error)
                }
            }
        })
    }
}

/// `fmi2CancelStep` (FMI 2.0 spec, section 4.2.2): allowed only in
/// `stepInProgress`, which a synchronous FMU never enters, so every call is
/// rejected as not allowed in the current state.
///
/// # Safety
/// `c` a live instance.
pub unsafe fn cancel_step<M: Model>(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { call::<M>(c, "fmi2CancelStep", state::CANCEL_STEP, |_| Ok(fmi2OK)) }
}

#[allow(non_upper_case_globals)]
fn status_kind_name(s: fmi2StatusKind) -> Option<&'static str> {
    Some(match s {
        fmi2DoStepStatus => "fmi2DoStepStatus",
        fmi2PendingStatus => "fmi2PendingStatus",
        fmi2LastSuccessfulTime => "fmi2LastSuccessfulTime",
        fmi2Terminated => "fmi2Terminated",
        _ => return None,
    })
}

/// Common part of the status functions (FMI 2.0 spec, section 4.2.3): an
/// invalid kind is an error; a valid kind this function does not answer is
/// "not available" (`fmi2Discard`).
unsafe fn status_query<M: Model, T>(
    c: fmi2Component,
    func: &str,
    s: fmi2StatusKind,
    value: *mut T,
    answer: impl FnOnce(&Instance<M>, fmi2StatusKind) -> Option<T>,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, func, state::GET_STATUS, |inst| {
            non_null(&inst.log, func, "value", value)?;
            let Some(kind) = status_kind_name(s) else {
                inst.log
                    .error(&format!("{func}: {s} is not an fmi2StatusKind"));
                return Err(fmi2Error);
            };
            match answer(inst, s) {
                Some(v) => {
                    *value = v;
                    Ok(fmi2OK)
                }
                None => {
                    inst.log.discard(&format!(
                        "{func}: {kind} is not available from this function (synchronous FMU)"
                    ));
                    Err(fmi2Discard)
                }
            }
        })
    }
}

/// `fmi2GetStatus` (FMI 2.0 spec, section 4.2.3): `fmi2DoStepStatus` gives
/// the status of the last `fmi2DoStep` (`fmi2OK` before the first step);
/// other kinds are not available (`fmi2Discard`).
///
/// # Safety
/// `c` a live instance; `value` a valid pointer.
pub unsafe fn get_status<M: Model>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Status,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        status_query::<M, _>(c, "fmi2GetStatus", s, value, |inst, s| {
            (s == fmi2DoStepStatus).then_some(inst.layer.last_step_status)
        })
    }
}

/// `fmi2GetRealStatus` (FMI 2.0 spec, section 4.2.3):
/// `fmi2LastSuccessfulTime` is the end of the last successful step (the
/// start time before the first); other kinds: `fmi2Discard`.
///
/// # Safety
/// `c` a live instance; `value` a valid pointer.
pub unsafe fn get_real_status<M: Model>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        status_query::<M, _>(c, "fmi2GetRealStatus", s, value, |inst, s| {
            (s == fmi2LastSuccessfulTime).then_some(inst.layer.last_successful_time)
        })
    }
}

/// `fmi2GetIntegerStatus` (FMI 2.0 spec, section 4.2.3): FMI 2.0 defines no
/// Integer status, so every valid kind gives `fmi2Discard`.
///
/// # Safety
/// `c` a live instance; `value` a valid pointer.
pub unsafe fn get_integer_status<M: Model>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Integer,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { status_query::<M, _>(c, "fmi2GetIntegerStatus", s, value, |_, _| None) }
}

/// `fmi2GetBooleanStatus` (FMI 2.0 spec, section 4.2.3): `fmi2Terminated`
/// is `fmi2True` only if the model asked to end the simulation (the current
/// models never do); other kinds: `fmi2Discard`.
///
/// # Safety
/// `c` a live instance; `value` a valid pointer.
pub unsafe fn get_boolean_status<M: Model>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        status_query::<M, _>(c, "fmi2GetBooleanStatus", s, value, |inst, s| {
            (s == fmi2Terminated).then_some(if inst.layer.model_terminated {
                fmi2True
            } else {
                fmi2False
            })
        })
    }
}

/// `fmi2GetStringStatus` (FMI 2.0 spec, section 4.2.3): `fmi2PendingStatus`
/// only exists for asynchronous steps, so every valid kind gives
/// `fmi2Discard`.
///
/// # Safety
/// `c` a live instance; `value` a valid pointer.
pub unsafe fn get_string_status<M: Model>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2String,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { status_query::<M, _>(c, "fmi2GetStringStatus", s, value, |_, _| None) }
}
