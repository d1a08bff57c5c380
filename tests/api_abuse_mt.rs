//! The FMI API of `HillMusculotendon1D` under abuse: the property-based
//! harness of `testkit::api_abuse` (what it generates and the properties it
//! checks are documented there), run on the musculotendon unit through the
//! generic C-signature functions `hill_muscle::fmi2::api::*::<Musculotendon>`,
//! exactly what its exported `fmi2Xxx` symbols forward to.
//!
//! # The subject
//!
//! The unit's `length` input is the length of its whole path; the harness's
//! lengths are multiples of the input's start (the rest path, tendon slack
//! length plus the fibres at L0), so a `Run` moves the fibres by a few times
//! its amplitude relative to L0. The jumps of `DiscardRecover` go from a
//! slack tendon (0.5: the muscle shortens until it carries nothing, a step
//! that completes) to paths of kilometres, which need the tendon past its
//! rupture strain (discarded). The prefix that reaches `stepFailed` adds a
//! length rate that ends the step at a negative path (discarded). No Integer
//! variables; every Real output but `stiffness` is differentiated
//! (`stiffness` is itself d force / d length: asking its derivative is
//! `fmi2Error`).
//!
//! CI mode runs the same case counts as `tests/api_abuse.rs`; long mode:
//! `API_ABUSE_CASES=1000000 cargo test --release --test api_abuse_mt`.

use hill_muscle::fmus::musculotendon1d::Musculotendon;
use testkit::api_abuse::{Integers, Subject};

/// `HillMusculotendon1D` as the harness's subject.
pub struct Unit;

impl Subject for Unit {
    type M = Musculotendon;
    const CI_CASES: u32 = 3000;
    const CORRUPT_CASES: (u32, u32) = (1, 4);
    const INSTANTIATE_CASES: (u32, u32) = (1, 4);
    const INIT_INTEGERS: &'static [(u32, Integers)] = &[];
    const CHEAP_INTEGERS: Integers = &[];
    const SOLVER_INTEGERS: Integers = &[];
    const INTEGER_SPAN: Option<i32> = None;
    const LONG_RUN: usize = 150;
    const DISCARD_FACTORS: &'static [f64] = &[0.5, 1.05, 6.0, 10.0, 100.0, 1e10, 0.01];
    const DRIFT_STEPS: usize = 25_000;
    const FAILING_LENGTH_RATE: f64 = -1e6;
    const SPECIAL_VALUE_VARS_PER_SEQUENCE: usize = 1;
    const SPECIAL_VALUE_BOTH_LOGGING: bool = true;
    const FUNCTIONS_PER_SEQUENCE: usize = 1;
    const LARGEST_INTEGER_TRIED: i32 = 100; // (no Integer variables)
    const INIT_MAY_FAIL: bool = false;
}

testkit::harness_tests!(Unit);
