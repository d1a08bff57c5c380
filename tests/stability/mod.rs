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
#![allow(dead_code)]

use std::ffi::{c_char, c_void, CStr, CString};
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
use hill_muscle::law::{ParamId, Params};

// ---------------------------------------------------------------------------
// The grid
// ---------------------------------------------------------------------------

/// Compressibility D [1/Pa] (bulk modulus 2/D: 2e12 ... 2e4 Pa).
pub const D_VALUES: [f64; 4] = [1e-12, 1e-9, 1e-6, 1e-4];
/// SEE exponent alpha.
pub const ALPHA_VALUES: [f64; 3] = [10.0, 100.0, 1000.0];
/// Activation rate S [1/s] (time constant 1 s ... 10 µs).
pub const S_VALUES: [f64; 4] = [1.0, 50.0, 1e3, 1e5];
/// Communication step h [s].
pub const H_VALUES: [f64; 5] = [1e-6, 1e-4, 1e-3, 1e-2, 0.1];

/// The reference run takes steps this many times smaller.
pub const FINE_FACTOR: usize = 100;
/// The reference run is made when it takes at most this many steps.
pub const FINE_BUDGET: usize = 1_000_000;
/// Agreement tolerance with the reference run, relative: at every
/// communication point |x − x_ref| ≤ AGREEMENT_TOL · max(sigma0, |x_ref|) for
/// x = stress and x = active_stress (see [`Agreement`]).
pub const AGREEMENT_TOL: f64 = 0.02;
/// Wall-clock bound of one cell (coarse and reference run together),
/// checked between steps. A cell past it is recorded as `timeout`.
pub const CELL_TIME_LIMIT: Duration = Duration::from_secs(120);
/// A single FMI call that has not returned after this long is a hang: the
/// watchdog names the cell and ends the process.
pub const HANG_LIMIT: Duration = Duration::from_secs(300);
/// The master's retry after a discard: the step cut into up to this many pieces.
pub const MAX_RETRY_PIECES: usize = 1024;

/// The paper's ranges of sigma0, kc, ke and d (MODEL_NOTES "Parameters") at
/// both ends, and Table 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamSet {
    Table2,
    /// sigma0 0.16 MPa, kc 4.0, ke 3.14, d 1.1.
    PaperMin,
    /// sigma0 1.0 MPa, kc 5.88, ke 7.56, d 1.8.
    PaperMax,
}

impl ParamSet {
    pub const ALL: [ParamSet; 3] = [ParamSet::Table2, ParamSet::PaperMin, ParamSet::PaperMax];

    pub fn name(self) -> &'static str {
        match self {
            ParamSet::Table2 => "table2",
            ParamSet::PaperMin => "paper-min",
            ParamSet::PaperMax => "paper-max",
        }
    }

    /// (parameter, value) of sigma0, kc, ke, d.
    #[allow(clippy::approx_constant)] // ke = 3.14 is the paper's bound, not π
    pub fn values(self) -> [(ParamId, f64); 4] {
        let (sigma0, kc, ke, d) = match self {
            ParamSet::Table2 => (7.0e5, 5.0, 5.0, 1.5),
            ParamSet::PaperMin => (1.6e5, 4.0, 3.14, 1.1),
            ParamSet::PaperMax => (1.0e6, 5.88, 7.56, 1.8),
        };
        [
            (ParamId::Sigma0, sigma0),
            (ParamId::Kc, kc),
            (ParamId::Ke, ke),
            (ParamId::D, d),
        ]
    }
}

/// The input programs (stretch = length / L0; |lambda_dot_min| = 17 1/s in
/// every parameter set).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scenario {
    /// At a fixed stretch, from rest: the command jumps 0 → 1 (held 0.2 s),
    /// then 1 → 0 (held 0.2 s). At 0.3 and 2.0 the fibre is outside the
    /// force-length support (f_λ = 0), at 1.05 at its optimum.
    ActivationJumps { stretch: f64 },
    /// At stretch 1.05 the command toggles 0, 1, 0, ... every step, 40 steps.
    Toggle,
    /// Activation held exactly at 0: stretch 1 → 2.0 → 0.3 → 1 at
    /// 10·|lambda_dot_min|, 0.05 s holds before, between and after.
    PassiveRamps,
    /// Activation held exactly at 1 (initial_activation = 1, command 1): the
    /// same path at `rate`·|lambda_dot_min|.
    ActiveRamps { rate: f64 },
    /// Activation held at 1: the length jumps in one step 1 → 2.0 → 0.3 → 1.3
    /// → 1, 0.05 s holds.
    LengthJumps,
    /// Length and command jump in the same step: (1, 0) → (1.3, 1) → (0.8, 0)
    /// → (1.05, 1), 0.1 s holds.
    JointJumps,
}

impl Scenario {
    pub const ALL: [Scenario; 9] = [
        Scenario::ActivationJumps { stretch: 0.3 },
        Scenario::ActivationJumps { stretch: 1.05 },
        Scenario::ActivationJumps { stretch: 2.0 },
        Scenario::Toggle,
        Scenario::PassiveRamps,
        Scenario::ActiveRamps { rate: 1.0 },
        Scenario::ActiveRamps { rate: 10.0 },
        Scenario::LengthJumps,
        Scenario::JointJumps,
    ];

    pub fn name(self) -> String {
        match self {
            Scenario::ActivationJumps { stretch } => format!("act-jumps@{stretch}"),
            Scenario::Toggle => "act-toggle".into(),
            Scenario::PassiveRamps => "passive-ramps-10x".into(),
            Scenario::ActiveRamps { rate } => format!("active-ramps-{rate}x"),
            Scenario::LengthJumps => "length-jumps".into(),
            Scenario::JointJumps => "joint-jumps".into(),
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Scenario::ActivationJumps { .. } => {
                "at the stretch named, from rest: command 0 → 1 held 0.2 s, then 1 → 0 held 0.2 s"
            }
            Scenario::Toggle => "stretch 1.05, command toggled 0/1 every step for 40 steps",
            Scenario::PassiveRamps => {
                "activation held exactly at 0; stretch 1 → 2.0 → 0.3 → 1 at 170 1/s (10·|lambda_dot_min|), 0.05 s holds"
            }
            Scenario::ActiveRamps { .. } => {
                "activation held exactly at 1; stretch 1 → 2.0 → 0.3 → 1 at the named multiple of |lambda_dot_min| = 17 1/s, 0.05 s holds"
            }
            Scenario::LengthJumps => {
                "activation held at 1; length jumps in one step 1 → 2.0 → 0.3 → 1.3 → 1, 0.05 s holds"
            }
            Scenario::JointJumps => {
                "length and command jump together: (1, 0) → (1.3, 1) → (0.8, 0) → (1.05, 1), 0.1 s holds"
            }
        }
    }
}

