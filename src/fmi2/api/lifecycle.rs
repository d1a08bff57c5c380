//! Instantiation, set-up, initialization, termination and reset (FMI 2.0
//! spec, sections 2.1.5 and 4.2.1).

use super::*;

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
            let msg = super::super::instance::panic_message(payload.as_ref());
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
                    let known: Vec<&str> = super::super::instance::LOG_CATEGORIES
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
