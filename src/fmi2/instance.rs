//! One FMU instance: the model, its variable table, the FMI state machine,
//! the communication time, logging, and the FMU states it handed out.
//!
//! There is no global mutable state: everything an FMI function touches
//! hangs off the `fmi2Component` pointer, so instances can be used from
//! several threads (one thread at a time per instance, as FMI 2.0 section
//! 2.1.4 allows) and moved between threads between calls.

use std::any::{Any, TypeId};
use std::collections::{HashMap, HashSet};
use std::ffi::{CStr, CString};

use super::bytes::{fnv1a64, ByteReader, ByteWriter, FNV64_OFFSET};
use super::model::{Model, ModelInfo, ScalarVariable};
use super::rules::Dispatch;
use super::state::FmiState;
use super::types::*;

/// First field of every instance; checked before a component pointer is used.
pub const INSTANCE_MAGIC: u64 = 0x4869_6c6c_464d_4932; // "HillFMI2"

/// Log categories declared in `<LogCategories>` (FMI 2.0 spec, sections
/// 2.1.5 and 2.2.4). The `logStatus*` categories carry messages of that
/// status, which are always logged; `logAll` and `logEvents` carry debug
/// messages (status `fmi2OK`), logged only when debug logging is on and the
/// category (or `logAll`) is enabled through `fmi2SetDebugLogging`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogCategory {
    StatusWarning = 0,
    StatusDiscard = 1,
    StatusError = 2,
    StatusFatal = 3,
    All = 4,
    Events = 5,
}

/// Name and description of each [`LogCategory`], in declaration order.
pub const LOG_CATEGORIES: [(&str, &str); 6] = [
    (
        "logStatusWarning",
        "Messages with status fmi2Warning (always logged)",
    ),
    (
        "logStatusDiscard",
        "Messages with status fmi2Discard (always logged)",
    ),
    (
        "logStatusError",
        "Messages with status fmi2Error (always logged)",
    ),
    (
        "logStatusFatal",
        "Messages with status fmi2Fatal (always logged)",
    ),
    (
        "logAll",
        "All debug messages: every FMI call with its arguments",
    ),
    (
        "logEvents",
        "Debug messages on state changes and FMU state handling",
    ),
];

const CATEGORY_CSTR: [&CStr; 6] = [
    c"logStatusWarning",
    c"logStatusDiscard",
    c"logStatusError",
    c"logStatusFatal",
    c"logAll",
    c"logEvents",
];

impl LogCategory {
    pub fn from_name(name: &str) -> Option<Self> {
        use LogCategory::*;
        let all = [
            StatusWarning,
            StatusDiscard,
            StatusError,
            StatusFatal,
            All,
            Events,
        ];
        all.into_iter()
            .find(|c| LOG_CATEGORIES[*c as usize].0 == name)
    }

    pub fn name(self) -> &'static str {
        LOG_CATEGORIES[self as usize].0
    }
}

/// Makes a message safe for the importer's logger: FMI 2.0 section 2.1.5
/// reserves `#<type><vr>#` for value-reference escapes, so every `#` becomes
/// `No.`; NUL bytes (which would end the C string) become `\0`.
pub fn sanitize_message(text: &str) -> CString {
    let clean = text.replace('#', "No.").replace('\0', "\\0");
    CString::new(clean).unwrap_or_default()
}

/// Where an instance's messages go: the importer's `logger` callback
/// (FMI 2.0 spec, section 2.1.5), called as
/// `logger(componentEnvironment, instanceName, status, category, "%s", text)`
/// because importers treat the message as a printf format.
#[derive(Clone)]
pub struct LogSink {
    name: CString,
    logger: fmi2CallbackLogger,
    env: fmi2ComponentEnvironment,
    /// Per-category debug logging flags, indexed by [`LogCategory`]. Debug
    /// logging is "on" exactly when one of them is set; the `logStatus*`
    /// flags select no debug message (those messages are always logged).
    enabled: [bool; 6],
}

