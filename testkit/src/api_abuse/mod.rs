//! The FMI API under abuse (issue 4, section 3): the property-based
//! (proptest) harness shared by `tests/api_abuse.rs` (`HillMuscle1D`) and
//! `tests/api_abuse_fe.rs` (`HillMuscleFE`). It drives the generic
//! C-signature functions `hill_muscle::fmi2::api::*::<M>` — exactly what the
//! exported `fmi2Xxx` symbols forward to — with random call sequences and
//! random arguments. Everything that differs between the two FMUs is behind
//! [`Subject`], which each test crate implements for its model;
//! [`install`] makes it the subject of the process (the harness reaches the
//! model's FMI functions through function pointers), and
//! [`harness_tests!(S)`](crate::harness_tests) defines the tests at the test
//! crate's root.
//!
//! # Parts
//!
//! `subject` (the [`Subject`] settings, the installed model, the modes, the
//! variable table), `pool` (instances, serialized states, the pool of
//! restorable states), `calls` (one FMI call and its executor), `ops` (the
//! generated operations and their expansion into calls), `oracle` (the
//! expected outcome of a call), `driver` (a sequence on the primary, its twin
//! and the snapshots, every property checked), `strategies` (proptest
//! strategies), and the tests: `properties`, `deterministic`, `regressions`,
//! `hostile` (well-formed hostile calls: meshes over the memory budget,
//! forged stored outputs, extreme input derivatives, time that does not
//! advance).
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
//!    outside its declared `min`/`max` (docs/reference/bad-input.md: a parameter
//!    outside its range is `fmi2Error`), a directional derivative of an
//!    output the model does not differentiate with respect to an input
//!    ([`NOT_DIFFERENTIATED`]) or with respect to anything but a
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
//!    may refuse its inputs there (docs/reference/bad-input.md; the FE muscle also
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
//! - `API_ABUSE_SEED`: another fixed seed (default 0x4d75_7363_6c65; the
//!   main property runs half its sequences from it and half from its
//!   successor, on two threads);
//! - `API_ABUSE_STATS=1`: print the calls made, by function, state before
//!   and status, and how many calls the twin and the reset shadows compared;
//! - `API_ABUSE_ROUND_TRIP=0`: do not require every state the FMU serializes
//!   to deserialize (property 7 above; on by default).
//!
//! # Bugs found in `HillMuscle1D` and the layer (now regression tests in `regressions`)
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
//! [`crate::logger`]: FMI's variadic logger, called by the layer as
//! `logger(env, name, status, category, "%s", text)`, received by a
//! non-variadic function with that one extra argument.

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

use crate::logger::{c_bytes, c_text, callbacks, callbacks_with, Entry, LogBook};

/// `return Err(format!(...))` unless `$cond`.
macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            return Err(format!($($arg)*));
        }
    };
}

mod calls;
mod deterministic;
mod driver;
mod hostile;
mod ops;
mod oracle;
mod pool;
mod properties;
mod regressions;
mod strategies;
mod subject;

pub(crate) use calls::*;
pub use deterministic::*;
pub(crate) use driver::*;
pub use hostile::*;
pub(crate) use ops::*;
pub(crate) use oracle::*;
pub use pool::*;
pub use properties::*;
pub use regressions::*;
pub(crate) use strategies::*;
pub use subject::*;

// ---------------------------------------------------------------------------
// The tests, defined at the root of each test crate
// ---------------------------------------------------------------------------

/// `harness_tests!(S)` at the root of a test crate defines every test of the
/// harness there, as `#[test] fn name() { install::<S>(); name() }` (the same
/// test names in both crates); `harness_tests!(S, release_only)` marks them
/// `#[ignore]` in an unoptimized build.
#[macro_export]
macro_rules! harness_tests {
    (@all $sub:ty, $attrs:tt) => {
        $crate::harness_tests!(
            @each $sub, $attrs,
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
            setup_experiment_with_a_non_finite_tolerance_is_refused,
            meshes_over_the_memory_budget_are_refused_at_once,
            forged_stored_outputs_are_refused,
            extreme_input_derivatives_keep_the_activation_level_in_range,
            a_step_that_does_not_advance_the_time_is_refused
        );
    };
    (@each $sub:ty, $attrs:tt, $name:ident $(, $rest:ident)*) => {
        $crate::harness_tests!(@one $sub, $attrs, $name);
        $crate::harness_tests!(@each $sub, $attrs $(, $rest)*);
    };
    (@each $sub:ty, $attrs:tt) => {};
    (@one $sub:ty, [$($attr:meta)?], $name:ident) => {
        #[test]
        $(#[$attr])?
        fn $name() {
            $crate::api_abuse::install::<$sub>();
            $crate::api_abuse::$name()
        }
    };
    ($sub:ty) => {
        $crate::harness_tests!(@all $sub, []);
    };
    ($sub:ty, release_only) => {
        $crate::harness_tests!(@all $sub, [cfg_attr(
            debug_assertions,
            ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
        )]);
    };
}
