//! The FMI API of `HillMuscleFE` under abuse (issue 4, section 3): the
//! property-based harness of `testkit::api_abuse` — what it
//! generates and the properties it checks for every call are documented
//! there — run on the finite-element muscle through
//! `hill_muscle::fmi2::api::*::<HillFE>`, exactly what its exported
//! `fmi2Xxx` symbols forward to. `tests/api_abuse.rs` runs the same harness
//! on `HillMuscle1D`.
//!
//! # What differs from `HillMuscle1D`, and how the harness handles it
//!
//! From the model's documentation (`src/fmus/hillfe.rs`,
//! docs/reference/bad-input.md) and its variable table:
//!
//! - **Integer parameters** `n_axial` ∈ [1, 96], `n_radial` ∈ [1, 16] (the
//!   mesh) and `fibre_layout` ∈ [0, 1], and the Integer output
//!   `newton_iterations`. The oracle takes their ranges from the table:
//!   an Integer parameter set outside its `min`/`max` must be `fmi2Error`,
//!   inside it must not; reading `newton_iterations` in initialization mode
//!   may compute the initial values (not a pure call there). Generated
//!   Integer values are mostly in `[min, min + 1]` and just outside the
//!   range ([`Fe::INTEGER_SPAN`]); the special-value test sets every Integer
//!   variable to i32::MIN, −1, 0, 1, 2 and both ends of its range ±1, but
//!   not to in-range values above 2 (a 96 × 16 mesh costs seconds per
//!   initialization). `axial_grading` and `radial_grading` are Real
//!   parameters (in the special-value test and the bound tests like the
//!   others).
//! - **Cost**: a new instance (and every `fmi2Reset`) builds and solves the
//!   default 16 × 3 mesh (2,592 tetrahedra, ~20 ms here), and a step on it
//!   costs ~1 ms or more. So the `Init` macro sets the smallest mesh, 1 × 1,
//!   in three of four cases and 2 × 1 in the fourth ([`Fe::INIT_INTEGERS`]);
//!   every other `fmi2EnterInitializationMode` of the random sequences, and
//!   of the deterministic tests and instantiation lives, is followed by
//!   setting 1 × 1 ([`Fe::CHEAP_INTEGERS`]), so no sequence steps the
//!   default mesh. A 1 × 1 mesh has no free node (every node is on a clamped
//!   end face): its step is one evaluation (tens of µs, one Newton
//!   iteration), which exercises the FMI layer, the activation dynamics,
//!   the CE–SEE histories and the serialized state, but not the solver. A
//!   2 × 1 mesh has one free slice: Newton, line search, substepping and
//!   the discards of a step whose substeps all fail (from ~40 µs to several
//!   ms per step), with a real factorised-tangent anchor and predictor trend
//!   in the FMU state. The pool of restorable states and the parameter-bound
//!   test use 2 × 1 ([`Fe::SOLVER_INTEGERS`]). Runs are at most 60 steps
//!   (150 for the 1D model); a `DiscardRecover` also jumps to 5 L0 (on the
//!   2 × 1 mesh the solver then fails on every substep split: a discard
//!   of the solver's, not of the law's range) and to 2 and 0.3 L0 (hard
//!   jumps completed in substeps); the special-value and every-function
//!   tests put all variables or calls of one state into one sequence (each
//!   from the same saved state) instead of one sequence each, the
//!   special-value test with debug logging on in every other state instead
//!   of both settings in each.
//! - **Discards**: `do_step` discards when the length leaves what the law
//!   can evaluate, when the end length is not finite and > 0, and when
//!   Newton fails on every substep split (up to 64); the instance is then
//!   "exactly as before the step". The harness checks that for every
//!   discarded step of both models: the model's serialized bytes are
//!   unchanged and the layer changed only to `stepFailed` at the step's
//!   communication point (`fmi2LastSuccessfulTime`), with
//!   `fmi2DoStepStatus` = `fmi2Discard`.
//! - **Initialization can fail**: `fmi2ExitInitializationMode` (and the
//!   first read of a computed value in initialization mode) may refuse
//!   in-range parameters when the isometric equilibrium solve fails
//!   ("initialization: ..."). The oracle leaves these calls open for both
//!   models; the harness checks that a refusal is an `fmi2Error` with a
//!   message that changes nothing (the instance stays in initialization
//!   mode). The parameter-bound test does not accept one
//!   ([`Fe::INIT_MAY_FAIL`] is false): every parameter at either end of
//!   its range, the others at their defaults, initializes.
//! - **Directional derivatives** of every Real output, as for
//!   `HillMuscle1D`.
//! - **A larger FMU state**: positions, element histories, the factorised
//!   tangent's anchor and the predictor's trend, and the geometry and mesh
//!   the committed muscle was built with. Every snapshot must deserialize
//!   (property 7); the corrupt states of `corrupt_fmu_states` reach these
//!   parts of the state too.
//! - **`StepError::Error`** only for a model without a muscle, which
//!   `HillFE::new` never makes (it initializes), `HillFE::serialize` never
//!   writes and `HillFE::deserialize` refuses after initialization: for
//!   every instance and every state, every `fmi2Error` is a rejection that
//!   must change nothing.
//!
//! # Case counts and time
//!
//! CI mode (the default, a release build): 200 random sequences for the
//! main property plus 50 corrupt-state and 50 instantiation cases, and the
//! deterministic tests: the every-function and special-value tests with one
//! sequence per state (7 each; the special-value sequences set all 34 Real
//! and 4 Integer variables, ~3,100 calls each, debug logging on in every
//! other state), 4 × 25,000 drift steps, the reset and NULL tests from
//! every state, 40 parameter-bound cases — ~350 sequences in all. Measured
//! with `cargo test --release --test api_abuse_fe` on the project's 2-core
//! machine: 31 s wall time (43 s CPU) with one other job running (load
//! average 2), 59 s while other jobs kept both cores busy (load average
//! 4.7). The main property costs ≈0.1 s per sequence, most of it the
//! ~20 ms of each new instance and reset (the primary, its twin, the reset
//! shadows). In an unoptimized build every test here is ignored (a new
//! instance costs ~2.4 s there). Long runs:
//!
//! ```sh
//! API_ABUSE_CASES=10000 cargo test --release --test api_abuse_fe   # ≈25 min
//! API_ABUSE_CASES=10000 API_ABUSE_SEED=7 cargo test --release --test api_abuse_fe
//! API_ABUSE_CASES=2000 API_ABUSE_STATS=1 cargo test --release --test api_abuse_fe \
//!     random_call_sequences -- --nocapture   # what was exercised
//! ```
//!
//! # Bugs found, fixed, and their regression tests (end of this file)
//!
//! In `HillMuscleFE`:
//!
//! - [`mesh_parameters_set_before_initialization_keep_the_state_serializable`]:
//!   after `n_axial` or `n_radial` was set, and before the next
//!   initialization, the FMU's own serialized state was refused by its own
//!   `fmi2DeSerializeFMUstate` ("N position values"): the deserializer
//!   built the mesh from the new parameters, the positions were the
//!   committed mesh's. The state now carries the committed geometry and
//!   mesh; [`a_state_whose_parameters_disagree_with_its_muscle_is_refused_after_initialization`]
//!   checks the other side (such a state is legal only before the next
//!   initialization).
//! - [`a_specimen_much_wider_than_long_initializes_at_rest`]: `L0` = 1e-3 m
//!   or `area` = 1 m² (both in their declared ranges) at rest were refused
//!   by `fmi2ExitInitializationMode` ("no decrease along the Newton
//!   direction"): Newton's rounding-level test was scaled by L0, not by the
//!   size of the specimen.
//! - [`a_state_without_a_muscle_is_refused`]: a crafted, well-formed state
//!   without a muscle in `stepComplete` deserialized; its first step was an
//!   `fmi2Error` into the `error` state.
//!
//! In the FMI layer, found when this model still refused the derivatives of
//! some outputs: a refused `fmi2GetDirectionalDerivative` in initialization
//! mode kept the initial values it had computed before the refusal (now
//! `a_refused_directional_derivative_in_initialization_changes_nothing` in
//! `tests/fmi2_layer.rs`, on a model that refuses one).