impl LogSink {
    /// `callbacks` may be absent or have a NULL logger: then nothing is logged.
    /// `logging_on` is `fmi2Instantiate`'s `loggingOn`: all debug categories
    /// on, or all off.
    pub fn new(name: CString, callbacks: Option<fmi2CallbackFunctions>, logging_on: bool) -> Self {
        let (logger, env) = match callbacks {
            Some(cb) => (cb.logger, cb.componentEnvironment),
            None => (None, std::ptr::null_mut()),
        };
        LogSink {
            name,
            logger,
            env,
            enabled: [logging_on; 6],
        }
    }

    pub fn instance_name(&self) -> &CStr {
        &self.name
    }

    fn emit(&self, status: fmi2Status, category: LogCategory, text: &str) {
        let Some(logger) = self.logger else { return };
        let msg = sanitize_message(text);
        // SAFETY: the importer gave us this callback for exactly this call
        // shape; all pointers are valid NUL-terminated strings for the call.
        unsafe {
            logger(
                self.env,
                self.name.as_ptr(),
                status,
                CATEGORY_CSTR[category as usize].as_ptr(),
                c"%s".as_ptr(),
                msg.as_ptr(),
            );
        }
    }

    pub fn warning(&self, text: &str) {
        self.emit(fmi2Warning, LogCategory::StatusWarning, text);
    }

    pub fn discard(&self, text: &str) {
        self.emit(fmi2Discard, LogCategory::StatusDiscard, text);
    }

    pub fn error(&self, text: &str) {
        self.emit(fmi2Error, LogCategory::StatusError, text);
    }

    pub fn fatal(&self, text: &str) {
        self.emit(fmi2Fatal, LogCategory::StatusFatal, text);
    }

    /// Whether a debug message of `category` would be logged.
    pub fn debug_on(&self, category: LogCategory) -> bool {
        self.logger.is_some()
            && (self.enabled[category as usize] || self.enabled[LogCategory::All as usize])
    }

    /// A debug message (status `fmi2OK`); `text` is only built when logged.
    pub fn debug(&self, category: LogCategory, text: impl FnOnce() -> String) {
        if self.debug_on(category) {
            self.emit(fmi2OK, category, &text());
        }
    }

    /// `fmi2SetDebugLogging`, after the caller has checked every category
    /// name (an unknown name must reject the call before anything changes).
    ///
    /// FMI 2.0 spec, section 2.1.5: "If loggingOn = fmi2True, debug logging
    /// is enabled, otherwise it is switched off. If loggingOn = fmi2True and
    /// nCategories = 0, then all debug messages shall be output. If
    /// loggingOn=fmi2True and nCategories > 0, then only debug messages
    /// according to the categories argument shall be output." Hence:
    ///
    /// - `(true, [])`: every debug category is enabled.
    /// - `(true, list)`: exactly the listed categories are enabled and all
    ///   others disabled ("only ... according to the categories argument"),
    ///   whatever was enabled before; the list replaces the selection, it
    ///   does not add to it. `logAll` selects every debug message; a
    ///   `logStatus*` name selects none (those messages are always logged),
    ///   so `(true, ["logStatusError"])` leaves no debug message on.
    /// - `(false, _)`: debug logging is switched off, all categories. The
    ///   standard gives `categories` no meaning when `loggingOn` is false
    ///   ("otherwise it is switched off"), so a list does not narrow it to
    ///   "switch off only these": `(false, ["logAll"])` also silences
    ///   `logEvents`. The names are still checked by the caller.
    ///
    /// Messages with status `fmi2Warning` or worse do not depend on any of
    /// this: they are always logged.
    pub fn set_debug_logging(&mut self, logging_on: bool, categories: &[LogCategory]) {
        let mut enabled = [false; 6];
        if logging_on {
            if categories.is_empty() {
                enabled = [true; 6];
            } else {
                for c in categories {
                    enabled[*c as usize] = true;
                }
            }
        }
        self.enabled = enabled;
    }
}

/// The layer's part of an instance's dynamic state (saved in FMU states
/// together with the model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerState {
    pub fmi_state: FmiState,
    /// Current communication point.
    pub time: f64,
    pub start_time: f64,
    /// `Some` when `stopTimeDefined` was true in `fmi2SetupExperiment`.
    pub stop_time: Option<f64>,
    /// `Some` when `toleranceDefined` was true (stored, not used).
    pub tolerance: Option<f64>,
    /// End of the last successful communication step (`fmi2LastSuccessfulTime`).
    pub last_successful_time: f64,
    /// A value was set since the last successful `Model::initialize`.
    pub dirty: bool,
    /// Status of the last `fmi2DoStep` (`fmi2DoStepStatus`).
    pub last_step_status: fmi2Status,
    /// The model asked to end the simulation (`fmi2Terminated`); never set
    /// by the current models.
    pub model_terminated: bool,
}

