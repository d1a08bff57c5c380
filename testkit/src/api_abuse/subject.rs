//! The subject: what differs between the FMUs the harness drives, installed
//! once per test binary; the case counts of the modes; the variable table.

use super::*;

// ---------------------------------------------------------------------------
// The subject
// ---------------------------------------------------------------------------

/// Integer parameters by name, with their values.
pub type Integers = &'static [(&'static str, i32)];

/// An FE subject's smallest mesh: no free node (every node on a clamped
/// end face), so a step is one evaluation.
pub const MESH_1X1: Integers = &[("n_axial", 1), ("n_radial", 1)];
/// An FE subject's smallest mesh with free nodes (one interior slice):
/// Newton, line search and substeps.
pub const MESH_2X1: Integers = &[("n_axial", 2), ("n_radial", 1)];
/// The Real output no model differentiates (docs/reference/conventions.md:
/// itself d force / d length); `fmi2GetDirectionalDerivative` of any other Real
/// output with respect to a Real input is defined.
pub const NOT_DIFFERENTIATED: &str = "stiffness";

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
    /// The lengths (× the `length` input's start) a `DiscardRecover` jumps
    /// to in one step.
    const DISCARD_FACTORS: &'static [f64];
    /// Steps of each of the four drift runs.
    const DRIFT_STEPS: usize;
    /// The length's input derivative (m/s) set before the jump to the
    /// longest length in the prefix reaching `stepFailed` (0: none). A unit
    /// with a compliant tendon may complete that jump (the tendon takes the
    /// length); a rate that ends the step at a negative path it cannot.
    const FAILING_LENGTH_RATE: f64 = 0.0;
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
}

/// The model's FMI functions (`hill_muscle::fmi2::api::*::<M>`, exactly
/// what the exported `fmi2Xxx` symbols forward to) as function pointers, so
/// that the harness is written once for any installed [`Subject`].
macro_rules! abi {
    ($($name:ident($($arg:ty),*) $(-> $ret:ty)?;)*) => {
        pub(crate) struct Abi {
            $(pub(crate) $name: unsafe fn($($arg),*) $(-> $ret)?,)*
        }

        impl Abi {
            fn of<M: Model>() -> Abi {
                Abi { $($name: api::$name::<M>,)* }
            }
        }
    };
}

abi! {
    instantiate(fmi2String, fmi2Type, fmi2String, fmi2String, *const fmi2CallbackFunctions, fmi2Boolean, fmi2Boolean) -> fmi2Component;
    free_instance(fmi2Component);
    set_debug_logging(fmi2Component, fmi2Boolean, usize, *const fmi2String) -> fmi2Status;
    setup_experiment(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real) -> fmi2Status;
    enter_initialization_mode(fmi2Component) -> fmi2Status;
    exit_initialization_mode(fmi2Component) -> fmi2Status;
    terminate(fmi2Component) -> fmi2Status;
    reset(fmi2Component) -> fmi2Status;
    get_real(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Real) -> fmi2Status;
    get_integer(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Integer) -> fmi2Status;
    get_boolean(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Boolean) -> fmi2Status;
    get_string(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2String) -> fmi2Status;
    set_real(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Real) -> fmi2Status;
    set_integer(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Integer) -> fmi2Status;
    set_boolean(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Boolean) -> fmi2Status;
    set_string(fmi2Component, *const fmi2ValueReference, usize, *const fmi2String) -> fmi2Status;
    get_fmu_state(fmi2Component, *mut fmi2FMUstate) -> fmi2Status;
    set_fmu_state(fmi2Component, fmi2FMUstate) -> fmi2Status;
    free_fmu_state(fmi2Component, *mut fmi2FMUstate) -> fmi2Status;
    serialized_fmu_state_size(fmi2Component, fmi2FMUstate, *mut usize) -> fmi2Status;
    serialize_fmu_state(fmi2Component, fmi2FMUstate, *mut fmi2Byte, usize) -> fmi2Status;
    deserialize_fmu_state(fmi2Component, *const fmi2Byte, usize, *mut fmi2FMUstate) -> fmi2Status;
    get_directional_derivative(fmi2Component, *const fmi2ValueReference, usize, *const fmi2ValueReference, usize, *const fmi2Real, *mut fmi2Real) -> fmi2Status;
    set_real_input_derivatives(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Integer, *const fmi2Real) -> fmi2Status;
    get_real_output_derivatives(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Integer, *mut fmi2Real) -> fmi2Status;
    do_step(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean) -> fmi2Status;
    cancel_step(fmi2Component) -> fmi2Status;
    get_status(fmi2Component, fmi2StatusKind, *mut fmi2Status) -> fmi2Status;
    get_real_status(fmi2Component, fmi2StatusKind, *mut fmi2Real) -> fmi2Status;
    get_integer_status(fmi2Component, fmi2StatusKind, *mut fmi2Integer) -> fmi2Status;
    get_boolean_status(fmi2Component, fmi2StatusKind, *mut fmi2Boolean) -> fmi2Status;
    get_string_status(fmi2Component, fmi2StatusKind, *mut fmi2String) -> fmi2Status;
}