#![cfg(feature = "fe")]

use std::ptr::null_mut;

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::bytes::ByteReader;
use hill_muscle::fmi2::instance::decode_state;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::state::FmiState;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmus::hillfe::HillFE;
use testkit::api_abuse::{
    fix_checksum, install, round_trip_status, split_state, vr_named, Fmu, Integers, Subject,
    MESH_1X1, MESH_2X1,
};

/// `HillMuscleFE` as the harness's subject.
pub struct Fe;

impl Subject for Fe {
    type M = HillFE;
    const CI_CASES: u32 = 200;
    const CORRUPT_CASES: (u32, u32) = (1, 4);
    const INSTANTIATE_CASES: (u32, u32) = (1, 4);
    const INIT_INTEGERS: &'static [(u32, Integers)] = &[(3, MESH_1X1), (1, MESH_2X1)];
    const CHEAP_INTEGERS: Integers = MESH_1X1;
    const SOLVER_INTEGERS: Integers = MESH_2X1;
    const INTEGER_SPAN: Option<i32> = Some(1);
    const LONG_RUN: usize = 60;
    /// Also 5 L0 (in the law's range; on the 2 × 1 mesh the solver fails
    /// on every substep split: a discard of the solver's), 2 L0 and 0.3 L0
    /// (hard jumps it completes in substeps).
    const DISCARD_FACTORS: &'static [f64] = &[1.05, 6.0, 10.0, 100.0, 1e10, 0.01, 5.0, 2.0, 0.3];
    const DRIFT_STEPS: usize = 25_000;
    const SPECIAL_VALUE_VARS_PER_SEQUENCE: usize = usize::MAX;
    const SPECIAL_VALUE_BOTH_LOGGING: bool = false;
    const FUNCTIONS_PER_SEQUENCE: usize = usize::MAX;
    const LARGEST_INTEGER_TRIED: i32 = 2;
    const INIT_MAY_FAIL: bool = false;
}