impl LayerState {
    /// State of a new (or reset) instance.
    pub fn fresh() -> Self {
        LayerState {
            fmi_state: FmiState::Instantiated,
            time: 0.0,
            start_time: 0.0,
            stop_time: None,
            tolerance: None,
            last_successful_time: 0.0,
            dirty: true,
            last_step_status: fmi2OK,
            model_terminated: false,
        }
    }
}

/// An FMU state (`fmi2FMUstate`): a copy of the model and the layer state.
/// Owned by the instance that created it; the importer only ever sees its
/// address.
#[derive(Clone)]
pub struct Snapshot<M> {
    pub model: M,
    pub layer: LayerState,
}

/// An FMU instance (what `fmi2Component` points to).
#[repr(C)]
pub struct Instance<M: Model> {
    magic: u64,
    type_id: TypeId,
    /// [`binary_mark`] of the binary that created the instance.
    binary: usize,
    pub model: M,
    /// Built once at `fmi2Instantiate` from [`Model::variables`];
    /// value reference = index.
    pub vars: Vec<ScalarVariable<M::Var>>,
    /// [`Dispatch`] of each of `vars` (same index): what the get and set
    /// functions check per value reference.
    pub dispatch: Vec<Dispatch<M::Var>>,
    pub info: ModelInfo,
    pub guid: String,
    pub log: LogSink,
    pub layer: LayerState,
    /// Variables whose `log_once` warning was already logged.
    pub warned: HashSet<String>,
    /// FMU states handed out, keyed by the address given to the importer.
    /// Looking pointers up here means an unknown `fmi2FMUstate` is rejected
    /// without being dereferenced, and `fmi2FreeInstance` frees the states
    /// the importer did not free (FMI 2.0 section 2.1.5: all memory of the
    /// instance is released).
    pub states: HashMap<usize, Box<Snapshot<M>>>,
}

/// An address unique to the binary this code is linked into. Every FMU
/// binary links its own copy of this crate and so of `MARK`; its address
/// tells their instances apart where the type does not: the scenes'
/// binaries of one variant all export the same type (`fmu_build`'s
/// `ExportedScene`), so the same `TypeId`. An immutable static, not state.
fn binary_mark() -> usize {
    static MARK: u8 = 0;
    std::ptr::addr_of!(MARK) as usize
}

impl<M: Model> Instance<M> {
    pub fn new(
        vars: Vec<ScalarVariable<M::Var>>,
        info: ModelInfo,
        guid: String,
        log: LogSink,
    ) -> Self {
        Instance {
            magic: INSTANCE_MAGIC,
            type_id: TypeId::of::<M>(),
            binary: binary_mark(),
            model: M::new(),
            dispatch: vars.iter().map(Dispatch::of).collect(),
            vars,
            info,
            guid,
            log,
            layer: LayerState::fresh(),
            warned: HashSet::new(),
            states: HashMap::new(),
        }
    }

    /// The instance behind a component pointer, or `None` for NULL or a
    /// pointer that is not an instance of this model type created by this
    /// binary.
    ///
    /// # Safety
    /// `c` must be NULL or point to readable memory of at least 8 bytes; if
    /// the first 8 bytes are [`INSTANCE_MAGIC`] it must be a live
    /// `Instance` created by this layer and not used concurrently.
    pub unsafe fn from_component<'a>(c: fmi2Component) -> Option<&'a mut Self> {
        if c.is_null() {
            return None;
        }
        // SAFETY: per the contract above.
        unsafe {
            if std::ptr::read_unaligned(c as *const u64) != INSTANCE_MAGIC {
                return None;
            }
            let p = c as *mut Self;
            // `magic`, `type_id` and `binary` are the first fields of a
            // `repr(C)` struct: same offsets for every model type.
            if (*p).type_id != TypeId::of::<M>() || (*p).binary != binary_mark() {
                return None;
            }
            Some(&mut *p)
        }
    }

