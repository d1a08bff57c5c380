//! The FMI API under abuse (issue 4, section 3): the property-based
//! (proptest) harness shared by `tests/api_abuse.rs` (`HillMuscle1D`) and
//! `tests/api_abuse_fe.rs` (`HillMuscleFE`). It drives the generic
//! C-signature functions `hill_muscle::fmi2::api::*::<M>` — exactly what the
//! exported `fmi2Xxx` symbols forward to — with random call sequences and
//! random arguments. Everything that differs between the two FMUs is behind
//! [`Subject`], which each test crate implements for its model and names
//! `Sub` at its root; this file is included by both with
//! `#[path = "api_abuse/harness.rs"] mod harness;`, and
//! `harness_tests!()` defines the tests at the crate root.
//!
//! # What is generated
//!
//! Sequences of up to 48 operations, each an FMI call with random arguments or
//! a macro that expands to several calls (`Init`: setup + enter + the
//! subject's cost parameters ([`Subject::INIT_INTEGERS`]) + inputs + exit;
//! `Run`: up to [`Subject::LONG_RUN`] × (set inputs + fmi2DoStep) with
//! `t += h` or `t0 + i·h` clocks, stopped at the first step that does not
//! complete; `DiscardRecover`: save, step into a discard, query the status,
//! roll back, step again; `Restore`: deserialize a stored FMU state and set
//! it, which also reaches the otherwise unreachable `error` and
//! `stepCanceled` states). Abuse covered: calls in every state (also those
//! the state table forbids); a NULL or foreign `fmi2Component`; NULL arrays
//! with `n > 0`, zero-length arrays, long arrays (up to 120 references, with
//! repeats) and impossible lengths (`usize::MAX`, which the layer must refuse
//! before reading); unknown value references (`n_vars..`, `u32::MAX`) and
//! wrong types; NaN, ±∞, ±0, negative, tiny and huge values for every Real
//! variable, in-range and out-of-range values for every Integer variable
//! ([`Subject::INTEGER_SPAN`]); NULL and unknown log categories; NULL and
//! non-UTF-8 strings; step sizes ≤ 0, NaN, ±∞, 5e-324 and 1e300;
//! communication points that drift (`t += h`, `t0 + i·h`, a few ulps, 1e-11
//! relative) or jump (NaN, ±∞, ± many times the tolerance, ± h); steps to
//! and past a defined stop time; repeated Terminate/Reset; FMU state
//! get/set/free with NULL, foreign (another instance's) and bogus pointers;
//! serialization into short, empty, NULL and oversized buffers;
//! deserialization of truncated, bit-flipped, overwritten (with and without
//! a recomputed checksum), foreign-GUID, zeroed, random and padded buffers
//! with right and wrong sizes. `fmi2FreeInstance` is called exactly once per
//! instance, at the end of each sequence (a second call or a use after it is
//! undefined behaviour on the importer's side); `fmi2FreeInstance(NULL)` and
//! of a foreign pointer are tested separately.
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
//! 3. **Expected outcomes** where the standard or the layer's and the
//!    model's documented contract fixes them (an oracle computed from the
//!    arguments, the variable table and the state before the call): a call
//!    the state table forbids, a NULL component, a NULL array with `n > 0`,
//!    an impossible length, an unknown or mistyped value reference, a
//!    variable that may not be set in this state, an Integer parameter
//!    outside its declared `min`/`max` (README "Bad input": a parameter
//!    outside its range is `fmi2Error`), a directional derivative of an
//!    output the model does not differentiate with respect to an input
//!    ([`Subject::DERIVATIVE_OUTPUTS`]) or with respect to anything but a
//!    Real input or (in initialization mode) a Real parameter, a step size that is not finite
//!    and positive, a communication point more than twice the tolerance
//!    away from the FMU's time, a step ending more than twice the tolerance past the stop
//!    time, an unknown FMU state pointer, a short serialization buffer, a
//!    truncated / bit-flipped / foreign-GUID state ... must give
//!    `fmi2Error`; an Integer parameter set within its range, a legal step
//!    whose communication point drifted by at most 1e-10 relative (far
//!    inside the layer's tolerance) and that does not pass the stop time, a
//!    legal FMU state call, an intact serialized state ... must not (a legal
//!    step may still be discarded: both models discard what they cannot
//!    compute). `fmi2ExitInitializationMode` and the first read of a
//!    computed value in initialization mode have no oracle: either model
//!    may refuse its inputs there (README "Bad input"; the FE muscle also
//!    when its equilibrium solve fails).
//! 4. **A rejected call changes nothing**: the instance is snapshotted
//!    before and after every call with a fresh `fmi2GetFMUstate` +
//!    `fmi2SerializedFMUstateSize` + `fmi2SerializeFMUstate` (+
//!    `fmi2FreeFMUstate`), which is allowed in every state but `fatal`. After
//!    every `fmi2Error` the bytes must be identical and no out-argument
//!    (value arrays, `*FMUstate`, serialization buffer, status value) may have
//!    been written. Per call, which results count as "changes nothing":
//!    - `fmi2Error` from any function. For both models every `fmi2Error` is
//!      a rejection: the layer's error state (which a model's
//!      `StepError::Error` would enter) is not reached by stepping —
//!      `HillMuscle1D`'s `do_step` never returns it, `HillMuscleFE`'s only
//!      for a model without a muscle, which `Model::new` never makes, no
//!      state the FMU serializes has and the deserializer refuses after
//!      initialization (`tests/api_abuse_fe.rs`) — and a failed
//!      `fmi2ExitInitializationMode` leaves the instance in initialization
//!      mode, unchanged (the `Model::initialize` contract).
//!    - `fmi2Discard` from any function but `fmi2DoStep` (the status
//!      functions' "not available").
//!    - any result of a function that only reads or manages FMU states:
//!      `fmi2Get{Integer,Boolean,String}` and `fmi2GetReal` and
//!      `fmi2GetDirectionalDerivative` outside initialization mode (inside it
//!      `fmi2GetReal`, `fmi2GetDirectionalDerivative` and an
//!      `fmi2GetInteger` of a computed variable may compute the initial
//!      values), `fmi2SetDebugLogging`, the status functions,
//!      `fmi2CancelStep`, `fmi2GetRealOutputDerivatives`,
//!      `fmi2Get/Free/(De)SerializeFMUstate`, `fmi2SerializedFMUstateSize`.
//!
//!    A `fmi2Discard` from `fmi2DoStep` is not a rejected call: the
//!    standard moves the instance to `stepFailed`. It must change exactly
//!    that: the model's part of the serialized state is unchanged (the
//!    `Model::do_step` contract: "the model is unchanged"), and of the
//!    layer's part only the FMI state (`stepFailed`), the time and
//!    `fmi2LastSuccessfulTime` (both the communication point of the step)
//!    and `fmi2DoStepStatus` (`fmi2Discard`).
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
//!    accepted by the layer's deserializer (and so intact serialized states
//!    by `fmi2DeSerializeFMUstate`). Each
//!    distinct serialized state is decoded once per test thread (the
//!    snapshot after a call is the one before the next).
//!
//! The snapshots read the layer's fields (FMI state, time, stop time) from
//! the serialized bytes directly (format of
//! `hill_muscle::fmi2::instance::encode_state`) to resolve communication
//! points and the oracle.
//!
//! Further tests: random `fmi2Instantiate` arguments (NULL/empty/non-UTF-8
//! names, wrong types, wrong/NULL GUIDs, odd resource locations, NULL
//! callbacks); every Real and Integer variable × every special value in
//! every state; every function in every state; 4 ×
//! [`Subject::DRIFT_STEPS`]-step drift runs (two master clocks
//! alternating); repeated Terminate/Reset from every state;
//! `fmi2FreeInstance(NULL)` and of a foreign pointer; a NULL
//! componentEnvironment with a live logger (passed back unchanged);
//! `fmi2SetFMUstate(NULL)` from every state; every parameter outside and at
//! either end of its range; the regressions of fixed bugs (below).
//!
//! # Case counts and modes
//!
//! CI mode (the default): a fixed seed (ChaCha, so the cases are the same on
//! every machine), [`Subject::CI_CASES`] random sequences for the main
//! property plus the corrupt-state and instantiation cases
//! ([`Subject::CORRUPT_CASES`], [`Subject::INSTANTIATE_CASES`]) and the
//! deterministic sequences; each test crate states its counts and wall
//! time. No failure files are persisted (`failure_persistence: None`,
//! nothing is written into the repository): a failure prints the shrunk
//! sequence, the failed property and the last calls with their statuses and
//! log messages. An unoptimized build (plain `cargo test`) runs a tenth of
//! the random cases. The CI cases are fixed by the seed, so a failure
//! reproduces exactly; other seeds and more cases are for long runs:
//!
//! - `API_ABUSE_CASES`: random sequences of the main property (the
//!   corrupt-state and instantiation properties get their subject's
//!   fraction of it);
//! - `API_ABUSE_SEED`: another fixed seed (default 0x4d75_7363_6c65);
//! - `API_ABUSE_STATS=1`: print the calls made, by function, state before
//!   and status, and how many calls the twin and the reset shadows compared;
//! - `API_ABUSE_ROUND_TRIP=0`: do not require every state the FMU serializes
//!   to deserialize (property 7 above; on by default).
//!
//! # Bugs found in `HillMuscle1D` and the layer (now regression tests at the end of this file)
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
//! These regressions run on both FMUs. Bugs of `HillMuscleFE` are listed in
//! `tests/api_abuse_fe.rs`.
//!
//! # The test logger
//!
//! As in `tests/fmi2_layer.rs`: FMI's logger is a C variadic function, which
//! stable Rust cannot define. The layer always calls it as `logger(env, name,
//! status, category, "%s", text)`, so the test logger is a non-variadic
//! `extern "C" fn` taking that one extra `const char*`, transmuted to the
//! variadic pointer type — sound on SysV x86-64 and AAPCS64 (Linux), where a
//! variadic pointer argument is passed like the next named argument.