/// Offset of `n_axial` (followed by `n_radial`, both i32) in a serialized
/// `HillMuscleFE` state: the model's bytes start with the law's parameters
/// (f64s), `L0`, `area`, `activation_dynamics`, `initial_activation`
/// (`HillFE::serialize`).
fn mesh_offset(bytes: &[u8]) -> Option<usize> {
    let (_, model) = split_state(bytes).ok()?;
    let start = model.as_ptr() as usize - bytes.as_ptr() as usize;
    let mut input = model;
    let mut r = ByteReader::new(&mut input);
    r.f64s().ok()?;
    r.f64().ok()?;
    r.f64().ok()?;
    r.bool().ok()?;
    r.f64().ok()?;
    let at = start + model.len() - r.remaining();
    (at + 8 <= bytes.len()).then_some(at)
}

testkit::harness_tests!(Fe, release_only);

// ---------------------------------------------------------------------------
// Regression tests of the bugs this harness found (module docs)
// ---------------------------------------------------------------------------

/// Found by `random_call_sequences` (every `Init`, which sets the mesh in
/// initialization mode, produced it). Sequence: `fmi2Instantiate`;
/// `fmi2SetInteger(n_axial = 2)` (instantiated, or in initialization mode);
/// `fmi2GetFMUstate`, `fmi2SerializeFMUstate`, `fmi2DeSerializeFMUstate`
/// of those bytes: must be `fmi2OK` (was "1887 position values").
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
)]
fn mesh_parameters_set_before_initialization_keep_the_state_serializable() {
    install::<Fe>();
    for in_initialization_mode in [false, true] {
        let f = Fmu::new(false);
        unsafe {
            if in_initialization_mode {
                assert_eq!(api::enter_initialization_mode::<HillFE>(f.c), fmi2OK);
            }
            let vr = vr_named("n_axial");
            assert_eq!(api::set_integer::<HillFE>(f.c, &vr, 1, &2), fmi2OK);
        }
        let (st, log, _) = round_trip_status(&f);
        assert_eq!(
            st,
            fmi2OK,
            "initialization mode {in_initialization_mode}: {:?}",
            log.iter().map(|e| &e.message).collect::<Vec<_>>()
        );
    }
}

