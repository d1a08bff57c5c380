//! A generic FMI 2.0 Co-Simulation layer over a [`Model`].
//!
//! The layer knows nothing about muscles. It owns the FMI state machine, the
//! communication time, argument checking, logging and FMU states; the model
//! owns its physics and one variable table ([`Model::variables`]) from which
//! both `modelDescription.xml` ([`model_description`]) and the value-reference
//! dispatch are built (value reference = index in the table).
//!
//! - [`types`]: the C types of `fmi2TypesPlatform.h` / `fmi2FunctionTypes.h`.
//! - [`api`]: every FMI 2.0 common and Co-Simulation function, generic over
//!   the model, with the exact C parameters.
//! - [`export_fmi2!`](crate::export_fmi2): defines the `#[no_mangle]`
//!   `fmi2Xxx` symbols of an FMU binary for one model type.
//! - [`state`]: the state machine table (FMI 2.0 spec, section 4.2.4).
//! - [`rules`]: FMI 2.0 variable rules (section 2.2.7), e.g. which
//!   variables may be set in which state.
//! - [`instance`]: the instance, logging, FMU state serialization.
//! - [`bytes`]: little-endian byte helpers for serialized FMU states.
//! - [`fp_env`]: the default floating-point environment every entry point
//!   computes in (a host's trapping exceptions are masked for the call).
//! - [`model_description`]: `modelDescription.xml`, the GUID, a table check,
//!   `documentation/index.html`.
//!
//! # State machine
//!
//! Calls are checked against the FMI 2.0 Co-Simulation state table
//! (section 4.2.4); steps are synchronous, so `stepInProgress` is never
//! entered. Allowed states per function:
//!
//! | function | allowed in |
//! |---|---|
//! | `fmi2GetTypesPlatform`, `fmi2GetVersion` | always (no instance) |
//! | `fmi2Instantiate` | start (no instance) |
//! | `fmi2SetDebugLogging` | instantiated, initializationMode, stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2FreeInstance` | as `fmi2SetDebugLogging` (and, since it cannot fail, also fatal) |
//! | `fmi2SetupExperiment`, `fmi2EnterInitializationMode` | instantiated |
//! | `fmi2ExitInitializationMode` | initializationMode |
//! | `fmi2Terminate` | stepComplete, stepFailed |
//! | `fmi2Reset` | instantiated, initializationMode, stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2GetReal/Integer/Boolean/String` | initializationMode, stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2SetReal/Integer/Boolean/String` | instantiated, initializationMode, stepComplete (which variables: [`rules::settable_in`]) |
//! | `fmi2Get/Set/FreeFMUstate`, `fmi2SerializedFMUstateSize`, `fmi2(De)SerializeFMUstate` | instantiated, initializationMode, stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2GetDirectionalDerivative` | initializationMode, stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2SetRealInputDerivatives` | instantiated, initializationMode, stepComplete |
//! | `fmi2GetRealOutputDerivatives` | stepComplete, stepFailed, stepCanceled, terminated, error |
//! | `fmi2DoStep` | stepComplete |
//! | `fmi2CancelStep` | stepInProgress only, i.e. never |
//! | `fmi2GetStatus`, `fmi2GetReal/Integer/Boolean/StringStatus` | stepComplete, stepFailed, terminated |
//!
//! Transitions: `fmi2EnterInitializationMode` → initializationMode;
//! `fmi2ExitInitializationMode` → stepComplete; `fmi2DoStep` → stepComplete
//! (`fmi2OK`), stepFailed (`fmi2Discard`) or error (`fmi2Error` from the
//! model); `fmi2Terminate` → terminated; `fmi2Reset` → instantiated;
//! `fmi2SetFMUstate` → the state saved in the FMU state; a panic → fatal.
//!
//! # Rejected calls change nothing
//!
//! A call that is not allowed in the current state, has invalid arguments
//! (NULL pointers, unknown value references, wrong types, a variable that may
//! not be set now, an out-of-range or mismatched step time), or sets a value
//! the model refuses returns `fmi2Error`, logs why (naming the function and,
//! where there is one, the variable, the value and the model's statement of
//! the valid range) and leaves the instance exactly as it was: the next legal
//! call behaves as if the rejected one never happened. A vector set is
//! all-or-nothing. We deliberately do **not** enter the FMI `error` state on
//! such rejected inputs: the instance keeps its last good state, so an
//! importer can correct the value and continue. Only a model's
//! unrecoverable step failure ([`StepError::Error`]) enters `error`, and only
//! a panic enters `fatal`.
//!
//! # Logging
//!
//! Messages go to the importer's logger as
//! `logger(env, instanceName, status, category, "%s", text)`, with every `#`
//! of the text replaced (FMI 2.0 reserves `#...#` for value-reference
//! escapes). Messages with status `fmi2Warning` or worse are always logged
//! (categories `logStatusWarning`, `logStatusDiscard`, `logStatusError`,
//! `logStatusFatal`); debug messages (`fmi2OK`, categories `logAll` and
//! `logEvents`) only when debug logging is on and their category (or
//! `logAll`) is enabled by `fmi2SetDebugLogging`.
//!
//! # Threads
//!
//! There is no global mutable state: all state hangs off the instance, so
//! different instances may be used concurrently and an instance may move
//! between threads between calls (FMI 2.0 section 2.1.4).