/// One cell of the matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub d_comp: f64,
    pub alpha: f64,
    pub s: f64,
    pub h: f64,
    pub params: ParamSet,
    pub scenario: Scenario,
}

impl Cell {
    /// The law's parameters of the cell (the rest at Table 2).
    pub fn law(&self) -> Params {
        let mut p = Params::default();
        for (id, v) in self.settings() {
            p.set(id, v)
                .expect("the grid stays inside the parameter ranges");
        }
        p
    }

    /// Every parameter the cell sets, with its value.
    pub fn settings(&self) -> Vec<(ParamId, f64)> {
        let mut v = vec![
            (ParamId::Dcomp, self.d_comp),
            (ParamId::Alpha, self.alpha),
            (ParamId::S, self.s),
        ];
        v.extend(self.params.values());
        v
    }

    pub fn key(&self) -> String {
        format!(
            "{} {} D={:e} alpha={} S={:e} h={:e}",
            self.scenario.name(),
            self.params.name(),
            self.d_comp,
            self.alpha,
            self.s,
            self.h
        )
    }
}

/// The full matrix, in a fixed order (scenario, parameter set, D, alpha, S, h).
pub fn full_grid() -> Vec<Cell> {
    let mut cells = Vec::new();
    for scenario in Scenario::ALL {
        for params in ParamSet::ALL {
            for d_comp in D_VALUES {
                for alpha in ALPHA_VALUES {
                    for s in S_VALUES {
                        for h in H_VALUES {
                            cells.push(Cell {
                                d_comp,
                                alpha,
                                s,
                                h,
                                params,
                                scenario,
                            });
                        }
                    }
                }
            }
        }
    }
    cells
}

/// The CI subset: every 19th cell of the full matrix (19 is prime to the
/// grid's dimensions 5, 4, 3, 4, 3 and 9, so every value of every dimension
/// appears, in changing combinations) — 342 cells.
pub fn ci_subset() -> Vec<Cell> {
    full_grid().into_iter().step_by(19).collect()
}

// ---------------------------------------------------------------------------
// Input programs
// ---------------------------------------------------------------------------

/// One communication step of a program: the command held over it and the
/// stretch at its end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgramStep {
    pub command: f64,
    pub stretch: f64,
}

/// A cell's input program on its communication grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    pub stretch0: f64,
    pub initial_activation: f64,
    /// The command set before initialization.
    pub command0: f64,
    pub steps: Vec<ProgramStep>,
}

impl Program {
    /// Largest |d stretch / dt| of the input.
    pub fn max_rate(&self, h: f64) -> f64 {
        let mut prev = self.stretch0;
        let mut m: f64 = 0.0;
        for s in &self.steps {
            m = m.max((s.stretch - prev).abs() / h);
            prev = s.stretch;
        }
        m
    }
}

struct Builder {
    h: f64,
    command: f64,
    stretch: f64,
    program: Program,
}

impl Builder {
    fn new(h: f64, stretch0: f64, initial_activation: f64, command0: f64) -> Builder {
        Builder {
            h,
            command: command0,
            stretch: stretch0,
            program: Program {
                stretch0,
                initial_activation,
                command0,
                steps: Vec::new(),
            },
        }
    }

    fn steps_for(&self, duration: f64) -> usize {
        ((duration / self.h).round() as usize).max(1)
    }

    fn push(&mut self, stretch: f64) {
        self.stretch = stretch;
        self.program.steps.push(ProgramStep {
            command: self.command,
            stretch,
        });
    }

    fn hold(&mut self, duration: f64) -> &mut Self {
        for _ in 0..self.steps_for(duration) {
            self.push(self.stretch);
        }
        self
    }

    fn ramp(&mut self, to: f64, rate: f64) -> &mut Self {
        let from = self.stretch;
        let n = self.steps_for((to - from).abs() / rate);
        for i in 1..=n {
            self.push(if i == n {
                to
            } else {
                from + (to - from) * i as f64 / n as f64
            });
        }
        self
    }

    fn jump(&mut self, to: f64) -> &mut Self {
        self.push(to);
        self
    }

    fn command(&mut self, u: f64) -> &mut Self {
        self.command = u;
        self
    }
}

const LAMBDA_DOT_MIN: f64 = 17.0;

/// The program of a scenario on the grid of step `h`.
pub fn program(scenario: Scenario, h: f64) -> Program {
    match scenario {
        Scenario::ActivationJumps { stretch } => {
            let mut b = Builder::new(h, stretch, 0.0, 0.0);
            b.command(1.0).hold(0.2).command(0.0).hold(0.2);
            b.program
        }
        Scenario::Toggle => {
            let mut b = Builder::new(h, 1.05, 0.0, 0.0);
            for i in 0..40 {
                b.command(f64::from(u8::from(i % 2 == 0))).hold(0.0);
            }
            b.program
        }
        Scenario::PassiveRamps | Scenario::ActiveRamps { .. } => {
            let (a, rate) = match scenario {
                Scenario::ActiveRamps { rate } => (1.0, rate * LAMBDA_DOT_MIN),
                _ => (0.0, 10.0 * LAMBDA_DOT_MIN),
            };
            let mut b = Builder::new(h, 1.0, a, a);
            b.hold(0.05)
                .ramp(2.0, rate)
                .hold(0.05)
                .ramp(0.3, rate)
                .hold(0.05)
                .ramp(1.0, rate)
                .hold(0.05);
            b.program
        }
        Scenario::LengthJumps => {
            let mut b = Builder::new(h, 1.0, 1.0, 1.0);
            b.hold(0.05);
            for to in [2.0, 0.3, 1.3, 1.0] {
                b.jump(to).hold(0.05);
            }
            b.program
        }
        Scenario::JointJumps => {
            let mut b = Builder::new(h, 1.0, 0.0, 0.0);
            for (to, u) in [(1.3, 1.0), (0.8, 0.0), (1.05, 1.0)] {
                b.command(u).jump(to).hold(0.1);
            }
            b.program
        }
    }
}

// ---------------------------------------------------------------------------
// The models
// ---------------------------------------------------------------------------

/// Solver counts of one step, as far as the model reports them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Internal substeps of the step.
    pub substeps: Option<u32>,
    /// Newton iterations of the step (for the 1D model: of the lateral solve,
    /// each an evaluation of the law; for a model with an Integer output
    /// `newton_iterations`: that output).
    pub iterations: Option<u32>,
    /// Iterations of the CE–SEE solve (inside the law's evaluations).
    pub ce_iterations: Option<u32>,
}