/// The other side of the fix above: once initialized, the mesh parameters
/// are fixed, so a state in `stepComplete` whose `n_axial` differs from the
/// mesh of its muscle (1 × 1 in the parameters of a 2 × 1 state, checksum
/// fixed) was not written by the FMU and is refused, with the instance
/// unchanged.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
)]
fn a_state_whose_parameters_disagree_with_its_muscle_is_refused_after_initialization() {
    install::<Fe>();
    let f = Fmu::new(false);
    unsafe {
        assert_eq!(api::enter_initialization_mode::<HillFE>(f.c), fmi2OK);
        let vr = vr_named("n_axial");
        assert_eq!(api::set_integer::<HillFE>(f.c, &vr, 1, &2), fmi2OK);
        assert_eq!(api::exit_initialization_mode::<HillFE>(f.c), fmi2OK);
    }
    let (st, log, bytes) = round_trip_status(&f);
    assert_eq!(st, fmi2OK, "{log:?}");
    let at = mesh_offset(&bytes).unwrap();
    assert_eq!(bytes[at..at + 4], 2i32.to_le_bytes(), "the layout changed");
    let mut corrupt = bytes.clone();
    corrupt[at..at + 4].copy_from_slice(&1i32.to_le_bytes());
    fix_checksum(&mut corrupt);
    let (layer, _) = split_state(&corrupt).unwrap();
    assert_eq!(layer.fmi_state, FmiState::StepComplete);
    let e = decode_state::<HillFE>(&guid::<HillFE>(), &corrupt)
        .err()
        .expect("a state whose mesh parameters are not its muscle's decodes");
    assert!(e.contains("no initialized state"), "{e}");
    let before = f.state_bytes().unwrap();
    let mut s: fmi2FMUstate = null_mut();
    let d = unsafe {
        api::deserialize_fmu_state::<HillFE>(
            f.c,
            corrupt.as_ptr() as *const fmi2Byte,
            corrupt.len(),
            &mut s,
        )
    };
    assert_eq!(d, fmi2Error);
    assert!(s.is_null());
    assert!(f.state_bytes().unwrap() == before);
}

/// Found by `every_parameter_at_either_bound_steps_and_round_trips`: on the
/// default 16 × 3 mesh, `L0` = 1e-3 m or `area` = 1 m² (both declared
/// valid), `length` = `L0` and activation 0 — the specimen at rest, whose
/// reference configuration is the exact equilibrium — was refused by
/// `fmi2ExitInitializationMode`. Now it initializes, and the force at rest
/// is round-off: below 1e-12 of the force scale sigma0 · area.
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
)]
fn a_specimen_much_wider_than_long_initializes_at_rest() {
    install::<Fe>();
    for (name, value) in [("L0", 1e-3), ("area", 1.0)] {
        let f = Fmu::new(false);
        let vr = vr_named(name);
        let [force, sigma0, area] = ["force", "sigma0", "area"].map(vr_named);
        let (mut out, mut s0, mut a) = (f64::NAN, f64::NAN, f64::NAN);
        let st = unsafe {
            assert_eq!(api::set_real::<HillFE>(f.c, &vr, 1, &value), fmi2OK);
            assert_eq!(api::enter_initialization_mode::<HillFE>(f.c), fmi2OK);
            let st = api::exit_initialization_mode::<HillFE>(f.c);
            api::get_real::<HillFE>(f.c, &force, 1, &mut out);
            api::get_real::<HillFE>(f.c, &sigma0, 1, &mut s0);
            api::get_real::<HillFE>(f.c, &area, 1, &mut a);
            st
        };
        let log: Vec<String> = f.book.take().into_iter().map(|e| e.message).collect();
        assert_eq!(st, fmi2OK, "{name} = {value}: {log:?}");
        assert!(
            out.abs() < 1e-12 * s0 * a,
            "{name} = {value}: force {out} N at rest (scale {} N)",
            s0 * a
        );
    }
}