use std::cell::RefCell;
use std::collections::HashSet;
use std::ffi::{c_char, c_void, CStr, CString};
use std::fmt;
use std::ptr::{null, null_mut};
use std::sync::{Mutex, OnceLock};

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::bytes::{fnv1a64, ByteError, ByteReader, FNV64_OFFSET};
use hill_muscle::fmi2::instance::{decode_state, LayerState};
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::rules::{is_computed, settable_in};
use hill_muscle::fmi2::state::{self as st, FmiState, StateSet};
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::{Causality, Model, ScalarVariable, VarType};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::strategy::Union;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed, TestCaseError, TestRunner};

use crate::Sub;

// ---------------------------------------------------------------------------
// The subject
// ---------------------------------------------------------------------------

/// Integer parameters by name, with their values.
pub type Integers = &'static [(&'static str, i32)];

/// What the harness needs to know about the FMU it drives beyond its
/// variable table (value references, types, causalities, start values and
/// parameter ranges all come from `Model::variables()`). Everything here is
/// either a documented difference of the model's contract or a cost
/// setting; with the `HillMuscle1D` values the harness is the one it was
/// before it was shared (same cases, same seed, the same calls in every
/// generated sequence).
pub trait Subject {
    /// The model behind the FMI functions.
    type M: Model;
    /// Sequences of the main property in CI mode (a release build).
    const CI_CASES: u32;
    /// The corrupt-state property's cases, as a fraction of the main
    /// property's.
    const CORRUPT_CASES: (u32, u32);
    /// The instantiation property's cases, as a fraction of the main
    /// property's.
    const INSTANTIATE_CASES: (u32, u32);
    /// Weighted choices of Integer parameters the `Init` macro sets after
    /// entering initialization mode (empty: it sets none and draws nothing).
    const INIT_INTEGERS: &'static [(u32, Integers)];
    /// Integer parameters set right after every other
    /// `fmi2EnterInitializationMode` of the generated sequences, of the
    /// deterministic tests and of `fmi2Instantiate`'s legal lives (a cost
    /// setting: empty for none).
    const CHEAP_INTEGERS: Integers;
    /// Integer parameters of the pool of serialized states (`Restore`,
    /// deserialization sources) and of the parameter-bound test: where the
    /// model's solver does its full work.
    const SOLVER_INTEGERS: Integers;
    /// `Some(k)`: generated Integer values are, besides any `i32`, in-range
    /// values in `[min, min + k]` and values just outside the declared
    /// range; `None`: any `i32` only.
    const INTEGER_SPAN: Option<i32>;
    /// Longest `Run` (steps).
    const LONG_RUN: usize;
    /// The lengths (× `L0`) a `DiscardRecover` jumps to in one step.
    const DISCARD_FACTORS: &'static [f64];
    /// Steps of each of the four drift runs.
    const DRIFT_STEPS: usize;
    /// Variables per sequence of the special-value test (1: one sequence
    /// per state, variable and logging setting; more: each value still
    /// starts from the same saved state).
    const SPECIAL_VALUE_VARS_PER_SEQUENCE: usize;
    /// Whether the special-value test runs every sequence with debug
    /// logging off and on (`false`: off and on in alternate states).
    const SPECIAL_VALUE_BOTH_LOGGING: bool;
    /// Calls per sequence of the every-function-in-every-state test (1: one
    /// sequence per state and call; more: each call from the same saved
    /// state).
    const FUNCTIONS_PER_SEQUENCE: usize;
    /// In-range Integer parameters above this are not set by the
    /// special-value and parameter-bound tests (cost: a 96 × 16 mesh).
    const LARGEST_INTEGER_TRIED: i32;
    /// Whether `fmi2ExitInitializationMode` may refuse in-range parameters
    /// with `fmi2Error` (and a message, staying in initialization mode).
    const INIT_MAY_FAIL: bool;
    /// The outputs `fmi2GetDirectionalDerivative` differentiates (`None`:
    /// every Real output); any other unknown with a known is `fmi2Error`.
    const DERIVATIVE_OUTPUTS: Option<&'static [&'static str]>;
}

type M = <Sub as Subject>::M;
type V = <M as Model>::Var;

// ---------------------------------------------------------------------------
// Modes
// ---------------------------------------------------------------------------

