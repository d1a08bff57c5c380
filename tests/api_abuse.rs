//! The FMI API of `HillMuscle1D` under abuse (issue 4, section 3): a
//! property-based harness (proptest) that drives the generic C-signature
//! functions `hill_muscle::fmi2::api::*::<Hill1D>` — exactly what the
//! exported `fmi2Xxx` symbols forward to — with random call sequences and
//! random arguments.
//!
//! # What is generated
//!
//! Sequences of up to 48 operations, each an FMI call with random arguments or
//! a macro that expands to several calls (`Init`: setup + enter + inputs +
//! exit; `Run`: up to 150 × (set inputs + fmi2DoStep) with `t += h` or
//! `t0 + i·h` clocks, stopped at the first step that does not complete;
//! `DiscardRecover`: save, step into a discard, query the status, roll back,
//! step again; `Restore`: deserialize a stored FMU state and set it, which
//! also reaches the otherwise unreachable `error` and `stepCanceled` states).
//! Abuse covered: calls in every state (also those the state table forbids);
//! a NULL or foreign `fmi2Component`; NULL arrays with `n > 0`, zero-length
//! arrays, long arrays (up to 120 references, with repeats) and impossible
//! lengths (`usize::MAX`, which the layer must refuse before reading);
//! unknown value references (`n_vars..`, `u32::MAX`) and wrong types; NaN,
//! ±∞, ±0, negative, tiny and huge values for every Real variable; NULL and
//! unknown log categories; NULL and non-UTF-8 strings; step sizes ≤ 0, NaN,
//! ±∞, 5e-324 and 1e300; communication points that drift (`t += h`,
//! `t0 + i·h`, a few ulps, 1e-11 relative) or jump (NaN, ±∞, ± many times the
//! tolerance, ± h); steps to and past a defined stop time; repeated
//! Terminate/Reset; FMU state get/set/free with NULL, foreign (another
//! instance's) and bogus pointers; serialization into short, empty, NULL and
//! oversized buffers; deserialization of truncated, bit-flipped, overwritten
//! (with and without a recomputed checksum), foreign-GUID, zeroed, random and
//! padded buffers with right and wrong sizes. `fmi2FreeInstance` is called
//! exactly once per instance, at the end of each sequence (a second call or a
//! use after it is undefined behaviour on the importer's side);
//! `fmi2FreeInstance(NULL)` and of a foreign pointer are tested separately.
//!
//! # Properties checked for every call of every sequence
//!
//! 1. **No panic escapes, every status is valid**: the call returns a status
//!    in `fmi2OK..=fmi2Error` — never `fmi2Fatal` (the layer's answer to a
//!    caught panic) and never `fmi2Pending` (steps are synchronous).
//! 2. **Errors are a status plus a log message**: every `fmi2Error` and
//!    `fmi2Discard` on a live instance comes with at least one logged message
//!    of that status, in the `logStatusError`/`logStatusDiscard` category,
//!    starting with the function's name; a call refused by the state table
//!    says "not allowed in state ...". A NULL or foreign component has no
//!    instance to log through: it must give `fmi2Error` and log nothing.
//!    Every message carries the instance name given at instantiation, is
//!    passed as `"%s"` + text, and contains no `#`.
//! 3. **Expected outcomes** where the standard or the layer's documented
//!    contract fixes them (an oracle computed from the arguments and the
//!    state before the call): a call the state table forbids, a NULL
//!    component, a NULL array with `n > 0`, an impossible length, an unknown
//!    or mistyped value reference, a variable that may not be set in this
//!    state, a step size that is not finite and > 0, a communication point
//!    more than twice the tolerance away from the FMU's time, a step ending
//!    more than twice the tolerance past the stop time, an unknown FMU state
//!    pointer, a short serialization buffer, a truncated / bit-flipped /
//!    foreign-GUID state ... must give `fmi2Error`; a legal step whose
//!    communication point drifted by at most 1e-10 relative (far inside the
//!    layer's tolerance) and that does not pass the stop time, a legal FMU
//!    state call, an intact serialized state ... must not.
//! 4. **A rejected call changes nothing**: the instance is snapshotted
//!    before and after every call with a fresh `fmi2GetFMUstate` +
//!    `fmi2SerializedFMUstateSize` + `fmi2SerializeFMUstate` (+
//!    `fmi2FreeFMUstate`), which is allowed in every state but `fatal`. After
//!    every `fmi2Error` the bytes must be identical and no out-argument
//!    (value arrays, `*FMUstate`, serialization buffer, status value) may have
//!    been written. Per call, which results count as "changes nothing":
//!    - `fmi2Error` from any function. For `HillMuscle1D` every `fmi2Error`
//!      is a rejection: its `do_step` never returns `StepError::Error`, so the
//!      layer's error state (which a model failure would enter) is not
//!      reached by stepping.
//!    - `fmi2Discard` from any function but `fmi2DoStep` (the status
//!      functions' "not available"). A `fmi2Discard` from `fmi2DoStep` is not
//!      a rejected call: the standard moves the instance to `stepFailed`.
//!    - any result of a function that only reads or manages FMU states:
//!      `fmi2Get{Integer,Boolean,String}`, `fmi2GetReal` and
//!      `fmi2GetDirectionalDerivative` outside initialization mode (inside it
//!      they may compute the initial values), `fmi2SetDebugLogging`, the
//!      status functions, `fmi2CancelStep`, `fmi2GetRealOutputDerivatives`,
//!      `fmi2Get/Free/(De)SerializeFMUstate`, `fmi2SerializedFMUstateSize`.
//!
//!    Accepted calls are checked too: `fmi2GetFMUstate` saves exactly the
//!    current state, `fmi2SetFMUstate` restores exactly the saved one.
//! 5. **The next legal call behaves as if the rejected one never
//!    happened**: a twin instance receives the same sequence minus the
//!    rejected calls (and minus the snapshots). Each call it receives must
//!    give the same status, the same values read, and the same log messages
//!    (FMU state addresses masked); at the end both must have identical
//!    serialized states, identical outputs and status values, and identical
//!    saved FMU states slot by slot.
//! 6. **`fmi2Reset` brings back a fresh instance**: right after an accepted
//!    reset the serialized state equals that of a newly instantiated
//!    instance; and a newly instantiated "shadow" (with the same logging
//!    settings) that receives every accepted call after the reset must behave
//!    identically (statuses, values, logs) and end in the same serialized
//!    state — in particular after the same init sequence and steps. The
//!    shadow stops following, after a final comparison, at the next reset or
//!    when the sequence uses an FMU state saved before the reset (which the
//!    fresh instance cannot have).
//! 7. (Unless `API_ABUSE_ROUND_TRIP=0`.) Every state the FMU serializes is
//!    accepted by the layer's deserializer; without it, intact serialized
//!    states must be accepted by `fmi2DeSerializeFMUstate` whenever they
//!    decode.
//!
//! The snapshots read the layer's fields (FMI state, time, stop time) from
//! the serialized bytes directly (format of
//! `hill_muscle::fmi2::instance::encode_state`) to resolve communication
//! points and the oracle.
//!
//! Further tests: random `fmi2Instantiate` arguments (NULL/empty/non-UTF-8
//! names, wrong types, wrong/NULL GUIDs, odd resource locations, NULL
//! callbacks); every Real variable × every special value in every state;
//! every function in every state; 4 × 25,000-step drift runs (two master
//! clocks alternating); repeated Terminate/Reset from every state;
//! `fmi2FreeInstance(NULL)` and of a foreign pointer; a NULL
//! componentEnvironment with a live logger (passed back unchanged);
//! `fmi2SetFMUstate(NULL)` from every state.
//!
//! # Case counts and modes
//!
//! CI mode (the default): a fixed seed (ChaCha, so the cases are the same on
//! every machine), 3,000 random sequences for the main property plus 750
//! corrupt-state and 750 instantiation cases and ~580 deterministic
//! sequences — about 5,000 in all, ~4 s wall time for this test binary with
//! `cargo test --release` on the project's 2-core machine. No failure files
//! are persisted (`failure_persistence: None`, nothing is written into the
//! repository): a failure prints the shrunk sequence, the failed property
//! and the last calls with their statuses and log messages. An unoptimized
//! build (plain `cargo test`) runs a tenth of the random cases (~4 s).
//! The CI cases are fixed by the seed, so a failure reproduces exactly;
//! other seeds and more cases are for long runs.
//!
//! Long mode (≈1.2 ms per main sequence: 10⁶ sequences ≈ 20 min, plus
//! ≈3 min for the 250,000 cases of each of the two other property tests):
//!
//! ```sh
//! API_ABUSE_CASES=1000000 cargo test --release --test api_abuse
//! API_ABUSE_CASES=1000000 API_ABUSE_SEED=7 cargo test --release --test api_abuse
//! API_ABUSE_CASES=20000 API_ABUSE_STATS=1 cargo test --release --test api_abuse \
//!     random_call_sequences -- --nocapture   # what was exercised
//! ```
//!
//! - `API_ABUSE_CASES`: random sequences of the main property (the
//!   corrupt-state and instantiation properties get a quarter of it each);
//! - `API_ABUSE_SEED`: another fixed seed (default 0x4d75_7363_6c65);
//! - `API_ABUSE_STATS=1`: print the calls made, by function, state before
//!   and status, and how many calls the twin and the reset shadows compared;
//! - `API_ABUSE_ROUND_TRIP=0`: do not require every state the FMU serializes
//!   to deserialize (property 7 above; on by default).
//!
//! # Bugs found (now regression tests at the end of this file)
//!
//! Values that were finite and "positive", hence accepted, but so extreme
//! that a derived quantity the model committed overflowed to ±inf/NaN:
//! `alpha` or `beta` = `f64::MIN_POSITIVE` or `L0` = 5e-324 (the FMU's own
//! serialized state refused by its own `fmi2DeSerializeFMUstate`, NaN
//! directional derivatives with `fmi2OK`, a step completing with
//! `ce_stretch` ≈ -9.5e289). Fixed by closed physical parameter ranges,
//! declared as min/max: [`out_of_range_parameters_are_refused_naming_the_range`]
//! and [`every_parameter_at_either_bound_steps_and_round_trips`] (which found
//! one more: `k` = 1e3 gave a negative CE length on shortening, now a
//! discard that names the bound). A legal step of `h = 5e-324` committed an
//! infinite predictor rate ([`tiny_step_leaves_a_serializable_state`]). In
//! the layer, a crafted (checksum-valid) state with time NaN disabled
//! `fmi2DoStep`'s time check ([`deserialized_state_with_non_finite_time_is_refused`]).
//!
//! # The test logger
//!
//! As in `tests/fmi2_layer.rs`: FMI's logger is a C variadic function, which
//! stable Rust cannot define. The layer always calls it as `logger(env, name,
//! status, category, "%s", text)`, so the test logger is a non-variadic
//! `extern "C" fn` taking that one extra `const char*`, transmuted to the
//! variadic pointer type — sound on SysV x86-64 and AAPCS64 (Linux), where a
//! variadic pointer argument is passed like the next named argument.

use std::ffi::{c_char, c_void, CStr, CString};
use std::fmt;
use std::ptr::{null, null_mut};
use std::sync::{Mutex, OnceLock};

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::bytes::{fnv1a64, ByteError, ByteReader, FNV64_OFFSET};
use hill_muscle::fmi2::instance::{decode_state, LayerState};
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::rules::settable_in;
use hill_muscle::fmi2::state::{self as st, FmiState, StateSet};
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::{Causality, Model, ScalarVariable, VarType};
use hill_muscle::fmus::hill1d::{Hill1D, Var, DEFAULT_L0};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::strategy::Union;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed, TestCaseError, TestRunner};

// ---------------------------------------------------------------------------
// Modes
// ---------------------------------------------------------------------------

/// Sequences of the main property in CI mode; the other property tests get a
/// fraction of it (see [`cases`]).
fn ci_cases() -> u32 {
    3000
}

/// `API_ABUSE_CASES` or the CI count (a tenth of it in an unoptimized
/// build, so that a plain `cargo test` stays quick), scaled by `num / den`.
fn cases(num: u32, den: u32) -> u32 {
    let ci = if cfg!(debug_assertions) {
        ci_cases() / 10
    } else {
        ci_cases()
    };
    let base = std::env::var("API_ABUSE_CASES")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(u64::from(ci));
    (base * u64::from(num) / u64::from(den)).clamp(1, u64::from(u32::MAX)) as u32
}

fn config(cases: u32) -> Config {
    let seed = std::env::var("API_ABUSE_SEED")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(0x4d75_7363_6c65);
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed),
        max_shrink_iters: 4096,
        ..Config::default()
    }
}

// ---------------------------------------------------------------------------
// The test logger
// ---------------------------------------------------------------------------

#[derive(Clone)]
struct Entry {
    instance: Vec<u8>,
    status: fmi2Status,
    category: String,
    format: String,
    message: String,
}

impl fmt::Debug for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[{} {:?} {} {:?}] {:?}",
            String::from_utf8_lossy(&self.instance),
            self.status,
            self.category,
            self.format,
            self.message
        )
    }
}

#[derive(Default)]
struct LogBook {
    entries: Mutex<Vec<Entry>>,
}

impl LogBook {
    fn take(&self) -> Vec<Entry> {
        std::mem::take(&mut *self.entries.lock().unwrap())
    }

    fn clear(&self) {
        self.entries.lock().unwrap().clear();
    }
}

fn c_bytes(p: *const c_char) -> Vec<u8> {
    if p.is_null() {
        b"<NULL>".to_vec()
    } else {
        unsafe { CStr::from_ptr(p) }.to_bytes().to_vec()
    }
}

fn c_text(p: *const c_char) -> String {
    String::from_utf8_lossy(&c_bytes(p)).into_owned()
}

/// See the module docs: the fixed arguments plus the one `%s` argument.
unsafe extern "C" fn test_logger(
    env: fmi2ComponentEnvironment,
    instance_name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    message: fmi2String,
    arg: *const c_char,
) {
    if env.is_null() {
        return;
    }
    let book = unsafe { &*(env as *const LogBook) };
    let e = Entry {
        instance: c_bytes(instance_name),
        status,
        category: c_text(category),
        format: c_text(message),
        message: c_text(arg),
    };
    if let Ok(mut g) = book.entries.lock() {
        g.push(e);
    }
}

type FixedLogger = unsafe extern "C" fn(
    fmi2ComponentEnvironment,
    fmi2String,
    fmi2Status,
    fmi2String,
    fmi2String,
    *const c_char,
);

fn callbacks(book: &LogBook) -> fmi2CallbackFunctions {
    callbacks_with(test_logger, book as *const LogBook as *mut c_void)
}

/// The callbacks with `fixed` as the logger and `env` as the
/// componentEnvironment.
fn callbacks_with(fixed: FixedLogger, env: fmi2ComponentEnvironment) -> fmi2CallbackFunctions {
    fmi2CallbackFunctions {
        // SAFETY: see the module docs.
        logger: Some(unsafe {
            std::mem::transmute::<
                FixedLogger,
                unsafe extern "C" fn(
                    fmi2ComponentEnvironment,
                    fmi2String,
                    fmi2Status,
                    fmi2String,
                    fmi2String,
                    ...
                ),
            >(fixed)
        }),
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: env,
    }
}

// ---------------------------------------------------------------------------
// The variable table
// ---------------------------------------------------------------------------

struct Table {
    vars: Vec<ScalarVariable<Var>>,
    guid: CString,
    outputs: Vec<u32>,
    reals: Vec<u32>,
    activation: u32,
    length: u32,
}

fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| {
        let vars = Hill1D::variables();
        let vr_of = |name: &str| vars.iter().position(|v| v.name == name).unwrap() as u32;
        let outputs = (0..vars.len() as u32)
            .filter(|&i| vars[i as usize].causality == Causality::Output)
            .collect();
        let reals = (0..vars.len() as u32)
            .filter(|&i| matches!(vars[i as usize].ty, VarType::Real { .. }))
            .collect();
        Table {
            activation: vr_of("activation"),
            length: vr_of("length"),
            guid: CString::new(guid::<Hill1D>()).unwrap(),
            outputs,
            reals,
            vars,
        }
    })
}

fn n_vars() -> u32 {
    table().vars.len() as u32
}

fn var(vr: u32) -> Option<&'static ScalarVariable<Var>> {
    table().vars.get(vr as usize)
}

fn is_real(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Real { .. }))
}

fn is_bool(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Boolean { .. }))
}

fn is_real_with(vr: u32, c: Causality) -> bool {
    is_real(vr) && var(vr).is_some_and(|v| v.causality == c)
}