/// The bytes of a serialized state with its model's bytes replaced by
/// `model` (length prefixes and checksum made consistent).
fn with_model_bytes(bytes: &[u8], model: &[u8]) -> Vec<u8> {
    let (_, old) = split_state(bytes).unwrap();
    let start = old.as_ptr() as usize - bytes.as_ptr() as usize;
    let mut b = bytes[..start].to_vec();
    b[start - 8..start].copy_from_slice(&(model.len() as u64).to_le_bytes());
    b.extend_from_slice(model);
    b.extend_from_slice(&[0; 8]);
    let body = (b.len() - 28) as u64;
    b[12..20].copy_from_slice(&body.to_le_bytes());
    fix_checksum(&mut b);
    b
}

/// Found while writing this harness (reading `HillFE::deserialize`); the
/// random mutations do not reach it (they would have to shorten the model's
/// bytes consistently). A `stepComplete` state with its model bytes cut
/// after the "has a muscle" flag, set to false (length prefixes and
/// checksum recomputed: well-formed, but never written by
/// `HillFE::serialize`): `fmi2DeSerializeFMUstate` must refuse it (it used
/// to accept it, and the first step was an `fmi2Error` into the `error`
/// state).
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "unoptimized, a new HillMuscleFE instance costs seconds: cargo test --release"
)]
fn a_state_without_a_muscle_is_refused() {
    install::<Fe>();
    let f = Fmu::new(false);
    let bytes = unsafe {
        assert_eq!(api::enter_initialization_mode::<HillFE>(f.c), fmi2OK);
        assert_eq!(api::exit_initialization_mode::<HillFE>(f.c), fmi2OK);
        f.state_bytes().unwrap()
    };
    let (_, model) = split_state(&bytes).unwrap();
    // HillFE::serialize: the parameters, L0, area, activation_dynamics,
    // initial_activation, n_axial, n_radial, axial_grading, radial_grading, fibre_layout,
    // adaptive_substeps, substep_tolerance, command, length, the rates, the level, the decay, the outputs, the
    // Newton iterations; then the flag.
    let mut input = model;
    let mut r = ByteReader::new(&mut input);
    let flag_at = (|| -> Result<usize, hill_muscle::fmi2::bytes::ByteError> {
        r.f64s()?;
        r.f64()?;
        r.f64()?;
        r.bool()?;
        r.f64()?;
        r.i32()?;
        r.i32()?;
        r.f64()?;
        r.f64()?;
        r.i32()?;
        r.bool()?;
        r.f64()?;
        r.f64()?;
        r.f64s()?;
        r.f64()?;
        r.f64()?;
        r.f64()?;
        r.f64s()?;
        r.f64s()?;
        r.i32()?;
        Ok(model.len() - r.remaining())
    })()
    .unwrap();
    assert_eq!(model[flag_at], 1, "the serialized layout changed");
    let mut crafted = model[..flag_at].to_vec();
    crafted.push(0);
    let b = with_model_bytes(&bytes, &crafted);
    let mut s: fmi2FMUstate = null_mut();
    let d = unsafe {
        api::deserialize_fmu_state::<HillFE>(f.c, b.as_ptr() as *const fmi2Byte, b.len(), &mut s)
    };
    let log: Vec<String> = f.book.take().into_iter().map(|e| e.message).collect();
    assert_eq!(d, fmi2Error, "{log:?}");
    assert!(s.is_null());
    assert!(
        log.iter().any(|m| m.contains("no initialized state")),
        "{log:?}"
    );
}
