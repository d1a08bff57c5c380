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

/// `fmi2Instantiate` (FMI 2.0 spec, section 2.1.5). Checks that `fmuType` is
/// `fmi2CoSimulation`, that `fmuGUID` equals [`guid_for`] of this model and
/// that `instanceName` is a non-empty string. `functions` may be NULL or have
/// NULL members (memory callbacks are never used:
/// `canNotUseMemoryManagementFunctions = true`); `fmuResourceLocation` and
/// `visible` are not used. On failure the reason is logged (if a logger was
/// given) and NULL is returned.
///
/// # Safety
/// Non-NULL pointers must be valid as described in `fmi2Functions.h`.
pub unsafe fn instantiate<M: Model>(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    fmu_guid: fmi2String,
    _fmu_resource_location: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    logging_on: fmi2Boolean,
) -> fmi2Component {
    const F: &str = "fmi2Instantiate";
    let _fp = QuietFp::enter();
    let callbacks = if functions.is_null() {
        None
    } else {
        // SAFETY: non-NULL and valid per the importer's contract.
        Some(unsafe { *functions })
    };
    let name = if instance_name.is_null() {
        None
    } else {
        // SAFETY: NUL-terminated per the contract.
        Some(CString::from(unsafe { CStr::from_ptr(instance_name) }))
    };
    let sink = LogSink::new(
        name.clone().unwrap_or_default(),
        callbacks,
        logging_on != fmi2False,
    );
    let result = catch_unwind(AssertUnwindSafe(|| -> Option<fmi2Component> {
        let Some(name) = name else {
            sink.error(&format!("{F}: instanceName is NULL"));
            return None;
        };
        if name.to_string_lossy().trim().is_empty() {
            sink.error(&format!("{F}: instanceName is empty"));
            return None;
        }
        if fmu_type != fmi2CoSimulation {
            let what = if fmu_type == fmi2ModelExchange {
                "fmi2ModelExchange"
            } else {
                "an unknown fmi2Type"
            };
            sink.error(&format!(
                "{F}: fmuType is {what} ({fmu_type}); this FMU supports only fmi2CoSimulation"
            ));
            return None;
        }
        let info = M::info();
        let vars = M::variables();
        let guid = guid_for(&info, &vars);
        if fmu_guid.is_null() {
            sink.error(&format!("{F}: fmuGUID is NULL (expected {guid})"));
            return None;
        }
        let given = cstr_lossy(fmu_guid);
        if given != guid {
            sink.error(&format!(
                "{F}: fmuGUID {given} does not match this binary ({guid}): modelDescription.xml and binary are from different builds"
            ));
            return None;
        }
        let inst = Instance::<M>::new(vars, info, guid, sink.clone());
        inst.log.debug(LogCategory::All, || {
            format!("{F}: instance created (GUID {})", inst.guid)
        });
        Some(Box::into_raw(Box::new(inst)) as fmi2Component)
    }));
    match result {
        Ok(Some(c)) => c,
        Ok(None) => std::ptr::null_mut(),
        Err(payload) => {
            let msg = super::instance::panic_message(payload.as_ref());
            let _ = catch_unwind(AssertUnwindSafe(|| {
                sink.fatal(&format!("{F}: internal error (panic): {msg}"))
            }));
            std::ptr::null_mut()
        }
    }
}

/// `fmi2FreeInstance` (FMI 2.0 spec, section 2.1.5): frees the instance and
/// every FMU state it still owns. NULL (or a pointer that is not an instance
/// of this model) is ignored. The state table does not list `fatal`; since
/// this function cannot report an error and releasing memory is always safe
/// here, the instance is freed in every state.
///
/// # Safety
/// `c` must be NULL or a live instance of this model; it is invalid afterwards.
pub unsafe fn free_instance<M: Model>(c: fmi2Component) {
    // SAFETY: forwarded contract.
    let Some(inst) = (unsafe { Instance::<M>::from_component(c) }) else {
        return;
    };
    let _ = catch_unwind(AssertUnwindSafe(|| {
        inst.log
            .debug(LogCategory::All, || "fmi2FreeInstance".to_string());
        inst.invalidate();
        // SAFETY: `c` came from `Box::into_raw` in `instantiate`.
        drop(unsafe { Box::from_raw(c as *mut Instance<M>) });
    }));
}

