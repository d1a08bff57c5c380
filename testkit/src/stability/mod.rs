//! The stability matrix of issue 4 §1: the muscle FMUs driven through their
//! FMI 2.0 C functions over a grid of stiff and extreme cases.
//!
//! Shared by the full matrix (`cargo run --release --example stability`,
//! which writes `docs/stability.md` and `docs/stability.csv`) and its CI subset
//! (`tests/stability_subset.rs`), so both run exactly the same cells with the
//! same checks.
//!
//! # How the FMU is driven
//!
//! In-process, through the generic functions `hill_muscle::fmi2::api::*::<M>`:
//! every exported `fmi2Xxx` symbol of an FMU binary is a one-line forward to
//! exactly these functions (`export_fmi2!`), so this is the C ABI's code path
//! minus the `extern "C"` shim. Chosen over dlopen of the built binaries
//! because (1) the runner is generic over the model: another FMU joins the
//! matrix by adding one [`ModelEntry`] to [`models`], with no binary to build
//! (the cdylib exports one FMU per build, behind mutually exclusive features);
//! (2) the CI subset then needs no `dist/` build; (3) a cell can read the
//! model's solver counts ([`Hooks::stats`]) next to the C calls. Everything a
//! cell sets, steps and reads goes through the FMI functions; the solver
//! counts are the only side channel and only feed the report.
//!
//! # A cell
//!
//! One model × one (D, alpha, S) × one communication step h × one input
//! program ([`Scenario`]) × one parameter set ([`ParamSet`]). The program is a
//! piecewise-linear stretch and a piecewise-constant activation command, with
//! every breakpoint on the cell's communication grid (phase durations are
//! rounded to whole steps, at least one: at h = 0.1 s a 6 ms ramp is a jump in
//! one step). Before the step from t_n to t_n+1 the master sets the command of
//! the step and the length at t_n+1 (the FMU's convention: the step ends at
//! the input length). So the input signal is the same function of time for
//! every step size that divides the grid, and the run at h/100 solves the
//! same continuous problem, only with smaller steps.
//!
//! A musculotendon unit's `length` is its whole path: its program is the
//! same capped inside the unit's physical range (below where the relaxed
//! fibres carry F0, far short of the tendon's rupture), and its stretch is
//! the relaxed unit's fibre stretch, the path its fibres' share (`unit`:
//! [`program_of`], [`UnitPath`]); the path is interpolated linearly between
//! the program's breakpoints.
//!
//! The master is an ordinary one: fmi2GetFMUstate before every step (into one
//! reused state); after an fmi2Discard it checks
//! fmi2GetRealStatus(fmi2LastSuccessfulTime), restores the state and retries
//! the step cut into 2, 4, ..., 1024 pieces (inputs interpolated on the same
//! signal); if even that fails the cell ends there.
//!
//! Every completed step (coarse and fine runs) is checked: every Real output
//! finite, and the model's physical bounds ([`Hooks::bounds`]). The outputs
//! at the communication points are compared with the run at h/100 where that
//! costs at most [`FINE_BUDGET`] steps.
//!
//! Each cell is bounded by [`CELL_TIME_LIMIT`] of **CPU time of the thread
//! running it** (coarse and reference run together, checked between steps,
//! [`Watch`]; a unit's program, which the harness maps by initializations
//! of the unit, is prepared before the bound starts), not wall time: a
//! cell's outcome does not depend on what else the machine runs. The `seconds` a run reports are its wall time. A
//! watchdog ends the process if one FMI call shows no sign of life for
//! [`HANG_LIMIT`] of its thread's CPU time (so that load does not pass for a
//! hang).

use std::ffi::CString;
use std::marker::PhantomData;
use std::ptr::null_mut;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use hill_muscle::fmi2::api;
use hill_muscle::fmi2::instance::Instance;
use hill_muscle::fmi2::model_description::guid;
use hill_muscle::fmi2::types::*;
use hill_muscle::fmi2::{Causality, Model, ScalarVariable, VarType};
use hill_muscle::fmus::hill1d::Hill1D;
#[cfg(feature = "fe")]
use hill_muscle::fmus::hillfe::HillFE;
use hill_muscle::fmus::musculotendon1d::Musculotendon;
#[cfg(feature = "fe")]
use hill_muscle::fmus::musculotendonfe::MusculotendonFe;
use hill_muscle::law::musculotendon::UnitParams;
use hill_muscle::law::{ParamId, Params};

use crate::logger::{callbacks, LogBook};

mod fmu;
mod grid;
mod models;
mod run;
mod unit;

pub use fmu::*;
pub use grid::*;
pub use models::*;
pub use run::*;
pub use unit::*;