/// [`Subject`]'s settings as values.
pub(crate) struct Profile {
    pub(crate) ci_cases: u32,
    pub(crate) corrupt_cases: (u32, u32),
    pub(crate) instantiate_cases: (u32, u32),
    pub(crate) init_integers: &'static [(u32, Integers)],
    pub(crate) cheap_integers: Integers,
    pub(crate) solver_integers: Integers,
    pub(crate) integer_span: Option<i32>,
    pub(crate) long_run: usize,
    pub(crate) discard_factors: &'static [f64],
    pub(crate) drift_steps: usize,
    pub(crate) failing_length_rate: f64,
    pub(crate) special_value_vars_per_sequence: usize,
    pub(crate) special_value_both_logging: bool,
    pub(crate) functions_per_sequence: usize,
    pub(crate) largest_integer_tried: i32,
    pub(crate) init_may_fail: bool,
}

/// The installed subject: its settings, its model's FMI functions, variable
/// table (with the model's variable handles dropped), GUID and state
/// decoder.
pub(crate) struct Installed {
    subject: &'static str,
    pub(crate) profile: Profile,
    pub(crate) abi: Abi,
    pub(crate) variables: fn() -> Vec<ScalarVariable<()>>,
    pub(crate) guid: fn() -> String,
    pub(crate) decode: fn(&str, &[u8]) -> Result<(), String>,
}

impl Installed {
    fn of<S: Subject>() -> Installed {
        Installed {
            subject: std::any::type_name::<S>(),
            profile: Profile {
                ci_cases: S::CI_CASES,
                corrupt_cases: S::CORRUPT_CASES,
                instantiate_cases: S::INSTANTIATE_CASES,
                init_integers: S::INIT_INTEGERS,
                cheap_integers: S::CHEAP_INTEGERS,
                solver_integers: S::SOLVER_INTEGERS,
                integer_span: S::INTEGER_SPAN,
                long_run: S::LONG_RUN,
                discard_factors: S::DISCARD_FACTORS,
                drift_steps: S::DRIFT_STEPS,
                failing_length_rate: S::FAILING_LENGTH_RATE,
                special_value_vars_per_sequence: S::SPECIAL_VALUE_VARS_PER_SEQUENCE,
                special_value_both_logging: S::SPECIAL_VALUE_BOTH_LOGGING,
                functions_per_sequence: S::FUNCTIONS_PER_SEQUENCE,
                largest_integer_tried: S::LARGEST_INTEGER_TRIED,
                init_may_fail: S::INIT_MAY_FAIL,
            },
            abi: Abi::of::<S::M>(),
            variables: || {
                S::M::variables()
                    .into_iter()
                    .map(|v| ScalarVariable {
                        name: v.name,
                        description: v.description,
                        causality: v.causality,
                        variability: v.variability,
                        initial: v.initial,
                        ty: v.ty,
                        depends_on: v.depends_on,
                        id: (),
                    })
                    .collect()
            },
            guid: guid::<S::M>,
            decode: |g, bytes| decode_state::<S::M>(g, bytes).map(|_| ()),
        }
    }
}

static INSTALLED: OnceLock<Installed> = OnceLock::new();

/// Makes `S` the subject of every harness function in this process (a test
/// binary drives one FMU); idempotent. [`harness_tests!`](crate::harness_tests)
/// calls it first in every test; a test using [`Fmu`] or [`vr_named`]
/// directly calls it itself.
pub fn install<S: Subject>() {
    let i = INSTALLED.get_or_init(Installed::of::<S>);
    assert_eq!(
        i.subject,
        std::any::type_name::<S>(),
        "one API-abuse subject per process"
    );
}

pub(crate) fn installed() -> &'static Installed {
    INSTALLED
        .get()
        .expect("no subject: call testkit::api_abuse::install::<S>() first")
}

pub(crate) fn abi() -> &'static Abi {
    &installed().abi
}

pub(crate) fn profile() -> &'static Profile {
    &installed().profile
}

// ---------------------------------------------------------------------------
// Modes
// ---------------------------------------------------------------------------

/// Sequences of the main property in CI mode; the other property tests get a
/// fraction of it (see [`cases`]).
pub(crate) fn ci_cases() -> u32 {
    profile().ci_cases
}

