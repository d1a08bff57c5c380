//! The FMI 2.0 common and Co-Simulation functions, generic over the model
//! (FMI 2.0 spec, sections 2.1 and 4.2). [`export_fmi2!`](crate::export_fmi2)
//! turns them into the `#[no_mangle] extern "C"` symbols of an FMU binary;
//! the function here named `do_step` becomes `fmi2DoStep`, and so on. The
//! parameters are exactly those of `fmi2FunctionTypes.h`.
//!
//! Every function
//! - rejects a NULL or foreign `fmi2Component` with `fmi2Error` (nothing can
//!   be logged without an instance);
//! - checks the state table ([`super::state`]); a call not allowed in the
//!   current state logs `"fmi2Xxx: not allowed in state yyy"` and returns
//!   `fmi2Error`;
//! - checks every pointer it will use (arrays only when their length is
//!   non-zero) and never reads or writes past the given lengths;
//! - runs inside `catch_unwind`: a panic puts the instance into state
//!   `fatal` and returns `fmi2Fatal` (`fmi2Instantiate`: NULL).
//!
//! A rejected call (`fmi2Error` because of state, arguments or a value the
//! model refuses) changes nothing in the instance; see the module docs of
//! [`crate::fmi2`].

use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::fp_env::QuietFp;
use super::initial_sensitivity::initial_parameter_column;
use super::instance::{decode_state, encode_state, Instance, LogCategory, LogSink};
use super::model::{
    Causality, Initial, Model, ModelError, ScalarVariable, SetOutcome, StepError, VarType,
};
use super::model_description::guid_for;
use super::rules::{
    causality_name, effective_initial, type_name, variability_name, Dispatch, ValueKind,
};
use super::state::{self, FmiState, StateSet};
use super::types::*;

mod derivatives;
mod fmu_state;
mod lifecycle;
mod stepping;
mod values;

pub use derivatives::*;
pub use fmu_state::*;
pub use lifecycle::*;
pub use stepping::*;
pub use values::*;

/// Tolerance when comparing `currentCommunicationPoint` with the FMU's time
/// (and `tc + h` with `stopTime`) in `fmi2DoStep`:
/// `min(1e-9 * max(1, |t|), h / 2) + 1e-6 * h`. The relative part absorbs
/// the rounding an importer accumulates (`t += h`, `t = t0 + i * h`); it is
/// capped at half a step, so the tolerance never exceeds 0.500001 h in
/// absolute terms and a point nearer another communication point is never
/// taken for this one.
pub fn time_tolerance(t: f64, h: f64) -> f64 {
    (1e-9 * t.abs().max(1.0)).min(0.5 * h.abs()) + 1e-6 * h.abs()
}

/// Largest relative difference between `communicationStepSize` and the step
/// the time can represent at `currentCommunicationPoint`, `(tc + h) - tc`:
/// beyond it the FMU's time would not advance by the step it computed (at
/// t = 1e16 a step of 1 ms does not advance it at all).
pub const STEP_RESOLUTION: f64 = 1e-2;

/// Whether the time at `tc` resolves a step of `h` ([`STEP_RESOLUTION`]).
pub fn step_resolved(tc: f64, h: f64) -> bool {
    (((tc + h) - tc) - h).abs() <= STEP_RESOLUTION * h
}