pub mod model;
pub use model::*;

pub mod api;
pub mod bytes;
pub mod fp_env;
pub mod initial_sensitivity;
pub mod instance;
pub mod model_description;
pub mod rules;
pub mod state;
pub mod types;

/// Defines the `#[no_mangle] extern "C"` FMI 2.0 Co-Simulation functions of
/// an FMU binary for one model type, forwarding to [`api`]:
///
/// ```ignore
/// crate::export_fmi2!(crate::fmus::hill1d::Hill1D);
/// ```
///
/// Invoke it exactly once per binary (the symbol names are fixed by FMI 2.0
/// section 2.1.1 for binary FMUs without a prefix).
#[macro_export]
macro_rules! export_fmi2 {
    ($model:ty) => {
        #[allow(non_snake_case)]
        mod __fmi2_exports {
            #![allow(unused_imports)]
            use super::*;
            use $crate::fmi2::api;
            use $crate::fmi2::types::{
                fmi2Boolean, fmi2Byte, fmi2CallbackFunctions, fmi2Component, fmi2FMUstate,
                fmi2Integer, fmi2Real, fmi2Status, fmi2StatusKind, fmi2String, fmi2Type,
                fmi2ValueReference,
            };
            type __Fmi2Model = $model;

            #[no_mangle]
            pub extern "C" fn fmi2GetTypesPlatform() -> *const ::std::ffi::c_char {
                api::get_types_platform()
            }

            #[no_mangle]
            pub extern "C" fn fmi2GetVersion() -> *const ::std::ffi::c_char {
                api::get_version()
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetDebugLogging(
                c: fmi2Component,
                loggingOn: fmi2Boolean,
                nCategories: usize,
                categories: *const fmi2String,
            ) -> fmi2Status {
                unsafe {
                    api::set_debug_logging::<__Fmi2Model>(c, loggingOn, nCategories, categories)
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Instantiate(
                instanceName: fmi2String,
                fmuType: fmi2Type,
                fmuGUID: fmi2String,
                fmuResourceLocation: fmi2String,
                functions: *const fmi2CallbackFunctions,
                visible: fmi2Boolean,
                loggingOn: fmi2Boolean,
            ) -> fmi2Component {
                unsafe {
                    api::instantiate::<__Fmi2Model>(
                        instanceName,
                        fmuType,
                        fmuGUID,
                        fmuResourceLocation,
                        functions,
                        visible,
                        loggingOn,
                    )
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
                unsafe { api::free_instance::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetupExperiment(
                c: fmi2Component,
                toleranceDefined: fmi2Boolean,
                tolerance: fmi2Real,
                startTime: fmi2Real,
                stopTimeDefined: fmi2Boolean,
                stopTime: fmi2Real,
            ) -> fmi2Status {
                unsafe {
                    api::setup_experiment::<__Fmi2Model>(
                        c,
                        toleranceDefined,
                        tolerance,
                        startTime,
                        stopTimeDefined,
                        stopTime,
                    )
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
                unsafe { api::enter_initialization_mode::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
                unsafe { api::exit_initialization_mode::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
                unsafe { api::terminate::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
                unsafe { api::reset::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe { api::get_real::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                unsafe { api::get_integer::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                unsafe { api::get_boolean::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2String,
            ) -> fmi2Status {
                unsafe { api::get_string::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Real,
            ) -> fmi2Status {
                unsafe { api::set_real::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Integer,
            ) -> fmi2Status {
                unsafe { api::set_integer::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Boolean,
            ) -> fmi2Status {
                unsafe { api::set_boolean::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2String,
            ) -> fmi2Status {
                unsafe { api::set_string::<__Fmi2Model>(c, vr, nvr, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(
                c: fmi2Component,
                FMUstate: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { api::get_fmu_state::<__Fmi2Model>(c, FMUstate) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(
                c: fmi2Component,
                FMUstate: fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { api::set_fmu_state::<__Fmi2Model>(c, FMUstate) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(
                c: fmi2Component,
                FMUstate: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { api::free_fmu_state::<__Fmi2Model>(c, FMUstate) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
                c: fmi2Component,
                FMUstate: fmi2FMUstate,
                size: *mut usize,
            ) -> fmi2Status {
                unsafe { api::serialized_fmu_state_size::<__Fmi2Model>(c, FMUstate, size) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(
                c: fmi2Component,
                FMUstate: fmi2FMUstate,
                serializedState: *mut fmi2Byte,
                size: usize,
            ) -> fmi2Status {
                unsafe {
                    api::serialize_fmu_state::<__Fmi2Model>(c, FMUstate, serializedState, size)
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: fmi2Component,
                serializedState: *const fmi2Byte,
                size: usize,
                FMUstate: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe {
                    api::deserialize_fmu_state::<__Fmi2Model>(c, serializedState, size, FMUstate)
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: fmi2Component,
                vUnknown_ref: *const fmi2ValueReference,
                nUnknown: usize,
                vKnown_ref: *const fmi2ValueReference,
                nKnown: usize,
                dvKnown: *const fmi2Real,
                dvUnknown: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe {
                    api::get_directional_derivative::<__Fmi2Model>(
                        c,
                        vUnknown_ref,
                        nUnknown,
                        vKnown_ref,
                        nKnown,
                        dvKnown,
                        dvUnknown,
                    )
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                order: *const fmi2Integer,
                value: *const fmi2Real,
            ) -> fmi2Status {
                unsafe { api::set_real_input_derivatives::<__Fmi2Model>(c, vr, nvr, order, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                order: *const fmi2Integer,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe { api::get_real_output_derivatives::<__Fmi2Model>(c, vr, nvr, order, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(
                c: fmi2Component,
                currentCommunicationPoint: fmi2Real,
                communicationStepSize: fmi2Real,
                noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
            ) -> fmi2Status {
                unsafe {
                    api::do_step::<__Fmi2Model>(
                        c,
                        currentCommunicationPoint,
                        communicationStepSize,
                        noSetFMUStatePriorToCurrentPoint,
                    )
                }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
                unsafe { api::cancel_step::<__Fmi2Model>(c) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Status,
            ) -> fmi2Status {
                unsafe { api::get_status::<__Fmi2Model>(c, s, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe { api::get_real_status::<__Fmi2Model>(c, s, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                unsafe { api::get_integer_status::<__Fmi2Model>(c, s, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                unsafe { api::get_boolean_status::<__Fmi2Model>(c, s, value) }
            }

            /// # Safety
            /// See `fmi2Functions.h`.
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2String,
            ) -> fmi2Status {
                unsafe { api::get_string_status::<__Fmi2Model>(c, s, value) }
            }
        }
    };
}
