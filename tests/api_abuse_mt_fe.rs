//! The FMI API of `HillMusculotendonFE` under abuse: the property-based
//! harness of `testkit::api_abuse` (what it generates and the properties it
//! checks are documented there) run on the FE musculotendon unit through
//! `hill_muscle::fmi2::api::*::<MusculotendonFe>`, exactly what its
//! exported `fmi2Xxx` symbols forward to.
//!
//! # The subject
//!
//! The unit of `tests/api_abuse_mt.rs` (a path length in, the tendon's force
//! out, the same outputs) with the FE muscle of `tests/api_abuse_fe.rs` in
//! place of the 1D one, so it takes both harnesses' measures:
//!
//! - **Cost**: every initialization sets the mesh small, as for
//!   `HillMuscleFE`: 1 × 1 (no free node: each of the equilibrium's trials
//!   is one evaluation) in three of four `Init`s and 2 × 1 (one free slice:
//!   Newton, line search and substeps inside every trial) in the fourth,
//!   the pool of restorable states and the parameter-bound test.
//! - **Integers**: `n_axial`, `n_radial`, `fibre_layout` and `threads`,
//!   their ranges from the variable table; no Integer output.
//! - **Lengths**: the rest path is the tendon's slack length plus the
//!   fibres at L0; the jumps of `DiscardRecover` go from a slack tendon
//!   (0.5: the muscle shortens until it carries nothing) and a small pull
//!   (1.05) to paths of kilometres, which ask the tendon for strains past
//!   its rupture and are discarded. Steps that stretch an active unit far
//!   move the path by multiples of the fibres' share of it (`Table::span`),
//!   not of the whole path, so they stretch the fibres, not the tendon.
//! - **Derivatives** of every Real output but `stiffness`, which is itself
//!   d force / d length (asking its derivative is `fmi2Error`).
//!
//! CI mode runs 60 random sequences (the FE muscle runs 200) and the FE
//! muscle's deterministic tests; with 200 the whole file took 368 s on the
//! 2-core machine at a load average of 10. Long mode:
//! `API_ABUSE_CASES=2000 cargo test --release --test api_abuse_mt_fe`.

#![cfg(feature = "fe")]

use hill_muscle::fmus::musculotendonfe::MusculotendonFe;
use testkit::api_abuse::{Integers, Subject, MESH_1X1, MESH_2X1};

/// `HillMusculotendonFE` as the harness's subject.
pub struct FeUnit;

impl Subject for FeUnit {
    type M = MusculotendonFe;
    /// Fewer than the FE muscle's 200: each case's instances solve the
    /// unit's equilibrium at every initialization and step.
    const CI_CASES: u32 = 60;
    const CORRUPT_CASES: (u32, u32) = (1, 4);
    const INSTANTIATE_CASES: (u32, u32) = (1, 4);
    const INIT_INTEGERS: &'static [(u32, Integers)] = &[(3, MESH_1X1), (1, MESH_2X1)];
    const CHEAP_INTEGERS: Integers = MESH_1X1;
    const SOLVER_INTEGERS: Integers = MESH_2X1;
    const INTEGER_SPAN: Option<i32> = Some(1);
    const LONG_RUN: usize = 60;
    const DISCARD_FACTORS: &'static [f64] = &[0.5, 1.05, 6.0, 10.0, 100.0, 1e10, 0.01];
    const DRIFT_STEPS: usize = 25_000;
    const SPECIAL_VALUE_VARS_PER_SEQUENCE: usize = usize::MAX;
    const SPECIAL_VALUE_BOTH_LOGGING: bool = false;
    const FUNCTIONS_PER_SEQUENCE: usize = usize::MAX;
    const LARGEST_INTEGER_TRIED: i32 = 2;
    const INIT_MAY_FAIL: bool = false;
}

testkit::harness_tests!(FeUnit, release_only);