/// `fmi2SetDebugLogging` (FMI 2.0 spec, section 2.1.5), with the semantics
/// documented at [`LogSink::set_debug_logging`]: `(true, [])` enables all
/// debug categories, `(true, list)` exactly the listed ones, `(false, _)`
/// switches debug logging off. An unknown (or NULL) category name rejects
/// the whole call with `fmi2Error` and changes nothing.
///
/// # Safety
/// `c` a live instance; `categories` `nCategories` valid C strings.
pub unsafe fn set_debug_logging<M: Model>(
    c: fmi2Component,
    logging_on: fmi2Boolean,
    n_categories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    const F: &str = "fmi2SetDebugLogging";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_DEBUG_LOGGING, |inst| {
            let names = in_slice(&inst.log, F, "categories", categories, n_categories)?;
            let mut parsed = Vec::with_capacity(names.len());
            for (i, &p) in names.iter().enumerate() {
                if p.is_null() {
                    inst.log.error(&format!("{F}: categories[{i}] is NULL"));
                    return Err(fmi2Error);
                }
                let name = cstr_lossy(p);
                let Some(cat) = LogCategory::from_name(&name) else {
                    let known: Vec<&str> = super::instance::LOG_CATEGORIES
                        .iter()
                        .map(|(n, _)| *n)
                        .collect();
                    inst.log.error(&format!(
                        "{F}: unknown log category '{name}' (known: {})",
                        known.join(", ")
                    ));
                    return Err(fmi2Error);
                };
                parsed.push(cat);
            }
            inst.log.set_debug_logging(logging_on != fmi2False, &parsed);
            inst.log.debug(LogCategory::All, || {
                format!(
                    "{F}: loggingOn = {}, categories = [{}]",
                    logging_on != fmi2False,
                    parsed
                        .iter()
                        .map(|c| c.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            });
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Initialization, termination, reset (FMI 2.0 spec, section 2.1.6)
// ---------------------------------------------------------------------------

/// `fmi2SetupExperiment` (FMI 2.0 spec, section 2.1.6). `startTime` must be
/// finite; with `stopTimeDefined`, `stopTime` must be finite and
/// `>= startTime` (then `fmi2DoStep` never goes past it). The tolerance is
/// stored but not used (the models' steps have no error control).
///
/// # Safety
/// `c` a live instance.
pub unsafe fn setup_experiment<M: Model>(
    c: fmi2Component,
    tolerance_defined: fmi2Boolean,
    tolerance: fmi2Real,
    start_time: fmi2Real,
    stop_time_defined: fmi2Boolean,
    stop_time: fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2SetupExperiment";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SETUP_EXPERIMENT, |inst| {
            if !start_time.is_finite() {
                inst.log
                    .error(&format!("{F}: startTime = {start_time:?} is not finite"));
                return Err(fmi2Error);
            }
            if tolerance_defined != fmi2False && !(tolerance.is_finite() && tolerance >= 0.0) {
                inst.log.error(&format!(
                    "{F}: tolerance = {tolerance:?} (toleranceDefined = fmi2True) must be finite and >= 0"
                ));
                return Err(fmi2Error);
            }
            let stop = if stop_time_defined != fmi2False {
                if !stop_time.is_finite() || stop_time < start_time {
                    inst.log.error(&format!(
                        "{F}: stopTime = {stop_time:?} must be finite and >= startTime = {start_time:?}"
                    ));
                    return Err(fmi2Error);
                }
                Some(stop_time)
            } else {
                None
            };
            let l = &mut inst.layer;
            l.start_time = start_time;
            l.time = start_time;
            l.last_successful_time = start_time;
            l.stop_time = stop;
            l.tolerance = (tolerance_defined != fmi2False).then_some(tolerance);
            inst.log.debug(LogCategory::All, || {
                format!("{F}: startTime = {start_time:?}, stopTime = {stop:?}")
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2EnterInitializationMode` (FMI 2.0 spec, section 2.1.6).
///
/// # Safety
/// `c` a live instance.
pub unsafe fn enter_initialization_mode<M: Model>(c: fmi2Component) -> fmi2Status {
    const F: &str = "fmi2EnterInitializationMode";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::ENTER_INITIALIZATION_MODE, |inst| {
            inst.layer.fmi_state = FmiState::InitializationMode;
            inst.log
                .debug(LogCategory::Events, || format!("{F}: initializationMode"));
            Ok(fmi2OK)
        })
    }
}

/// `fmi2ExitInitializationMode` (FMI 2.0 spec, section 2.1.6): calls
/// [`Model::initialize`]. If that fails the call returns `fmi2Error` and
/// the instance stays in initialization mode with the model unchanged, so
/// the importer can correct the offending values and try again.
///
/// # Safety
/// `c` a live instance.
pub unsafe fn exit_initialization_mode<M: Model>(c: fmi2Component) -> fmi2Status {
    const F: &str = "fmi2ExitInitializationMode";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::EXIT_INITIALIZATION_MODE, |inst| {
            if let Err(ModelError(msg)) = inst.model.initialize() {
                inst.log
                    .error(&format!("{F}: initialization failed: {msg}"));
                return Err(fmi2Error);
            }
            let l = &mut inst.layer;
            l.dirty = false;
            l.fmi_state = FmiState::StepComplete;
            l.last_successful_time = l.time;
            inst.log.debug(LogCategory::Events, || {
                format!("{F}: stepComplete at t = {:?}", inst.layer.time)
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2Terminate` (FMI 2.0 spec, section 2.1.6): state `terminated`.
///
/// # Safety
/// `c` a live instance.
pub unsafe fn terminate<M: Model>(c: fmi2Component) -> fmi2Status {
    const F: &str = "fmi2Terminate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::TERMINATE, |inst| {
            inst.layer.fmi_state = FmiState::Terminated;
            inst.log.debug(LogCategory::Events, || {
                format!("{F}: terminated at t = {:?}", inst.layer.time)
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2Reset` (FMI 2.0 spec, section 2.1.6): a fresh model
/// ([`Model::new`]), state `instantiated`, time and experiment setup
/// cleared, as after `fmi2Instantiate`. Logging settings and the FMU states
/// handed out are kept.
///
/// # Safety
/// `c` a live instance.
pub unsafe fn reset<M: Model>(c: fmi2Component) -> fmi2Status {
    const F: &str = "fmi2Reset";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::RESET, |inst| {
            inst.reset();
            inst.log
                .debug(LogCategory::Events, || format!("{F}: instantiated"));
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Getting and setting values (FMI 2.0 spec, section 2.1.7)
// ---------------------------------------------------------------------------

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

fn known_state<'a, M: Model>(
    inst: &'a Instance<M>,
    func: &str,
    s: fmi2FMUstate,
) -> Result<&'a super::instance::Snapshot<M>, fmi2Status> {
    non_null(&inst.log, func, "FMUstate", s)?;
    inst.states.get(&(s as usize)).map(|b| &**b).ok_or_else(|| {
        inst.log.error(&format!(
            "{func}: FMUstate {s:p} is not an FMU state of this instance (freed, or from another instance)"
        ));
        fmi2Error
    })
}

fn register_state<M: Model>(
    inst: &mut Instance<M>,
    snap: super::instance::Snapshot<M>,
) -> fmi2FMUstate {
    let boxed = Box::new(snap);
    let key = &*boxed as *const super::instance::Snapshot<M> as usize;
    inst.states.insert(key, boxed);
    key as fmi2FMUstate
}

/// `fmi2GetFMUstate` (FMI 2.0 spec, section 2.1.8): a copy of the model and
/// of the layer state (FMI state, time, experiment setup, last successful
/// time, dirty flag). If `*FMUstate` is non-NULL it must be a state of this
/// instance, which is overwritten in place.
///
/// # Safety
/// `c` a live instance; `fmu_state` a valid `fmi2FMUstate*`.
pub unsafe fn get_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2GetFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "FMUstate", fmu_state)?;
            let existing = *fmu_state;
            let snap = inst.snapshot();
            if existing.is_null() {
                *fmu_state = register_state(inst, snap);
            } else {
                known_state(inst, F, existing)?;
                if let Some(slot) = inst.states.get_mut(&(existing as usize)) {
                    **slot = snap;
                }
            }
            inst.log.debug(LogCategory::Events, || {
                format!(
                    "{F}: state {:p} saved at t = {:?}",
                    *fmu_state, inst.layer.time
                )
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SetFMUstate` (FMI 2.0 spec, section 2.1.8): restores model and layer
/// state exactly as saved, including the FMI state (so a state saved in
/// `stepComplete` brings an instance in `stepFailed` or `error` back to
/// `stepComplete`).
///
/// # Safety
/// `c` a live instance.
pub unsafe fn set_fmu_state<M: Model>(c: fmi2Component, fmu_state: fmi2FMUstate) -> fmi2Status {
    const F: &str = "fmi2SetFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            let snap = known_state(inst, F, fmu_state)?.clone();
            inst.model = snap.model;
            inst.layer = snap.layer;
            inst.log.debug(LogCategory::Events, || {
                format!(
                    "{F}: state {fmu_state:p} restored: {} at t = {:?}",
                    inst.layer.fmi_state.name(),
                    inst.layer.time
                )
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2FreeFMUstate` (FMI 2.0 spec, section 2.1.8): frees `*FMUstate` and
/// sets it to NULL. A NULL `FMUstate` or `*FMUstate` is ignored.
///
/// # Safety
/// `c` a live instance; `fmu_state` NULL or a valid `fmi2FMUstate*`.
pub unsafe fn free_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2FreeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            if fmu_state.is_null() || (*fmu_state).is_null() {
                return Ok(fmi2OK);
            }
            let s = *fmu_state;
            known_state(inst, F, s)?;
            inst.states.remove(&(s as usize));
            *fmu_state = std::ptr::null_mut();
            inst.log
                .debug(LogCategory::Events, || format!("{F}: state {s:p} freed"));
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SerializedFMUstateSize` (FMI 2.0 spec, section 2.1.8).
///
/// # Safety
/// `c` a live instance; `size` a valid `size_t*`.
pub unsafe fn serialized_fmu_state_size<M: Model>(
    c: fmi2Component,
    fmu_state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    const F: &str = "fmi2SerializedFMUstateSize";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "size", size)?;
            let snap = known_state(inst, F, fmu_state)?;
            *size = encode_state(&inst.guid, snap).len();
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SerializeFMUstate` (FMI 2.0 spec, section 2.1.8): writes the bytes
/// of [`encode_state`] (values, never pointers; restorable in another
/// process). `size` must be at least `fmi2SerializedFMUstateSize`; only that
/// many bytes are written.
///
/// # Safety
/// `c` a live instance; `serialized_state` `size` writable bytes.
pub unsafe fn serialize_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: fmi2FMUstate,
    serialized_state: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    const F: &str = "fmi2SerializeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            let snap = known_state(inst, F, fmu_state)?;
            let bytes = encode_state(&inst.guid, snap);
            if size < bytes.len() {
                inst.log.error(&format!(
                    "{F}: buffer of {size} bytes is too small, {} bytes needed (fmi2SerializedFMUstateSize)",
                    bytes.len()
                ));
                return Err(fmi2Error);
            }
            let out = out_slice(&inst.log, F, "serializedState", serialized_state, size)?;
            for (o, b) in out.iter_mut().zip(&bytes) {
                *o = *b as fmi2Byte;
            }
            Ok(fmi2OK)
        })
    }
}

/// `fmi2DeSerializeFMUstate` (FMI 2.0 spec, section 2.1.8): checks the
/// bytes ([`decode_state`]: magic, format version, length, checksum, GUID,
/// model data) and on success stores a new FMU state of this instance in
/// `*FMUstate`. Invalid bytes give `fmi2Error` and allocate nothing.
///
/// # Safety
/// `c` a live instance; `serialized_state` `size` readable bytes;
/// `fmu_state` a valid `fmi2FMUstate*`.
pub unsafe fn deserialize_fmu_state<M: Model>(
    c: fmi2Component,
    serialized_state: *const fmi2Byte,
    size: usize,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2DeSerializeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "FMUstate", fmu_state)?;
            let bytes = in_slice(&inst.log, F, "serializedState", serialized_state, size)?;
            let bytes: &[u8] = std::slice::from_raw_parts(bytes.as_ptr() as *const u8, bytes.len());
            let snap = decode_state::<M>(&inst.guid, bytes).map_err(|msg| {
                inst.log.error(&format!("{F}: {msg}"));
                fmi2Error
            })?;
            *fmu_state = register_state(inst, snap);
            inst.log.debug(LogCategory::Events, || {
                format!("{F}: state {:p} created from {size} bytes", *fmu_state)
            });
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Partial derivatives (FMI 2.0 spec, section 2.1.9)
// ---------------------------------------------------------------------------

/// What a known of [`get_directional_derivative`] is: an input, or a
/// parameter (initialization mode only) with its declared range.
#[derive(Clone, Copy)]
enum Known {
    Input,
    Parameter { min: Option<f64>, max: Option<f64> },
}

/// `fmi2GetDirectionalDerivative` (FMI 2.0 spec, section 2.1.9):
/// `dvUnknown[i] = Σ_j ∂unknown_i/∂known_j · dvKnown[j]`. Unknowns must be
/// Real outputs. Knowns are Real inputs, with the partial derivatives from
/// [`Model::partial_derivative`], and in initialization mode also Real
/// parameters (the knowns of `<InitialUnknowns>`, section 2.2.8), with the
/// partial derivatives of the initial values from
/// [`initial_parameter_column`] (0 where the unknown's `depends_on` does not
/// name the parameter).
///
/// # Safety
/// `c` a live instance; arrays of the given lengths.
#[allow(clippy::too_many_arguments)]
pub unsafe fn get_directional_derivative<M: Model>(
    c: fmi2Component,
    v_unknown_ref: *const fmi2ValueReference,
    n_unknown: usize,
    v_known_ref: *const fmi2ValueReference,
    n_known: usize,
    dv_known: *const fmi2Real,
    dv_unknown: *mut fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2GetDirectionalDerivative";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_DIRECTIONAL_DERIVATIVE, |inst| {
            let unknowns = in_slice(&inst.log, F, "vUnknown_ref", v_unknown_ref, n_unknown)?;
            let knowns = in_slice(&inst.log, F, "vKnown_ref", v_known_ref, n_known)?;
            let dv_k = in_slice(&inst.log, F, "dvKnown", dv_known, n_known)?;
            if let Some(i) = dv_k.iter().position(|d| !d.is_finite()) {
                inst.log.error(&format!(
                    "{F}: dvKnown[{i}] = {:?} must be finite (a seed of the known variables)",
                    dv_k[i]
                ));
                return Err(fmi2Error);
            }
            let dv_u = out_slice(&inst.log, F, "dvUnknown", dv_unknown, n_unknown)?;
            let initializing = inst.layer.fmi_state == FmiState::InitializationMode;
            let refuse =
                |v: &ScalarVariable<M::Var>, vr: fmi2ValueReference, role: &str, rule: &str| {
                    inst.log.error(&format!(
                        "{F}: '{}' (value reference {vr}, {} {}) cannot be {role}: {rule}",
                        v.name,
                        type_name(&v.ty),
                        causality_name(v.causality)
                    ));
                    fmi2Error
                };
            let u_ids = unknowns
                .iter()
                .map(|&vr| {
                    let v = lookup(&inst.vars, &inst.log, F, vr)?;
                    if v.causality != Causality::Output || !matches!(v.ty, VarType::Real { .. }) {
                        return Err(refuse(v, vr, "an unknown", "unknowns must be Real outputs"));
                    }
                    Ok((v.id, v.name, &v.depends_on))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let k_ids = knowns
                .iter()
                .map(|&vr| {
                    let v = lookup(&inst.vars, &inst.log, F, vr)?;
                    match (v.causality, v.ty) {
                        (Causality::Input, VarType::Real { .. }) => {
                            Ok((v.id, v.name, Known::Input))
                        }
                        (Causality::Parameter, VarType::Real { min, max, .. })
                            if initializing && effective_initial(v) == Some(Initial::Exact) =>
                        {
                            Ok((v.id, v.name, Known::Parameter { min, max }))
                        }
                        _ if initializing => {
                            Err(refuse(v, vr, "a known", "knowns must be Real inputs or Real parameters"))
                        }
                        _ => Err(refuse(
                            v,
                            vr,
                            "a known",
                            "knowns must be Real inputs (Real parameters only in initialization mode)",
                        )),
                    }
                })
                .collect::<Result<Vec<_>, _>>()?;
            // In initialization mode the initial values are computed first —
            // on a copy, committed only when every partial derivative can be
            // taken, so that a refused call changes nothing.
            let pending = !u_ids.is_empty() && initializing && inst.layer.dirty;
            let mut initialized = None;
            if pending {
                let mut trial = inst.model.clone();
                if let Err(ModelError(msg)) = trial.initialize() {
                    inst.log.error(&format!(
                        "{F}: the initial values cannot be computed: {msg}"
                    ));
                    return Err(fmi2Error);
                }
                initialized = Some(trial);
            }
            let model = initialized.as_ref().unwrap_or(&inst.model);
            let mut result = vec![0.0; u_ids.len()];
            for (&(k, k_name, known), &dk) in k_ids.iter().zip(dv_k) {
                let Known::Parameter { min, max } = known else {
                    for (r, &(u, u_name, _)) in result.iter_mut().zip(&u_ids) {
                        match model.partial_derivative(u, k) {
                            Ok(p) => *r += p * dk,
                            Err(ModelError(msg)) => {
                                inst.log
                                    .error(&format!("{F}: d({u_name})/d({k_name}): {msg}"));
                                return Err(fmi2Error);
                            }
                        }
                    }
                    continue;
                };
                // A parameter: differences of the initial values, for the
                // unknowns whose initial value depends on it.
                let dependent: Vec<usize> = (0..u_ids.len())
                    .filter(|&i| u_ids[i].2.contains(&k_name))
                    .collect();
                if dependent.is_empty() {
                    continue;
                }
                let of: Vec<M::Var> = dependent.iter().map(|&i| u_ids[i].0).collect();
                match initial_parameter_column(model, k, min, max, &of) {
                    Ok(column) => {
                        for (&i, p) in dependent.iter().zip(column) {
                            result[i] += p * dk;
                        }
                    }
                    Err(msg) => {
                        let names: Vec<&str> = dependent.iter().map(|&i| u_ids[i].1).collect();
                        inst.log.error(&format!(
                            "{F}: d({})/d({k_name}) in initialization mode: {msg}",
                            names.join(", ")
                        ));
                        return Err(fmi2Error);
                    }
                }
            }
            if let Some(trial) = initialized {
                inst.model = trial;
                inst.layer.dirty = false;
                inst.log.debug(LogCategory::Events, || {
                    format!("{F}: initial values computed")
                });
            }
            dv_u.copy_from_slice(&result);
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Co-Simulation (FMI 2.0 spec, sections 4.2.1 - 4.2.3)
// ---------------------------------------------------------------------------

/// `fmi2SetRealInputDerivatives` (FMI 2.0 spec, section 4.2.1): only Real
/// inputs, `order` in `1..=ModelInfo::max_input_derivative_order`, forwarded
/// to [`Model::set_real_input_derivative`]. All-or-nothing like
/// [`set_real`].
///
/// # Safety
/// `c` a live instance; `vr`, `order`, `value` `nvr` elements each.
pub unsafe fn set_real_input_derivatives<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2SetRealInputDerivatives";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_REAL_INPUT_DERIVATIVES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let orders = in_slice(&inst.log, F, "order", order, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            let max = inst.info.max_input_derivative_order;
            let mut targets = Vec::with_capacity(nvr);
            for ((&vr, &ord), &val) in vrs.iter().zip(orders).zip(vals) {
                let v = lookup(&inst.vars, &inst.log, F, vr)?;
                if v.causality != Causality::Input || !matches!(v.ty, VarType::Real { .. }) {
                    inst.log.error(&format!(
                        "{F}: '{}' (value reference {vr}) is not a Real input",
                        v.name
                    ));
                    return Err(fmi2Error);
                }
                if ord < 1 || ord > max {
                    inst.log.error(&format!(
                        "{F}: order {ord} for '{}' is not supported (this FMU accepts input derivatives of order 1 to {max}; canInterpolateInputs = {})",
                        v.name,
                        max >= 1
                    ));
                    return Err(fmi2Error);
                }
                targets.push((v.id, v.name, ord, val));
            }
            let backup = (targets.len() > 1).then(|| inst.model.clone());
            for &(id, name, ord, val) in &targets {
                if let Err(ModelError(msg)) = inst.model.set_real_input_derivative(id, ord, val) {
                    if let Some(b) = backup {
                        inst.model = b;
                    }
                    inst.log.error(&format!(
                        "{F}: cannot set derivative of order {ord} of '{name}' = {val:?}: {msg}"
                    ));
                    return Err(fmi2Error);
                }
            }
            inst.log.debug(LogCategory::All, || {
                let items: Vec<String> = targets
                    .iter()
                    .map(|&(_, name, ord, val)| format!("d^{ord} {name} = {val:?}"))
                    .collect();
                format!("{F}: {}", items.join(", "))
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2GetRealOutputDerivatives` (FMI 2.0 spec, section 4.2.1). The FMUs
/// declare `maxOutputDerivativeOrder = 0`: after the state and pointer
/// checks, any request (`nvr > 0`) is an error saying output derivatives are
/// not provided; `nvr == 0` requests nothing and returns `fmi2OK`.
///
/// # Safety
/// `c` a live instance; `vr`, `order`, `value` `nvr` elements each.
pub unsafe fn get_real_output_derivatives<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2GetRealOutputDerivatives";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_REAL_OUTPUT_DERIVATIVES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let orders = in_slice(&inst.log, F, "order", order, nvr)?;
            out_slice(&inst.log, F, "value", value, nvr)?;
            if let (Some(&vr), Some(&ord)) = (vrs.first(), orders.first()) {
                let v = lookup(&inst.vars, &inst.log, F, vr)?;
                inst.log.error(&format!(
                    "{F}: output derivatives are not provided (maxOutputDerivativeOrder = 0); requested order {ord} of '{}'",
                    v.name
                ));
                return Err(fmi2Error);
            }
            Ok(fmi2OK)
        })
    }
}

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