fn start_of(vr: u32) -> f64 {
    match var(vr).map(|v| v.ty) {
        Some(VarType::Real { start: Some(s), .. }) => s,
        _ => 1.0,
    }
}

// ---------------------------------------------------------------------------
// Instances
// ---------------------------------------------------------------------------

/// The instance name: `#` and `%` check that the name reaches the logger
/// unchanged and that messages are passed as `"%s"` + text.
const NAME: &CStr = c"abuse #1 %s";
const N_SLOTS: usize = 4;

/// One instance with its log book and its FMU state slots (the importer's
/// `fmi2FMUstate` variables).
struct Fmu {
    c: fmi2Component,
    book: Box<LogBook>,
    slots: [fmi2FMUstate; N_SLOTS],
}

impl Fmu {
    fn new(logging_on: bool) -> Fmu {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let c = unsafe {
            api::instantiate::<Hill1D>(
                NAME.as_ptr(),
                fmi2CoSimulation,
                table().guid.as_ptr(),
                c"file:///tmp/".as_ptr(),
                &cb,
                fmi2False,
                if logging_on { fmi2True } else { fmi2False },
            )
        };
        assert!(!c.is_null(), "instantiate: {:?}", book.take());
        book.clear();
        Fmu {
            c,
            book,
            slots: [null_mut(); N_SLOTS],
        }
    }

    fn serialize_state(&self, s: fmi2FMUstate) -> Result<Vec<u8>, String> {
        let mut n = 0usize;
        let st = unsafe { api::serialized_fmu_state_size::<Hill1D>(self.c, s, &mut n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializedFMUstateSize = {st:?}"));
        }
        let mut buf = vec![0 as fmi2Byte; n];
        let st = unsafe { api::serialize_fmu_state::<Hill1D>(self.c, s, buf.as_mut_ptr(), n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializeFMUstate = {st:?}"));
        }
        Ok(buf.into_iter().map(|b| b as u8).collect())
    }

    /// The complete dynamic state of the instance, through a fresh FMU state.
    /// Logs nothing into the book (its debug messages are dropped).
    fn state_bytes(&self) -> Result<Vec<u8>, String> {
        let mut s: fmi2FMUstate = null_mut();
        let st = unsafe { api::get_fmu_state::<Hill1D>(self.c, &mut s) };
        if st != fmi2OK || s.is_null() {
            return Err(format!(
                "snapshot: fmi2GetFMUstate = {st:?}: {:?}",
                self.book.take()
            ));
        }
        let bytes = self.serialize_state(s);
        let st = unsafe { api::free_fmu_state::<Hill1D>(self.c, &mut s) };
        let logs = self.book.take();
        let bytes = bytes.map_err(|e| format!("snapshot: {e}: {logs:?}"))?;
        if st != fmi2OK || !s.is_null() {
            return Err(format!("snapshot: fmi2FreeFMUstate = {st:?}: {logs:?}"));
        }
        Ok(bytes)
    }

    fn slot_bytes(&self, k: usize) -> Result<Vec<u8>, String> {
        let r = self.serialize_state(self.slots[k]);
        self.book.clear();
        r
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        // Exactly once per instance, in whatever state it is, with the FMU
        // states it still owns.
        unsafe { api::free_instance::<Hill1D>(self.c) };
    }
}

/// The layer's part of a serialized state (the format documented at
/// `hill_muscle::fmi2::instance::encode_state`), read without the model's
/// deserializer so that a model state that does not deserialize (see
/// [`bug_tiny_parameter_serialized_state_is_rejected_by_deserialize`]) does not
/// hide everything else. With `API_ABUSE_ROUND_TRIP=1` every snapshot must
/// also pass the layer's full `decode_state` (what
/// `fmi2DeSerializeFMUstate` runs).
fn layer_of(bytes: &[u8]) -> Result<LayerState, String> {
    let bad = |e: ByteError| format!("a snapshot does not parse: {e}");
    let mut input = bytes;
    let mut r = ByteReader::new(&mut input);
    r.take(8).map_err(bad)?;
    r.u32().map_err(bad)?;
    r.u64().map_err(bad)?;
    r.str().map_err(bad)?;
    let code = r.u8().map_err(bad)?;
    let fmi_state = FmiState::from_u8(code).ok_or(format!("bad state code {code}"))?;
    let time = r.f64().map_err(bad)?;
    let start_time = r.f64().map_err(bad)?;
    let stop_def = r.bool().map_err(bad)?;
    let stop = r.f64().map_err(bad)?;
    let tol_def = r.bool().map_err(bad)?;
    let tol = r.f64().map_err(bad)?;
    let last_successful_time = r.f64().map_err(bad)?;
    let dirty = r.bool().map_err(bad)?;
    let status = r.u8().map_err(bad)?;
    let last_step_status = fmi2Status::from_u8(status).ok_or(format!("bad status {status}"))?;
    let model_terminated = r.bool().map_err(bad)?;
    if round_trip() {
        decode_state::<Hill1D>(&guid::<Hill1D>(), bytes)
            .map_err(|e| format!("the instance's serialized state does not deserialize: {e}"))?;
    }
    Ok(LayerState {
        fmi_state,
        time,
        start_time,
        stop_time: stop_def.then_some(stop),
        tolerance: tol_def.then_some(tol),
        last_successful_time,
        dirty,
        last_step_status,
        model_terminated,
    })
}

/// `API_ABUSE_ROUND_TRIP=1`: every serialized state the FMU produces must
/// deserialize (off by default while
/// [`bug_tiny_parameter_serialized_state_is_rejected_by_deserialize`] stands).
fn round_trip() -> bool {
    static R: OnceLock<bool> = OnceLock::new();
    *R.get_or_init(|| std::env::var("API_ABUSE_ROUND_TRIP").map_or(true, |v| v != "0"))
}

/// Whether `fmi2DeSerializeFMUstate` must accept these bytes of a state the
/// FMU serialized itself.
fn decodes(bytes: &[u8]) -> bool {
    round_trip() || decode_state::<Hill1D>(&guid::<Hill1D>(), bytes).is_ok()
}

/// Recomputes the checksum of a serialized state after the header's body
/// length (so corruptions reach the body parsers).
fn fix_checksum(b: &mut [u8]) {
    if b.len() < 20 {
        return;
    }
    let body = u64::from_le_bytes(b[12..20].try_into().unwrap());
    let Some(needed) = usize::try_from(body)
        .ok()
        .and_then(|n| n.checked_add(28))
        .filter(|&n| n <= b.len())
    else {
        return;
    };
    let sum = fnv1a64(FNV64_OFFSET, &b[..needed - 8]);
    b[needed - 8..needed].copy_from_slice(&sum.to_le_bytes());
}

/// Offset of the FMI state code in a serialized state: header (20), GUID
/// length (8), GUID.
fn state_code_offset() -> usize {
    28 + guid::<Hill1D>().len()
}

// The pool of serialized states (valid, of this GUID) that `Restore` and
// deserialization draw from.
const P_FRESH: usize = 0;
const P_IM: usize = 1;
const P_SC: usize = 2;
const P_RUN: usize = 3;
const P_SF: usize = 4;
const P_T: usize = 5;
const P_E: usize = 6;
const P_SCA: usize = 7;
const P_LATE: usize = 8;
const POOL_LEN: usize = 9;

fn pool() -> &'static Vec<Vec<u8>> {
    static P: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    P.get_or_init(|| {
        let t = table();
        let ok = |s: fmi2Status| assert!(s == fmi2OK || s == fmi2Warning, "pool: {s:?}");
        let f = Fmu::new(false);
        let c = f.c;
        let mut pool = vec![Vec::new(); POOL_LEN];
        pool[P_FRESH] = f.state_bytes().unwrap();
        unsafe {
            ok(api::setup_experiment::<Hill1D>(c, 0, 0.0, 0.0, 1, 1.0));
            ok(api::enter_initialization_mode::<Hill1D>(c));
            let vrs = [t.activation, t.length];
            ok(api::set_real::<Hill1D>(
                c,
                vrs.as_ptr(),
                2,
                [0.3, 0.055].as_ptr(),
            ));
            pool[P_IM] = f.state_bytes().unwrap();
            ok(api::exit_initialization_mode::<Hill1D>(c));
            pool[P_SC] = f.state_bytes().unwrap();
            ok(api::set_real::<Hill1D>(
                c,
                vrs.as_ptr(),
                2,
                [1.0, 0.052].as_ptr(),
            ));
            let mut tc = 0.0;
            for _ in 0..20 {
                ok(api::do_step::<Hill1D>(c, tc, 1e-3, 1));
                tc += 1e-3;
            }
            pool[P_RUN] = f.state_bytes().unwrap();
            let mut e = pool[P_RUN].clone();
            e[state_code_offset()] = FmiState::Error.to_u8();
            fix_checksum(&mut e);
            pool[P_E] = e;
            let mut sca = pool[P_RUN].clone();
            sca[state_code_offset()] = FmiState::StepCanceled.to_u8();
            fix_checksum(&mut sca);
            pool[P_SCA] = sca;
            // A length 20 L0: beyond what the law can evaluate, discarded.
            ok(api::set_real::<Hill1D>(c, &t.length, 1, &1.0));
            let s = api::do_step::<Hill1D>(c, tc, 1e-3, 1);
            assert_eq!(s, fmi2Discard, "{:?}", f.book.take());
            pool[P_SF] = f.state_bytes().unwrap();
            ok(api::terminate::<Hill1D>(c));
            pool[P_T] = f.state_bytes().unwrap();
            ok(api::reset::<Hill1D>(c));
            ok(api::setup_experiment::<Hill1D>(
                c,
                1,
                1e-6,
                1e6,
                1,
                1e6 + 0.5,
            ));
            ok(api::enter_initialization_mode::<Hill1D>(c));
            ok(api::exit_initialization_mode::<Hill1D>(c));
            ok(api::do_step::<Hill1D>(c, 1e6, 0.01, 0));
            pool[P_LATE] = f.state_bytes().unwrap();
        }
        for (i, b) in pool.iter().enumerate() {
            assert!(layer_of(b).is_ok(), "pool state {i} does not decode");
        }
        pool
    })
}

/// The serialized state of a new instance.
fn fresh_bytes() -> &'static Vec<u8> {
    pool().get(P_FRESH).unwrap()
}

/// Pointers that are not this instance's: a zeroed buffer (not an
/// instance: its first 8 bytes are not the magic) used as a foreign
/// `fmi2Component` and as a bogus `fmi2FMUstate`, and another instance
/// holding an FMU state.
struct Env {
    foreign: Box<[u64; 8]>,
    bogus: Box<[u64; 8]>,
    other: Fmu,
}

impl Env {
    fn new() -> Env {
        let mut other = Fmu::new(false);
        let s = unsafe { api::get_fmu_state::<Hill1D>(other.c, &mut other.slots[0]) };
        assert_eq!(s, fmi2OK);
        Env {
            foreign: Box::new([0; 8]),
            bogus: Box::new([0; 8]),
            other,
        }
    }

    fn foreign(&self) -> fmi2Component {
        &*self.foreign as *const [u64; 8] as *mut c_void
    }

    fn bogus(&self) -> fmi2FMUstate {
        &*self.bogus as *const [u64; 8] as *mut c_void
    }

    fn other_state(&self) -> fmi2FMUstate {
        self.other.slots[0]
    }
}