    /// Marks the instance as freed (so a stale pointer is rejected as long
    /// as the memory is not reused).
    pub fn invalidate(&mut self) {
        self.magic = 0;
    }

    /// `fmi2Reset`: like a new instance, keeping name, callbacks, logging
    /// settings and the FMU states handed out.
    pub fn reset(&mut self) {
        self.model = M::new();
        self.layer = LayerState::fresh();
        self.warned.clear();
    }

    /// A panic escaped the model: the instance is in state `fatal`.
    pub fn enter_fatal(&mut self, func: &str, payload: &(dyn Any + Send)) {
        self.layer.fmi_state = FmiState::Fatal;
        let what = panic_message(payload);
        self.log.fatal(&format!(
            "{func}: internal error (panic): {what}; the instance is unusable"
        ));
    }

    pub fn snapshot(&self) -> Snapshot<M> {
        Snapshot {
            model: self.model.clone(),
            layer: self.layer,
        }
    }
}

/// The text of a panic payload.
pub fn panic_message(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic payload".to_string()
    }
}

/// Magic bytes at the start of a serialized FMU state.
pub const STATE_MAGIC: [u8; 8] = *b"HMFMI2ST";
/// Version of the serialized FMU state format.
pub const STATE_FORMAT_VERSION: u32 = 1;
/// Bytes before the body: magic, version, body length.
const STATE_HEADER_LEN: usize = 8 + 4 + 8;

/// Serializes an FMU state (`fmi2SerializeFMUstate`, FMI 2.0 spec, section
/// 2.1.8) as values in little-endian order:
///
/// ```text
/// magic "HMFMI2ST" | format version u32 | body length u64 |
/// body: GUID (u64 length + UTF-8) | FMI state u8 | time f64 | start f64 |
///       stop defined u8 | stop f64 | tolerance defined u8 | tolerance f64 |
///       last successful time f64 | dirty u8 | last step status u8 |
///       model terminated u8 | model bytes (u64 length + Model::serialize) |
/// checksum u64 (FNV-1a 64 of everything before it)
/// ```
pub fn encode_state<M: Model>(guid: &str, snap: &Snapshot<M>) -> Vec<u8> {
    let mut body = Vec::new();
    let mut model_bytes = Vec::new();
    snap.model.serialize(&mut model_bytes);
    let l = &snap.layer;
    ByteWriter::new(&mut body)
        .str(guid)
        .u8(l.fmi_state.to_u8())
        .f64(l.time)
        .f64(l.start_time)
        .bool(l.stop_time.is_some())
        .f64(l.stop_time.unwrap_or(0.0))
        .bool(l.tolerance.is_some())
        .f64(l.tolerance.unwrap_or(0.0))
        .f64(l.last_successful_time)
        .bool(l.dirty)
        .u8(l.last_step_status as u8)
        .bool(l.model_terminated)
        .bytes(&model_bytes);
    let mut out = Vec::with_capacity(STATE_HEADER_LEN + body.len() + 8);
    ByteWriter::new(&mut out)
        .raw(&STATE_MAGIC)
        .u32(STATE_FORMAT_VERSION)
        .u64(body.len() as u64)
        .raw(&body);
    let sum = fnv1a64(FNV64_OFFSET, &out);
    ByteWriter::new(&mut out).u64(sum);
    out
}