/// What one completed step gave, for the bounds check.
pub struct Sample<'a> {
    /// Output names and values (every Real output of the model).
    pub names: &'a [&'static str],
    pub values: &'a [f64],
    /// length / L0 at the end of the step.
    pub stretch: f64,
    pub params: &'a Params,
}

impl Sample<'_> {
    pub fn get(&self, name: &str) -> Option<f64> {
        self.names
            .iter()
            .position(|n| *n == name)
            .map(|i| self.values[i])
    }
}

/// A model's hooks into the generic runner.
pub struct Hooks<M> {
    /// Solver counts of the last step read from the model (`None`: only what
    /// the FMI interface shows, i.e. an Integer output `newton_iterations`).
    pub stats: Option<fn(&M) -> StepStats>,
    /// Physical bounds of a completed step: `Err` names the violated bound.
    pub bounds: fn(&Sample) -> Result<(), String>,
    /// Integer parameters set before initialization (e.g. the FE mesh).
    pub integers: &'static [(&'static str, i32)],
    /// Boolean parameters set before initialization (e.g. an FE option).
    pub booleans: &'static [(&'static str, bool)],
    /// The run at h / [`FINE_FACTOR`] is made when it costs at most this
    /// many steps.
    pub fine_budget: usize,
}

/// One model of the matrix.
pub struct ModelEntry {
    pub name: &'static str,
    /// Runs one cell (the generic runner, monomorphized for the model).
    pub run: fn(&Cell, &Watch) -> CellResult,
    /// The cells of the full matrix this model runs.
    pub select: fn(&Cell) -> bool,
    /// Whether the CI subset (`tests/stability_subset.rs`) runs this model.
    pub in_ci_subset: bool,
    /// Whether the CI subset also requires agreement with the run at h/100
    /// (beyond the acceptance criteria): for a model that controls
    /// its time error. Otherwise the deviations are reported, not asserted.
    pub time_error_controlled: bool,
}

/// The models of the matrix. A model joins with one entry: its runner
/// (monomorphized for the model, with its hooks) and the cells it runs.
pub fn models() -> Vec<ModelEntry> {
    vec![
        ModelEntry {
            name: "HillMuscle1D",
            run: |c, w| run_cell::<Hill1D>(c, w, &HILL1D_HOOKS),
            select: |_| true,
            in_ci_subset: true,
            // Error-controlled substeps of the CE–SEE update (issue 4 §2).
            time_error_controlled: true,
        },
        // Only with the `fe` feature (on by default).
        #[cfg(feature = "fe")]
        ModelEntry {
            name: "HillMuscleFE",
            run: |c, w| run_cell::<HillFE>(c, w, &HILLFE_HOOKS),
            select: fe_cell,
            // Its 11 cells of the CI subset meet the acceptance criteria
            // (about 20 s); the full matrix's report lists the cells it
            // fails (docs/stability.md).
            in_ci_subset: true,
            // One backward-Euler step of the CE–SEE update per
            // communication step (substeps only when Newton does not
            // converge, whose directional derivatives are those of the last
            // substep): first order in h, no error control, so at h >= 1e-2
            // s with S h >= 0.5 or alpha = 1000 it deviates from the run at
            // h/100 by more than AGREEMENT_TOL (92 of its 149 compared cells
            // of the full matrix, docs/stability.md).
            time_error_controlled: false,
        },
        // The same FMU with its opt-in time-error control: the FE's
        // before/after of issue 4 §2 on the same cells.
        #[cfg(feature = "fe")]
        ModelEntry {
            name: FE_ADAPTIVE,
            run: |c, w| run_cell_named::<HillFE>(FE_ADAPTIVE, c, w, &HILLFE_ADAPTIVE_HOOKS),
            // The cells with a reference run at h/100 (h >= 1e-2 s; at
            // 1e-3 s only the 40-step act-toggle program has one): where
            // the comparison shows what the control changes.
            select: |c| fe_cell(c) && c.h >= 1e-2,
            in_ci_subset: false,
            time_error_controlled: true,
        },
    ]
}

/// The name of the FE muscle with `adaptive_substeps = true` in the reports.
pub const FE_ADAPTIVE: &str = "HillMuscleFE(adaptive)";

/// The FE muscle's part of the grid: its steps cost milliseconds, not
/// microseconds, so it runs every D, the soft and the stiff corner of
/// (alpha, S) — (10, 50) and (1000, 1e5) —, the three largest steps (S·h up
/// to 1e4) and every input program, at the Table 2 parameters: 216 cells of
/// the full grid.
pub fn fe_cell(c: &Cell) -> bool {
    c.params == ParamSet::Table2
        && ((c.alpha == 10.0 && c.s == 50.0) || (c.alpha == 1000.0 && c.s == 1e5))
        && c.h >= 1e-3
}

/// The FE muscle in the matrix: a 6 × 1 mesh (the matrix probes time
/// stepping and stiffness, not spatial accuracy; the default mesh's step
/// costs tens of times more), newton_iterations read from its output, the
/// active-stress bound (its `active_stress` is a volume average of σ_s, so
/// the bound of every element holds for it), and the reference run at
/// h / 100 only where it costs at most 20,000 steps (h ≥ 1e-2 s).
#[cfg(feature = "fe")]
const HILLFE_HOOKS: Hooks<HillFE> = Hooks {
    stats: None,
    bounds: active_stress_bounds,
    integers: &[("n_axial", 6), ("n_radial", 1)],
    booleans: &[],
    fine_budget: 20_000,
};

/// [`HILLFE_HOOKS`] with the FE's opt-in time-error control
/// (`adaptive_substeps = true`, the default `substep_tolerance`): the FE
/// half of issue 4 §2's before/after, on the same cells.
#[cfg(feature = "fe")]
const HILLFE_ADAPTIVE_HOOKS: Hooks<HillFE> = Hooks {
    booleans: &[("adaptive_substeps", true)],
    ..HILLFE_HOOKS
};

const HILL1D_HOOKS: Hooks<Hill1D> = Hooks {
    stats: Some(|m: &Hill1D| {
        let s = m.last_step_statistics();
        StepStats {
            substeps: Some(s.substeps),
            iterations: Some(s.lateral_iterations),
            ce_iterations: Some(s.ce_iterations),
        }
    }),
    bounds: uniaxial_bounds,
    integers: &[],
    booleans: &[],
    fine_budget: FINE_BUDGET,
};

/// Relative round-off allowance of the bounds (a millionth of a percent).
const BOUND_RTOL: f64 = 1e-9;

