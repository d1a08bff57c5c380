//! The FMI API of `HillMuscle1D` under abuse (issue 4, section 3): the
//! property-based harness of `testkit::api_abuse` — what it
//! generates and the properties it checks for every call are documented
//! there — run on `HillMuscle1D` through the generic C-signature functions
//! `hill_muscle::fmi2::api::*::<Hill1D>`, exactly what the exported
//! `fmi2Xxx` symbols forward to. `tests/api_abuse_fe.rs` runs the same
//! harness on `HillMuscleFE`.
//!
//! # The subject
//!
//! The harness was written for this model, and these settings ([`OneD`])
//! keep it exactly as it was: no Integer variables (so no Integer values
//! are generated beyond `any::<i32>()` for wrong-type calls, and the `Init`
//! macro sets none), every Real output differentiated, no known bug,
//! initialization never refuses in-range parameters (docs/reference/bad-input.md:
//! only a length or `L0` outside what the law can evaluate, or a CE length
//! ≤ 0, which the oracle leaves open anyway). Its `do_step` never returns
//! `StepError::Error`: every `fmi2Error` is a rejection.
//!
//! # Case counts and time
//!
//! CI mode (the default): 3,000 random sequences for the main property plus
//! 750 corrupt-state and 750 instantiation cases and ~580 deterministic
//! sequences — about 5,000 in all, ~4 s wall time for this test binary with
//! `cargo test --release` on the project's 2-core machine (idle). An
//! unoptimized build (plain `cargo test`) runs a tenth of the random cases
//! (~4 s).
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
//! The bugs this harness found in `HillMuscle1D` and the layer are listed
//! in the harness's module docs; their regression tests run on both FMUs.

use hill_muscle::fmus::hill1d::Hill1D;
use testkit::api_abuse::{Integers, Subject};

/// `HillMuscle1D` as the harness's subject.
pub struct OneD;

impl Subject for OneD {
    type M = Hill1D;
    const CI_CASES: u32 = 3000;
    const CORRUPT_CASES: (u32, u32) = (1, 4);
    const INSTANTIATE_CASES: (u32, u32) = (1, 4);
    const INIT_INTEGERS: &'static [(u32, Integers)] = &[];
    const CHEAP_INTEGERS: Integers = &[];
    const SOLVER_INTEGERS: Integers = &[];
    const INTEGER_SPAN: Option<i32> = None;
    const LONG_RUN: usize = 150;
    const DISCARD_FACTORS: &'static [f64] = &[1.05, 6.0, 10.0, 100.0, 1e10, 0.01];
    const DRIFT_STEPS: usize = 25_000;
    const SPECIAL_VALUE_VARS_PER_SEQUENCE: usize = 1;
    const SPECIAL_VALUE_BOTH_LOGGING: bool = true;
    const FUNCTIONS_PER_SEQUENCE: usize = 1;
    const LARGEST_INTEGER_TRIED: i32 = 100; // (no Integer variables)
    const INIT_MAY_FAIL: bool = false;
}

testkit::harness_tests!(OneD);