// ---------------------------------------------------------------------------
// Calls
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Comp {
    Valid,
    Null,
    /// Readable memory that is not an instance.
    Foreign,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ptr {
    Ok,
    Null,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Len {
    /// The array's length.
    Exact,
    /// `usize::MAX` with a valid pointer: must be refused before any read.
    Impossible,
}

/// A `fmi2FMUstate` argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum StateIn {
    Slot(usize),
    Null,
    Bogus,
    /// A state of another instance.
    Other,
}

/// A `fmi2FMUstate*` argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum StateOut {
    Slot(usize),
    NullPtr,
    /// Points to a variable holding a bogus state pointer.
    HoldsBogus,
    /// Points to a variable holding another instance's state.
    HoldsOther,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    Real,
    Integer,
    Boolean,
    String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum StatusFn {
    Status,
    Real,
    Integer,
    Boolean,
    String,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Str {
    Null,
    Text(&'static str),
    NonUtf8,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cat {
    Known(usize),
    Unknown,
    Empty,
    Null,
    NonUtf8,
}

const CATEGORIES: [&CStr; 6] = [
    c"logStatusWarning",
    c"logStatusDiscard",
    c"logStatusError",
    c"logStatusFatal",
    c"logAll",
    c"logEvents",
];

/// Bytes of a deserialization, printed short.
#[derive(Clone, PartialEq, Eq)]
struct Bytes(Vec<u8>);

impl fmt::Debug for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "<{} bytes, fnv {:016x}>",
            self.0.len(),
            fnv1a64(FNV64_OFFSET, &self.0)
        )
    }
}

/// One FMI call with concrete arguments, replayable on any instance (slots
/// are indices into that instance's own slots).
#[derive(Clone, Debug)]
enum Call {
    Setup {
        comp: Comp,
        tol_def: i32,
        tol: f64,
        start: f64,
        stop_def: i32,
        stop: f64,
    },
    Enter(Comp),
    Exit(Comp),
    Terminate(Comp),
    Reset(Comp),
    Cancel(Comp),
    Logging {
        comp: Comp,
        on: i32,
        cats: Vec<Cat>,
        ptr: Ptr,
        len: Len,
    },
    SetReal {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<f64>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetInteger {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<i32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetBoolean {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<i32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    SetString {
        comp: Comp,
        vrs: Vec<u32>,
        vals: Vec<Str>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    Get {
        comp: Comp,
        ty: Ty,
        vrs: Vec<u32>,
        ptrs: [Ptr; 2],
        len: Len,
    },
    GetState {
        comp: Comp,
        out: StateOut,
    },
    SetState {
        comp: Comp,
        st: StateIn,
    },
    FreeState {
        comp: Comp,
        out: StateOut,
    },
    StateSize {
        comp: Comp,
        st: StateIn,
        null: bool,
    },
    Serialize {
        comp: Comp,
        st: StateIn,
        size: usize,
        ptr: Ptr,
        impossible: bool,
    },
    Deserialize {
        comp: Comp,
        bytes: Bytes,
        size: usize,
        ptr: Ptr,
        impossible: bool,
        out: StateOut,
    },
    DirDeriv {
        comp: Comp,
        unknowns: Vec<u32>,
        knowns: Vec<u32>,
        dv: Vec<f64>,
        ptrs: [Ptr; 4],
        len: Len,
    },
    SetInputDer {
        comp: Comp,
        vrs: Vec<u32>,
        orders: Vec<i32>,
        vals: Vec<f64>,
        ptrs: [Ptr; 3],
        len: Len,
    },
    GetOutputDer {
        comp: Comp,
        vrs: Vec<u32>,
        orders: Vec<i32>,
        ptrs: [Ptr; 3],
        len: Len,
    },
    Step {
        comp: Comp,
        tc: f64,
        h: f64,
        flag: i32,
    },
    Status {
        comp: Comp,
        func: StatusFn,
        kind: i32,
        null: bool,
    },
}

impl Call {
    fn comp(&self) -> Comp {
        use Call::*;
        match self {
            Enter(c) | Exit(c) | Terminate(c) | Reset(c) | Cancel(c) => *c,
            Setup { comp, .. }
            | Logging { comp, .. }
            | SetReal { comp, .. }
            | SetInteger { comp, .. }
            | SetBoolean { comp, .. }
            | SetString { comp, .. }
            | Get { comp, .. }
            | GetState { comp, .. }
            | SetState { comp, .. }
            | FreeState { comp, .. }
            | StateSize { comp, .. }
            | Serialize { comp, .. }
            | Deserialize { comp, .. }
            | DirDeriv { comp, .. }
            | SetInputDer { comp, .. }
            | GetOutputDer { comp, .. }
            | Step { comp, .. }
            | Status { comp, .. } => *comp,
        }
    }

    /// The function's name and the states the table allows it in.
    fn meta(&self) -> (&'static str, StateSet) {
        use Call::*;
        match self {
            Setup { .. } => ("fmi2SetupExperiment", st::SETUP_EXPERIMENT),
            Enter(_) => ("fmi2EnterInitializationMode", st::ENTER_INITIALIZATION_MODE),
            Exit(_) => ("fmi2ExitInitializationMode", st::EXIT_INITIALIZATION_MODE),
            Terminate(_) => ("fmi2Terminate", st::TERMINATE),
            Reset(_) => ("fmi2Reset", st::RESET),
            Cancel(_) => ("fmi2CancelStep", st::CANCEL_STEP),
            Logging { .. } => ("fmi2SetDebugLogging", st::SET_DEBUG_LOGGING),
            SetReal { .. } => ("fmi2SetReal", st::SET_VALUES),
            SetInteger { .. } => ("fmi2SetInteger", st::SET_VALUES),
            SetBoolean { .. } => ("fmi2SetBoolean", st::SET_VALUES),
            SetString { .. } => ("fmi2SetString", st::SET_VALUES),
            Get { ty, .. } => (
                match ty {
                    Ty::Real => "fmi2GetReal",
                    Ty::Integer => "fmi2GetInteger",
                    Ty::Boolean => "fmi2GetBoolean",
                    Ty::String => "fmi2GetString",
                },
                st::GET_VALUES,
            ),
            GetState { .. } => ("fmi2GetFMUstate", st::FMU_STATE),
            SetState { .. } => ("fmi2SetFMUstate", st::FMU_STATE),
            FreeState { .. } => ("fmi2FreeFMUstate", st::FMU_STATE),
            StateSize { .. } => ("fmi2SerializedFMUstateSize", st::FMU_STATE),
            Serialize { .. } => ("fmi2SerializeFMUstate", st::FMU_STATE),
            Deserialize { .. } => ("fmi2DeSerializeFMUstate", st::FMU_STATE),
            DirDeriv { .. } => (
                "fmi2GetDirectionalDerivative",
                st::GET_DIRECTIONAL_DERIVATIVE,
            ),
            SetInputDer { .. } => (
                "fmi2SetRealInputDerivatives",
                st::SET_REAL_INPUT_DERIVATIVES,
            ),
            GetOutputDer { .. } => (
                "fmi2GetRealOutputDerivatives",
                st::GET_REAL_OUTPUT_DERIVATIVES,
            ),
            Step { .. } => ("fmi2DoStep", st::DO_STEP),
            Status { func, .. } => (
                match func {
                    StatusFn::Status => "fmi2GetStatus",
                    StatusFn::Real => "fmi2GetRealStatus",
                    StatusFn::Integer => "fmi2GetIntegerStatus",
                    StatusFn::Boolean => "fmi2GetBooleanStatus",
                    StatusFn::String => "fmi2GetStringStatus",
                },
                st::GET_STATUS,
            ),
        }
    }

    /// FMU state slots the call refers to.
    fn slots(&self) -> Vec<usize> {
        let mut v = Vec::new();
        match self {
            Call::GetState { out, .. }
            | Call::FreeState { out, .. }
            | Call::Deserialize { out, .. } => {
                if let StateOut::Slot(k) = out {
                    v.push(*k);
                }
            }
            Call::SetState { st, .. } | Call::StateSize { st, .. } | Call::Serialize { st, .. } => {
                if let StateIn::Slot(k) = st {
                    v.push(*k);
                }
            }
            _ => {}
        }
        v
    }

    /// Calls that must leave the serialized state unchanged whatever they
    /// return (module docs, property 4).
    fn is_pure(&self, pre: FmiState) -> bool {
        use Call::*;
        match self {
            Get { ty: Ty::Real, .. } | DirDeriv { .. } => pre != FmiState::InitializationMode,
            Get { .. }
            | Logging { .. }
            | Status { .. }
            | Cancel(_)
            | GetOutputDer { .. }
            | GetState { .. }
            | FreeState { .. }
            | StateSize { .. }
            | Serialize { .. }
            | Deserialize { .. } => true,
            _ => false,
        }
    }
}

/// What a call returned and wrote.
struct Outcome {
    status: fmi2Status,
    /// Everything written to out-arguments on success (bit patterns), for
    /// comparing instances.
    reads: Vec<u64>,
    /// No out-argument was written (checked after `fmi2Error`).
    untouched: bool,
}

const SENT_F64: f64 = -7.777e77;
const SENT_I32: i32 = -777_777;
const SENT_BYTE: u8 = 0xA5;
static SENT_STR: &CStr = c"sentinel";

fn in_ptr<T>(v: &[T], p: Ptr) -> *const T {
    match p {
        Ptr::Ok => v.as_ptr(),
        Ptr::Null => null(),
    }
}

fn out_ptr<T>(v: &mut [T], p: Ptr) -> *mut T {
    match p {
        Ptr::Ok => v.as_mut_ptr(),
        Ptr::Null => null_mut(),
    }
}

fn n_of(n: usize, len: Len) -> usize {
    match len {
        Len::Exact => n,
        Len::Impossible => usize::MAX,
    }
}

fn bits_f64(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn bits_i32(v: &[i32]) -> Vec<u64> {
    v.iter().map(|&x| x as u32 as u64).collect()
}

/// Runs `call` on `f`.
fn exec(f: &mut Fmu, env: &Env, call: &Call) -> Outcome {
    type M = Hill1D;
    let c = match call.comp() {
        Comp::Valid => f.c,
        Comp::Null => null_mut(),
        Comp::Foreign => env.foreign(),
    };
    let mut reads = Vec::new();
    let mut untouched = true;
    let status = unsafe {
        match call {
            Call::Setup {
                tol_def,
                tol,
                start,
                stop_def,
                stop,
                ..
            } => api::setup_experiment::<M>(c, *tol_def, *tol, *start, *stop_def, *stop),
            Call::Enter(_) => api::enter_initialization_mode::<M>(c),
            Call::Exit(_) => api::exit_initialization_mode::<M>(c),
            Call::Terminate(_) => api::terminate::<M>(c),
            Call::Reset(_) => api::reset::<M>(c),
            Call::Cancel(_) => api::cancel_step::<M>(c),
            Call::Logging {
                on, cats, ptr, len, ..
            } => {
                let owned: Vec<Option<CString>> = cats
                    .iter()
                    .map(|cat| match cat {
                        Cat::Known(i) => Some(CATEGORIES[*i].to_owned()),
                        Cat::Unknown => Some(c"logNothing".to_owned()),
                        Cat::Empty => Some(c"".to_owned()),
                        Cat::NonUtf8 => Some(CString::new(vec![0xff, 0xfe, b'l']).unwrap()),
                        Cat::Null => None,
                    })
                    .collect();
                let ptrs: Vec<fmi2String> = owned
                    .iter()
                    .map(|o| o.as_ref().map_or(null(), |s| s.as_ptr()))
                    .collect();
                api::set_debug_logging::<M>(c, *on, n_of(ptrs.len(), *len), in_ptr(&ptrs, *ptr))
            }
            Call::SetReal {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => api::set_real::<M>(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetInteger {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => api::set_integer::<M>(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetBoolean {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => api::set_boolean::<M>(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(vals, ptrs[1]),
            ),
            Call::SetString {
                vrs,
                vals,
                ptrs,
                len,
                ..
            } => {
                let owned: Vec<Option<CString>> = vals
                    .iter()
                    .map(|s| match s {
                        Str::Null => None,
                        Str::Text(t) => Some(CString::new(*t).unwrap()),
                        Str::NonUtf8 => Some(CString::new(vec![0xc3, 0x28]).unwrap()),
                    })
                    .collect();
                let sp: Vec<fmi2String> = owned
                    .iter()
                    .map(|o| o.as_ref().map_or(null(), |s| s.as_ptr()))
                    .collect();
                api::set_string::<M>(
                    c,
                    in_ptr(vrs, ptrs[0]),
                    n_of(vrs.len(), *len),
                    in_ptr(&sp, ptrs[1]),
                )
            }
            Call::Get {
                ty, vrs, ptrs, len, ..
            } => {
                let (vp, n) = (in_ptr(vrs, ptrs[0]), n_of(vrs.len(), *len));
                match ty {
                    Ty::Real => {
                        let mut out = vec![SENT_F64; vrs.len()];
                        let s = api::get_real::<M>(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                        reads = bits_f64(&out);
                        s
                    }
                    Ty::Integer => {
                        let mut out = vec![SENT_I32; vrs.len()];
                        let s = api::get_integer::<M>(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_I32);
                        reads = bits_i32(&out);
                        s
                    }
                    Ty::Boolean => {
                        let mut out = vec![SENT_I32; vrs.len()];
                        let s = api::get_boolean::<M>(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_I32);
                        reads = bits_i32(&out);
                        s
                    }
                    Ty::String => {
                        let mut out: Vec<fmi2String> = vec![SENT_STR.as_ptr(); vrs.len()];
                        let s = api::get_string::<M>(c, vp, n, out_ptr(&mut out, ptrs[1]));
                        untouched = out.iter().all(|&x| x == SENT_STR.as_ptr());
                        reads = out.iter().map(|&p| c_bytes(p).len() as u64).collect();
                        s
                    }
                }
            }
            Call::GetState { out, .. } | Call::FreeState { out, .. } => {
                let mut holder = match out {
                    StateOut::HoldsBogus => env.bogus(),
                    StateOut::HoldsOther => env.other_state(),
                    _ => null_mut(),
                };
                let p: *mut fmi2FMUstate = match out {
                    StateOut::Slot(k) => &mut f.slots[*k],
                    StateOut::NullPtr => null_mut(),
                    _ => &mut holder,
                };
                let before = if p.is_null() { null_mut() } else { *p };
                let s = if matches!(call, Call::GetState { .. }) {
                    api::get_fmu_state::<M>(c, p)
                } else {
                    api::free_fmu_state::<M>(c, p)
                };
                untouched = p.is_null() || *p == before;
                if !p.is_null() {
                    reads.push(u64::from((*p).is_null()));
                }
                s
            }
            Call::SetState { st, .. } => api::set_fmu_state::<M>(c, state_in(f, env, *st)),
            Call::StateSize { st, null, .. } => {
                let mut n = usize::MAX - 1;
                let p: *mut usize = if *null { null_mut() } else { &mut n };
                let s = api::serialized_fmu_state_size::<M>(c, state_in(f, env, *st), p);
                untouched = n == usize::MAX - 1;
                reads.push(n as u64);
                s
            }
            Call::Serialize {
                st,
                size,
                ptr,
                impossible,
                ..
            } => {
                let mut buf = vec![SENT_BYTE as fmi2Byte; if *impossible { 16 } else { *size }];
                let n = if *impossible { usize::MAX } else { *size };
                let s = api::serialize_fmu_state::<M>(
                    c,
                    state_in(f, env, *st),
                    out_ptr(&mut buf, *ptr),
                    n,
                );
                untouched = buf.iter().all(|&b| b as u8 == SENT_BYTE);
                reads = buf.iter().map(|&b| u64::from(b as u8)).collect();
                s
            }
            Call::Deserialize {
                bytes,
                size,
                ptr,
                impossible,
                out,
                ..
            } => {
                let mut holder = match out {
                    StateOut::HoldsBogus => env.bogus(),
                    StateOut::HoldsOther => env.other_state(),
                    _ => null_mut(),
                };
                let p: *mut fmi2FMUstate = match out {
                    StateOut::Slot(k) => &mut f.slots[*k],
                    StateOut::NullPtr => null_mut(),
                    _ => &mut holder,
                };
                let before = if p.is_null() { null_mut() } else { *p };
                let n = if *impossible { usize::MAX } else { *size };
                let s = api::deserialize_fmu_state::<M>(
                    c,
                    in_ptr(&bytes.0, *ptr) as *const fmi2Byte,
                    n,
                    p,
                );
                untouched = p.is_null() || *p == before;
                s
            }
            Call::DirDeriv {
                unknowns,
                knowns,
                dv,
                ptrs,
                len,
                ..
            } => {
                let mut out = vec![SENT_F64; unknowns.len()];
                let s = api::get_directional_derivative::<M>(
                    c,
                    in_ptr(unknowns, ptrs[0]),
                    n_of(unknowns.len(), *len),
                    in_ptr(knowns, ptrs[1]),
                    knowns.len(),
                    in_ptr(dv, ptrs[2]),
                    out_ptr(&mut out, ptrs[3]),
                );
                untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                reads = bits_f64(&out);
                s
            }
            Call::SetInputDer {
                vrs,
                orders,
                vals,
                ptrs,
                len,
                ..
            } => api::set_real_input_derivatives::<M>(
                c,
                in_ptr(vrs, ptrs[0]),
                n_of(vrs.len(), *len),
                in_ptr(orders, ptrs[1]),
                in_ptr(vals, ptrs[2]),
            ),
            Call::GetOutputDer {
                vrs,
                orders,
                ptrs,
                len,
                ..
            } => {
                let mut out = vec![SENT_F64; vrs.len()];
                let s = api::get_real_output_derivatives::<M>(
                    c,
                    in_ptr(vrs, ptrs[0]),
                    n_of(vrs.len(), *len),
                    in_ptr(orders, ptrs[1]),
                    out_ptr(&mut out, ptrs[2]),
                );
                untouched = out.iter().all(|x| x.to_bits() == SENT_F64.to_bits());
                reads = bits_f64(&out);
                s
            }
            Call::Step { tc, h, flag, .. } => api::do_step::<M>(c, *tc, *h, *flag),
            Call::Status {
                func, kind, null, ..
            } => match func {
                StatusFn::Status => {
                    let mut v = fmi2Pending;
                    let p: *mut fmi2Status = if *null { null_mut() } else { &mut v };
                    let s = api::get_status::<M>(c, *kind, p);
                    untouched = v == fmi2Pending;
                    reads.push(v as u64);
                    s
                }
                StatusFn::Real => {
                    let mut v = SENT_F64;
                    let p: *mut f64 = if *null { null_mut() } else { &mut v };
                    let s = api::get_real_status::<M>(c, *kind, p);
                    untouched = v.to_bits() == SENT_F64.to_bits();
                    reads.push(v.to_bits());
                    s
                }
                StatusFn::Integer | StatusFn::Boolean => {
                    let mut v = SENT_I32;
                    let p: *mut i32 = if *null { null_mut() } else { &mut v };
                    let s = if *func == StatusFn::Integer {
                        api::get_integer_status::<M>(c, *kind, p)
                    } else {
                        api::get_boolean_status::<M>(c, *kind, p)
                    };
                    untouched = v == SENT_I32;
                    reads.push(v as u32 as u64);
                    s
                }
                StatusFn::String => {
                    let mut v: fmi2String = SENT_STR.as_ptr();
                    let p: *mut fmi2String = if *null { null_mut() } else { &mut v };
                    let s = api::get_string_status::<M>(c, *kind, p);
                    untouched = v == SENT_STR.as_ptr();
                    s
                }
            },
        }
    };
    Outcome {
        status,
        reads,
        untouched,
    }
}

fn state_in(f: &Fmu, env: &Env, s: StateIn) -> fmi2FMUstate {
    match s {
        StateIn::Slot(k) => f.slots[k],
        StateIn::Null => null_mut(),
        StateIn::Bogus => env.bogus(),
        StateIn::Other => env.other_state(),
    }
}

// ---------------------------------------------------------------------------
// Operations (what is generated) and their resolution into calls
// ---------------------------------------------------------------------------

/// How `fmi2DoStep`'s `currentCommunicationPoint` is chosen, relative to the
/// FMU's time `t` before the call.
#[derive(Clone, Copy, Debug)]
enum Tc {
    /// `t` itself.
    Exact,
    /// The master's own `t += h` accumulation.
    Accumulated,
    /// The master's `t0 + i * h`.
    Multiplied,
    /// `t` moved by a few ulps.
    Ulps(i32),
    /// `t + r · max(1, |t|)`, |r| ≤ 1e-11.
    Rel(f64),
    /// `t ± factor · tolerance`, factor ≥ 3: a jump.
    Jump(f64),
    /// `t ± h`: a whole step off.
    JumpH(bool),
    Lit(f64),
}

#[derive(Clone, Copy, Debug)]
enum H {
    Lit(f64),
    /// Exactly to the stop time (1e-3 without one).
    ToStop,
    /// To the stop time plus this.
    PastStop(f64),
}

#[derive(Clone, Copy, Debug)]
enum Buf {
    Exact,
    Short(Index),
    Zero,
    Long(usize),
    Null,
    Impossible,
}

#[derive(Clone, Debug)]
enum Src {
    /// The instance's current state.
    Current,
    Pool(usize),
    Slot(usize),
    Random(Vec<u8>),
    Empty,
}

#[derive(Clone, Debug)]
enum Mutation {
    None,
    Truncate(Index),
    Flip { at: Index, bit: u8, fix: bool },
    Overwrite { at: Index, value: f64, fix: bool },
    Append(Vec<u8>),
    ForeignGuid,
    Zero,
}

#[derive(Clone, Copy, Debug)]
enum Size {
    Exact,
    Less(Index),
    Zero,
    Impossible,
}

#[derive(Clone, Debug)]
enum Op {
    Call(Call),
    Step {
        comp: Comp,
        tc: Tc,
        h: H,
        flag: i32,
    },
    Serialize {
        comp: Comp,
        st: StateIn,
        buf: Buf,
    },
    Deserialize {
        comp: Comp,
        src: Src,
        mutation: Mutation,
        size: Size,
        ptr: Ptr,
        out: StateOut,
    },
    /// Setup, enter, set inputs, exit.
    Init {
        start: f64,
        stop: Option<f64>,
        inputs: Vec<(u32, f64)>,
    },
    /// `n` × (set activation and length, step).
    Run {
        n: usize,
        h: f64,
        tc: Tc,
        amp: f64,
        act: f64,
    },
    /// Deserialize a pool state into slot 3 and set it.
    Restore(usize),
    /// What a master does on a discard: save the state in slot 0, set the
    /// length to `factor` · L0 (beyond what the law can evaluate for large
    /// factors), step (discarded), ask why, roll back, step again.
    DiscardRecover(f64),
    /// Deterministic tests only: the FMI state before the next call.
    ExpectState(FmiState),
}

fn set_real(vrs: Vec<u32>, vals: Vec<f64>) -> Call {
    Call::SetReal {
        comp: Comp::Valid,
        vrs,
        vals,
        ptrs: [Ptr::Ok; 2],
        len: Len::Exact,
    }
}

fn get(ty: Ty, vrs: Vec<u32>) -> Call {
    Call::Get {
        comp: Comp::Valid,
        ty,
        vrs,
        ptrs: [Ptr::Ok; 2],
        len: Len::Exact,
    }
}

/// Macros into primitive operations.
fn expand(op: &Op) -> Vec<Op> {
    let t = table();
    match op {
        Op::Init {
            start,
            stop,
            inputs,
        } => {
            let mut v = vec![
                Op::Call(Call::Setup {
                    comp: Comp::Valid,
                    tol_def: 0,
                    tol: 0.0,
                    start: *start,
                    stop_def: i32::from(stop.is_some()),
                    stop: stop.unwrap_or(f64::NAN),
                }),
                Op::Call(Call::Enter(Comp::Valid)),
            ];
            if !inputs.is_empty() {
                let (vrs, vals) = inputs.iter().copied().unzip();
                v.push(Op::Call(set_real(vrs, vals)));
            }
            v.push(Op::Call(Call::Exit(Comp::Valid)));
            v
        }
        Op::Run { n, h, tc, amp, act } => (0..*n)
            .flat_map(|i| {
                let phase = 2.0 * std::f64::consts::PI * i as f64 / 40.0;
                let length = DEFAULT_L0 * (1.0 + amp * phase.sin());
                [
                    Op::Call(set_real(vec![t.activation, t.length], vec![*act, length])),
                    Op::Step {
                        comp: Comp::Valid,
                        tc: *tc,
                        h: H::Lit(*h),
                        flag: 0,
                    },
                ]
            })
            .collect(),
        Op::Restore(i) => vec![
            Op::Deserialize {
                comp: Comp::Valid,
                src: Src::Pool(*i),
                mutation: Mutation::None,
                size: Size::Exact,
                ptr: Ptr::Ok,
                out: StateOut::Slot(N_SLOTS - 1),
            },
            Op::Call(Call::SetState {
                comp: Comp::Valid,
                st: StateIn::Slot(N_SLOTS - 1),
            }),
        ],
        Op::DiscardRecover(factor) => {
            let step = Op::Step {
                comp: Comp::Valid,
                tc: Tc::Exact,
                h: H::Lit(1e-3),
                flag: 0,
            };
            let status = |func, kind| {
                Op::Call(Call::Status {
                    comp: Comp::Valid,
                    func,
                    kind,
                    null: false,
                })
            };
            vec![
                Op::Call(Call::GetState {
                    comp: Comp::Valid,
                    out: StateOut::Slot(0),
                }),
                Op::Call(set_real(vec![t.length], vec![DEFAULT_L0 * factor])),
                step.clone(),
                status(StatusFn::Status, fmi2DoStepStatus),
                status(StatusFn::Real, fmi2LastSuccessfulTime),
                status(StatusFn::Boolean, fmi2Terminated),
                Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(0),
                }),
                Op::Call(set_real(vec![t.length], vec![DEFAULT_L0])),
                step,
            ]
        }
        other => vec![other.clone()],
    }
}

fn mutate(mut b: Vec<u8>, m: &Mutation) -> Vec<u8> {
    match m {
        Mutation::None => {}
        Mutation::Truncate(i) => {
            let n = i.index(b.len().max(1));
            b.truncate(n);
        }
        Mutation::Flip { at, bit, fix } => {
            if !b.is_empty() {
                let k = at.index(b.len());
                b[k] ^= 1 << (bit % 8);
                if *fix {
                    fix_checksum(&mut b);
                }
            }
        }
        Mutation::Overwrite { at, value, fix } => {
            if b.len() >= 8 {
                let k = at.index(b.len() - 7);
                b[k..k + 8].copy_from_slice(&value.to_le_bytes());
                if *fix {
                    fix_checksum(&mut b);
                }
            }
        }
        Mutation::Append(x) => b.extend_from_slice(x),
        Mutation::ForeignGuid => {
            let k = 28;
            if b.len() > k {
                b[k] = if b[k] == b'X' { b'Y' } else { b'X' };
                fix_checksum(&mut b);
            }
        }
        Mutation::Zero => b.iter_mut().for_each(|x| *x = 0),
    }
    b
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Expect {
    Reject,
    Accept,
    Unknown,
}

use Expect::{Accept, Reject, Unknown};

/// Arrays of one call: any NULL pointer with `n > 0`, or an impossible
/// length, must be refused.
fn arrays_bad(n: usize, ptrs: &[Ptr], len: Len) -> bool {
    len == Len::Impossible || (n > 0 && ptrs.contains(&Ptr::Null))
}

/// The outcome the standard / the layer's contract fixes for `call` in the
/// state `pre`, as far as it is simple to tell.
fn expect(call: &Call, pre: &LayerState, f: &Fmu) -> Expect {
    if call.comp() != Comp::Valid || !call.meta().1.contains(pre.fmi_state) {
        return Reject;
    }
    let state = pre.fmi_state;
    let settable = |vr: u32| var(vr).is_some_and(|v| settable_in(v, state));
    match call {
        Call::Setup {
            start,
            stop_def,
            stop,
            ..
        } => {
            if !start.is_finite() || (*stop_def != 0 && !(stop.is_finite() && stop >= start)) {
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
        Call::SetInteger { vrs, ptrs, len, .. } | Call::SetString { vrs, ptrs, len, .. } => {
            // HillMuscle1D has no Integer and no String variables.
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
                Ty::Integer | Ty::String => false,
            };
            if arrays_bad(vrs.len(), ptrs, *len) || !vrs.iter().all(|&vr| type_ok(vr)) {
                Reject
            } else if *ty == Ty::Real && state == FmiState::InitializationMode {
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
            ptrs,
            len,
            ..
        } => {
            let bad_arrays = *len == Len::Impossible
                || (!unknowns.is_empty() && (ptrs[0] == Ptr::Null || ptrs[3] == Ptr::Null))
                || (!knowns.is_empty() && (ptrs[1] == Ptr::Null || ptrs[2] == Ptr::Null));
            if bad_arrays
                || !unknowns
                    .iter()
                    .all(|&vr| is_real_with(vr, Causality::Output))
                || !knowns.iter().all(|&vr| is_real_with(vr, Causality::Input))
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
fn step_expect(tc: f64, h: f64, pre: &LayerState) -> Expect {
    let t = pre.time;
    if !(h.is_finite() && h > 0.0 && tc.is_finite()) {
        return Reject;
    }
    let tol = api::time_tolerance(t, h);
    if t.is_finite() && (tc - t).abs() > 2.0 * tol {
        return Reject;
    }
    if let Some(stop) = pre.stop_time {
        if tc + h > stop + 2.0 * tol {
            return Reject;
        }
    }
    let drift_ok = t.is_finite() && (tc - t).abs() <= 1e-10 * t.abs().max(1.0);
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

/// The master's clock: its own `t += h` accumulation and `t0 + i * h`,
/// resynchronized with the FMU's time only when that jumped (a reset, a
/// restored FMU state, a new experiment), never to absorb drift.
struct Master {
    t_acc: f64,
    t0: f64,
    i: u64,
    h: f64,
}

impl Master {
    fn new() -> Master {
        Master {
            t_acc: 0.0,
            t0: 0.0,
            i: 0,
            h: f64::NAN,
        }
    }

    fn tc(&mut self, kind: Tc, t: f64, h: f64) -> f64 {
        let near = (self.t_acc - t).abs() <= 1e-7 * t.abs().max(1.0);
        if !near {
            *self = Master {
                t_acc: t,
                t0: t,
                ..Master::new()
            };
        }
        if h.to_bits() != self.h.to_bits() {
            self.t0 = self.t_acc;
            self.i = 0;
            self.h = h;
        }
        let tol = api::time_tolerance(t, h);
        match kind {
            Tc::Exact => t,
            Tc::Accumulated => self.t_acc,
            Tc::Multiplied => self.t0 + self.i as f64 * h,
            Tc::Ulps(k) => t + f64::from(k) * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE),
            Tc::Rel(r) => t + r * t.abs().max(1.0),
            Tc::Jump(x) => t + x * tol,
            Tc::JumpH(up) => {
                if up {
                    t + h
                } else {
                    t - h
                }
            }
            Tc::Lit(x) => x,
        }
    }

    fn stepped(&mut self, h: f64) {
        self.t_acc += h;
        self.i += 1;
    }
}

// ---------------------------------------------------------------------------
// The harness
// ---------------------------------------------------------------------------

/// `API_ABUSE_STATS=1`: counts of (function, state before, status) and of
/// the harness's comparisons, printed after the property tests.
fn stats() -> Option<&'static Mutex<std::collections::BTreeMap<String, u64>>> {
    static S: OnceLock<Option<Mutex<std::collections::BTreeMap<String, u64>>>> = OnceLock::new();
    S.get_or_init(|| {
        std::env::var("API_ABUSE_STATS")
            .is_ok_and(|v| v == "1")
            .then(Default::default)
    })
    .as_ref()
}

fn stat(key: impl FnOnce() -> String) {
    if let Some(s) = stats() {
        *s.lock().unwrap().entry(key()).or_default() += 1;
    }
}

fn print_stats(test: &str) {
    if let Some(s) = stats() {
        let s = s.lock().unwrap();
        eprintln!("-- {test}: calls by (function, state before, status), and comparisons");
        for (k, n) in s.iter() {
            eprintln!("{n:>10}  {k}");
        }
    }
}

macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            return Err(format!($($arg)*));
        }
    };
}

/// Masks FMU state addresses (`0x...`) in log messages.
fn mask(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find("0x") {
        out.push_str(&rest[..i + 2]);
        out.push('?');
        rest = rest[i + 2..].trim_start_matches(|c: char| c.is_ascii_hexdigit());
    }
    out.push_str(rest);
    out
}

fn masked(logs: &[Entry]) -> Vec<(fmi2Status, String, String)> {
    logs.iter()
        .map(|e| (e.status, e.category.clone(), mask(&e.message)))
        .collect()
}

fn expected_category(s: fmi2Status) -> &'static [&'static str] {
    match s {
        fmi2OK => &["logAll", "logEvents"],
        fmi2Warning => &["logStatusWarning"],
        fmi2Discard => &["logStatusDiscard"],
        fmi2Error => &["logStatusError"],
        fmi2Fatal => &["logStatusFatal"],
        fmi2Pending => &[],
    }
}

/// After an accepted `fmi2SetDebugLogging`: whether any debug category is
/// on (a `logStatus*` name selects no debug message).
fn debug_after(call: &Call, s: fmi2Status) -> Option<bool> {
    match call {
        Call::Logging { on, cats, .. } if s == fmi2OK => Some(
            *on != 0
                && (cats.is_empty()
                    || cats
                        .iter()
                        .any(|c| matches!(c, Cat::Known(4) | Cat::Known(5)))),
        ),
        _ => None,
    }
}

struct Harness {
    logging_on: bool,
    p: Fmu,
    twin: Fmu,
    /// A fresh instance following the primary since its last accepted reset.
    shadow: Option<Fmu>,
    master: Master,
    /// The last accepted `fmi2SetDebugLogging` (replayed on a new shadow:
    /// a reset keeps the logging settings).
    last_logging: Option<Call>,
    /// Whether a debug message may be logged (instantiation's `loggingOn`,
    /// then the last accepted `fmi2SetDebugLogging`).
    debug_on: bool,
    trace: Vec<String>,
    calls: usize,
}

impl Harness {
    fn new(logging_on: bool) -> Harness {
        Harness {
            logging_on,
            p: Fmu::new(logging_on),
            twin: Fmu::new(logging_on),
            shadow: None,
            master: Master::new(),
            last_logging: None,
            debug_on: logging_on,
            trace: Vec::new(),
            calls: 0,
        }
    }

    fn fail(&self, e: String) -> String {
        let tail = self.trace.len().saturating_sub(25);
        format!(
            "{e}\n-- last calls (of {}):\n{}",
            self.calls,
            self.trace[tail..].join("\n")
        )
    }

    fn resolve(
        &mut self,
        op: &Op,
        pre: &LayerState,
        pre_bytes: &[u8],
    ) -> Result<(Call, Expect), String> {
        Ok(match op {
            Op::Call(c) => (c.clone(), Unknown),
            Op::Step { comp, tc, h, flag } => {
                let t = pre.time;
                let h = match *h {
                    H::Lit(x) => x,
                    H::ToStop => pre.stop_time.map_or(1e-3, |s| s - t),
                    H::PastStop(x) => pre.stop_time.map_or(x, |s| s - t + x),
                };
                let tc = self.master.tc(*tc, t, h);
                let call = Call::Step {
                    comp: *comp,
                    tc,
                    h,
                    flag: *flag,
                };
                (call, step_expect(tc, h, pre))
            }
            Op::Serialize { comp, st, buf } => {
                let need = match st {
                    StateIn::Slot(k) if !self.p.slots[*k].is_null() => {
                        Some(self.p.slot_bytes(*k)?.len())
                    }
                    _ => None,
                };
                let n = need.unwrap_or(256);
                let (size, ptr, impossible) = match buf {
                    Buf::Exact => (n, Ptr::Ok, false),
                    Buf::Short(i) => (i.index(n), Ptr::Ok, false),
                    Buf::Zero => (0, Ptr::Ok, false),
                    Buf::Long(k) => (n + k, Ptr::Ok, false),
                    Buf::Null => (n, Ptr::Null, false),
                    Buf::Impossible => (0, Ptr::Ok, true),
                };
                let e = if need.is_some() && matches!(buf, Buf::Exact | Buf::Long(_)) {
                    Accept
                } else {
                    Reject
                };
                let call = Call::Serialize {
                    comp: *comp,
                    st: *st,
                    size,
                    ptr,
                    impossible,
                };
                (call, e)
            }
            Op::Deserialize {
                comp,
                src,
                mutation,
                size,
                ptr,
                out,
            } => {
                let (bytes, valid) = match src {
                    Src::Current => (pre_bytes.to_vec(), true),
                    Src::Pool(i) => (pool()[*i].clone(), true),
                    Src::Slot(k) if !self.p.slots[*k].is_null() => (self.p.slot_bytes(*k)?, true),
                    Src::Slot(_) | Src::Empty => (Vec::new(), false),
                    Src::Random(b) => (b.clone(), false),
                };
                // Unless API_ABUSE_ROUND_TRIP=1: a state of the known bug is
                // not expected to deserialize.
                let intact = valid && decodes(&bytes);
                let full = bytes.len();
                let bytes = mutate(bytes, mutation);
                let (n, impossible) = match size {
                    Size::Exact => (bytes.len(), false),
                    Size::Less(i) => (i.index(bytes.len().max(1)), false),
                    Size::Zero => (0, false),
                    Size::Impossible => (0, true),
                };
                let e = if *ptr == Ptr::Null
                    || impossible
                    || *out == StateOut::NullPtr
                    || matches!(src, Src::Empty)
                    || (matches!(src, Src::Slot(_)) && !valid)
                {
                    Reject
                } else if !valid {
                    Unknown
                } else {
                    match mutation {
                        Mutation::None | Mutation::Append(_) if n >= full && intact => Accept,
                        Mutation::None | Mutation::Append(_) if n >= full => Unknown,
                        Mutation::None
                        | Mutation::Truncate(_)
                        | Mutation::Zero
                        | Mutation::ForeignGuid
                        | Mutation::Flip { fix: false, .. } => Reject,
                        _ => Unknown,
                    }
                };
                let call = Call::Deserialize {
                    comp: *comp,
                    bytes: Bytes(bytes),
                    size: n,
                    ptr: *ptr,
                    impossible,
                    out: *out,
                };
                (call, e)
            }
            Op::Init { .. }
            | Op::Run { .. }
            | Op::Restore(_)
            | Op::DiscardRecover(_)
            | Op::ExpectState(_) => {
                unreachable!("expanded before")
            }
        })
    }

    /// Runs one primitive operation on the primary with every check, then on
    /// the followers.
    fn one(&mut self, env: &Env, op: &Op) -> Result<fmi2Status, String> {
        let pre_bytes = self.p.state_bytes()?;
        let pre = layer_of(&pre_bytes)?;
        if let Op::ExpectState(s) = op {
            ensure!(
                pre.fmi_state == *s,
                "expected state {s:?}, in {:?}",
                pre.fmi_state
            );
            return Ok(fmi2OK);
        }
        let (call, resolved) = self.resolve(op, &pre, &pre_bytes)?;
        let mut want = expect(&call, &pre, &self.p);
        if want != Reject && resolved != Unknown {
            want = resolved;
        }
        let (fname, allowed) = call.meta();
        let state_ok = allowed.contains(pre.fmi_state);

        // The shadow cannot follow a call on an FMU state saved before its
        // reset: compare and stop following.
        if let Some(s) = &self.shadow {
            if call
                .slots()
                .iter()
                .any(|&k| s.slots[k].is_null() != self.p.slots[k].is_null())
            {
                let sb = s.state_bytes()?;
                ensure!(sb == pre_bytes, "reset shadow diverged before {call:?}");
                self.shadow = None;
            }
        }
        let set_from = match &call {
            Call::SetState {
                st: StateIn::Slot(k),
                ..
            } if !self.p.slots[*k].is_null() => Some(self.p.slot_bytes(*k)?),
            _ => None,
        };

        self.p.book.clear();
        let out = exec(&mut self.p, env, &call);
        let logs = self.p.book.take();
        let s = out.status;
        self.calls += 1;
        self.trace.push(format!(
            "[{}] {:?} -> {:?}: {:?}",
            pre.fmi_state.name(),
            call,
            s,
            logs.iter().map(|e| &e.message).collect::<Vec<_>>()
        ));

        stat(|| format!("{fname} [{}] -> {s:?}", pre.fmi_state.name()));
        stat(|| format!("~ oracle {want:?}"));
        // 1. A valid status, no caught panic, synchronous.
        ensure!(
            (0..=5).contains(&(s as i32)) && s != fmi2Fatal && s != fmi2Pending,
            "{fname} returned {s:?}"
        );
        // 3. The oracle.
        match want {
            Reject => ensure!(s == fmi2Error, "{fname} must be rejected, got {s:?}"),
            Accept => ensure!(s != fmi2Error, "{fname} must be accepted, got {s:?}"),
            Unknown => {}
        }
        // 2. Logging.
        for e in &logs {
            ensure!(
                e.instance == NAME.to_bytes(),
                "{fname}: logged with instance name {:?}",
                String::from_utf8_lossy(&e.instance)
            );
            ensure!(e.format == "%s", "{fname}: format {:?}", e.format);
            ensure!(!e.message.is_empty(), "{fname}: empty message");
            ensure!(!e.message.contains('#'), "{fname}: '#' in {:?}", e.message);
            ensure!(
                expected_category(e.status).contains(&e.category.as_str()),
                "{fname}: status {:?} in category {}",
                e.status,
                e.category
            );
            ensure!(
                e.status != fmi2OK || self.debug_on || debug_after(&call, s) == Some(true),
                "{fname}: debug message with debug logging off: {:?}",
                e.message
            );
        }
        if call.comp() != Comp::Valid {
            ensure!(
                s == fmi2Error,
                "{fname} on a {:?} component: {s:?}",
                call.comp()
            );
            ensure!(
                logs.is_empty(),
                "{fname} on a {:?} component logged {logs:?}",
                call.comp()
            );
        } else if s == fmi2Error || s == fmi2Discard {
            let prefix = format!("{fname}: ");
            ensure!(
                logs.iter()
                    .any(|e| e.status == s && e.message.starts_with(&prefix)),
                "{fname} returned {s:?} without a {s:?} message starting with {prefix:?}: {logs:?}"
            );
            if !state_ok {
                let why = format!("{fname}: not allowed in state {}", pre.fmi_state.name());
                ensure!(
                    logs.iter().any(|e| e.message == why),
                    "{fname} in state {}: no {why:?} in {logs:?}",
                    pre.fmi_state.name()
                );
            }
        }

        // 4. Rejected (and read-only) calls change nothing.
        let post_bytes = self.p.state_bytes()?;
        let is_step = matches!(call, Call::Step { .. });
        let keep = s == fmi2Error || (s == fmi2Discard && !is_step) || call.is_pure(pre.fmi_state);
        if keep && post_bytes != pre_bytes {
            let post = layer_of(&post_bytes)?;
            let at = pre_bytes
                .iter()
                .zip(&post_bytes)
                .position(|(a, b)| a != b)
                .unwrap_or(pre_bytes.len().min(post_bytes.len()));
            return Err(format!(
                "{fname} returned {s:?} but changed the instance: layer {pre:?} -> {post:?}; \
                 serialized state: {} -> {} bytes, first difference at byte {at}",
                pre_bytes.len(),
                post_bytes.len()
            ));
        }
        if s == fmi2Error {
            ensure!(
                out.untouched,
                "{fname} returned fmi2Error but wrote an out-argument"
            );
            return Ok(s);
        }
        match &call {
            Call::Reset(_) => ensure!(
                &post_bytes == fresh_bytes(),
                "fmi2Reset: the state differs from a new instance's"
            ),
            Call::SetState { .. } => ensure!(
                Some(&post_bytes) == set_from.as_ref(),
                "fmi2SetFMUstate: the state differs from the saved one"
            ),
            Call::GetState {
                out: StateOut::Slot(k),
                ..
            } => ensure!(
                self.p.slot_bytes(*k)? == pre_bytes,
                "fmi2GetFMUstate: the saved state differs from the instance's"
            ),
            _ => {}
        }

        // 5. and 6. The followers.
        let t = &mut self.twin;
        t.book.clear();
        let o = exec(t, env, &call);
        let tl = t.book.take();
        ensure!(
            o.status == s && o.reads == out.reads,
            "twin: {fname} gave {:?} (values {:?}), the primary {s:?} (values {:?})",
            o.status,
            o.reads,
            out.reads
        );
        ensure!(
            masked(&tl) == masked(&logs),
            "twin: {fname} logged {tl:?}, the primary {logs:?}"
        );
        stat(|| "~ twin: calls compared".into());
        if matches!(call, Call::Reset(_)) {
            if let Some(sh) = self.shadow.take() {
                ensure!(
                    sh.state_bytes()? == pre_bytes,
                    "reset shadow diverged before a reset"
                );
            }
            let sh = Fmu::new(self.logging_on);
            if let Some(l) = &self.last_logging {
                let mut sh = sh;
                let r = exec(&mut sh, env, l);
                ensure!(
                    r.status == fmi2OK,
                    "replaying logging settings: {:?}",
                    r.status
                );
                sh.book.clear();
                self.shadow = Some(sh);
            } else {
                self.shadow = Some(sh);
            }
            let sb = self.shadow.as_ref().unwrap().state_bytes()?;
            ensure!(sb == post_bytes, "fmi2Reset: differs from a new instance");
            stat(|| "~ reset shadows started".into());
        } else if let Some(sh) = &mut self.shadow {
            sh.book.clear();
            let o = exec(sh, env, &call);
            let sl = sh.book.take();
            ensure!(
                o.status == s && o.reads == out.reads,
                "reset shadow: {fname} gave {:?} (values {:?}), the reset instance {s:?} (values {:?})",
                o.status,
                o.reads,
                out.reads
            );
            ensure!(
                masked(&sl) == masked(&logs),
                "reset shadow: {fname} logged {sl:?}, the reset instance {logs:?}"
            );
            stat(|| "~ reset shadow: calls compared".into());
        }

        if let Call::Step { h, .. } = call {
            if s == fmi2OK {
                self.master.stepped(h);
            }
        }
        if let Some(on) = debug_after(&call, s) {
            self.debug_on = on;
            self.last_logging = Some(call);
        }
        Ok(s)
    }

    /// End of a sequence: the twin, the shadow and the primary agree.
    fn finish(&mut self, env: &Env) -> Result<(), String> {
        let pb = self.p.state_bytes()?;
        ensure!(
            self.twin.state_bytes()? == pb,
            "twin: the final serialized states differ"
        );
        if let Some(sh) = &self.shadow {
            ensure!(
                sh.state_bytes()? == pb,
                "reset shadow: the final serialized states differ"
            );
        }
        for k in 0..N_SLOTS {
            let (a, b) = (self.p.slots[k], self.twin.slots[k]);
            ensure!(a.is_null() == b.is_null(), "twin: slot {k} differs");
            if !a.is_null() {
                ensure!(
                    self.p.slot_bytes(k)? == self.twin.slot_bytes(k)?,
                    "twin: saved FMU state {k} differs"
                );
            }
        }
        let mut finals = vec![Call::Get {
            comp: Comp::Valid,
            ty: Ty::Real,
            vrs: table().outputs.clone(),
            ptrs: [Ptr::Ok; 2],
            len: Len::Exact,
        }];
        for (func, kind) in [
            (StatusFn::Status, fmi2DoStepStatus),
            (StatusFn::Real, fmi2LastSuccessfulTime),
            (StatusFn::Boolean, fmi2Terminated),
        ] {
            finals.push(Call::Status {
                comp: Comp::Valid,
                func,
                kind,
                null: false,
            });
        }
        for call in &finals {
            let a = exec(&mut self.p, env, call);
            let b = exec(&mut self.twin, env, call);
            ensure!(
                a.status == b.status && a.reads == b.reads,
                "twin: final {:?}: {:?} {:?} vs {:?} {:?}",
                call.meta().0,
                a.status,
                a.reads,
                b.status,
                b.reads
            );
            if let Some(sh) = &mut self.shadow {
                let c = exec(sh, env, call);
                ensure!(
                    a.status == c.status && a.reads == c.reads,
                    "reset shadow: final {:?} differs",
                    call.meta().0
                );
            }
        }
        Ok(())
    }
}

fn run_sequence(logging_on: bool, ops: &[Op]) -> Result<(), String> {
    let env = Env::new();
    let mut h = Harness::new(logging_on);
    for op in ops {
        let is_run = matches!(op, Op::Run { .. });
        for prim in expand(op) {
            let s = h.one(&env, &prim).map_err(|e| h.fail(e))?;
            // A master stops a run at the first step that does not complete.
            if is_run && matches!(prim, Op::Step { .. }) && s != fmi2OK {
                break;
            }
        }
    }
    h.finish(&env).map_err(|e| h.fail(e))
}

// ---------------------------------------------------------------------------
// Strategies
// ---------------------------------------------------------------------------

fn special() -> impl Strategy<Value = f64> + Clone {
    prop::sample::select(vec![
        f64::NAN,
        -f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
        -0.0,
        -1.0,
        1.0,
        0.5,
        2.0,
        -1e-3,
        f64::MIN_POSITIVE,
        5e-324,
        1e-300,
        1e300,
        f64::MAX,
        -f64::MAX,
    ])
}

fn arb_comp() -> impl Strategy<Value = Comp> + Clone {
    prop_oneof![
        40 => Just(Comp::Valid),
        1 => Just(Comp::Null),
        1 => Just(Comp::Foreign),
    ]
}

fn arb_ptr() -> impl Strategy<Value = Ptr> + Clone {
    prop_oneof![25 => Just(Ptr::Ok), 1 => Just(Ptr::Null)]
}

fn arb_len() -> impl Strategy<Value = Len> + Clone {
    prop_oneof![40 => Just(Len::Exact), 1 => Just(Len::Impossible)]
}

fn arb_vr() -> impl Strategy<Value = u32> + Clone {
    let n = n_vars();
    let t = table();
    prop_oneof![
        8 => 0..n,
        6 => prop::sample::select(vec![t.activation, t.length]),
        1 => n..n + 4,
        1 => Just(u32::MAX),
        1 => any::<u32>(),
    ]
}

/// A value for a Real variable: near its start value, in [0, 1], special, or
/// any bit pattern.
fn real_for(vr: u32) -> BoxedStrategy<f64> {
    let start = start_of(vr);
    prop_oneof![
        4 => (0.5f64..1.5).prop_map(move |f| start * f),
        2 => Just(start),
        2 => 0.0f64..=1.0,
        3 => special(),
        1 => any::<f64>(),
    ]
    .boxed()
}

fn vr_real() -> impl Strategy<Value = (u32, f64)> + Clone {
    arb_vr().prop_flat_map(|vr| (Just(vr), real_for(vr)))
}

/// Short arrays mostly; sometimes long ones (up to 120, with repeats).
fn items<T: Strategy + Clone>(s: T) -> impl Strategy<Value = Vec<T::Value>> + Clone
where
    T::Value: Clone,
{
    prop_oneof![
        12 => prop::collection::vec(s.clone(), 0..4),
        1 => prop::collection::vec(s, 20..120),
    ]
}

fn arb_state_in() -> impl Strategy<Value = StateIn> + Clone {
    prop_oneof![
        12 => (0..N_SLOTS).prop_map(StateIn::Slot),
        1 => Just(StateIn::Null),
        1 => Just(StateIn::Bogus),
        1 => Just(StateIn::Other),
    ]
}

fn arb_state_out() -> impl Strategy<Value = StateOut> + Clone {
    prop_oneof![
        12 => (0..N_SLOTS).prop_map(StateOut::Slot),
        1 => Just(StateOut::NullPtr),
        1 => Just(StateOut::HoldsBogus),
        1 => Just(StateOut::HoldsOther),
    ]
}

fn arb_tc() -> impl Strategy<Value = Tc> + Clone {
    prop_oneof![
        6 => Just(Tc::Exact),
        6 => Just(Tc::Accumulated),
        4 => Just(Tc::Multiplied),
        2 => (-1000i32..=1000).prop_map(Tc::Ulps),
        2 => (-1e-11f64..1e-11).prop_map(Tc::Rel),
        2 => prop_oneof![3.0f64..1e6, -1e6f64..-3.0].prop_map(Tc::Jump),
        1 => any::<bool>().prop_map(Tc::JumpH),
        1 => prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(0.0),
            any::<f64>()
        ]
        .prop_map(Tc::Lit),
    ]
}

fn step_size() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        6 => prop::sample::select(vec![1e-6, 1e-4, 1e-3, 1e-2, 0.1, 0.5]),
        3 => 1e-7f64..0.2,
        1 => prop::sample::select(vec![
            0.0,
            -0.0,
            -1e-3,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            5e-324,
            1e300,
        ]),
    ]
}

fn arb_h() -> impl Strategy<Value = H> + Clone {
    prop_oneof![
        8 => step_size().prop_map(H::Lit),
        1 => Just(H::ToStop),
        1 => prop::sample::select(vec![1e-9, 1e-3, 1.0]).prop_map(H::PastStop),
    ]
}

fn start_time() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![
        6 => prop::sample::select(vec![0.0, 1.0, -3.5, 1e6, 1e-300, -1e9]),
        2 => -1e3f64..1e3,
        1 => special(),
    ]
}

/// `(start, stop_defined, stop)`.
fn experiment() -> impl Strategy<Value = (f64, i32, f64)> + Clone {
    (
        start_time(),
        prop_oneof![3 => Just(1), 2 => Just(0), 1 => Just(7)],
        prop_oneof![
            6 => prop::sample::select(vec![0.0, 1e-3, 0.05, 1.0, 10.0]).prop_map(Some),
            1 => Just(None),
        ],
        special(),
    )
        .prop_map(|(start, def, rel, sp)| (start, def, rel.map_or(sp, |r| start + r)))
}

fn arb_cat() -> impl Strategy<Value = Cat> + Clone {
    prop_oneof![
        10 => (0..6usize).prop_map(Cat::Known),
        1 => Just(Cat::Unknown),
        1 => Just(Cat::Empty),
        1 => Just(Cat::Null),
        1 => Just(Cat::NonUtf8),
    ]
}

fn arb_mutation() -> impl Strategy<Value = Mutation> + Clone {
    prop_oneof![
        3 => Just(Mutation::None),
        2 => any::<Index>().prop_map(Mutation::Truncate),
        3 => (any::<Index>(), 0u8..8, any::<bool>())
            .prop_map(|(at, bit, fix)| Mutation::Flip { at, bit, fix }),
        3 => (any::<Index>(), special(), prop_oneof![3 => Just(true), 1 => Just(false)])
            .prop_map(|(at, value, fix)| Mutation::Overwrite { at, value, fix }),
        1 => prop::collection::vec(any::<u8>(), 1..32).prop_map(Mutation::Append),
        1 => Just(Mutation::ForeignGuid),
        1 => Just(Mutation::Zero),
    ]
}

fn arb_src() -> impl Strategy<Value = Src> + Clone {
    prop_oneof![
        4 => Just(Src::Current),
        4 => (0..POOL_LEN).prop_map(Src::Pool),
        2 => (0..N_SLOTS).prop_map(Src::Slot),
        1 => prop::collection::vec(any::<u8>(), 0..400).prop_map(Src::Random),
        1 => Just(Src::Empty),
    ]
}

fn deserialize_op() -> impl Strategy<Value = Op> + Clone {
    (
        arb_comp(),
        arb_src(),
        arb_mutation(),
        prop_oneof![
            8 => Just(Size::Exact),
            2 => any::<Index>().prop_map(Size::Less),
            1 => Just(Size::Zero),
            1 => Just(Size::Impossible),
        ],
        arb_ptr(),
        arb_state_out(),
    )
        .prop_map(|(comp, src, mutation, size, ptr, out)| Op::Deserialize {
            comp,
            src,
            mutation,
            size,
            ptr,
            out,
        })
}

fn init_op() -> impl Strategy<Value = Op> + Clone {
    let t = table();
    let inputs = prop_oneof![
        2 => Just(vec![]),
        3 => (0.0f64..=1.0, 0.8f64..1.2)
            .prop_map(move |(a, l)| vec![(t.activation, a), (t.length, DEFAULT_L0 * l)]),
        1 => prop::collection::vec(vr_real(), 1..3),
    ];
    (
        prop::sample::select(vec![0.0, 0.0, 1.0, 1e6, -2.0]),
        prop_oneof![
            2 => Just(None),
            3 => prop::sample::select(vec![1e-3, 0.05, 0.2, 10.0]).prop_map(Some),
        ],
        inputs,
    )
        .prop_map(|(start, stop, inputs)| Op::Init {
            start,
            stop: stop.map(|d: f64| start + d),
            inputs,
        })
}

fn run_op() -> impl Strategy<Value = Op> + Clone {
    (
        prop_oneof![3 => 1usize..20, 1 => 20usize..150],
        prop_oneof![
            4 => prop::sample::select(vec![1e-4, 1e-3, 1e-2]),
            1 => prop::sample::select(vec![1e-6, 0.1, 0.5]),
            1 => 1e-5f64..0.05,
        ],
        prop_oneof![
            Just(Tc::Accumulated),
            Just(Tc::Multiplied),
            Just(Tc::Exact),
            (-3i32..=3).prop_map(Tc::Ulps),
        ],
        prop::sample::select(vec![0.0, 0.05, 0.3, 1.5]),
        prop::sample::select(vec![0.0, 0.5, 1.0, 1.5]),
    )
        .prop_map(|(n, h, tc, amp, act)| Op::Run { n, h, tc, amp, act })
}

fn op() -> BoxedStrategy<Op> {
    let c = |s: BoxedStrategy<Call>| s.prop_map(Op::Call).boxed();
    let setup = (arb_comp(), any::<bool>(), special(), experiment()).prop_map(
        |(comp, td, tol, (start, stop_def, stop))| Call::Setup {
            comp,
            tol_def: i32::from(td),
            tol,
            start,
            stop_def,
            stop,
        },
    );
    let simple = (arb_comp(), 0..6u8).prop_map(|(comp, k)| match k {
        0 => Call::Enter(comp),
        1 => Call::Exit(comp),
        2 | 3 => Call::Terminate(comp),
        4 => Call::Reset(comp),
        _ => Call::Cancel(comp),
    });
    let logging = (
        arb_comp(),
        prop::sample::select(vec![0, 1, 2, -1]),
        prop::collection::vec(arb_cat(), 0..4),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, on, cats, ptr, len)| Call::Logging {
            comp,
            on,
            cats,
            ptr,
            len,
        });
    let set_r = (
        arb_comp(),
        items(vr_real()),
        arb_ptr(),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, items, p0, p1, len)| {
            let (vrs, vals) = items.into_iter().unzip();
            Call::SetReal {
                comp,
                vrs,
                vals,
                ptrs: [p0, p1],
                len,
            }
        });
    let set_other = (
        arb_comp(),
        items((arb_vr(), any::<i32>())),
        arb_ptr(),
        arb_ptr(),
        arb_len(),
        0..3u8,
    )
        .prop_map(|(comp, items, p0, p1, len, k)| {
            let (vrs, vals): (Vec<u32>, Vec<i32>) = items.into_iter().unzip();
            let ptrs = [p0, p1];
            match k {
                0 => Call::SetInteger {
                    comp,
                    vrs,
                    vals,
                    ptrs,
                    len,
                },
                1 => Call::SetBoolean {
                    comp,
                    vrs,
                    vals,
                    ptrs,
                    len,
                },
                _ => {
                    let vals = vals
                        .iter()
                        .map(|v| match v.rem_euclid(3) {
                            0 => Str::Null,
                            1 => Str::Text("a string"),
                            _ => Str::NonUtf8,
                        })
                        .collect();
                    Call::SetString {
                        comp,
                        vrs,
                        vals,
                        ptrs,
                        len,
                    }
                }
            }
        });
    let outputs = table().outputs.clone();
    let get = (
        arb_comp(),
        prop_oneof![
            6 => Just(Ty::Real),
            1 => Just(Ty::Integer),
            2 => Just(Ty::Boolean),
            1 => Just(Ty::String),
        ],
        prop_oneof![
            2 => Just(outputs),
            3 => items(arb_vr()),
        ],
        arb_ptr(),
        arb_ptr(),
        arb_len(),
    )
        .prop_map(|(comp, ty, vrs, p0, p1, len)| Call::Get {
            comp,
            ty,
            vrs,
            ptrs: [p0, p1],
            len,
        });
    let get_state =
        (arb_comp(), arb_state_out()).prop_map(|(comp, out)| Call::GetState { comp, out });
    let set_state = (arb_comp(), arb_state_in()).prop_map(|(comp, st)| Call::SetState { comp, st });
    let free_state =
        (arb_comp(), arb_state_out()).prop_map(|(comp, out)| Call::FreeState { comp, out });
    let size = (
        arb_comp(),
        arb_state_in(),
        prop_oneof![8 => Just(false), 1 => Just(true)],
    )
        .prop_map(|(comp, st, null)| Call::StateSize { comp, st, null });
    let serialize = (
        arb_comp(),
        arb_state_in(),
        prop_oneof![
            6 => Just(Buf::Exact),
            2 => any::<Index>().prop_map(Buf::Short),
            1 => Just(Buf::Zero),
            1 => (1usize..64).prop_map(Buf::Long),
            1 => Just(Buf::Null),
            1 => Just(Buf::Impossible),
        ],
    )
        .prop_map(|(comp, st, buf)| Op::Serialize { comp, st, buf });
    let dir = (
        arb_comp(),
        items(arb_vr()),
        prop::collection::vec(vr_real(), 0..3),
        [arb_ptr(), arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, unknowns, knowns, ptrs, len)| {
            let (knowns, dv) = knowns.into_iter().unzip();
            Call::DirDeriv {
                comp,
                unknowns,
                knowns,
                dv,
                ptrs,
                len,
            }
        });
    let order = prop_oneof![6 => Just(1), 1 => Just(0), 1 => Just(2), 1 => any::<i32>()];
    let set_der = (
        arb_comp(),
        items((vr_real(), order.clone())),
        [arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, items, ptrs, len)| {
            let mut vrs = Vec::new();
            let mut orders = Vec::new();
            let mut vals = Vec::new();
            for ((vr, v), o) in items {
                vrs.push(vr);
                orders.push(o);
                vals.push(v);
            }
            Call::SetInputDer {
                comp,
                vrs,
                orders,
                vals,
                ptrs,
                len,
            }
        });
    let get_der = (
        arb_comp(),
        items((arb_vr(), order)),
        [arb_ptr(), arb_ptr(), arb_ptr()],
        arb_len(),
    )
        .prop_map(|(comp, items, ptrs, len)| {
            let (vrs, orders) = items.into_iter().unzip();
            Call::GetOutputDer {
                comp,
                vrs,
                orders,
                ptrs,
                len,
            }
        });
    let step = (
        arb_comp(),
        arb_tc(),
        arb_h(),
        prop::sample::select(vec![0, 1, 2]),
    )
        .prop_map(|(comp, tc, h, flag)| Op::Step { comp, tc, h, flag });
    let status = (
        arb_comp(),
        prop::sample::select(vec![
            StatusFn::Status,
            StatusFn::Real,
            StatusFn::Integer,
            StatusFn::Boolean,
            StatusFn::String,
        ]),
        prop_oneof![8 => 0..4i32, 1 => Just(-1), 1 => Just(4), 1 => any::<i32>()],
        prop_oneof![8 => Just(false), 1 => Just(true)],
    )
        .prop_map(|(comp, func, kind, null)| Call::Status {
            comp,
            func,
            kind,
            null,
        });
    Union::new_weighted(vec![
        (10, init_op().boxed()),
        (8, run_op().boxed()),
        (10, step.boxed()),
        (3, (0..POOL_LEN).prop_map(Op::Restore).boxed()),
        (
            3,
            prop::sample::select(vec![1.05, 6.0, 10.0, 100.0, 1e10, 0.01])
                .prop_map(Op::DiscardRecover)
                .boxed(),
        ),
        (3, c(setup.boxed())),
        (10, c(simple.boxed())),
        (2, c(logging.boxed())),
        (8, c(set_r.boxed())),
        (3, c(set_other.boxed())),
        (8, c(get.boxed())),
        (5, c(get_state.boxed())),
        (5, c(set_state.boxed())),
        (3, c(free_state.boxed())),
        (2, c(size.boxed())),
        (3, serialize.boxed()),
        (4, deserialize_op().boxed()),
        (2, c(dir.boxed())),
        (3, c(set_der.boxed())),
        (1, c(get_der.boxed())),
        (3, c(status.boxed())),
    ])
    .boxed()
}

// ---------------------------------------------------------------------------
// The property tests
// ---------------------------------------------------------------------------

/// The main property: random call sequences with random arguments
/// (module docs, properties 1–6).
#[test]
fn random_call_sequences() {
    let mut runner = TestRunner::new(config(cases(1, 1)));
    let strategy = (
        prop_oneof![3 => Just(false), 1 => Just(true)],
        prop::collection::vec(op(), 1..48),
    );
    let result = runner.run(&strategy, |(logging_on, ops)| {
        run_sequence(logging_on, &ops).map_err(TestCaseError::fail)
    });
    print_stats("random_call_sequences");
    if let Err(e) = result {
        panic!("{e}");
    }
}

proptest! {
    #![proptest_config(config(cases(1, 4)))]

    /// FMU states: random, corrupt, truncated and padded buffers with right
    /// and wrong sizes, restored and stepped from, in random states.
    #[test]
    fn corrupt_fmu_states(
        prefix in prop::collection::vec(
            prop_oneof![init_op(), run_op(), (0..POOL_LEN).prop_map(Op::Restore)], 0..3),
        des in prop::collection::vec(deserialize_op(), 1..4),
        tail in prop::collection::vec(op(), 0..6),
    ) {
        let mut ops = prefix;
        for d in des {
            let out = match &d {
                Op::Deserialize { out, .. } => *out,
                _ => unreachable!(),
            };
            ops.push(d);
            if let StateOut::Slot(k) = out {
                ops.push(Op::Call(Call::SetState { comp: Comp::Valid, st: StateIn::Slot(k) }));
                ops.push(Op::Step { comp: Comp::Valid, tc: Tc::Exact, h: H::Lit(1e-3), flag: 0 });
                ops.push(Op::Call(get(Ty::Real, table().outputs.clone())));
            }
        }
        ops.extend(tail);
        run_sequence(false, &ops).map_err(TestCaseError::fail)?;
    }
}

/// `fmi2Instantiate`'s arguments.
#[derive(Clone, Debug)]
struct InstArgs {
    name: Option<Vec<u8>>,
    fmu_type: i32,
    guid: Option<Vec<u8>>,
    resource: Option<Vec<u8>>,
    /// 0: NULL callbacks, 1: no logger, 2: the test logger.
    callbacks: u8,
    visible: i32,
    logging_on: i32,
}

fn c_string_bytes() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(1u8..=255, 0..24)
}

fn inst_args() -> impl Strategy<Value = InstArgs> {
    let g = guid::<Hill1D>().into_bytes();
    let name = prop_oneof![
        1 => Just(None),
        1 => prop::sample::select(vec![
            b"".to_vec(),
            b" \t ".to_vec(),
            b"muscle #3 (left) %d%s".to_vec(),
            vec![0xff, 0xfe, b'x'],
            vec![b'x'; 5000],
        ]).prop_map(Some),
        4 => Just(Some(b"abuse".to_vec())),
        1 => c_string_bytes().prop_map(Some),
    ];
    let guid = prop_oneof![
        4 => Just(Some(g.clone())),
        1 => Just(None),
        1 => prop::sample::select(vec![
            b"".to_vec(),
            b"{00000000-0000-0000-0000-000000000000}".to_vec(),
            [g.as_slice(), b" "].concat(),
            g.to_ascii_lowercase(),
            g[..g.len() - 1].to_vec(),
        ]).prop_map(Some),
        1 => c_string_bytes().prop_map(Some),
    ];
    let resource = prop_oneof![
        Just(None),
        prop::sample::select(vec![
            b"file:///".to_vec(),
            b"file:///tmp/muscle/resources".to_vec(),
            b"file:////srv/share/resources/".to_vec(),
            b"file:///C:/fmu%20dir/resources/".to_vec(),
            b"".to_vec(),
            b"http://example.invalid/".to_vec(),
        ])
        .prop_map(Some),
        c_string_bytes().prop_map(Some),
    ];
    (
        name,
        prop_oneof![6 => Just(fmi2CoSimulation), 1 => Just(fmi2ModelExchange), 1 => any::<i32>()],
        guid,
        resource,
        prop_oneof![1 => Just(0u8), 1 => Just(1u8), 4 => Just(2u8)],
        prop::sample::select(vec![0, 1, 2, -1]),
        prop::sample::select(vec![0, 1, 2, -1]),
    )
        .prop_map(
            move |(name, fmu_type, guid, resource, callbacks, visible, logging_on)| InstArgs {
                name,
                fmu_type,
                guid,
                resource,
                callbacks,
                visible,
                logging_on,
            },
        )
}

fn check_instantiate(a: &InstArgs) -> Result<(), String> {
    type M = Hill1D;
    let cs = |b: &Option<Vec<u8>>| b.as_ref().map(|b| CString::new(b.clone()).unwrap());
    let (name, g, res) = (cs(&a.name), cs(&a.guid), cs(&a.resource));
    let p = |s: &Option<CString>| s.as_ref().map_or(null(), |s| s.as_ptr());
    let book = Box::new(LogBook::default());
    let mut cb = callbacks(&book);
    if a.callbacks == 1 {
        cb.logger = None;
    }
    let cbp: *const fmi2CallbackFunctions = if a.callbacks == 0 { null() } else { &cb };
    let c = unsafe {
        api::instantiate::<M>(
            p(&name),
            a.fmu_type,
            p(&g),
            p(&res),
            cbp,
            a.visible,
            a.logging_on,
        )
    };
    let logs = book.take();
    let name_ok = a
        .name
        .as_ref()
        .is_some_and(|n| !String::from_utf8_lossy(n).trim().is_empty());
    let should = name_ok
        && a.fmu_type == fmi2CoSimulation
        && a.guid.as_deref() == Some(guid::<M>().as_bytes());
    let logger = a.callbacks == 2;
    let given_name = a.name.clone().unwrap_or_default();
    for e in &logs {
        ensure!(e.format == "%s", "format {:?}", e.format);
        ensure!(!e.message.contains('#'), "'#' in {:?}", e.message);
        ensure!(
            e.instance == given_name,
            "logged as {:?}, given {:?}",
            String::from_utf8_lossy(&e.instance),
            String::from_utf8_lossy(&given_name)
        );
    }
    if c.is_null() {
        ensure!(!should, "fmi2Instantiate refused valid arguments: {logs:?}");
        if logger {
            ensure!(
                logs.iter()
                    .any(|e| e.status == fmi2Error && e.message.starts_with("fmi2Instantiate: ")),
                "fmi2Instantiate returned NULL without an error message: {logs:?}"
            );
        }
        ensure!(logs.is_empty() || logger, "logged without a logger");
        return Ok(());
    }
    ensure!(should, "fmi2Instantiate accepted invalid arguments");
    ensure!(
        !logger || logs.iter().any(|e| e.status == fmi2OK) == (a.logging_on != 0),
        "loggingOn = {}: debug messages {logs:?}",
        a.logging_on
    );
    // A legal life.
    let r = (|| unsafe {
        let ok = |s: fmi2Status, what: &str| -> Result<(), String> {
            ensure!(s == fmi2OK, "{what}: {s:?}");
            Ok(())
        };
        ok(api::setup_experiment::<M>(c, 1, 1e-4, 0.0, 1, 1.0), "setup")?;
        ok(api::enter_initialization_mode::<M>(c), "enter")?;
        ok(api::exit_initialization_mode::<M>(c), "exit")?;
        ok(api::do_step::<M>(c, 0.0, 1e-3, 1), "step")?;
        let o = table().outputs.clone();
        let mut v = vec![0.0; o.len()];
        ok(
            api::get_real::<M>(c, o.as_ptr(), o.len(), v.as_mut_ptr()),
            "get",
        )?;
        ensure!(v.iter().all(|x| x.is_finite()), "outputs {v:?}");
        ok(api::terminate::<M>(c), "terminate")?;
        ok(api::reset::<M>(c), "reset")?;
        Ok(())
    })();
    let logs = book.take();
    unsafe { api::free_instance::<M>(c) };
    r?;
    for e in &logs {
        ensure!(e.instance == given_name, "instance name in {e:?}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(cases(1, 4)))]

    /// `fmi2Instantiate` with random arguments: NULL exactly when an argument
    /// is invalid, with an error message when there is a logger; otherwise a
    /// working instance that logs under the given name.
    #[test]
    fn instantiate_arguments(a in inst_args()) {
        check_instantiate(&a).map_err(TestCaseError::fail)?;
    }
}

// ---------------------------------------------------------------------------
// Deterministic tests
// ---------------------------------------------------------------------------

#[test]
fn free_instance_of_null_or_foreign_pointer_is_harmless() {
    unsafe {
        api::free_instance::<Hill1D>(null_mut());
        let foreign = Box::new([0u64; 8]);
        api::free_instance::<Hill1D>(&*foreign as *const [u64; 8] as *mut c_void);
        assert_eq!(*foreign, [0; 8]);
    }
    // And every function refuses them without touching anything.
    let env = Env::new();
    let mut f = Fmu::new(true);
    for comp in [Comp::Null, Comp::Foreign] {
        for call in [
            Call::Enter(comp),
            Call::Reset(comp),
            Call::Terminate(comp),
            Call::Step {
                comp,
                tc: 0.0,
                h: 1e-3,
                flag: 0,
            },
            Call::GetState {
                comp,
                out: StateOut::Slot(0),
            },
        ] {
            let o = exec(&mut f, &env, &call);
            assert_eq!(o.status, fmi2Error, "{call:?}");
            assert!(o.untouched);
            assert!(f.book.take().is_empty());
        }
    }
    assert_eq!(&f.state_bytes().unwrap(), fresh_bytes());
}

/// Prefixes that reach each state.
fn reach(state: FmiState) -> Vec<Op> {
    let t = table();
    let init = Op::Init {
        start: 0.0,
        stop: Some(10.0),
        inputs: vec![(t.activation, 0.5)],
    };
    let mut v = match state {
        FmiState::Instantiated => vec![],
        FmiState::InitializationMode => vec![
            Op::Call(Call::Setup {
                comp: Comp::Valid,
                tol_def: 0,
                tol: 0.0,
                start: 0.0,
                stop_def: 0,
                stop: 0.0,
            }),
            Op::Call(Call::Enter(Comp::Valid)),
        ],
        FmiState::StepComplete => vec![init],
        FmiState::StepFailed => vec![
            init,
            // 20 L0: beyond what the law can evaluate.
            Op::Call(set_real(vec![t.length], vec![1.0])),
            Op::Step {
                comp: Comp::Valid,
                tc: Tc::Exact,
                h: H::Lit(1e-3),
                flag: 0,
            },
        ],
        FmiState::Terminated => vec![init, Op::Call(Call::Terminate(Comp::Valid))],
        FmiState::Error => vec![Op::Restore(P_E)],
        FmiState::StepCanceled => vec![Op::Restore(P_SCA)],
        FmiState::Fatal => unreachable!(),
    };
    v.push(Op::ExpectState(state));
    v
}

const ALL_STATES: [FmiState; 7] = [
    FmiState::Instantiated,
    FmiState::InitializationMode,
    FmiState::StepComplete,
    FmiState::StepFailed,
    FmiState::StepCanceled,
    FmiState::Terminated,
    FmiState::Error,
];

#[test]
fn every_real_variable_with_every_special_value_in_every_state() {
    let t = table();
    let values = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        -1.0,
        -1e-300,
        -0.0,
        0.0,
        5e-324,
        1e-300,
        1e300,
        f64::MAX,
        0.5,
        1.0,
    ];
    for state in ALL_STATES {
        for &vr in &t.reals {
            for logging_on in [false, true] {
                // Each value from the same saved state.
                let mut ops = reach(state);
                ops.push(Op::Call(Call::GetState {
                    comp: Comp::Valid,
                    out: StateOut::Slot(1),
                }));
                for v in values {
                    ops.push(Op::Call(Call::SetState {
                        comp: Comp::Valid,
                        st: StateIn::Slot(1),
                    }));
                    ops.push(Op::ExpectState(state));
                    ops.push(Op::Call(set_real(vec![vr], vec![v])));
                    ops.push(Op::Call(set_real(vec![t.activation, vr], vec![0.5, v])));
                    ops.push(Op::Call(get(Ty::Real, t.outputs.clone())));
                    ops.push(Op::Step {
                        comp: Comp::Valid,
                        tc: Tc::Accumulated,
                        h: H::Lit(1e-3),
                        flag: 0,
                    });
                    ops.push(Op::Call(get(Ty::Real, vec![vr])));
                    if state == FmiState::InitializationMode {
                        ops.push(Op::Call(Call::Exit(Comp::Valid)));
                    }
                }
                ops.push(Op::Call(Call::Reset(Comp::Valid)));
                ops.push(Op::Init {
                    start: 0.0,
                    stop: None,
                    inputs: vec![],
                });
                ops.push(Op::Run {
                    n: 3,
                    h: 1e-3,
                    tc: Tc::Accumulated,
                    amp: 0.05,
                    act: 1.0,
                });
                if let Err(e) = run_sequence(logging_on, &ops) {
                    panic!(
                        "state {state:?}, variable {} (vr {vr}), logging {logging_on}: {e}",
                        t.vars[vr as usize].name
                    );
                }
            }
        }
    }
}

#[test]
fn every_function_in_every_state_with_legal_and_illegal_arguments() {
    // Calls of every function, each run after reaching every state; the
    // harness checks the state table, the log messages and that rejected
    // calls change nothing.
    let t = table();
    let calls: Vec<Op> = vec![
        Op::Call(Call::Setup {
            comp: Comp::Valid,
            tol_def: 1,
            tol: 1e-6,
            start: 0.0,
            stop_def: 1,
            stop: 1.0,
        }),
        Op::Call(Call::Enter(Comp::Valid)),
        Op::Call(Call::Exit(Comp::Valid)),
        Op::Call(Call::Cancel(Comp::Valid)),
        Op::Call(Call::Logging {
            comp: Comp::Valid,
            on: 1,
            cats: vec![Cat::Known(4)],
            ptr: Ptr::Ok,
            len: Len::Exact,
        }),
        Op::Call(set_real(vec![t.activation], vec![0.25])),
        Op::Call(set_real(vec![0], vec![30.0])),
        Op::Call(get(Ty::Real, t.outputs.clone())),
        Op::Call(get(Ty::Boolean, vec![0])),
        Op::Call(Call::SetBoolean {
            comp: Comp::Valid,
            vrs: vec![],
            vals: vec![],
            ptrs: [Ptr::Null; 2],
            len: Len::Exact,
        }),
        Op::Call(Call::GetState {
            comp: Comp::Valid,
            out: StateOut::Slot(0),
        }),
        Op::Call(Call::StateSize {
            comp: Comp::Valid,
            st: StateIn::Slot(0),
            null: false,
        }),
        Op::Serialize {
            comp: Comp::Valid,
            st: StateIn::Slot(0),
            buf: Buf::Exact,
        },
        Op::Deserialize {
            comp: Comp::Valid,
            src: Src::Current,
            mutation: Mutation::None,
            size: Size::Exact,
            ptr: Ptr::Ok,
            out: StateOut::Slot(1),
        },
        Op::Call(Call::SetState {
            comp: Comp::Valid,
            st: StateIn::Slot(1),
        }),
        Op::Call(Call::FreeState {
            comp: Comp::Valid,
            out: StateOut::Slot(1),
        }),
        Op::Call(Call::DirDeriv {
            comp: Comp::Valid,
            unknowns: t.outputs.clone(),
            knowns: vec![t.length],
            dv: vec![1.0],
            ptrs: [Ptr::Ok; 4],
            len: Len::Exact,
        }),
        Op::Call(Call::SetInputDer {
            comp: Comp::Valid,
            vrs: vec![t.length],
            orders: vec![1],
            vals: vec![0.01],
            ptrs: [Ptr::Ok; 3],
            len: Len::Exact,
        }),
        Op::Call(Call::GetOutputDer {
            comp: Comp::Valid,
            vrs: vec![],
            orders: vec![],
            ptrs: [Ptr::Ok; 3],
            len: Len::Exact,
        }),
        Op::Step {
            comp: Comp::Valid,
            tc: Tc::Exact,
            h: H::Lit(1e-3),
            flag: 0,
        },
        Op::Call(Call::Status {
            comp: Comp::Valid,
            func: StatusFn::Status,
            kind: fmi2DoStepStatus,
            null: false,
        }),
        Op::Call(Call::Status {
            comp: Comp::Valid,
            func: StatusFn::String,
            kind: fmi2PendingStatus,
            null: false,
        }),
        Op::Call(Call::Terminate(Comp::Valid)),
        Op::Call(Call::Terminate(Comp::Valid)),
        Op::Call(Call::Reset(Comp::Valid)),
        Op::Call(Call::Reset(Comp::Valid)),
    ];
    for state in ALL_STATES {
        for call in &calls {
            let mut ops = reach(state);
            ops.push(call.clone());
            ops.push(Op::Init {
                start: 0.0,
                stop: None,
                inputs: vec![],
            });
            ops.push(Op::Run {
                n: 2,
                h: 1e-3,
                tc: Tc::Accumulated,
                amp: 0.0,
                act: 1.0,
            });
            if let Err(e) = run_sequence(false, &ops) {
                panic!("state {state:?}, {call:?}: {e}");
            }
        }
    }
}

/// A master that keeps `t += h` and one that computes `t0 + i * h`,
/// alternating, over 25,000 steps per case: every step must be accepted.
/// Then jumps and steps past the stop time are rejected and change nothing.
#[test]
fn drifting_communication_points_are_accepted_and_jumps_rejected() {
    type M = Hill1D;
    let t = table();
    for (t0, h) in [
        (0.0, 1e-4),
        (1e3, 1e-3),
        (-50.0, 1.0 / 3.0 * 1e-2),
        (1e6, 1e-3),
    ] {
        let n = 25_000usize;
        let stop = t0 + n as f64 * h;
        let f = Fmu::new(false);
        let c = f.c;
        unsafe {
            assert_eq!(api::setup_experiment::<M>(c, 0, 0.0, t0, 1, stop), fmi2OK);
            assert_eq!(api::enter_initialization_mode::<M>(c), fmi2OK);
            assert_eq!(api::exit_initialization_mode::<M>(c), fmi2OK);
            assert_eq!(api::set_real::<M>(c, &t.activation, 1, &1.0), fmi2OK);
        }
        let mut acc = t0;
        let mut max_drift = 0.0f64;
        for i in 0..n {
            let mult = t0 + i as f64 * h;
            max_drift = max_drift.max((mult - acc).abs());
            let tc = if i % 2 == 0 { acc } else { mult };
            // The last step ends at the stop time up to the drift.
            let hh = if i + 1 == n { stop - tc } else { h };
            let s = unsafe { api::do_step::<M>(c, tc, hh, 1) };
            assert_eq!(
                s,
                fmi2OK,
                "t0 = {t0}, h = {h}, step {i}, tc = {tc}: {:?}",
                f.book.take()
            );
            acc += h;
        }
        let before = f.state_bytes().unwrap();
        let layer = layer_of(&before).unwrap();
        let tn = layer.time;
        assert!(
            (tn - stop).abs() <= 1e-9 * stop.abs().max(1.0),
            "{tn} vs {stop}"
        );
        let tol = api::time_tolerance(tn, h);
        for (tc, hh) in [
            (tn, 1.0 + 10.0 * tol), // past the stop time
            (tn - 1.0, h),          // a jump back
            (tn + 3.0 * tol, 1e-9), // a jump forward
            (tn, -h),
            (tn, 0.0),
            (f64::NAN, h),
        ] {
            f.book.clear();
            let s = unsafe { api::do_step::<M>(c, tc, hh, 1) };
            assert_eq!(s, fmi2Error, "tc = {tc}, h = {hh}");
            let logs = f.book.take();
            assert!(
                logs.iter()
                    .any(|e| e.status == fmi2Error && e.message.starts_with("fmi2DoStep: ")),
                "{logs:?}"
            );
            assert_eq!(f.state_bytes().unwrap(), before, "tc = {tc}, h = {hh}");
        }
        // Max drift seen (both clocks within the tolerance all along).
        assert!(max_drift <= 1e-9 * stop.abs().max(1.0), "{max_drift}");
    }
}

#[test]
fn repeated_terminate_and_reset_and_reset_in_every_state() {
    for state in ALL_STATES {
        let mut ops = reach(state);
        for _ in 0..3 {
            ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        }
        for _ in 0..3 {
            ops.push(Op::Call(Call::Reset(Comp::Valid)));
        }
        ops.push(Op::ExpectState(FmiState::Instantiated));
        ops.push(Op::Init {
            start: 0.5,
            stop: Some(1.0),
            inputs: vec![],
        });
        ops.push(Op::Run {
            n: 10,
            h: 1e-2,
            tc: Tc::Multiplied,
            amp: 0.1,
            act: 1.0,
        });
        ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        ops.push(Op::Call(Call::Terminate(Comp::Valid)));
        ops.push(Op::Call(Call::Reset(Comp::Valid)));
        ops.push(Op::Init {
            start: 0.5,
            stop: Some(1.0),
            inputs: vec![],
        });
        ops.push(Op::Run {
            n: 50,
            h: 1e-2,
            tc: Tc::Accumulated,
            amp: 0.1,
            act: 1.0,
        });
        ops.push(Op::Step {
            comp: Comp::Valid,
            tc: Tc::Exact,
            h: H::PastStop(1e-3),
            flag: 0,
        });
        if let Err(e) = run_sequence(true, &ops) {
            panic!("from {state:?}: {e}");
        }
    }
}

/// What [`null_env_logger`] received, call by call: (componentEnvironment
/// as an address, instance name, status, category, format, message).
type NullEnvEntry = (usize, Vec<u8>, fmi2Status, String, String, String);

static NULL_ENV_LOG: Mutex<Vec<NullEnvEntry>> = Mutex::new(Vec::new());

/// Like [`test_logger`], but it records every call whatever the environment
/// pointer (the book cannot be reached through it: it is NULL). Used only by
/// [`null_component_environment_is_passed_to_the_logger`].
unsafe extern "C" fn null_env_logger(
    env: fmi2ComponentEnvironment,
    instance_name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    message: fmi2String,
    arg: *const c_char,
) {
    let e = (
        env as usize,
        c_bytes(instance_name),
        status,
        c_text(category),
        c_text(message),
        c_text(arg),
    );
    if let Ok(mut g) = NULL_ENV_LOG.lock() {
        g.push(e);
    }
}

/// FMI 2.0 §2.1.5: componentEnvironment is the importer's pointer, passed back
/// unchanged as the logger's first argument; NULL is a legal value. With a
/// live logger and a NULL environment, `fmi2Instantiate` must work, and every
/// message (the refusal of a wrong GUID, the debug message at creation, the
/// error of an illegal call, ...) must reach the logger with that NULL
/// environment and the given instance name, without a crash.
#[test]
fn null_component_environment_is_passed_to_the_logger() {
    type M = Hill1D;
    let t = table();
    let take = || std::mem::take(&mut *NULL_ENV_LOG.lock().unwrap());
    let name = c"null env #2 %s";
    let check_all = |logs: &[NullEnvEntry]| {
        assert!(!logs.is_empty(), "the logger was not called");
        for e in logs {
            assert_eq!(e.0, 0, "componentEnvironment not passed through: {e:?}");
            assert_eq!(e.1, name.to_bytes(), "instance name: {e:?}");
            assert_eq!(e.4, "%s", "format: {e:?}");
        }
    };
    let cb = callbacks_with(null_env_logger, null_mut());
    assert!(cb.componentEnvironment.is_null() && cb.logger.is_some());
    take();

    // Refused: the reason still reaches the logger.
    let c = unsafe {
        api::instantiate::<M>(
            name.as_ptr(),
            fmi2CoSimulation,
            c"{00000000-0000-0000-0000-000000000000}".as_ptr(),
            null(),
            &cb,
            fmi2False,
            fmi2True,
        )
    };
    assert!(c.is_null());
    let logs = take();
    check_all(&logs);
    assert!(
        logs.iter().any(|e| e.2 == fmi2Error
            && e.3 == "logStatusError"
            && e.5.starts_with("fmi2Instantiate: ")
            && e.5.contains("does not match")),
        "{logs:?}"
    );

    // Accepted, logging on: a life with one illegal call in it.
    let c = unsafe {
        api::instantiate::<M>(
            name.as_ptr(),
            fmi2CoSimulation,
            t.guid.as_ptr(),
            null(),
            &cb,
            fmi2False,
            fmi2True,
        )
    };
    assert!(!c.is_null(), "{:?}", take());
    let mut out = vec![f64::NAN; t.outputs.len()];
    unsafe {
        assert_eq!(api::do_step::<M>(c, 0.0, 1e-3, fmi2True), fmi2Error);
        assert_eq!(
            api::setup_experiment::<M>(c, fmi2False, 0.0, 0.0, fmi2True, 1.0),
            fmi2OK
        );
        assert_eq!(api::enter_initialization_mode::<M>(c), fmi2OK);
        assert_eq!(api::exit_initialization_mode::<M>(c), fmi2OK);
        let (vrs, vals) = ([t.activation, t.length], [1.0, 1.05 * DEFAULT_L0]);
        assert_eq!(
            api::set_real::<M>(c, vrs.as_ptr(), 2, vals.as_ptr()),
            fmi2OK
        );
        assert_eq!(api::do_step::<M>(c, 0.0, 1e-3, fmi2True), fmi2OK);
        assert_eq!(
            api::get_real::<M>(c, t.outputs.as_ptr(), t.outputs.len(), out.as_mut_ptr()),
            fmi2OK
        );
        api::free_instance::<M>(c);
    }
    assert!(out.iter().all(|v| v.is_finite()), "{out:?}");
    let logs = take();
    check_all(&logs);
    assert!(
        logs.iter()
            .any(|e| e.2 == fmi2OK && e.5.contains("fmi2Instantiate: instance created")),
        "the debug message at creation: {logs:?}"
    );
    assert!(
        logs.iter().any(|e| e.2 == fmi2Error
            && e.5.starts_with("fmi2DoStep: ")
            && e.5.contains("not allowed in state")),
        "the illegal step's error: {logs:?}"
    );
}

/// `fmi2SetFMUstate(c, NULL)`: `fmi2Error` naming the NULL argument, and the
/// instance is unchanged — its serialized state and outputs are as before,
/// its FMI state is kept (it steps on), and it continues bit for bit like a
/// twin that never saw the call. Then the same through the harness from
/// every FMI state (which checks properties 2, 4 and 5 of the module docs).
#[test]
fn set_fmu_state_with_null_pointer_is_an_error_and_changes_nothing() {
    type M = Hill1D;
    let t = table();
    let outputs = |f: &Fmu| {
        let mut v = vec![f64::NAN; t.outputs.len()];
        let s =
            unsafe { api::get_real::<M>(f.c, t.outputs.as_ptr(), t.outputs.len(), v.as_mut_ptr()) };
        assert_eq!(s, fmi2OK);
        bits_f64(&v)
    };
    let step = |f: &Fmu, i: usize| unsafe {
        let h = 1e-3;
        let vrs = [t.activation, t.length];
        let vals = [1.0, DEFAULT_L0 * (1.0 + 0.01 * i as f64)];
        assert_eq!(
            api::set_real::<M>(f.c, vrs.as_ptr(), 2, vals.as_ptr()),
            fmi2OK
        );
        assert_eq!(api::do_step::<M>(f.c, i as f64 * h, h, fmi2True), fmi2OK);
    };
    let drive = |bad_call: bool| {
        let mut f = Fmu::new(true);
        unsafe {
            assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
            assert_eq!(api::exit_initialization_mode::<M>(f.c), fmi2OK);
            // A saved state exists (slot 0): "unchanged" must not mean "restored".
            assert_eq!(api::get_fmu_state::<M>(f.c, &mut f.slots[0]), fmi2OK);
        }
        (0..10).for_each(|i| step(&f, i));
        if bad_call {
            let before = f.state_bytes().unwrap();
            let out_before = outputs(&f);
            f.book.clear();
            assert_eq!(
                unsafe { api::set_fmu_state::<M>(f.c, null_mut()) },
                fmi2Error
            );
            let logs = f.book.take();
            assert!(
                logs.iter().any(|e| e.status == fmi2Error
                    && e.category == "logStatusError"
                    && e.message.starts_with("fmi2SetFMUstate: FMUstate is NULL")),
                "{logs:?}"
            );
            assert_eq!(f.state_bytes().unwrap(), before, "the instance changed");
            assert_eq!(outputs(&f), out_before);
        }
        (10..20).for_each(|i| step(&f, i));
        (outputs(&f), f.state_bytes().unwrap())
    };
    let (with, without) = (drive(true), drive(false));
    assert!(with == without, "the instance diverged from its twin");

    for state in ALL_STATES {
        for logging_on in [false, true] {
            let mut ops = reach(state);
            ops.push(Op::Call(Call::GetState {
                comp: Comp::Valid,
                out: StateOut::Slot(1),
            }));
            ops.push(Op::Call(Call::SetState {
                comp: Comp::Valid,
                st: StateIn::Null,
            }));
            ops.push(Op::ExpectState(state));
            ops.push(Op::Run {
                n: 3,
                h: 1e-3,
                tc: Tc::Accumulated,
                amp: 0.05,
                act: 1.0,
            });
            if let Err(e) = run_sequence(logging_on, &ops) {
                panic!("from {state:?}, logging {logging_on}: {e}");
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Regressions: bugs this harness found, fixed
// ---------------------------------------------------------------------------

/// A new instance with one Real parameter set to `value`, initialized.
fn initialized_with(name: &str, value: f64) -> Fmu {
    type M = Hill1D;
    let f = Fmu::new(false);
    let vr = table().vars.iter().position(|v| v.name == name).unwrap() as u32;
    unsafe {
        assert_eq!(api::set_real::<M>(f.c, &vr, 1, &value), fmi2OK, "{name}");
        assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
        assert_eq!(api::exit_initialization_mode::<M>(f.c), fmi2OK);
    }
    f
}

/// `fmi2GetFMUstate` + `fmi2SerializeFMUstate` + `fmi2DeSerializeFMUstate`
/// of the instance's current state: the status and the log.
fn round_trip_status(f: &Fmu) -> (fmi2Status, Vec<Entry>) {
    let mut s: fmi2FMUstate = null_mut();
    assert_eq!(unsafe { api::get_fmu_state::<Hill1D>(f.c, &mut s) }, fmi2OK);
    let bytes = f.serialize_state(s).unwrap();
    let mut d: fmi2FMUstate = null_mut();
    let st = unsafe {
        api::deserialize_fmu_state::<Hill1D>(
            f.c,
            bytes.as_ptr() as *const fmi2Byte,
            bytes.len(),
            &mut d,
        )
    };
    (st, f.book.take())
}

/// The declared `min`/`max` of every Real parameter.
fn parameter_bounds() -> Vec<(&'static str, f64, f64)> {
    table()
        .vars
        .iter()
        .filter(|v| v.causality == Causality::Parameter)
        .filter_map(|v| match v.ty {
            VarType::Real {
                min: Some(lo),
                max: Some(hi),
                ..
            } => Some((v.name, lo, hi)),
            _ => None,
        })
        .collect()
}

/// Found by `random_call_sequences` (and by `corrupt_fmu_states`): a
/// parameter that was positive and finite, hence accepted, but so small
/// that a derived value overflowed — `alpha` or `beta` = `f64::MIN_POSITIVE`
/// (the SEE stiffness alpha·beta underflowed: ±inf/NaN in the Jacobian and
/// the predictor, a step completing with a CE stretch of -9.5e289),
/// `L0` = 5e-324 (the Jacobian's 1/L0 was inf) — so the FMU's own
/// serialized state was refused by its own `fmi2DeSerializeFMUstate`. Fixed
/// by giving every parameter a closed physical range (declared as min/max in
/// the modelDescription): such values are now refused when set, with a
/// message that names the parameter and the range.
#[test]
fn out_of_range_parameters_are_refused_naming_the_range() {
    type M = Hill1D;
    let bounds = parameter_bounds();
    assert!(bounds.len() >= 16, "{bounds:?}");
    for (name, lo, hi) in bounds {
        let vr = table().vars.iter().position(|v| v.name == name).unwrap() as u32;
        let below = if lo > 0.0 { lo * 0.5 } else { lo - 1.0 };
        let above = if hi > 0.0 { hi * 2.0 } else { hi * 0.5 };
        for bad in [below, above, f64::MIN_POSITIVE, 5e-324, -5e-324] {
            if (lo..=hi).contains(&bad) {
                continue;
            }
            let f = Fmu::new(false);
            let st = unsafe { api::set_real::<M>(f.c, &vr, 1, &bad) };
            assert_eq!(st, fmi2Error, "{name} = {bad:e} accepted");
            let log = f.book.take();
            assert!(
                log.iter()
                    .any(|e| e.message.contains(name) && e.message.contains("in [")),
                "{name} = {bad:e}: {log:?}"
            );
        }
    }
}

/// Every parameter at either end of its declared range (the others at their
/// defaults): initialization succeeds; steps that stretch and shorten the
/// muscle at full activation either complete with finite outputs and
/// physical stretches (CE and SEE stretch > 0) and finite directional
/// derivatives, or are discarded with a message; the FMU's own serialized
/// state always deserializes.
#[test]
fn every_parameter_at_either_bound_steps_and_round_trips() {
    type M = Hill1D;
    let t = table();
    let vr = |n: &str| t.vars.iter().position(|v| v.name == n).unwrap() as u32;
    let (ce, see) = (vr("ce_stretch"), vr("see_stretch"));
    let mut failures = Vec::new();
    for (name, lo, hi) in parameter_bounds() {
        for value in [lo, hi] {
            let f = initialized_with(name, value);
            let mut l0 = f64::NAN;
            unsafe { api::get_real::<M>(f.c, &vr("L0"), 1, &mut l0) };
            let mut time = 0.0;
            for (k, stretch) in [1.0, 1.1, 1.2, 0.9, 1.0].into_iter().enumerate() {
                unsafe {
                    api::set_real::<M>(f.c, &t.activation, 1, &1.0);
                    api::set_real::<M>(f.c, &t.length, 1, &(stretch * l0));
                    let st = api::do_step::<M>(f.c, time, 1e-3, 0);
                    if st == fmi2OK {
                        time += 1e-3;
                        let mut out = vec![f64::NAN; t.outputs.len()];
                        api::get_real::<M>(f.c, t.outputs.as_ptr(), out.len(), out.as_mut_ptr());
                        let (mut c, mut s) = (f64::NAN, f64::NAN);
                        api::get_real::<M>(f.c, &ce, 1, &mut c);
                        api::get_real::<M>(f.c, &see, 1, &mut s);
                        let mut dv = vec![f64::NAN; t.outputs.len()];
                        let dd = api::get_directional_derivative::<M>(
                            f.c,
                            t.outputs.as_ptr(),
                            t.outputs.len(),
                            &t.activation,
                            1,
                            &1.0,
                            dv.as_mut_ptr(),
                        );
                        if !(out.iter().all(|x| x.is_finite()) && c > 0.0 && s > 0.0) {
                            failures.push(format!("{name} = {value:e}, step {k}: {out:?}"));
                        }
                        if dd == fmi2OK && !dv.iter().all(|x| x.is_finite()) {
                            failures.push(format!("{name} = {value:e}, step {k}: d/da {dv:?}"));
                        }
                    } else {
                        assert_eq!(st, fmi2Discard, "{name} = {value:e}");
                        assert!(!f.book.take().is_empty(), "discard without a message");
                        break;
                    }
                }
            }
            f.book.clear();
            let (st, log) = round_trip_status(&f);
            if st != fmi2OK {
                failures.push(format!("{name} = {value:e}: round trip {st:?} {log:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Found by `random_call_sequences` with `API_ABUSE_ROUND_TRIP=1`. A legal
/// communication step of `h = 5e-324` (finite and > 0) while the length
/// input changes completes with `fmi2OK`, but the step predictor's history
/// rate (a change divided by h) overflows to ±inf and is committed: the
/// FMU's own serialized state is then rejected by `fmi2DeSerializeFMUstate`
/// ("a non-finite value"). Inputs: defaults; length 0.06, `fmi2DoStep(0,
/// 0.01)`; length 0.05, `fmi2DoStep(0.01, 5e-324)` → `fmi2OK`; serialize →
/// deserialize. Expected: `fmi2OK` (or the step refused or discarded with
/// a message). Was: `fmi2Error` (fixed: a rate that overflows is not committed, and a step whose partial derivatives are not finite is discarded).
#[test]
fn tiny_step_leaves_a_serializable_state() {
    type M = Hill1D;
    let t = table();
    let f = Fmu::new(false);
    unsafe {
        assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
        assert_eq!(api::exit_initialization_mode::<M>(f.c), fmi2OK);
        assert_eq!(api::set_real::<M>(f.c, &t.length, 1, &0.06), fmi2OK);
        assert_eq!(api::do_step::<M>(f.c, 0.0, 0.01, 0), fmi2OK);
        assert_eq!(api::set_real::<M>(f.c, &t.length, 1, &0.05), fmi2OK);
        let s = api::do_step::<M>(f.c, 0.01, 5e-324, 0);
        f.book.clear();
        if s != fmi2OK {
            return; // refused or discarded: fine
        }
    }
    let (st, logs) = round_trip_status(&f);
    assert_eq!(st, fmi2OK, "{logs:?}");
}

/// Found by reading `do_step` while writing this harness, confirmed here. A
/// serialized state whose FMU time is NaN (crafted: the checksum is
/// recomputed) is accepted by `fmi2DeSerializeFMUstate` and
/// `fmi2SetFMUstate` (`decode_state` checks no value of the layer's part),
/// and then `fmi2DoStep` accepts any `currentCommunicationPoint`:
/// `(tc - NaN).abs() > tol` is false, so the documented "does not match the
/// FMU time" check never fires. Inputs: the pool state after 20 steps (stop
/// time 1.0) with the time field set to NaN; `fmi2DoStep(0.5, 1e-3)`.
/// Expected: the state refused at `fmi2DeSerializeFMUstate` (non-finite
/// time), or the step refused. Was: both `fmi2OK`, time NaN → 0.501 (fixed: `decode_state` checks the layer's times).
#[test]
fn deserialized_state_with_non_finite_time_is_refused() {
    type M = Hill1D;
    let f = Fmu::new(false);
    let mut b = pool()[P_RUN].clone();
    let at = state_code_offset() + 1; // the time follows the state code
    b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    fix_checksum(&mut b);
    let mut s: fmi2FMUstate = null_mut();
    unsafe {
        let d =
            api::deserialize_fmu_state::<M>(f.c, b.as_ptr() as *const fmi2Byte, b.len(), &mut s);
        if d != fmi2OK {
            return; // refused: fine
        }
        assert_eq!(api::set_fmu_state::<M>(f.c, s), fmi2OK);
        let step = api::do_step::<M>(f.c, 0.5, 1e-3, 0);
        assert_eq!(step, fmi2Error, "tc = 0.5 accepted with the FMU time NaN");
    }
}