/// The active-stress bound of any model of the law: the activation level in
/// [0, 1] and 0 ≤ active_stress ≤ f_v,max · sigma0 · activation_level, with
/// f_v,max = d + (d − 1)/(ke·kc) the eccentric asymptote of f_v (MODEL_NOTES
/// "Hill fibre"; f_λ ≤ 1). Allowed above the bound: a relative
/// [`BOUND_RTOL`] and the resolution of the SEE stress, one ulp of the SEE
/// stretch λs times dσ_s/dλs = alpha (σ_s + beta) (eq 31): σ_s is a function
/// of λs, and next to λs = 1 it moves in steps of alpha·beta·2⁻⁵² (2.2e-10 Pa
/// for alpha = 1000, beta = 1e3). The first run of the matrix met exactly
/// that: with the activation level decaying to ~1e-16 after the command went
/// to 0, σ_s sat one to four such steps above a bound of the same size.
pub fn active_stress_bounds(s: &Sample) -> Result<(), String> {
    let (Some(a), Some(active)) = (s.get("activation_level"), s.get("active_stress")) else {
        return Err("no activation_level or active_stress output".into());
    };
    if !(0.0..=1.0).contains(&a) {
        return Err(format!("activation_level {a} outside [0, 1]"));
    }
    let p = s.params;
    let max = p.fv_max() * p.sigma0 * a;
    let lambda_s = s.get("see_stretch").unwrap_or(1.0).max(1.0);
    let resolution = p.alpha * (active.abs() + p.beta) * f64::EPSILON * lambda_s;
    if active < 0.0 || active > max * (1.0 + BOUND_RTOL) + resolution {
        return Err(format!(
            "active_stress {active:e} Pa outside [0, fv_max sigma0 a = {max:e}] (a = {a}, \
             resolution of sigma_s {resolution:e} Pa)"
        ));
    }
    Ok(())
}