/// `fmi2GetTypesPlatform`: `"default"`.
pub fn get_types_platform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`: `"2.0"`.
pub fn get_version() -> *const c_char {
    c"2.0".as_ptr()
}

type Outcome = Result<fmi2Status, fmi2Status>;

/// Runs `body` on the instance behind `c` if `func` is allowed in its state.
///
/// # Safety
/// `c` as in [`Instance::from_component`].
unsafe fn call<M: Model>(
    c: fmi2Component,
    func: &str,
    allowed: StateSet,
    body: impl FnOnce(&mut Instance<M>) -> Outcome,
) -> fmi2Status {
    let _fp = QuietFp::enter();
    // SAFETY: forwarded contract.
    let Some(inst) = (unsafe { Instance::<M>::from_component(c) }) else {
        return fmi2Error;
    };
    let result = catch_unwind(AssertUnwindSafe(|| {
        let s = inst.layer.fmi_state;
        if !allowed.contains(s) {
            inst.log
                .error(&format!("{func}: not allowed in state {}", s.name()));
            return fmi2Error;
        }
        match body(inst) {
            Ok(s) | Err(s) => s,
        }
    }));
    match result {
        Ok(status) => status,
        Err(payload) => {
            let _ = catch_unwind(AssertUnwindSafe(|| {
                inst.enter_fatal(func, payload.as_ref())
            }));
            fmi2Fatal
        }
    }
}

/// An input array of `n` elements (empty for `n == 0`, whatever `p` is).
#[inline]
unsafe fn in_slice<'a, T>(
    log: &LogSink,
    func: &str,
    what: &str,
    p: *const T,
    n: usize,
) -> Result<&'a [T], fmi2Status> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        log.error(&format!("{func}: {what} is NULL but its length is {n}"));
        return Err(fmi2Error);
    }
    if n > isize::MAX as usize / std::mem::size_of::<T>().max(1) {
        log.error(&format!("{func}: length {n} of {what} is impossible"));
        return Err(fmi2Error);
    }
    // SAFETY: the importer guarantees `n` readable elements at `p`.
    Ok(unsafe { std::slice::from_raw_parts(p, n) })
}

/// An output array of `n` elements.
#[inline]
unsafe fn out_slice<'a, T>(
    log: &LogSink,
    func: &str,
    what: &str,
    p: *mut T,
    n: usize,
) -> Result<&'a mut [T], fmi2Status> {
    if n == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        log.error(&format!("{func}: {what} is NULL but its length is {n}"));
        return Err(fmi2Error);
    }
    if n > isize::MAX as usize / std::mem::size_of::<T>().max(1) {
        log.error(&format!("{func}: length {n} of {what} is impossible"));
        return Err(fmi2Error);
    }
    // SAFETY: the importer guarantees `n` writable elements at `p`.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, n) })
}

/// A non-NULL pointer argument.
fn non_null<T>(log: &LogSink, func: &str, what: &str, p: *const T) -> Result<(), fmi2Status> {
    if p.is_null() {
        log.error(&format!("{func}: {what} is NULL"));
        Err(fmi2Error)
    } else {
        Ok(())
    }
}

#[inline]
fn lookup<'v, V>(
    vars: &'v [ScalarVariable<V>],
    log: &LogSink,
    func: &str,
    vr: fmi2ValueReference,
) -> Result<&'v ScalarVariable<V>, fmi2Status> {
    vars.get(vr as usize)
        .ok_or_else(|| unknown_reference(vars.len(), log, func, vr))
}

/// The [`Dispatch`] entry of `vr` (the get and set functions' hot path).
#[inline]
fn dispatch_of<'d, V>(
    dispatch: &'d [Dispatch<V>],
    log: &LogSink,
    func: &str,
    vr: fmi2ValueReference,
) -> Result<&'d Dispatch<V>, fmi2Status> {
    dispatch
        .get(vr as usize)
        .ok_or_else(|| unknown_reference(dispatch.len(), log, func, vr))
}

/// Logs an unknown value reference.
#[cold]
fn unknown_reference(
    n_vars: usize,
    log: &LogSink,
    func: &str,
    vr: fmi2ValueReference,
) -> fmi2Status {
    log.error(&format!(
        "{func}: unknown value reference {vr} (this FMU has {n_vars} variables, value references 0 to {})",
        n_vars.saturating_sub(1)
    ));
    fmi2Error
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Real,
    Integer,
    Boolean,
    String,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Real => "Real",
            Kind::Integer => "Integer",
            Kind::Boolean => "Boolean",
            Kind::String => "String",
        }
    }

    /// Whether a variable of value type `v` is accessed by this kind's
    /// functions (no variable is a String).
    #[inline]
    fn is(self, v: ValueKind) -> bool {
        matches!(
            (self, v),
            (Kind::Real, ValueKind::Real)
                | (Kind::Integer, ValueKind::Integer)
                | (Kind::Boolean, ValueKind::Boolean)
        )
    }
}

/// Logs that `v` is not of the value type `kind`'s functions access.
#[cold]
fn wrong_kind<V>(
    log: &LogSink,
    func: &str,
    vr: fmi2ValueReference,
    v: &ScalarVariable<V>,
    kind: Kind,
) -> fmi2Status {
    log.error(&format!(
        "{func}: variable '{}' (value reference {vr}) is of type {}, not {}",
        v.name,
        type_name(&v.ty),
        kind.name()
    ));
    fmi2Error
}

/// In initialization mode, make the outputs consistent with what was set
/// (FMI 2.0 spec, section 4.2.4: outputs may be read in initialization
/// mode). On error the model is unchanged and stays dirty.
#[inline]
fn ensure_initialized<M: Model>(inst: &mut Instance<M>, func: &str) -> Result<(), fmi2Status> {
    if inst.layer.fmi_state == FmiState::InitializationMode && inst.layer.dirty {
        if let Err(ModelError(msg)) = inst.model.initialize() {
            inst.log.error(&format!(
                "{func}: the initial values cannot be computed: {msg}"
            ));
            return Err(fmi2Error);
        }
        inst.layer.dirty = false;
        inst.log.debug(LogCategory::Events, || {
            format!("{func}: initial values computed")
        });
    }
    Ok(())
}

fn get_values<M: Model, T: Copy + std::fmt::Debug>(
    inst: &mut Instance<M>,
    func: &str,
    vrs: &[fmi2ValueReference],
    out: &mut [T],
    kind: Kind,
    read: impl Fn(&M, M::Var) -> T,
) -> Outcome {
    // First pass: validate (no allocation: this is the hot path).
    let mut needs_init = false;
    for &vr in vrs {
        let d = dispatch_of(&inst.dispatch, &inst.log, func, vr)?;
        if !kind.is(d.kind) {
            return Err(wrong_kind(
                &inst.log,
                func,
                vr,
                &inst.vars[vr as usize],
                kind,
            ));
        }
        needs_init |= d.computed;
    }
    if needs_init {
        ensure_initialized(inst, func)?;
    }
    for (o, &vr) in out.iter_mut().zip(vrs) {
        *o = read(&inst.model, inst.dispatch[vr as usize].id);
    }
    inst.log.debug(LogCategory::All, || {
        let items: Vec<String> = vrs
            .iter()
            .zip(out.iter())
            .map(|(&vr, val)| format!("{} = {val:?}", inst.vars[vr as usize].name))
            .collect();
        format!("{func}: {}", items.join(", "))
    });
    Ok(fmi2OK)
}

fn set_values<M: Model, T: Copy>(
    inst: &mut Instance<M>,
    func: &str,
    vrs: &[fmi2ValueReference],
    vals: &[T],
    kind: Kind,
    show: impl Fn(T) -> String,
    apply: impl Fn(&mut M, M::Var, T) -> Result<SetOutcome, ModelError>,
) -> Outcome {
    let state = inst.layer.fmi_state;
    // First pass: every reference valid, of the right type and settable now,
    // before anything changes (no allocation: this is the hot path).
    for &vr in vrs {
        let d = dispatch_of(&inst.dispatch, &inst.log, func, vr)?;
        let v = &inst.vars[vr as usize];
        if !kind.is(d.kind) {
            return Err(wrong_kind(&inst.log, func, vr, v, kind));
        }
        if !d.settable.contains(state) {
            inst.log.error(&format!(
                "{func}: variable '{}' (causality = {}, variability = {}) cannot be set in state {}",
                v.name,
                causality_name(v.causality),
                variability_name(v.variability),
                state.name()
            ));
            return Err(fmi2Error);
        }
    }
    // A multi-element set that fails half-way must leave the model as it was.
    let backup = (vrs.len() > 1).then(|| inst.model.clone());
    let mut warnings = Vec::new();
    for (&vr, &val) in vrs.iter().zip(vals) {
        let v = &inst.vars[vr as usize];
        let (id, name) = (v.id, v.name);
        match apply(&mut inst.model, id, val) {
            Ok(SetOutcome::Ok) => {}
            Ok(SetOutcome::Warning { message, log_once }) => {
                warnings.push((name, message, log_once));
            }
            Err(ModelError(msg)) => {
                if let Some(b) = backup {
                    inst.model = b;
                }
                inst.log.error(&format!(
                    "{func}: cannot set '{name}' = {}: {msg}",
                    show(val)
                ));
                return Err(fmi2Error);
            }
        }
    }
    if !vrs.is_empty() {
        inst.layer.dirty = true;
    }
    inst.log.debug(LogCategory::All, || {
        let items: Vec<String> = vrs
            .iter()
            .zip(vals)
            .map(|(&vr, &val)| format!("{} = {}", inst.vars[vr as usize].name, show(val)))
            .collect();
        format!("{func}: {}", items.join(", "))
    });
    if warnings.is_empty() {
        return Ok(fmi2OK);
    }
    for (name, message, log_once) in warnings {
        if !log_once || inst.warned.insert(name.to_string()) {
            inst.log.warning(&format!("{func}: '{name}': {message}"));
        }
    }
    Ok(fmi2Warning)
}

fn show_real(v: f64) -> String {
    format!("{v:?}")
}

fn show_bool(v: fmi2Boolean) -> String {
    match v {
        0 => "false".to_string(),
        1 => "true".to_string(),
        v => format!("true ({v})"),
    }
}

fn cstr_lossy(p: fmi2String) -> String {
    if p.is_null() {
        "(NULL)".to_string()
    } else {
        // SAFETY: non-NULL strings from the importer are NUL-terminated.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

// ---------------------------------------------------------------------------
// Creation, destruction and logging (FMI 2.0 spec, section 2.1.5)
// ---------------------------------------------------------------------------