/// Sequences of the main property in CI mode; the other property tests get a
/// fraction of it (see [`cases`]).
fn ci_cases() -> u32 {
    Sub::CI_CASES
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
pub struct Entry {
    pub instance: Vec<u8>,
    pub status: fmi2Status,
    pub category: String,
    pub format: String,
    pub message: String,
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
pub struct LogBook {
    entries: Mutex<Vec<Entry>>,
}

impl LogBook {
    pub fn take(&self) -> Vec<Entry> {
        std::mem::take(&mut *self.entries.lock().unwrap())
    }

    pub fn clear(&self) {
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
    vars: Vec<ScalarVariable<V>>,
    guid: CString,
    /// The Real outputs.
    outputs: Vec<u32>,
    /// The Integer outputs.
    int_outputs: Vec<u32>,
    reals: Vec<u32>,
    /// Integer variables (parameters and outputs).
    integers: Vec<u32>,
    /// The outputs `fmi2GetDirectionalDerivative` differentiates.
    differentiated: Vec<u32>,
    activation: u32,
    length: u32,
    /// The start value of the rest length `L0`: the lengths of `Run`,
    /// `DiscardRecover` and `Init` are multiples of it.
    l0: f64,
}

fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| {
        let vars = M::variables();
        let vr_of = |name: &str| {
            vars.iter()
                .position(|v| v.name == name)
                .unwrap_or_else(|| panic!("no variable {name:?}")) as u32
        };
        let outputs_of = |real: bool| -> Vec<u32> {
            (0..vars.len() as u32)
                .filter(|&i| {
                    let v = &vars[i as usize];
                    v.causality == Causality::Output && matches!(v.ty, VarType::Real { .. }) == real
                })
                .collect()
        };
        let (outputs, int_outputs) = (outputs_of(true), outputs_of(false));
        let reals = (0..vars.len() as u32)
            .filter(|&i| matches!(vars[i as usize].ty, VarType::Real { .. }))
            .collect();
        let integers = (0..vars.len() as u32)
            .filter(|&i| matches!(vars[i as usize].ty, VarType::Integer { .. }))
            .collect();
        let differentiated = match Sub::DERIVATIVE_OUTPUTS {
            Some(names) => names.iter().map(|n| vr_of(n)).collect(),
            None => outputs.clone(),
        };
        let l0 = match vars[vr_of("L0") as usize].ty {
            VarType::Real { start: Some(s), .. } => s,
            other => panic!("L0: {other:?}"),
        };
        Table {
            activation: vr_of("activation"),
            length: vr_of("length"),
            guid: CString::new(guid::<M>()).unwrap(),
            outputs,
            int_outputs,
            reals,
            integers,
            differentiated,
            l0,
            vars,
        }
    })
}

/// The value reference of the variable called `name`.
pub fn vr_named(name: &str) -> u32 {
    table()
        .vars
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name:?}")) as u32
}

/// Integer parameters by value reference.
fn integer_refs(ints: Integers) -> Vec<(u32, i32)> {
    ints.iter().map(|&(n, v)| (vr_named(n), v)).collect()
}

fn n_vars() -> u32 {
    table().vars.len() as u32
}

fn var(vr: u32) -> Option<&'static ScalarVariable<V>> {
    table().vars.get(vr as usize)
}

fn is_real(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Real { .. }))
}

fn is_bool(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Boolean { .. }))
}

fn is_int(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Integer { .. }))
}

/// The declared range of an Integer variable (`i32::MIN..=i32::MAX` where
/// none is declared).
fn int_range(vr: u32) -> (i32, i32) {
    match var(vr).map(|v| v.ty) {
        Some(VarType::Integer { min, max, .. }) => {
            (min.unwrap_or(i32::MIN), max.unwrap_or(i32::MAX))
        }
        _ => (i32::MIN, i32::MAX),
    }
}