/// [`active_stress_bounds`] and, for the 1D model in homogeneous uniaxial
/// stress, the sign of the matrix and PE stresses. At lateral equilibrium
/// the axial Kirchhoff stress is τ11 = 2 U_I' (λ̄f² − 1/λ̄f) + λ̄f (σ_s + σ_p)
/// (`src/law/uniaxial.rs`), so the nominal stress of the matrix and the PE is
/// stress − active_stress · λ̄f / λ = [2 U_I' (λ̄f² − 1/λ̄f) + λ̄f σ_p] / λ,
/// which is ≥ 0 in fibre tension (λ̄f ≥ 1: both terms ≥ 0) and ≤ 0 in fibre
/// compression (σ_p = 0, the matrix term ≤ 0). (passive_stress = stress −
/// active_stress also holds the volumetric coupling σ_s (λ̄f/λ − 1), which
/// may have either sign.)
pub fn uniaxial_bounds(s: &Sample) -> Result<(), String> {
    active_stress_bounds(s)?;
    let (Some(stress), Some(active), Some(lf)) = (
        s.get("stress"),
        s.get("active_stress"),
        s.get("fibre_stretch"),
    ) else {
        return Err("no stress, active_stress or fibre_stretch output".into());
    };
    let fibre_part = active * lf / s.stretch;
    let matrix_pe = stress - fibre_part;
    let slack = BOUND_RTOL * (stress.abs() + fibre_part.abs()) + 1e-9;
    if lf >= 1.0 && matrix_pe < -slack {
        return Err(format!(
            "matrix + PE nominal stress {matrix_pe:e} Pa < 0 in fibre tension (fibre_stretch {lf})"
        ));
    }
    if lf < 1.0 && matrix_pe > slack {
        return Err(format!(
            "matrix + PE nominal stress {matrix_pe:e} Pa > 0 in fibre compression (fibre_stretch {lf})"
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// The logger (as in tests/api_abuse.rs: FMI's logger is variadic; the layer
// always calls it as logger(env, name, status, category, "%s", text), so a
// non-variadic function with that one extra argument is transmuted to the
// variadic type — sound on SysV x86-64 and AAPCS64, where a variadic pointer
// argument is passed like the next named one.)
// ---------------------------------------------------------------------------

#[derive(Default)]
struct LogBook {
    entries: Mutex<Vec<(fmi2Status, String)>>,
}

impl LogBook {
    fn take(&self) -> Vec<(fmi2Status, String)> {
        std::mem::take(&mut *self.entries.lock().unwrap())
    }
}

unsafe extern "C" fn logger(
    env: fmi2ComponentEnvironment,
    _instance_name: fmi2String,
    status: fmi2Status,
    _category: fmi2String,
    _message: fmi2String,
    arg: *const c_char,
) {
    if env.is_null() || arg.is_null() {
        return;
    }
    let book = unsafe { &*(env as *const LogBook) };
    let text = unsafe { CStr::from_ptr(arg) }
        .to_string_lossy()
        .into_owned();
    if let Ok(mut g) = book.entries.lock() {
        g.push((status, text));
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
    let fixed: FixedLogger = logger;
    fmi2CallbackFunctions {
        // SAFETY: see the section comment.
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
        componentEnvironment: book as *const LogBook as *mut c_void,
    }
}

// ---------------------------------------------------------------------------
// One instance, driven through the FMI functions
// ---------------------------------------------------------------------------

/// An instance of model `M` with its log book and one saved FMU state.
pub struct Fmu<M: Model> {
    c: fmi2Component,
    book: Box<LogBook>,
    vars: Vec<ScalarVariable<M::Var>>,
    saved: fmi2FMUstate,
    /// Value references and names of the Real outputs.
    out_vrs: Vec<u32>,
    pub out_names: Vec<&'static str>,
    iterations_vr: Option<u32>,
    /// Value references of the inputs `activation` and `length`.
    input_vrs: [u32; 2],
    _m: PhantomData<M>,
}

fn status_name(s: fmi2Status) -> &'static str {
    match s {
        fmi2OK => "fmi2OK",
        fmi2Warning => "fmi2Warning",
        fmi2Discard => "fmi2Discard",
        fmi2Error => "fmi2Error",
        fmi2Fatal => "fmi2Fatal",
        fmi2Pending => "fmi2Pending",
    }
}

impl<M: Model> Fmu<M> {
    pub fn new(name: &str) -> Result<Fmu<M>, String> {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let guid = CString::new(guid::<M>()).unwrap();
        let name = CString::new(name).unwrap();
        // SAFETY: valid C strings and callbacks; the book outlives the instance.
        let c = unsafe {
            api::instantiate::<M>(
                name.as_ptr(),
                fmi2CoSimulation,
                guid.as_ptr(),
                c"file:///tmp/".as_ptr(),
                &cb,
                fmi2False,
                fmi2False,
            )
        };
        if c.is_null() {
            return Err(format!("fmi2Instantiate failed: {:?}", book.take()));
        }
        let vars = M::variables();
        let outputs: Vec<u32> = (0..vars.len() as u32)
            .filter(|&i| {
                let v = &vars[i as usize];
                v.causality == Causality::Output && matches!(v.ty, VarType::Real { .. })
            })
            .collect();
        let iterations_vr = vars
            .iter()
            .position(|v| v.name == "newton_iterations" && matches!(v.ty, VarType::Integer { .. }))
            .map(|i| i as u32);
        let vr_of = |name: &str| {
            vars.iter()
                .position(|v| v.name == name && v.causality == Causality::Input)
                .map(|i| i as u32)
                .ok_or_else(|| format!("the model has no input {name}"))
        };
        let input_vrs = [vr_of("activation")?, vr_of("length")?];
        Ok(Fmu {
            input_vrs,
            c,
            out_names: outputs.iter().map(|&i| vars[i as usize].name).collect(),
            out_vrs: outputs,
            iterations_vr,
            vars,
            book,
            saved: null_mut(),
            _m: PhantomData,
        })
    }

    fn vr(&self, name: &str) -> Result<u32, String> {
        self.vars
            .iter()
            .position(|v| v.name == name)
            .map(|i| i as u32)
            .ok_or_else(|| format!("the model has no variable {name}"))
    }

    /// The status as a `Result`, with the messages logged by the call.
    fn check(&self, what: &str, st: fmi2Status) -> Result<fmi2Status, String> {
        let logs = self.book.take();
        if st == fmi2OK || st == fmi2Warning {
            Ok(st)
        } else {
            let msgs: Vec<String> = logs.into_iter().map(|(_, m)| m).collect();
            Err(format!("{what}: {}: {}", status_name(st), msgs.join(" | ")))
        }
    }

    pub fn set_integer(&mut self, name: &str, value: i32) -> Result<(), String> {
        let vr = self.vr(name)?;
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_integer::<M>(self.c, &vr, 1, &value) };
        self.check(&format!("fmi2SetInteger({name} = {value})"), st)
            .map(|_| ())
    }

    pub fn set_boolean(&mut self, name: &str, value: bool) -> Result<(), String> {
        let vr = self.vr(name)?;
        let v = fmi2Boolean::from(value);
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_boolean::<M>(self.c, &vr, 1, &v) };
        self.check(&format!("fmi2SetBoolean({name} = {value})"), st)
            .map(|_| ())
    }

    pub fn set_real(&mut self, name: &str, value: f64) -> Result<(), String> {
        let vr = self.vr(name)?;
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_real::<M>(self.c, &vr, 1, &value) };
        self.check(&format!("fmi2SetReal({name} = {value})"), st)
            .map(|_| ())
    }

    /// Sets the activation command and the length in one fmi2SetReal.
    pub fn set_inputs(&mut self, command: f64, length: f64) -> Result<(), String> {
        let vals = [command, length];
        // SAFETY: live instance, two-element arrays.
        let st = unsafe { api::set_real::<M>(self.c, self.input_vrs.as_ptr(), 2, vals.as_ptr()) };
        self.check("fmi2SetReal(activation, length)", st)
            .map(|_| ())
    }

    pub fn initialize(&mut self) -> Result<(), String> {
        // SAFETY: live instance.
        let st = unsafe { api::setup_experiment::<M>(self.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) };
        self.check("fmi2SetupExperiment", st)?;
        let st = unsafe { api::enter_initialization_mode::<M>(self.c) };
        self.check("fmi2EnterInitializationMode", st)?;
        let st = unsafe { api::exit_initialization_mode::<M>(self.c) };
        self.check("fmi2ExitInitializationMode", st).map(|_| ())
    }

    /// fmi2DoStep: the status and, unless fmi2OK, the messages logged.
    pub fn step(&mut self, t: f64, h: f64) -> (fmi2Status, String) {
        // SAFETY: live instance.
        let st = unsafe { api::do_step::<M>(self.c, t, h, fmi2True) };
        let logs = self.book.take();
        let msg = logs
            .into_iter()
            .map(|(_, m)| m)
            .collect::<Vec<_>>()
            .join(" | ");
        (st, msg)
    }

    pub fn outputs(&self, into: &mut Vec<f64>) -> Result<(), String> {
        into.clear();
        into.resize(self.out_vrs.len(), f64::NAN);
        // SAFETY: live instance, arrays of the same length.
        let st = unsafe {
            api::get_real::<M>(
                self.c,
                self.out_vrs.as_ptr(),
                self.out_vrs.len(),
                into.as_mut_ptr(),
            )
        };
        self.check("fmi2GetReal(outputs)", st).map(|_| ())
    }

    pub fn save(&mut self) -> Result<(), String> {
        // SAFETY: live instance; `saved` NULL or a state of this instance.
        let st = unsafe { api::get_fmu_state::<M>(self.c, &mut self.saved) };
        self.check("fmi2GetFMUstate", st).map(|_| ())
    }

    pub fn restore(&mut self) -> Result<(), String> {
        // SAFETY: live instance; `saved` a state of this instance.
        let st = unsafe { api::set_fmu_state::<M>(self.c, self.saved) };
        self.check("fmi2SetFMUstate", st).map(|_| ())
    }

    pub fn last_successful_time(&self) -> Result<f64, String> {
        let mut t = f64::NAN;
        // SAFETY: live instance.
        let st = unsafe { api::get_real_status::<M>(self.c, fmi2LastSuccessfulTime, &mut t) };
        self.check("fmi2GetRealStatus(fmi2LastSuccessfulTime)", st)
            .map(|_| t)
    }

    pub fn stats(&self, hook: Option<fn(&M) -> StepStats>) -> StepStats {
        if let Some(f) = hook {
            // SAFETY: live instance of `M`; read only, between FMI calls on
            // this thread.
            if let Some(inst) = unsafe { Instance::<M>::from_component(self.c) } {
                return f(&inst.model);
            }
        }
        let mut s = StepStats::default();
        if let Some(vr) = self.iterations_vr {
            let mut n: fmi2Integer = 0;
            // SAFETY: live instance, one-element arrays.
            if unsafe { api::get_integer::<M>(self.c, &vr, 1, &mut n) } == fmi2OK {
                s.iterations = u32::try_from(n).ok();
            }
            self.book.take();
        }
        s
    }
}

impl<M: Model> Drop for Fmu<M> {
    fn drop(&mut self) {
        // SAFETY: live instance, freed exactly once (with its FMU states).
        unsafe { api::free_instance::<M>(self.c) };
    }
}

// ---------------------------------------------------------------------------
// Running a cell
// ---------------------------------------------------------------------------

/// What the watchdog sees of one worker thread.
pub struct Slot {
    origin: Instant,
    /// Milliseconds since `origin` at the worker's last sign of life.
    heartbeat: AtomicU64,
    busy: AtomicBool,
    key: Mutex<String>,
}

impl Slot {
    pub fn new() -> Arc<Slot> {
        Arc::new(Slot {
            origin: Instant::now(),
            heartbeat: AtomicU64::new(0),
            busy: AtomicBool::new(false),
            key: Mutex::new(String::new()),
        })
    }

    fn beat(&self) {
        self.heartbeat
            .store(self.origin.elapsed().as_millis() as u64, Ordering::Relaxed);
    }

    /// How long since the last sign of life, if the worker is in a cell.
    fn silent_for(&self) -> Option<Duration> {
        self.busy.load(Ordering::Relaxed).then(|| {
            let now = self.origin.elapsed().as_millis() as u64;
            Duration::from_millis(now.saturating_sub(self.heartbeat.load(Ordering::Relaxed)))
        })
    }
}

/// The time bound of one cell.
pub struct Watch {
    pub deadline: Instant,
    slot: Arc<Slot>,
}

impl Watch {
    pub fn new(slot: Arc<Slot>) -> Watch {
        slot.beat();
        Watch {
            deadline: Instant::now() + CELL_TIME_LIMIT,
            slot,
        }
    }

    fn beat(&self) {
        self.slot.beat();
    }
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every step completed (some perhaps after a master retry).
    Completed,
    /// A step was discarded and no retry with up to [`MAX_RETRY_PIECES`]
    /// pieces completed it: the run ends at `t`.
    Discarded { t: f64, message: String },
    /// A call returned fmi2Error or fmi2Fatal (or the setup failed).
    Error { message: String },
    /// The cell's time bound passed.
    Timeout { t: f64 },
}

/// A discard the master met, and how it went on.
#[derive(Clone, Debug, PartialEq)]
pub struct Discard {
    pub t: f64,
    pub message: String,
    /// The retry that completed the step: the step cut into this many pieces.
    pub recovered_with: Option<usize>,
}

/// One run of a cell's program at one step size.
#[derive(Clone, Debug, Default)]
pub struct Run {
    pub outcome: Option<Outcome>,
    /// The model's Real outputs.
    pub names: Vec<&'static str>,
    pub steps: usize,
    pub discards: Vec<Discard>,
    /// stress and active_stress at the cell's communication points 0..=n
    /// (recorded only for a comparison with a reference run).
    pub samples: Vec<[f64; 2]>,
    pub nonfinite: Vec<String>,
    pub violations: Vec<String>,
    /// Steps with a bound violated / an output not finite.
    pub n_violations: usize,
    pub n_nonfinite: usize,
    /// Sum and maximum over the steps of the solver counts.
    pub iterations: Counts,
    pub ce_iterations: Counts,
    pub substeps: Counts,
    /// Largest active_stress / (fv_max sigma0 activation_level) met.
    pub max_active_ratio: f64,
    pub seconds: f64,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    pub sum: u64,
    pub max: u32,
    pub n: u64,
}

impl Counts {
    fn add(&mut self, x: Option<u32>) {
        if let Some(x) = x {
            self.sum += u64::from(x);
            self.max = self.max.max(x);
            self.n += 1;
        }
    }

    pub fn mean(&self) -> Option<f64> {
        (self.n > 0).then(|| self.sum as f64 / self.n as f64)
    }
}

/// Agreement of the coarse run with the run at h / [`FINE_FACTOR`] at the
/// coarse communication points both reached: the largest
/// |x − x_ref| / max(sigma0, |x_ref|) for x = stress and active_stress, and
/// the time it occurs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Agreement {
    pub stress: f64,
    pub stress_t: f64,
    pub active: f64,
    pub active_t: f64,
    pub points: usize,
}