/// Inverse of [`encode_state`]. Checks magic, format version, length,
/// checksum and GUID (a state of another model or interface version is
/// rejected); bytes after the checksum are ignored.
pub fn decode_state<M: Model>(guid: &str, data: &[u8]) -> Result<Snapshot<M>, String> {
    let mut input = data;
    let mut r = ByteReader::new(&mut input);
    let magic = r
        .take(8)
        .map_err(|_| format!("too short ({} bytes) to be an FMU state", data.len()))?;
    if magic != STATE_MAGIC {
        return Err("not a serialized FMU state of this layer (bad magic bytes)".into());
    }
    let version = r.u32().map_err(|e| format!("truncated header: {e}"))?;
    if version != STATE_FORMAT_VERSION {
        return Err(format!(
            "serialized FMU state format version {version} is not supported (expected {STATE_FORMAT_VERSION})"
        ));
    }
    let body_len = r.u64().map_err(|e| format!("truncated header: {e}"))?;
    let needed = usize::try_from(body_len)
        .ok()
        .and_then(|b| b.checked_add(STATE_HEADER_LEN + 8));
    let Some(needed) = needed.filter(|&n| n <= data.len()) else {
        return Err(format!(
            "truncated: the header announces a {body_len}-byte body, only {} bytes given",
            data.len()
        ));
    };
    let covered = &data[..needed - 8];
    let mut sum_bytes = [0u8; 8];
    sum_bytes.copy_from_slice(&data[needed - 8..needed]);
    if fnv1a64(FNV64_OFFSET, covered) != u64::from_le_bytes(sum_bytes) {
        return Err("checksum mismatch: the serialized FMU state is corrupt".into());
    }
    let mut body = &covered[STATE_HEADER_LEN..];
    let mut r = ByteReader::new(&mut body);
    let e = |e: super::bytes::ByteError| format!("malformed FMU state: {e}");
    let their_guid = r.str().map_err(e)?;
    if their_guid != guid {
        return Err(format!(
            "the FMU state belongs to another model or interface version (GUID {their_guid}, this FMU is {guid})"
        ));
    }
    let code = r.u8().map_err(e)?;
    let fmi_state = FmiState::from_u8(code)
        .filter(|s| *s != FmiState::Fatal)
        .ok_or_else(|| format!("malformed FMU state: invalid FMI state code {code}"))?;
    let time = r.f64().map_err(e)?;
    let start_time = r.f64().map_err(e)?;
    let stop_defined = r.bool().map_err(e)?;
    let stop = r.f64().map_err(e)?;
    let tol_defined = r.bool().map_err(e)?;
    let tol = r.f64().map_err(e)?;
    let last_successful_time = r.f64().map_err(e)?;
    let dirty = r.bool().map_err(e)?;
    let status_code = r.u8().map_err(e)?;
    // fmi2DoStep leaves fmi2OK, fmi2Discard or fmi2Error (fmi2Warning
    // allowed); never fmi2Pending (no asynchronous steps) or fmi2Fatal.
    let last_step_status = fmi2Status::from_u8(status_code)
        .filter(|s| matches!(*s, fmi2OK | fmi2Warning | fmi2Discard | fmi2Error))
        .ok_or_else(|| format!("malformed FMU state: invalid last step status {status_code}"))?;
    let model_terminated = r.bool().map_err(e)?;
    let mut model_bytes = r.bytes().map_err(e)?;
    r.expect_end().map_err(e)?;
    // The layer's own values, checked as strictly as the calls that set them.
    for (name, v) in [
        ("time", time),
        ("start time", start_time),
        ("last successful time", last_successful_time),
    ] {
        if !v.is_finite() {
            return Err(format!("malformed FMU state: {name} = {v} is not finite"));
        }
    }
    if tol_defined && !(tol.is_finite() && tol >= 0.0) {
        return Err(format!(
            "malformed FMU state: tolerance {tol} must be finite and >= 0"
        ));
    }
    if stop_defined && !(stop.is_finite() && stop >= start_time) {
        return Err(format!(
            "malformed FMU state: stop time {stop} must be finite and >= the start time {start_time}"
        ));
    }

    let model = M::deserialize(&mut model_bytes)
        .map_err(|err| format!("malformed model state: {}", err.0))?;
    if !model_bytes.is_empty() {
        return Err(format!(
            "malformed model state: {} unread bytes",
            model_bytes.len()
        ));
    }
    let stepping = matches!(
        fmi_state,
        FmiState::StepComplete | FmiState::StepFailed | FmiState::StepCanceled
    );
    if stepping && !model.is_initialized() {
        return Err(format!(
            "malformed FMU state: the instance is in state {} but its model holds no initialized state",
            fmi_state.name()
        ));
    }
    if stepping {
        model
            .check_stepping_outputs()
            .map_err(|msg| format!("malformed model state: {msg}"))?;
    }
    Ok(Snapshot {
        model,
        layer: LayerState {
            fmi_state,
            time,
            start_time,
            stop_time: stop_defined.then_some(stop),
            tolerance: tol_defined.then_some(tol),
            last_successful_time,
            dirty,
            last_step_status,
            model_terminated,
        },
    })
}
