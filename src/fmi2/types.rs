//! The C types of the FMI 2.0 headers `fmi2TypesPlatform.h` and
//! `fmi2FunctionTypes.h` (FMI 2.0 spec, sections 2.1.2 "Platform Dependent
//! Definitions" and 2.1.3 "Status Returned by Functions").
//!
//! C enumerations that the importer passes *into* the FMU (`fmi2Type`,
//! `fmi2StatusKind`) are plain `c_int` aliases with constants, so that an
//! out-of-range value from a faulty importer is an ordinary integer we can
//! reject rather than an invalid Rust enum. `fmi2Status`, which only the FMU
//! produces, is a `#[repr(C)]` enum (same size and values as the C enum).

#![allow(non_camel_case_types, non_upper_case_globals, non_snake_case)]

use std::os::raw::{c_char, c_int, c_uint, c_void};

/// Pointer to an FMU instance (`typedef void* fmi2Component`).
pub type fmi2Component = *mut c_void;
/// Pointer to the importer's environment, handed back in callbacks.
pub type fmi2ComponentEnvironment = *mut c_void;
/// Pointer to an internal FMU state (`typedef void* fmi2FMUstate`).
pub type fmi2FMUstate = *mut c_void;
/// Handle of a variable (`typedef unsigned int fmi2ValueReference`).
pub type fmi2ValueReference = c_uint;
/// `typedef double fmi2Real`.
pub type fmi2Real = f64;
/// `typedef int fmi2Integer`.
pub type fmi2Integer = c_int;
/// `typedef int fmi2Boolean` (values [`fmi2True`] and [`fmi2False`]).
pub type fmi2Boolean = c_int;
/// `typedef char fmi2Char`.
pub type fmi2Char = c_char;
/// `typedef const fmi2Char* fmi2String`.
pub type fmi2String = *const fmi2Char;
/// `typedef char fmi2Byte` (serialized FMU states).
pub type fmi2Byte = c_char;

/// `#define fmi2True 1`.
pub const fmi2True: fmi2Boolean = 1;
/// `#define fmi2False 0`.
pub const fmi2False: fmi2Boolean = 0;

/// Value of `fmi2GetTypesPlatform()` for the standard header set.
pub const fmi2TypesPlatform: &str = "default";
/// Value of `fmi2GetVersion()`.
pub const fmi2Version: &str = "2.0";

/// Status returned by every FMI function (FMI 2.0 spec, section 2.1.3).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum fmi2Status {
    fmi2OK = 0,
    fmi2Warning = 1,
    fmi2Discard = 2,
    fmi2Error = 3,
    fmi2Fatal = 4,
    fmi2Pending = 5,
}
pub use fmi2Status::{fmi2Discard, fmi2Error, fmi2Fatal, fmi2OK, fmi2Pending, fmi2Warning};

impl fmi2Status {
    /// Name as in the C header (for messages).
    pub fn name(self) -> &'static str {
        match self {
            fmi2OK => "fmi2OK",
            fmi2Warning => "fmi2Warning",
            fmi2Discard => "fmi2Discard",
            fmi2Error => "fmi2Error",
            fmi2Fatal => "fmi2Fatal",
            fmi2Pending => "fmi2Pending",
        }
    }

    /// Inverse of `self as u8` (for serialized FMU states).
    pub fn from_u8(v: u8) -> Option<Self> {
        Some(match v {
            0 => fmi2OK,
            1 => fmi2Warning,
            2 => fmi2Discard,
            3 => fmi2Error,
            4 => fmi2Fatal,
            5 => fmi2Pending,
            _ => return None,
        })
    }
}

/// `typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type`.
pub type fmi2Type = c_int;
pub const fmi2ModelExchange: fmi2Type = 0;
pub const fmi2CoSimulation: fmi2Type = 1;

/// `typedef enum {...} fmi2StatusKind` (FMI 2.0 spec, section 4.2.3).
pub type fmi2StatusKind = c_int;
pub const fmi2DoStepStatus: fmi2StatusKind = 0;
pub const fmi2PendingStatus: fmi2StatusKind = 1;
pub const fmi2LastSuccessfulTime: fmi2StatusKind = 2;
pub const fmi2Terminated: fmi2StatusKind = 3;

/// `fmi2CallbackLogger`: variadic, `message` is a printf format string.
pub type fmi2CallbackLogger = Option<
    unsafe extern "C" fn(
        componentEnvironment: fmi2ComponentEnvironment,
        instanceName: fmi2String,
        status: fmi2Status,
        category: fmi2String,
        message: fmi2String,
        ...
    ),
>;
/// `fmi2CallbackAllocateMemory` (`calloc` semantics). Never used by this FMU.
pub type fmi2CallbackAllocateMemory =
    Option<unsafe extern "C" fn(nobj: usize, size: usize) -> *mut c_void>;
/// `fmi2CallbackFreeMemory`. Never used by this FMU.
pub type fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(obj: *mut c_void)>;
/// `fmi2StepFinished` (asynchronous steps only). Never used by this FMU.
pub type fmi2StepFinished = Option<
    unsafe extern "C" fn(componentEnvironment: fmi2ComponentEnvironment, status: fmi2Status),
>;

/// `fmi2CallbackFunctions` (FMI 2.0 spec, section 2.1.5; fields not const
/// since FMI 2.0.1).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocateMemory: fmi2CallbackAllocateMemory,
    pub freeMemory: fmi2CallbackFreeMemory,
    pub stepFinished: fmi2StepFinished,
    pub componentEnvironment: fmi2ComponentEnvironment,
}