impl Agreement {
    pub fn worst(&self) -> f64 {
        self.stress.max(self.active)
    }

    pub fn within(&self) -> bool {
        self.worst() <= AGREEMENT_TOL
    }
}

/// The result of one cell.
#[derive(Clone, Debug)]
pub struct CellResult {
    pub model: &'static str,
    pub cell: Cell,
    pub max_input_rate: f64,
    pub coarse: Run,
    pub fine: Option<Run>,
    /// Why there is no reference run.
    pub fine_skipped: Option<String>,
    pub agreement: Option<Agreement>,
}

/// What a sample's checks need.
struct Checker<'a, M> {
    hooks: &'a Hooks<M>,
    params: Params,
}

/// Runs the program with `m` steps per communication step.
fn execute<M: Model>(
    cell: &Cell,
    prog: &Program,
    m: usize,
    checker: &Checker<M>,
    watch: &Watch,
    record: bool,
) -> Run {
    let started = Instant::now();
    let mut run = Run::default();
    let outcome = execute_inner(cell, prog, m, checker, watch, record, &mut run);
    run.outcome = Some(match outcome {
        Ok(o) => o,
        Err(message) => Outcome::Error { message },
    });
    run.seconds = started.elapsed().as_secs_f64();
    run
}

fn execute_inner<M: Model>(
    cell: &Cell,
    prog: &Program,
    m: usize,
    checker: &Checker<M>,
    watch: &Watch,
    record: bool,
    run: &mut Run,
) -> Result<Outcome, String> {
    let l0 = 0.05;
    let mut fmu = Fmu::<M>::new("stability")?;
    for (name, v) in checker.hooks.integers {
        fmu.set_integer(name, *v)?;
    }
    for (name, v) in checker.hooks.booleans {
        fmu.set_boolean(name, *v)?;
    }
    for (id, v) in cell.settings() {
        fmu.set_real(Params::info(id).name, v)?;
    }
    fmu.set_real("L0", l0)?;
    fmu.set_real("initial_activation", prog.initial_activation)?;
    fmu.set_inputs(prog.command0, prog.stretch0 * l0)?;
    fmu.initialize()?;
    run.names = fmu.out_names.clone();
    let idx = |name: &str| {
        fmu.out_names
            .iter()
            .position(|n| *n == name)
            .ok_or_else(|| format!("the model has no output {name}"))
    };
    let (i_stress, i_active) = (idx("stress")?, idx("active_stress")?);
    let mut out = Vec::new();
    fmu.outputs(&mut out)?;
    check_sample(&fmu, checker, &out, prog.stretch0, run, 0.0);
    if record {
        run.samples.push([out[i_stress], out[i_active]]);
    }
    let h = cell.h / m as f64;
    let n_total = prog.steps.len() * m;
    // The signal at fine step i (0-based): command and stretch at its end.
    let signal = |i: usize, frac: f64| -> (f64, f64) {
        let n = i / m;
        let s = prog.steps[n];
        let from = if n == 0 {
            prog.stretch0
        } else {
            prog.steps[n - 1].stretch
        };
        let x = ((i % m) as f64 + frac) / m as f64;
        let stretch = if x >= 1.0 {
            s.stretch
        } else {
            from + (s.stretch - from) * x
        };
        (s.command, stretch)
    };
    for i in 0..n_total {
        watch.beat();
        if i % 256 == 0 && Instant::now() > watch.deadline {
            return Ok(Outcome::Timeout { t: i as f64 * h });
        }
        let t = i as f64 * h;
        let (u, stretch) = signal(i, 1.0);
        fmu.save()?;
        fmu.set_inputs(u, stretch * l0)?;
        let (st, msg) = fmu.step(t, h);
        match st {
            fmi2OK => {}
            fmi2Discard => {
                let last = fmu.last_successful_time()?;
                if last != t {
                    return Err(format!(
                        "after a discard at t = {t}: fmi2LastSuccessfulTime = {last}"
                    ));
                }
                let mut recovered = None;
                let mut pieces = 2;
                while pieces <= MAX_RETRY_PIECES {
                    fmu.restore()?;
                    let mut ok = true;
                    for k in 0..pieces {
                        // Every FMI call is a sign of life, and the cell's
                        // time bound holds inside a retry too.
                        watch.beat();
                        if Instant::now() > watch.deadline {
                            return Ok(Outcome::Timeout { t });
                        }
                        let (u, s) = signal(i, (k + 1) as f64 / pieces as f64);
                        fmu.set_inputs(u, s * l0)?;
                        let hp = h / pieces as f64;
                        let (st, _) = fmu.step(t + k as f64 * hp, hp);
                        if st != fmi2OK {
                            ok = false;
                            break;
                        }
                    }
                    if ok {
                        recovered = Some(pieces);
                        break;
                    }
                    pieces *= 2;
                }
                run.discards.push(Discard {
                    t,
                    message: msg.clone(),
                    recovered_with: recovered,
                });
                if recovered.is_none() {
                    fmu.restore()?;
                    return Ok(Outcome::Discarded { t, message: msg });
                }
            }
            other => {
                return Ok(Outcome::Error {
                    message: format!("fmi2DoStep at t = {t}: {}: {msg}", status_name(other)),
                })
            }
        }
        run.steps += 1;
        let s = fmu.stats(checker.hooks.stats);
        run.iterations.add(s.iterations);
        run.ce_iterations.add(s.ce_iterations);
        run.substeps.add(s.substeps);
        fmu.outputs(&mut out)?;
        check_sample(&fmu, checker, &out, stretch, run, t + h);
        if record && (i + 1) % m == 0 {
            run.samples.push([out[i_stress], out[i_active]]);
        }
    }
    Ok(Outcome::Completed)
}