/// A value the model computes (an output): reading it in initialization
/// mode may compute the initial values.
fn computed(vr: u32) -> bool {
    var(vr).is_some_and(is_computed)
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

/// `fmi2SetInteger` of `ints` on `c`, which must succeed (the cost
/// parameters of [`Subject`], set in initialization mode).
fn set_integers(c: fmi2Component, ints: Integers) -> Result<(), String> {
    let (vrs, vals): (Vec<u32>, Vec<i32>) = integer_refs(ints).into_iter().unzip();
    if vrs.is_empty() {
        return Ok(());
    }
    let s = unsafe { api::set_integer::<M>(c, vrs.as_ptr(), vrs.len(), vals.as_ptr()) };
    if s == fmi2OK {
        Ok(())
    } else {
        Err(format!("fmi2SetInteger({ints:?}) = {s:?}"))
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
pub struct Fmu {
    pub c: fmi2Component,
    pub book: Box<LogBook>,
    pub slots: [fmi2FMUstate; N_SLOTS],
}

impl Fmu {
    pub fn new(logging_on: bool) -> Fmu {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let c = unsafe {
            api::instantiate::<M>(
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
        let st = unsafe { api::serialized_fmu_state_size::<M>(self.c, s, &mut n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializedFMUstateSize = {st:?}"));
        }
        let mut buf = vec![0 as fmi2Byte; n];
        let st = unsafe { api::serialize_fmu_state::<M>(self.c, s, buf.as_mut_ptr(), n) };
        if st != fmi2OK {
            return Err(format!("fmi2SerializeFMUstate = {st:?}"));
        }
        Ok(buf.into_iter().map(|b| b as u8).collect())
    }

    /// The complete dynamic state of the instance, through a fresh FMU state.
    /// Logs nothing into the book (its debug messages are dropped).
    pub fn state_bytes(&self) -> Result<Vec<u8>, String> {
        let mut s: fmi2FMUstate = null_mut();
        let st = unsafe { api::get_fmu_state::<M>(self.c, &mut s) };
        if st != fmi2OK || s.is_null() {
            return Err(format!(
                "snapshot: fmi2GetFMUstate = {st:?}: {:?}",
                self.book.take()
            ));
        }
        let bytes = self.serialize_state(s);
        let st = unsafe { api::free_fmu_state::<M>(self.c, &mut s) };
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
        unsafe { api::free_instance::<M>(self.c) };
    }
}

/// The layer's part of a serialized state (the format documented at
/// `hill_muscle::fmi2::instance::encode_state`) and the model's bytes, read
/// without the model's deserializer so that a model state that does not
/// deserialize does not hide everything else.
pub fn split_state(bytes: &[u8]) -> Result<(LayerState, &[u8]), String> {
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
    let model = r.bytes().map_err(bad)?;
    let layer = LayerState {
        fmi_state,
        time,
        start_time,
        stop_time: stop_def.then_some(stop),
        tolerance: tol_def.then_some(tol),
        last_successful_time,
        dirty,
        last_step_status,
        model_terminated,
    };
    Ok((layer, model))
}

/// The layer's part of a snapshot ([`split_state`]). Unless
/// `API_ABUSE_ROUND_TRIP=0`, every snapshot must also pass the layer's full
/// `decode_state` (what `fmi2DeSerializeFMUstate` runs; module docs,
/// property 7).
fn layer_of(bytes: &[u8]) -> Result<LayerState, String> {
    let (layer, _) = split_state(bytes)?;
    if round_trip() {
        round_trip_verdict(bytes)?;
    }
    Ok(layer)
}

/// `API_ABUSE_ROUND_TRIP=0` turns property 7 off: then not every
/// serialized state the FMU produces has to deserialize.
fn round_trip() -> bool {
    static R: OnceLock<bool> = OnceLock::new();
    *R.get_or_init(|| std::env::var("API_ABUSE_ROUND_TRIP").map_or(true, |v| v != "0"))
}

fn guid_str() -> &'static str {
    table().guid.to_str().unwrap()
}

thread_local! {
    /// The serialized states this thread has decoded (key: the state's own
    /// checksum, its last 8 bytes, and its length).
    static DECODED: RefCell<HashSet<(u64, usize)>> = RefCell::new(HashSet::new());
}

/// `Err` when bytes the FMU serialized itself do not decode.
fn round_trip_verdict(bytes: &[u8]) -> Result<(), String> {
    let key = (
        bytes
            .len()
            .checked_sub(8)
            .map_or(0, |n| u64::from_le_bytes(bytes[n..].try_into().unwrap())),
        bytes.len(),
    );
    if DECODED.with(|d| d.borrow().contains(&key)) {
        return Ok(());
    }
    if let Err(e) = decode_state::<M>(guid_str(), bytes) {
        return Err(format!(
            "the instance's serialized state does not deserialize: {e}"
        ));
    }
    DECODED.with(|d| {
        let mut d = d.borrow_mut();
        if d.len() >= 100_000 {
            d.clear();
        }
        d.insert(key);
    });
    Ok(())
}

/// Whether `fmi2DeSerializeFMUstate` must accept these bytes of a state the
/// FMU serialized itself: always with property 7 on (the snapshot checks
/// it); with it off, when they decode.
fn decodes(bytes: &[u8]) -> bool {
    round_trip() || decode_state::<M>(guid_str(), bytes).is_ok()
}

/// Recomputes the checksum of a serialized state after the header's body
/// length (so corruptions reach the body parsers).
pub fn fix_checksum(b: &mut [u8]) {
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
    28 + guid_str().len()
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
            ok(api::setup_experiment::<M>(c, 0, 0.0, 0.0, 1, 1.0));
            ok(api::enter_initialization_mode::<M>(c));
            if !Sub::SOLVER_INTEGERS.is_empty() {
                set_integers(c, Sub::SOLVER_INTEGERS).unwrap();
                // Reading an output computes the initial values, on the new
                // mesh: a state in initialization mode that deserializes
                // (tests/api_abuse_fe.rs, the mesh bug).
                let mut out = 0.0;
                ok(api::get_real::<M>(c, &t.outputs[0], 1, &mut out));
            }
            let vrs = [t.activation, t.length];
            ok(api::set_real::<M>(
                c,
                vrs.as_ptr(),
                2,
                [0.3, 0.055].as_ptr(),
            ));
            pool[P_IM] = f.state_bytes().unwrap();
            ok(api::exit_initialization_mode::<M>(c));
            pool[P_SC] = f.state_bytes().unwrap();
            ok(api::set_real::<M>(
                c,
                vrs.as_ptr(),
                2,
                [1.0, 0.052].as_ptr(),
            ));
            let mut tc = 0.0;
            for _ in 0..20 {
                ok(api::do_step::<M>(c, tc, 1e-3, 1));
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
            // A length 20 L0 (L0 = 0.05 m): beyond what the law can
            // evaluate, discarded.
            ok(api::set_real::<M>(c, &t.length, 1, &1.0));
            let s = api::do_step::<M>(c, tc, 1e-3, 1);
            assert_eq!(s, fmi2Discard, "{:?}", f.book.take());
            pool[P_SF] = f.state_bytes().unwrap();
            ok(api::terminate::<M>(c));
            pool[P_T] = f.state_bytes().unwrap();
            ok(api::reset::<M>(c));
            ok(api::setup_experiment::<M>(c, 1, 1e-6, 1e6, 1, 1e6 + 0.5));
            ok(api::enter_initialization_mode::<M>(c));
            set_integers(c, Sub::SOLVER_INTEGERS).unwrap();
            ok(api::exit_initialization_mode::<M>(c));
            ok(api::do_step::<M>(c, 1e6, 0.01, 0));
            pool[P_LATE] = f.state_bytes().unwrap();
        }
        // Every pool state restores (`Restore` reaches its state).
        for (i, b) in pool.iter().enumerate() {
            if let Err(e) = decode_state::<M>(guid_str(), b) {
                panic!("pool state {i} does not decode: {e}");
            }
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
/// holding an FMU state. Nothing the harness does changes it (the calls
/// that receive its pointers must refuse them), so each test thread makes
/// one ([`with_env`]).
struct Env {
    foreign: Box<[u64; 8]>,
    bogus: Box<[u64; 8]>,
    other: Fmu,
}

impl Env {
    fn new() -> Env {
        let mut other = Fmu::new(false);
        let s = unsafe { api::get_fmu_state::<M>(other.c, &mut other.slots[0]) };
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

thread_local! {
    static ENV: Env = Env::new();
}

/// This thread's [`Env`].
fn with_env<R>(f: impl FnOnce(&Env) -> R) -> R {
    ENV.with(f)
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
            Get {
                ty: Ty::Integer,
                vrs,
                ..
            } => pre != FmiState::InitializationMode || !vrs.iter().any(|&vr| computed(vr)),
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
    /// Setup, enter, set Integer parameters (the subject's cost
    /// parameters, [`Subject::INIT_INTEGERS`]), set inputs, exit.
    Init {
        start: f64,
        stop: Option<f64>,
        integers: Vec<(u32, i32)>,
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

fn set_integer(vrs: Vec<u32>, vals: Vec<i32>) -> Call {
    Call::SetInteger {
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
            integers,
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
            if !integers.is_empty() {
                let (vrs, vals) = integers.iter().copied().unzip();
                v.push(Op::Call(set_integer(vrs, vals)));
            }
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
                let length = t.l0 * (1.0 + amp * phase.sin());
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
                Op::Call(set_real(vec![t.length], vec![t.l0 * factor])),
                step.clone(),
                status(StatusFn::Status, fmi2DoStepStatus),
                status(StatusFn::Real, fmi2LastSuccessfulTime),
                status(StatusFn::Boolean, fmi2Terminated),
                Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(0),
                }),
                Op::Call(set_real(vec![t.length], vec![t.l0])),
                step,
            ]
        }
        // The subject's cost parameters after every entry into
        // initialization mode (nothing for an empty list).
        Op::Call(Call::Enter(Comp::Valid)) if !Sub::CHEAP_INTEGERS.is_empty() => {
            let (vrs, vals) = integer_refs(Sub::CHEAP_INTEGERS).into_iter().unzip();
            vec![op.clone(), Op::Call(set_integer(vrs, vals))]
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
            // min/max (README "Bad input"); there are no Integer inputs.
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
            // A seed must be finite (README "Bad input").
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
fn step_expect(tc: f64, h: f64, pre: &LayerState) -> Expect {
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
        // A discarded step: stepFailed at the step's start, the model as it was.
        if let (Call::Step { tc, .. }, fmi2Discard) = (&call, s) {
            let (post, post_model) = split_state(&post_bytes)?;
            let (_, pre_model) = split_state(&pre_bytes)?;
            let want = LayerState {
                fmi_state: FmiState::StepFailed,
                time: *tc,
                last_successful_time: *tc,
                last_step_status: fmi2Discard,
                ..pre
            };
            ensure!(
                post == want,
                "fmi2DoStep discarded, but the layer went from {pre:?} to {post:?}, not {want:?}"
            );
            ensure!(
                post_model == pre_model,
                "fmi2DoStep discarded, but the model changed ({} -> {} bytes)",
                pre_model.len(),
                post_model.len()
            );
            stat(|| {
                // The model's reason, without numbers.
                let why = logs
                    .iter()
                    .find_map(|e| e.message.split_once("discarded: ").map(|(_, w)| w))
                    .unwrap_or("?");
                let words: String = why
                    .split_whitespace()
                    .filter(|w| !w.contains(|c: char| c.is_ascii_digit()))
                    .take(8)
                    .collect::<Vec<_>>()
                    .join(" ");
                format!("~ discarded steps, model unchanged: {words}")
            });
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
        if !table().int_outputs.is_empty() {
            finals.push(get(Ty::Integer, table().int_outputs.clone()));
        }
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
    with_env(|env| {
        let mut h = Harness::new(logging_on);
        for op in ops {
            let is_run = matches!(op, Op::Run { .. });
            for prim in expand(op) {
                let s = h.one(env, &prim).map_err(|e| h.fail(e))?;
                // A master stops a run at the first step that does not complete.
                if is_run && matches!(prim, Op::Step { .. }) && s != fmi2OK {
                    break;
                }
            }
        }
        h.finish(env).map_err(|e| h.fail(e))
    })
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
            .prop_map(move |(a, l)| vec![(t.activation, a), (t.length, t.l0 * l)]),
        1 => prop::collection::vec(vr_real(), 1..3),
    ];
    (
        prop::sample::select(vec![0.0, 0.0, 1.0, 1e6, -2.0]),
        prop_oneof![
            2 => Just(None),
            3 => prop::sample::select(vec![1e-3, 0.05, 0.2, 10.0]).prop_map(Some),
        ],
        inputs,
        init_integers(),
    )
        .prop_map(|(start, stop, inputs, integers)| Op::Init {
            start,
            stop: stop.map(|d: f64| start + d),
            integers,
            inputs,
        })
}

/// The Integer parameters of an `Init` ([`Subject::INIT_INTEGERS`]; draws
/// nothing when there are none).
fn init_integers() -> BoxedStrategy<Vec<(u32, i32)>> {
    match Sub::INIT_INTEGERS {
        [] => Just(Vec::new()).boxed(),
        choices => Union::new_weighted(
            choices
                .iter()
                .map(|&(w, ints)| (w, Just(integer_refs(ints)).boxed()))
                .collect(),
        )
        .boxed(),
    }
}

/// A value reference and an Integer value for it: any `i32`, or with
/// [`Subject::INTEGER_SPAN`] mostly in-range (cheap) values of an Integer
/// variable and values just outside its range.
fn vr_int() -> BoxedStrategy<(u32, i32)> {
    let Some(span) = Sub::INTEGER_SPAN else {
        return (arb_vr(), any::<i32>()).boxed();
    };
    arb_vr()
        .prop_flat_map(move |vr| {
            let values = if is_int(vr) {
                let (lo, hi) = int_range(vr);
                prop_oneof![
                    4 => lo..=hi.min(lo.saturating_add(span)),
                    1 => prop::sample::select(vec![
                        lo.saturating_sub(1),
                        hi.saturating_add(1),
                        0,
                        -1,
                        i32::MIN,
                        i32::MAX,
                    ]),
                    1 => any::<i32>(),
                ]
                .boxed()
            } else {
                any::<i32>().boxed()
            };
            (Just(vr), values)
        })
        .boxed()
}

fn run_op() -> impl Strategy<Value = Op> + Clone {
    (
        prop_oneof![3 => 1usize..20, 1 => 20usize..Sub::LONG_RUN],
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
        items(vr_int()),
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
            prop::sample::select(Sub::DISCARD_FACTORS.to_vec())
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

/// Runs `test` on `cases` cases of `strategy` (what `proptest!` does, as a
/// function the test crates can call).
fn run_cases<T: Strategy>(
    cases: u32,
    strategy: &T,
    test: impl Fn(T::Value) -> Result<(), TestCaseError>,
) {
    let mut runner = TestRunner::new(config(cases));
    if let Err(e) = runner.run(strategy, test) {
        panic!("{e}\n{runner}");
    }
}

/// The main property: random call sequences with random arguments
/// (module docs, properties 1–6).
pub fn random_call_sequences() {
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

/// FMU states: random, corrupt, truncated and padded buffers with right
/// and wrong sizes, restored and stepped from, in random states.
pub fn corrupt_fmu_states() {
    let (num, den) = Sub::CORRUPT_CASES;
    let strategy = (
        prop::collection::vec(
            prop_oneof![init_op(), run_op(), (0..POOL_LEN).prop_map(Op::Restore)],
            0..3,
        ),
        prop::collection::vec(deserialize_op(), 1..4),
        prop::collection::vec(op(), 0..6),
    );
    run_cases(cases(num, den), &strategy, |(prefix, des, tail)| {
        let mut ops = prefix;
        for d in des {
            let out = match &d {
                Op::Deserialize { out, .. } => *out,
                _ => unreachable!(),
            };
            ops.push(d);
            if let StateOut::Slot(k) = out {
                ops.push(Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(k),
                }));
                ops.push(Op::Step {
                    comp: Comp::Valid,
                    tc: Tc::Exact,
                    h: H::Lit(1e-3),
                    flag: 0,
                });
                ops.push(Op::Call(get(Ty::Real, table().outputs.clone())));
            }
        }
        ops.extend(tail);
        run_sequence(false, &ops).map_err(TestCaseError::fail)
    });
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
    let g = guid::<M>().into_bytes();
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
        set_integers(c, Sub::CHEAP_INTEGERS)?;
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

/// `fmi2Instantiate` with random arguments: NULL exactly when an argument
/// is invalid, with an error message when there is a logger; otherwise a
/// working instance that logs under the given name.
pub fn instantiate_arguments() {
    let (num, den) = Sub::INSTANTIATE_CASES;
    run_cases(cases(num, den), &inst_args(), |a| {
        check_instantiate(&a).map_err(TestCaseError::fail)
    });
}

// ---------------------------------------------------------------------------
// Deterministic tests
// ---------------------------------------------------------------------------

pub fn free_instance_of_null_or_foreign_pointer_is_harmless() {
    unsafe {
        api::free_instance::<M>(null_mut());
        let foreign = Box::new([0u64; 8]);
        api::free_instance::<M>(&*foreign as *const [u64; 8] as *mut c_void);
        assert_eq!(*foreign, [0; 8]);
    }
    // And every function refuses them without touching anything.
    with_env(refused_without_an_instance);
}

fn refused_without_an_instance(env: &Env) {
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
            let o = exec(&mut f, env, &call);
            assert_eq!(o.status, fmi2Error, "{call:?}");
            assert!(o.untouched);
            assert!(f.book.take().is_empty());
        }
    }
    assert_eq!(&f.state_bytes().unwrap(), fresh_bytes());
}

/// The subject's cheap Integer parameters ([`Subject::CHEAP_INTEGERS`]), for
/// the `Init` of deterministic tests.
fn cheap() -> Vec<(u32, i32)> {
    integer_refs(Sub::CHEAP_INTEGERS)
}

/// Prefixes that reach each state.
fn reach(state: FmiState) -> Vec<Op> {
    let t = table();
    let init = Op::Init {
        start: 0.0,
        stop: Some(10.0),
        integers: cheap(),
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

/// Every state an instance can be driven into (all but `fatal`, the last).
const ALL_STATES: [FmiState; 7] = {
    let a = FmiState::ALL;
    [a[0], a[1], a[2], a[3], a[4], a[5], a[6]]
};

/// A variable of the special-value test.
#[derive(Clone, Copy)]
enum Target {
    Real(u32),
    Integer(u32),
}

/// Values of an Integer variable for the special-value test: the extremes,
/// 0, ±1, 2 and the values at and just outside either end of the declared
/// range, without in-range values above [`Subject::LARGEST_INTEGER_TRIED`].
fn special_integers(vr: u32) -> Vec<i32> {
    let (lo, hi) = int_range(vr);
    let mut v: Vec<i32> = [
        i32::MIN,
        -1,
        0,
        1,
        2,
        lo.saturating_sub(1),
        lo,
        lo.saturating_add(1),
        hi,
        hi.saturating_add(1),
        i32::MAX,
    ]
    .into_iter()
    .filter(|x| !(lo..=hi).contains(x) || *x <= Sub::LARGEST_INTEGER_TRIED)
    .collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Every Real variable × NaN, ±∞, ±0, negative, tiny, huge and ordinary
/// values, and every Integer variable × [`special_integers`], set alone and
/// together with an input, then the outputs read, a step and the variable
/// read, each value from the same saved state, in every state; then a reset
/// and a run. [`Subject::SPECIAL_VALUE_VARS_PER_SEQUENCE`] variables share
/// a sequence.
pub fn every_real_variable_with_every_special_value_in_every_state() {
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
    let targets: Vec<Target> = t
        .reals
        .iter()
        .map(|&vr| Target::Real(vr))
        .chain(t.integers.iter().map(|&vr| Target::Integer(vr)))
        .collect();
    let step = Op::Step {
        comp: Comp::Valid,
        tc: Tc::Accumulated,
        h: H::Lit(1e-3),
        flag: 0,
    };
    for (k, state) in ALL_STATES.into_iter().enumerate() {
        let logging: &[bool] = match (Sub::SPECIAL_VALUE_BOTH_LOGGING, k % 2) {
            (true, _) => &[false, true],
            (false, 0) => &[false],
            (false, _) => &[true],
        };
        for group in targets.chunks(Sub::SPECIAL_VALUE_VARS_PER_SEQUENCE) {
            for &logging_on in logging {
                // Each value from the same saved state.
                let mut ops = reach(state);
                ops.push(Op::Call(Call::GetState {
                    comp: Comp::Valid,
                    out: StateOut::Slot(1),
                }));
                let restore = [
                    Op::Call(Call::SetState {
                        comp: Comp::Valid,
                        st: StateIn::Slot(1),
                    }),
                    Op::ExpectState(state),
                ];
                for &target in group {
                    match target {
                        Target::Real(vr) => {
                            for v in values {
                                ops.extend(restore.clone());
                                ops.push(Op::Call(set_real(vec![vr], vec![v])));
                                ops.push(Op::Call(set_real(vec![t.activation, vr], vec![0.5, v])));
                                ops.push(Op::Call(get(Ty::Real, t.outputs.clone())));
                                ops.push(step.clone());
                                ops.push(Op::Call(get(Ty::Real, vec![vr])));
                                if state == FmiState::InitializationMode {
                                    ops.push(Op::Call(Call::Exit(Comp::Valid)));
                                }
                            }
                        }
                        Target::Integer(vr) => {
                            for v in special_integers(vr) {
                                ops.extend(restore.clone());
                                ops.push(Op::Call(set_integer(vec![vr], vec![v])));
                                ops.push(Op::Call(get(Ty::Integer, vec![vr])));
                                ops.push(Op::Call(get(Ty::Real, t.outputs.clone())));
                                ops.push(step.clone());
                                ops.push(Op::Call(get(Ty::Integer, t.integers.clone())));
                                if state == FmiState::InitializationMode {
                                    ops.push(Op::Call(Call::Exit(Comp::Valid)));
                                }
                            }
                        }
                    }
                }
                ops.push(Op::Call(Call::Reset(Comp::Valid)));
                ops.push(Op::Init {
                    start: 0.0,
                    stop: None,
                    integers: cheap(),
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
                    let names: Vec<String> = group
                        .iter()
                        .map(|&g| match g {
                            Target::Real(vr) | Target::Integer(vr) => {
                                format!("{} (vr {vr})", t.vars[vr as usize].name)
                            }
                        })
                        .collect();
                    panic!(
                        "state {state:?}, variable {}, logging {logging_on}: {e}",
                        names.join(", ")
                    );
                }
            }
        }
    }
}

pub fn every_function_in_every_state_with_legal_and_illegal_arguments() {
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
    // Integer variables and a subset of differentiated outputs, where the
    // model has them.
    let mut calls = calls;
    if !t.integers.is_empty() {
        let (vrs, vals): (Vec<u32>, Vec<i32>) = cheap().into_iter().unzip();
        calls.push(Op::Call(set_integer(vrs, vals)));
        calls.push(Op::Call(get(Ty::Integer, t.integers.clone())));
    }
    if t.differentiated != t.outputs {
        calls.push(Op::Call(Call::DirDeriv {
            comp: Comp::Valid,
            unknowns: t.differentiated.clone(),
            knowns: vec![t.length, t.activation],
            dv: vec![1.0, 0.5],
            ptrs: [Ptr::Ok; 4],
            len: Len::Exact,
        }));
    }
    let after = [
        Op::Init {
            start: 0.0,
            stop: None,
            integers: cheap(),
            inputs: vec![],
        },
        Op::Run {
            n: 2,
            h: 1e-3,
            tc: Tc::Accumulated,
            amp: 0.0,
            act: 1.0,
        },
    ];
    for state in ALL_STATES {
        if Sub::FUNCTIONS_PER_SEQUENCE == 1 {
            for call in &calls {
                let mut ops = reach(state);
                ops.push(call.clone());
                ops.extend(after.clone());
                if let Err(e) = run_sequence(false, &ops) {
                    panic!("state {state:?}, {call:?}: {e}");
                }
            }
            continue;
        }
        // Several calls per sequence, each from the same saved state (slot
        // 2, which no call uses).
        for group in calls.chunks(Sub::FUNCTIONS_PER_SEQUENCE) {
            let mut ops = reach(state);
            ops.push(Op::Call(Call::GetState {
                comp: Comp::Valid,
                out: StateOut::Slot(2),
            }));
            for call in group {
                ops.push(Op::Call(Call::SetState {
                    comp: Comp::Valid,
                    st: StateIn::Slot(2),
                }));
                ops.push(Op::ExpectState(state));
                ops.push(call.clone());
                ops.extend(after.clone());
            }
            if let Err(e) = run_sequence(false, &ops) {
                panic!("state {state:?}, one of {group:?}: {e}");
            }
        }
    }
}

/// A master that keeps `t += h` and one that computes `t0 + i * h`,
/// alternating, over [`Subject::DRIFT_STEPS`] steps per case: every step
/// must be accepted.
/// Then jumps and steps past the stop time are rejected and change nothing.
pub fn drifting_communication_points_are_accepted_and_jumps_rejected() {
    let t = table();
    for (t0, h) in [
        (0.0, 1e-4),
        (1e3, 1e-3),
        (-50.0, 1.0 / 3.0 * 1e-2),
        (1e6, 1e-3),
    ] {
        let n = Sub::DRIFT_STEPS;
        let stop = t0 + n as f64 * h;
        let f = Fmu::new(false);
        let c = f.c;
        unsafe {
            assert_eq!(api::setup_experiment::<M>(c, 0, 0.0, t0, 1, stop), fmi2OK);
            assert_eq!(api::enter_initialization_mode::<M>(c), fmi2OK);
            set_integers(c, Sub::CHEAP_INTEGERS).unwrap();
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

pub fn repeated_terminate_and_reset_and_reset_in_every_state() {
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
            integers: cheap(),
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
            integers: cheap(),
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
pub fn null_component_environment_is_passed_to_the_logger() {
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
        set_integers(c, Sub::CHEAP_INTEGERS).unwrap();
        assert_eq!(api::exit_initialization_mode::<M>(c), fmi2OK);
        let (vrs, vals) = ([t.activation, t.length], [1.0, 1.05 * t.l0]);
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
pub fn set_fmu_state_with_null_pointer_is_an_error_and_changes_nothing() {
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
        let vals = [1.0, t.l0 * (1.0 + 0.01 * i as f64)];
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
            set_integers(f.c, Sub::CHEAP_INTEGERS).unwrap();
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

/// A parameter's value in the parameter-bound test.
#[derive(Clone, Copy, Debug)]
enum Value {
    Real(f64),
    Integer(i32),
}

/// A new instance with [`Subject::SOLVER_INTEGERS`] and one parameter set
/// to `value`, initialized: `Ok(instance)`, or, where the subject's
/// initialization may refuse in-range parameters
/// ([`Subject::INIT_MAY_FAIL`]), `Err(message)` after checking that the
/// refusal is an `fmi2Error` with a message that left the instance in
/// initialization mode, unchanged.
fn initialized_with(name: &str, value: Value) -> Result<Fmu, (Fmu, String)> {
    let f = Fmu::new(false);
    let vr = vr_named(name);
    unsafe {
        set_integers(f.c, Sub::SOLVER_INTEGERS).unwrap();
        let st = match value {
            Value::Real(x) => api::set_real::<M>(f.c, &vr, 1, &x),
            Value::Integer(i) => api::set_integer::<M>(f.c, &vr, 1, &i),
        };
        assert_eq!(st, fmi2OK, "{name} = {value:?}");
        assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
        let before = f.state_bytes().unwrap();
        f.book.clear();
        let st = api::exit_initialization_mode::<M>(f.c);
        if st == fmi2OK {
            return Ok(f);
        }
        let log = f.book.take();
        if !Sub::INIT_MAY_FAIL {
            panic!("{name} = {value:?}: initialization {st:?} {log:?}");
        }
        assert_eq!(st, fmi2Error, "{name} = {value:?}: {log:?}");
        let why = log
            .iter()
            .find(|e| {
                e.status == fmi2Error
                    && e.message
                        .starts_with("fmi2ExitInitializationMode: initialization failed: ")
            })
            .map(|e| e.message.clone());
        let Some(why) = why else {
            panic!("{name} = {value:?}: initialization refused without a message: {log:?}");
        };
        assert!(
            f.state_bytes().unwrap() == before,
            "{name} = {value:?}: the refused initialization changed the instance"
        );
        Err((f, why))
    }
}

/// `fmi2GetFMUstate` + `fmi2SerializeFMUstate` + `fmi2DeSerializeFMUstate`
/// of the instance's current state: the status, the log and the bytes.
pub fn round_trip_status(f: &Fmu) -> (fmi2Status, Vec<Entry>, Vec<u8>) {
    let mut s: fmi2FMUstate = null_mut();
    assert_eq!(unsafe { api::get_fmu_state::<M>(f.c, &mut s) }, fmi2OK);
    let bytes = f.serialize_state(s).unwrap();
    let mut d: fmi2FMUstate = null_mut();
    let st = unsafe {
        api::deserialize_fmu_state::<M>(f.c, bytes.as_ptr() as *const fmi2Byte, bytes.len(), &mut d)
    };
    (st, f.book.take(), bytes)
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

/// The declared `min`/`max` of every Integer parameter.
fn integer_parameter_bounds() -> Vec<(&'static str, i32, i32)> {
    table()
        .vars
        .iter()
        .filter(|v| v.causality == Causality::Parameter)
        .filter_map(|v| match v.ty {
            VarType::Integer {
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
/// message that names the parameter and the range. Integer parameters
/// (`HillMuscleFE`'s mesh and fibre layout) likewise.
pub fn out_of_range_parameters_are_refused_naming_the_range() {
    let bounds = parameter_bounds();
    assert!(bounds.len() >= 16, "{bounds:?}");
    for (name, lo, hi) in bounds {
        let vr = table().vars.iter().position(|v| v.name == name).unwrap() as u32;
        let below = if lo > 0.0 { lo * 0.5 } else { lo - 1.0 };
        let above = if hi > 0.0 { hi * 2.0 } else { hi * 0.5 };
        let f = Fmu::new(false);
        for bad in [below, above, f64::MIN_POSITIVE, 5e-324, -5e-324] {
            if (lo..=hi).contains(&bad) {
                continue;
            }
            let st = unsafe { api::set_real::<M>(f.c, &vr, 1, &bad) };
            assert_eq!(st, fmi2Error, "{name} = {bad:e} accepted");
            let log = f.book.take();
            assert!(
                log.iter()
                    .any(|e| e.message.contains(name) && e.message.contains("in [")),
                "{name} = {bad:e}: {log:?}"
            );
        }
        assert_eq!(
            &f.state_bytes().unwrap(),
            fresh_bytes(),
            "{name}: refused values changed the instance"
        );
    }
    for (name, lo, hi) in integer_parameter_bounds() {
        let vr = vr_named(name);
        let f = Fmu::new(false);
        for bad in [
            lo.saturating_sub(1),
            hi.saturating_add(1),
            i32::MIN,
            i32::MAX,
        ] {
            if (lo..=hi).contains(&bad) {
                continue;
            }
            let st = unsafe { api::set_integer::<M>(f.c, &vr, 1, &bad) };
            assert_eq!(st, fmi2Error, "{name} = {bad} accepted");
            let log = f.book.take();
            assert!(
                log.iter()
                    .any(|e| e.message.contains(name)
                        && e.message.contains(&format!("in [{lo}, {hi}]"))),
                "{name} = {bad}: {log:?}"
            );
        }
        assert_eq!(
            &f.state_bytes().unwrap(),
            fresh_bytes(),
            "{name}: refused values changed the instance"
        );
    }
}

/// Every parameter at either end of its declared range (the others at their
/// defaults, with [`Subject::SOLVER_INTEGERS`]; Integer parameters up to
/// [`Subject::LARGEST_INTEGER_TRIED`]): initialization succeeds (or, with
/// [`Subject::INIT_MAY_FAIL`], is refused with a message, the instance
/// unchanged); steps that stretch and shorten the muscle at full activation
/// either complete with finite outputs and physical stretches (CE and SEE
/// stretch > 0) and finite directional derivatives, or are discarded with a
/// message; the FMU's own serialized state always deserializes.
pub fn every_parameter_at_either_bound_steps_and_round_trips() {
    let t = table();
    let vr = |n: &str| t.vars.iter().position(|v| v.name == n).unwrap() as u32;
    let (ce, see) = (vr("ce_stretch"), vr("see_stretch"));
    let mut failures = Vec::new();
    let mut refused = Vec::new();
    let mut cases: Vec<(&str, Value)> = Vec::new();
    for (name, lo, hi) in parameter_bounds() {
        cases.extend([(name, Value::Real(lo)), (name, Value::Real(hi))]);
    }
    for (name, lo, hi) in integer_parameter_bounds() {
        for v in [lo, hi] {
            if v <= Sub::LARGEST_INTEGER_TRIED {
                cases.push((name, Value::Integer(v)));
            }
        }
    }
    for (name, value) in cases {
        let f = match initialized_with(name, value) {
            Ok(f) => {
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
                            api::get_real::<M>(
                                f.c,
                                t.outputs.as_ptr(),
                                out.len(),
                                out.as_mut_ptr(),
                            );
                            let (mut c, mut s) = (f64::NAN, f64::NAN);
                            api::get_real::<M>(f.c, &ce, 1, &mut c);
                            api::get_real::<M>(f.c, &see, 1, &mut s);
                            let d = &t.differentiated;
                            let mut dv = vec![f64::NAN; d.len()];
                            let dd = api::get_directional_derivative::<M>(
                                f.c,
                                d.as_ptr(),
                                d.len(),
                                &t.activation,
                                1,
                                &1.0,
                                dv.as_mut_ptr(),
                            );
                            if !(out.iter().all(|x| x.is_finite()) && c > 0.0 && s > 0.0) {
                                failures.push(format!("{name} = {value:?}, step {k}: {out:?}"));
                            }
                            if dd == fmi2OK && !dv.iter().all(|x| x.is_finite()) {
                                failures.push(format!("{name} = {value:?}, step {k}: d/da {dv:?}"));
                            }
                        } else {
                            assert_eq!(st, fmi2Discard, "{name} = {value:?}");
                            assert!(!f.book.take().is_empty(), "discard without a message");
                            break;
                        }
                    }
                }
                f
            }
            Err((f, why)) => {
                refused.push(format!("{name} = {value:?}: {why}"));
                f
            }
        };
        f.book.clear();
        let (st, log, _) = round_trip_status(&f);
        if st != fmi2OK {
            failures.push(format!("{name} = {value:?}: round trip {st:?} {log:?}"));
        }
    }
    if !refused.is_empty() {
        eprintln!("initializations refused: {refused:#?}");
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
pub fn tiny_step_leaves_a_serializable_state() {
    let t = table();
    let f = Fmu::new(false);
    unsafe {
        assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
        set_integers(f.c, Sub::CHEAP_INTEGERS).unwrap();
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
    let (st, logs, _) = round_trip_status(&f);
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
pub fn deserialized_state_with_non_finite_time_is_refused() {
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

/// Found by a review probe (a crafted state, checksum recomputed). A
/// serialized state whose last step status is `fmi2Pending` (or any code
/// `fmi2DoStep` never leaves) was accepted, and `fmi2GetStatus
/// (fmi2DoStepStatus)` then reported an asynchronous step this FMU never
/// runs. Inputs: the pool state after 20 steps with the status byte set to
/// each of fmi2Pending and fmi2Fatal. Expected: `fmi2DeSerializeFMUstate`
/// refuses it, naming the status; the unmodified state is accepted. Was:
/// `fmi2OK` (fixed: `decode_state` accepts OK, Warning, Discard, Error).
pub fn deserialized_state_with_an_impossible_step_status_is_refused() {
    let f = Fmu::new(false);
    // After the state code: time, start, stop flag, stop, tolerance flag,
    // tolerance, last successful time, dirty (1 + 8 + 8 + 1 + 8 + 1 + 8 + 8 + 1).
    let at = state_code_offset() + 44;
    let good = pool()[P_RUN].clone();
    assert_eq!(
        good[at], fmi2OK as u8,
        "the status byte is not where expected"
    );
    for code in [fmi2OK as u8, fmi2Pending as u8, fmi2Fatal as u8] {
        let mut b = good.clone();
        b[at] = code;
        fix_checksum(&mut b);
        let mut s: fmi2FMUstate = null_mut();
        let d = unsafe {
            api::deserialize_fmu_state::<M>(f.c, b.as_ptr() as *const fmi2Byte, b.len(), &mut s)
        };
        if code == fmi2OK as u8 {
            assert_eq!(d, fmi2OK, "the unmodified state was refused");
            continue;
        }
        assert_eq!(d, fmi2Error, "last step status {code} accepted");
        assert!(s.is_null());
        let logs = f.book.take();
        assert!(
            logs.iter().any(|e| e
                .message
                .contains(&format!("invalid last step status {code}"))),
            "{logs:?}"
        );
    }
}

/// Found by the second long run (`API_ABUSE_CASES=1000000`, default seed,
/// after 2,882 s): `fmi2SetupExperiment(startTime = f64::MAX, stopTime =
/// f64::MAX)`, initialization, `fmi2DoStep(f64::MAX, 1e300)` completed with
/// `fmi2OK` and the FMU time +inf (the stop-time test `tc + h > stop + tol`
/// is false when both sides overflow), a state the FMU's own deserializer
/// refuses. Now a step whose end `tc + h` is not finite is `fmi2Error`
/// naming it, nothing changed; the largest finite step from there is not.
pub fn a_step_to_an_infinite_time_is_refused() {
    let f = Fmu::new(false);
    let t0 = f64::MAX / 2.0;
    unsafe {
        assert_eq!(
            api::setup_experiment::<M>(f.c, fmi2False, 0.0, t0, fmi2True, f64::MAX),
            fmi2OK
        );
        assert_eq!(api::enter_initialization_mode::<M>(f.c), fmi2OK);
        set_integers(f.c, Sub::CHEAP_INTEGERS).unwrap();
        assert_eq!(api::exit_initialization_mode::<M>(f.c), fmi2OK);
    }
    let before = f.state_bytes().unwrap();
    f.book.clear();
    let st = unsafe { api::do_step::<M>(f.c, t0, f64::MAX, 0) };
    let log = f.book.take();
    assert_eq!(st, fmi2Error, "{log:?}");
    assert!(
        log.iter().any(|e| e.message.contains("not a finite time")),
        "{log:?}"
    );
    assert!(f.state_bytes().unwrap() == before);
    // A finite end (f64::MAX itself) is a legal step.
    let st = unsafe { api::do_step::<M>(f.c, t0, f64::MAX - t0, 0) };
    assert!(st == fmi2OK || st == fmi2Discard, "{st:?}");
    let (rt, log, _) = round_trip_status(&f);
    assert_eq!(rt, fmi2OK, "{log:?}");
}

/// Found by the long run (`API_ABUSE_CASES=1000000`, seed 0x4d75_7363_6c65):
/// `fmi2SetupExperiment(toleranceDefined = fmi2True, tolerance = NaN)` was
/// accepted, and the NaN kept in the layer (a state the layer cannot
/// compare with itself). Now a defined tolerance that is not finite and at
/// least 0 is `fmi2Error` naming it, nothing changed, and a crafted state
/// holding one is refused; an undefined tolerance is ignored whatever its
/// value, and 0 is accepted.
pub fn setup_experiment_with_a_non_finite_tolerance_is_refused() {
    for tol in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1e-6] {
        let f = Fmu::new(false);
        let before = f.state_bytes().unwrap();
        let st = unsafe { api::setup_experiment::<M>(f.c, fmi2True, tol, 0.0, fmi2False, 0.0) };
        let log = f.book.take();
        assert_eq!(st, fmi2Error, "tolerance {tol}");
        assert!(
            log.iter().any(|e| e.message.contains("tolerance = ")),
            "{log:?}"
        );
        assert!(f.state_bytes().unwrap() == before, "tolerance {tol}");
        // The same value in a serialized state (checksum recomputed).
        let mut b = before.clone();
        let at = state_code_offset() + 1 + 8 + 8 + 1 + 8; // time, start, stop flag, stop
        assert_eq!(b[at], 0, "the layout changed");
        b[at] = 1;
        b[at + 1..at + 9].copy_from_slice(&tol.to_le_bytes());
        fix_checksum(&mut b);
        let e = decode_state::<M>(guid_str(), &b).err();
        assert!(
            e.is_some_and(|e| e.contains("tolerance")),
            "tolerance {tol} decodes"
        );
    }
    for (defined, tol) in [(fmi2False, f64::NAN), (fmi2True, 0.0), (fmi2True, 1e-6)] {
        let f = Fmu::new(false);
        let st = unsafe { api::setup_experiment::<M>(f.c, defined, tol, 0.0, fmi2False, 0.0) };
        assert_eq!(st, fmi2OK, "toleranceDefined {defined}, tolerance {tol}");
        let (rt, log, _) = round_trip_status(&f);
        assert_eq!(rt, fmi2OK, "{log:?}");
    }
}

// ---------------------------------------------------------------------------
// The tests, defined at the root of each test crate
// ---------------------------------------------------------------------------

/// `harness_tests!()` at the root of a test crate defines every test of the
/// harness there, as `#[test] fn name() { harness::name() }` (the same test
/// names in both crates); `harness_tests!(release_only)` marks them
/// `#[ignore]` in an unoptimized build.
macro_rules! harness_tests {
    () => {
        harness_tests!(@all []);
    };
    (release_only) => {
        harness_tests!(@all [cfg_attr(
            debug_assertions,
            ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
        )]);
    };
    (@all $attrs:tt) => {
        harness_tests!(
            @each $attrs
            random_call_sequences,
            corrupt_fmu_states,
            instantiate_arguments,
            free_instance_of_null_or_foreign_pointer_is_harmless,
            every_real_variable_with_every_special_value_in_every_state,
            every_function_in_every_state_with_legal_and_illegal_arguments,
            drifting_communication_points_are_accepted_and_jumps_rejected,
            repeated_terminate_and_reset_and_reset_in_every_state,
            null_component_environment_is_passed_to_the_logger,
            set_fmu_state_with_null_pointer_is_an_error_and_changes_nothing,
            out_of_range_parameters_are_refused_naming_the_range,
            every_parameter_at_either_bound_steps_and_round_trips,
            tiny_step_leaves_a_serializable_state,
            a_step_to_an_infinite_time_is_refused,
            deserialized_state_with_non_finite_time_is_refused,
            deserialized_state_with_an_impossible_step_status_is_refused,
            setup_experiment_with_a_non_finite_tolerance_is_refused
        );
    };
    (@each $attrs:tt $name:ident $(, $rest:ident)*) => {
        harness_tests!(@one $attrs $name);
        harness_tests!(@each $attrs $($rest),*);
    };
    (@each $attrs:tt) => {};
    (@one [$($attr:meta)?] $name:ident) => {
        #[test]
        $(#[$attr])?
        fn $name() {
            $crate::harness::$name()
        }
    };
}
