//! The grid of the stability matrix and the input program of a cell.

use super::*;

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

/// The rest length L0 of every model's muscle in the matrix (m).
pub const L0: f64 = 0.05;

/// The reference run takes steps this many times smaller.
pub const FINE_FACTOR: usize = 100;
/// The reference run is made when it takes at most this many steps.
pub const FINE_BUDGET: usize = 1_000_000;
/// Agreement tolerance with the reference run, relative: at every
/// communication point |x − x_ref| ≤ AGREEMENT_TOL · max(sigma0, |x_ref|) for
/// x = stress and x = active_stress (see [`Agreement`]).
pub const AGREEMENT_TOL: f64 = 0.02;
/// Bound of one cell (coarse and reference run together) in CPU time of
/// the thread running it ([`Watch`]), checked between steps: a cell's
/// outcome does not depend on the machine's load. A cell past it is
/// recorded as `timeout`. The reported `seconds` are wall time.
pub const CELL_TIME_LIMIT: Duration = Duration::from_secs(120);
/// A single FMI call (or a program's setup) that has not returned after
/// this much CPU time of its thread is a hang: the watchdog names the cell
/// and ends the process.
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

pub(crate) struct Builder {
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

pub(crate) const LAMBDA_DOT_MIN: f64 = 17.0;

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