fn check_sample<M: Model>(
    fmu: &Fmu<M>,
    checker: &Checker<M>,
    out: &[f64],
    stretch: f64,
    run: &mut Run,
    t: f64,
) {
    let bad: Vec<String> = fmu
        .out_names
        .iter()
        .zip(out)
        .filter(|(_, v)| !v.is_finite())
        .map(|(n, v)| format!("{n} = {v}"))
        .collect();
    if !bad.is_empty() {
        run.n_nonfinite += 1;
        if run.nonfinite.len() < 3 {
            run.nonfinite.push(format!("t = {t:e}: {}", bad.join(", ")));
        }
        return;
    }
    let sample = Sample {
        names: &fmu.out_names,
        values: out,
        stretch,
        params: &checker.params,
    };
    if let Err(e) = (checker.hooks.bounds)(&sample) {
        run.n_violations += 1;
        if run.violations.len() < 3 {
            run.violations.push(format!("t = {t:e}: {e}"));
        }
    }
    if let (Some(a), Some(active)) = (sample.get("activation_level"), sample.get("active_stress")) {
        let max = checker.params.fv_max() * checker.params.sigma0 * a;
        if max > 0.0 {
            run.max_active_ratio = run.max_active_ratio.max(active / max);
        }
    }
}

/// Runs one cell: the program at h, and at h / [`FINE_FACTOR`] when affordable.
pub fn run_cell<M: Model>(cell: &Cell, watch: &Watch, hooks: &Hooks<M>) -> CellResult {
    run_cell_named(std::any::type_name::<M>(), cell, watch, hooks)
}

/// [`run_cell`] under another model name (one model type in two settings).
pub fn run_cell_named<M: Model>(
    name: &'static str,
    cell: &Cell,
    watch: &Watch,
    hooks: &Hooks<M>,
) -> CellResult {
    let prog = program(cell.scenario, cell.h);
    let checker = Checker {
        hooks,
        params: cell.law(),
    };
    let fine_steps = prog.steps.len() * FINE_FACTOR;
    let affordable = fine_steps <= hooks.fine_budget;
    let mut coarse = execute::<M>(cell, &prog, 1, &checker, watch, affordable);
    let (mut fine, fine_skipped) = if !affordable {
        (
            None,
            Some(format!(
                "not affordable: {fine_steps} steps > {}",
                hooks.fine_budget
            )),
        )
    } else if matches!(coarse.outcome, Some(Outcome::Timeout { .. })) {
        (None, Some("the coarse run timed out".into()))
    } else {
        (
            Some(execute::<M>(
                cell,
                &prog,
                FINE_FACTOR,
                &checker,
                watch,
                true,
            )),
            None,
        )
    };
    // A reference run cut by the cell's time bound is not affordable
    // either: no comparison (its steps up to the cut are still checked).
    let (agreement, fine_skipped) = match fine.as_ref().and_then(|f| f.outcome.as_ref()) {
        Some(Outcome::Timeout { t }) => (
            None,
            Some(format!(
                "the reference run exceeded the cell's time bound at t = {t}"
            )),
        ),
        _ => (
            fine.as_ref()
                .map(|f| agreement(&coarse, f, &checker.params, cell.h)),
            fine_skipped,
        ),
    };
    // The samples have served; a matrix keeps thousands of results
    // (`STABILITY_KEEP_SAMPLES` keeps them, for looking into one cell).
    if std::env::var_os("STABILITY_KEEP_SAMPLES").is_none() {
        coarse.samples = Vec::new();
        if let Some(f) = fine.as_mut() {
            f.samples = Vec::new();
        }
    }
    CellResult {
        model: short_name(name),
        cell: *cell,
        max_input_rate: prog.max_rate(cell.h),
        coarse,
        fine,
        fine_skipped,
        agreement,
    }
}