/// `API_ABUSE_CASES` or the CI count (a tenth of it in an unoptimized
/// build, so that a plain `cargo test` stays quick), scaled by `num / den`.
pub(crate) fn cases(num: u32, den: u32) -> u32 {
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

pub(crate) fn config(cases: u32) -> Config {
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
// The variable table
// ---------------------------------------------------------------------------

pub(crate) struct Table {
    pub(crate) vars: Vec<ScalarVariable<()>>,
    pub(crate) guid: CString,
    /// The Real outputs.
    pub(crate) outputs: Vec<u32>,
    /// The Integer outputs.
    pub(crate) int_outputs: Vec<u32>,
    pub(crate) reals: Vec<u32>,
    /// Integer variables (parameters and outputs).
    pub(crate) integers: Vec<u32>,
    /// The outputs `fmi2GetDirectionalDerivative` differentiates.
    pub(crate) differentiated: Vec<u32>,
    pub(crate) activation: u32,
    pub(crate) length: u32,
    /// The start value of the `length` input: the lengths of `Run`,
    /// `DiscardRecover` and `Init` are multiples of it. For a muscle it is
    /// its rest length `L0`; for a musculotendon unit, whose length is its
    /// whole path, the rest path (tendon slack length plus the fibres).
    pub(crate) length0: f64,
    /// The length change that stretches the muscle by its rest length: the
    /// lengths that step an active subject far (`l0 + x span`) are measured
    /// in it. For a muscle, `length0`; for a unit, the rest path less the
    /// tendon's slack length, so that such a step stretches the fibres and
    /// not the tendon past its rupture strain.
    pub(crate) span: f64,
}

pub(crate) fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| {
        let vars = (installed().variables)();
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
        let differentiated = outputs
            .iter()
            .copied()
            .filter(|&i| vars[i as usize].name != NOT_DIFFERENTIATED)
            .collect();
        let length0 = match vars[vr_of("length") as usize].ty {
            VarType::Real { start: Some(s), .. } => s,
            other => panic!("length: {other:?}"),
        };
        let span = vars
            .iter()
            .find(|v| v.name == "tendon_slack_length")
            .map_or(length0, |v| match v.ty {
                VarType::Real { start: Some(s), .. } => length0 - s,
                other => panic!("tendon_slack_length: {other:?}"),
            });
        Table {
            span,
            activation: vr_of("activation"),
            length: vr_of("length"),
            guid: CString::new((installed().guid)()).unwrap(),
            outputs,
            int_outputs,
            reals,
            integers,
            differentiated,
            length0,
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
pub(crate) fn integer_refs(ints: Integers) -> Vec<(u32, i32)> {
    ints.iter().map(|&(n, v)| (vr_named(n), v)).collect()
}

pub(crate) fn n_vars() -> u32 {
    table().vars.len() as u32
}

pub(crate) fn var(vr: u32) -> Option<&'static ScalarVariable<()>> {
    table().vars.get(vr as usize)
}

pub(crate) fn is_real(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Real { .. }))
}

pub(crate) fn is_bool(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Boolean { .. }))
}

pub(crate) fn is_int(vr: u32) -> bool {
    var(vr).is_some_and(|v| matches!(v.ty, VarType::Integer { .. }))
}

/// The declared range of an Integer variable (`i32::MIN..=i32::MAX` where
/// none is declared).
pub(crate) fn int_range(vr: u32) -> (i32, i32) {
    match var(vr).map(|v| v.ty) {
        Some(VarType::Integer { min, max, .. }) => {
            (min.unwrap_or(i32::MIN), max.unwrap_or(i32::MAX))
        }
        _ => (i32::MIN, i32::MAX),
    }
}

/// A value the model computes (an output): reading it in initialization
/// mode may compute the initial values.
pub(crate) fn computed(vr: u32) -> bool {
    var(vr).is_some_and(is_computed)
}

pub(crate) fn is_real_with(vr: u32, c: Causality) -> bool {
    is_real(vr) && var(vr).is_some_and(|v| v.causality == c)
}

pub(crate) fn start_of(vr: u32) -> f64 {
    match var(vr).map(|v| v.ty) {
        Some(VarType::Real { start: Some(s), .. }) => s,
        _ => 1.0,
    }
}

/// `fmi2SetInteger` of `ints` on `c`, which must succeed (the cost
/// parameters of [`Subject`], set in initialization mode).
pub(crate) fn set_integers(c: fmi2Component, ints: Integers) -> Result<(), String> {
    let (vrs, vals): (Vec<u32>, Vec<i32>) = integer_refs(ints).into_iter().unzip();
    if vrs.is_empty() {
        return Ok(());
    }
    let s = unsafe { (abi().set_integer)(c, vrs.as_ptr(), vrs.len(), vals.as_ptr()) };
    if s == fmi2OK {
        Ok(())
    } else {
        Err(format!("fmi2SetInteger({ints:?}) = {s:?}"))
    }
}