fn short_name(type_name: &'static str) -> &'static str {
    type_name.rsplit("::").next().unwrap_or(type_name)
}

fn agreement(coarse: &Run, fine: &Run, p: &Params, h: f64) -> Agreement {
    let mut a = Agreement {
        points: coarse.samples.len().min(fine.samples.len()),
        ..Agreement::default()
    };
    for (i, (c, f)) in coarse.samples.iter().zip(&fine.samples).enumerate() {
        let t = i as f64 * h;
        for (k, err, at) in [
            (0, &mut a.stress, &mut a.stress_t),
            (1, &mut a.active, &mut a.active_t),
        ] {
            let e = (c[k] - f[k]).abs() / p.sigma0.max(f[k].abs());
            // NaN counts as the worst (it cannot occur with finite outputs).
            if e > *err || e.is_nan() {
                *err = if e.is_nan() { f64::INFINITY } else { e };
                *at = t;
            }
        }
    }
    a
}

// ---------------------------------------------------------------------------
// Running many cells
// ---------------------------------------------------------------------------

/// Runs `jobs` (an index into `entries` and a cell) on `threads` worker
/// threads, results in job order. A watchdog thread ends the process (exit
/// code 3), naming the cell, when a worker shows no sign of life for
/// [`HANG_LIMIT`]: one FMI call that does not return. `progress` prints a
/// line every 5 % to stderr.
pub fn run_jobs(
    entries: &[ModelEntry],
    jobs: &[(usize, Cell)],
    threads: usize,
    progress: bool,
) -> Vec<CellResult> {
    let threads = threads.max(1);
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let finished = AtomicBool::new(false);
    let results: Mutex<Vec<Option<CellResult>>> = Mutex::new(vec![None; jobs.len()]);
    let slots: Vec<Arc<Slot>> = (0..threads).map(|_| Slot::new()).collect();
    let started = Instant::now();
    std::thread::scope(|scope| {
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                for slot in &slots {
                    if slot.silent_for().is_some_and(|d| d > HANG_LIMIT) {
                        eprintln!(
                            "stability: HANG: no progress for {HANG_LIMIT:?} in cell {}",
                            slot.key.lock().unwrap()
                        );
                        std::process::exit(3);
                    }
                }
            }
        });
        let workers: Vec<_> = slots
            .iter()
            .map(|slot| {
                let (next, done, results) = (&next, &done, &results);
                scope.spawn(move || loop {
                    let j = next.fetch_add(1, Ordering::Relaxed);
                    let Some((e, cell)) = jobs.get(j) else {
                        break;
                    };
                    let entry = &entries[*e];
                    *slot.key.lock().unwrap() = format!("{} {}", entry.name, cell.key());
                    let watch = Watch::new(slot.clone());
                    slot.busy.store(true, Ordering::Relaxed);
                    let mut r = (entry.run)(cell, &watch);
                    slot.busy.store(false, Ordering::Relaxed);
                    r.model = entry.name;
                    results.lock().unwrap()[j] = Some(r);
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if progress && (n * 20 / jobs.len() != (n - 1) * 20 / jobs.len()) {
                        eprintln!(
                            "stability: {n}/{} cells, {:.0} s",
                            jobs.len(),
                            started.elapsed().as_secs_f64()
                        );
                    }
                })
            })
            .collect();
        for w in workers {
            if w.join().is_err() {
                finished.store(true, Ordering::Relaxed);
                panic!("a worker panicked (a panic escaped the FMI layer?)");
            }
        }
        finished.store(true, Ordering::Relaxed);
    });
    results
        .into_inner()
        .unwrap()
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect()
}

/// Worker threads: `STABILITY_THREADS`, else the available parallelism.
pub fn threads() -> usize {
    std::env::var("STABILITY_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

// ---------------------------------------------------------------------------
// Acceptance
// ---------------------------------------------------------------------------

/// The explanation of a discard, from its message (the FMU's discard
/// messages name their cause); `None`: not explained. A model that joins the
/// matrix adds the causes its own messages name.
pub fn explain(message: &str) -> Option<&'static str> {
    const CAUSES: [(&str, &str); 6] = [
        (
            "the volume change",
            "the law's own limit with a soft volumetric term: with a large D (bulk modulus 2/D) against \
             the active and matrix stresses, the lateral equilibrium lets J run away until the matrix \
             term c exp(b (I1bar - 3)) overflows; a smaller D keeps J near 1",
        ),
        (
            "outside the range the law",
            "the input length lies outside the stretches at which the matrix term c exp(b (I1bar - 3)) \
             is finite",
        ),
        (
            "non-positive length",
            "the series kinematics would give the contractile element a non-positive length \
             ((1 + k) fibre_stretch - k see_stretch <= 0)",
        ),
        (
            "non-finite partial derivative",
            "a step so short that the partial derivatives of the step map overflow",
        ),
        (
            "length at the end of the step",
            "length + h dlength/dt is not a positive length",
        ),
        (
            "did not converge, even in",
            "the FE muscle's implicit quasi-static solve (Newton's method, continuation in the step's \
             inputs, up to 64 substeps, within its work budget) could not take the step's input change — \
             a length jump, the compression of the slender clamped specimen towards stretch 0.3, an \
             activation jump with S h >> 1 at the kink of f_v, mostly at D <= 1e-9 — and refused it \
             with fmi2Discard, its state unchanged (issue 3's contract); the message names the last \
             failure, and the master's retry in smaller pieces completes most such steps",
        ),
    ];
    CAUSES
        .iter()
        .find(|(pattern, _)| message.contains(pattern))
        .map(|(_, why)| *why)
}

/// The acceptance criteria of issue 4 §1 a cell fails (empty: it passes): no
/// error (a crash would end the process, a caught panic is fmi2Fatal, an
/// error), no timeout of the run at h, no non-finite output, no completed
/// step outside the model's bounds, every discard explained — in the run at
/// h and in the reference run (up to where the time bound cut it: a
/// reference run is made where affordable).
pub fn acceptance(r: &CellResult) -> Vec<String> {
    let mut fails = Vec::new();
    for (what, run, reference) in
        std::iter::once(("h", &r.coarse, false)).chain(r.fine.as_ref().map(|f| ("h/100", f, true)))
    {
        match &run.outcome {
            Some(Outcome::Error { message }) => fails.push(format!("{what}: error: {message}")),
            // The reference run is made where affordable; one the time bound
            // cuts is not (`CellResult::fine_skipped` says so), and the
            // bound itself holds.
            Some(Outcome::Timeout { .. }) if reference => {}
            Some(Outcome::Timeout { t }) => fails.push(format!("{what}: timeout at t = {t}")),
            None => fails.push(format!("{what}: no outcome")),
            _ => {}
        }
        if run.n_nonfinite > 0 {
            fails.push(format!("{what}: non-finite outputs: {:?}", run.nonfinite));
        }
        if run.n_violations > 0 {
            fails.push(format!("{what}: bounds: {:?}", run.violations));
        }
        for d in &run.discards {
            if explain(&d.message).is_none() {
                fails.push(format!(
                    "{what}: unexplained discard at t = {}: {}",
                    d.t, d.message
                ));
            }
        }
    }
    fails
}
