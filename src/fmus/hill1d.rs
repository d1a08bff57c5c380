//! `HillMuscle1D`: the 1D Hill reduction of the law as an FMI 2.0
//! Co-Simulation model (MODEL_NOTES "The 1D Hill reduction" and
//! "Co-simulation conventions").
//!
//! A prismatic muscle of rest length `L0` and cross-section `area` in
//! homogeneous uniaxial stress. Each step:
//! 1. the activation level follows da/dt = S (u − a) exactly for the command
//!    held over the step (or linear over the step when an input derivative is
//!    set); with `activation_dynamics = false` the level is the command;
//! 2. the length moves linearly from where it is to the input `length` — or
//!    to `length + h · dlength/dt` when the importer set an input derivative
//!    — and the step ends there;
//! 3. the uniaxial state (lateral stretch from σ22 = 0, CE–SEE solve inside)
//!    is solved at the end of the step, in substeps when the error estimate
//!    of the CE–SEE update asks for them ([`piece_error`], `solve_step`):
//!    each substep is MODEL_NOTES' backward-Euler step over its own length
//!    (CE rate from the CE stretch change over it), so a step that needs no
//!    substep — the usual case with smooth inputs — is exactly that step over
//!    h; stiff transients (a stiff SEE, fast activation, length jumps) get
//!    as many as keep the estimated local error of the SEE stress below
//!    [`SUBSTEP_RTOL`]·sigma0. The state is committed only on success.
//!
//! At initialization the muscle is in isometric equilibrium at its initial
//! length and `initial_activation`.

use super::common::{
    check_range, check_restored_drive, check_restored_history, check_unit_interval, parameter,
    real, substep_tolerance_type, units,
};
pub use super::common::{SUBSTEP_RTOL, SUBSTEP_TOLERANCE_RANGE};
use crate::fmi2::bytes::{ByteReader, ByteWriter};
use crate::fmi2::{
    Causality, Initial, Model, ModelError, ModelInfo, ScalarVariable, SetOutcome, StepError,
    VarType, Variability,
};
use crate::law::activation::{level_at, Decay};
use crate::law::force_length::force_length;
use crate::law::force_velocity::branch_included;
use crate::law::hill_fibre::{backward_euler_error, ce_stretch};
use crate::law::params::{AREA_RANGE, L0_RANGE, LENGTH_RANGE};
use crate::law::series_element::see_stiffness;
use crate::law::uniaxial::{cauchy_sensitivity, evaluable_stretch_range, Sensitivity};
use crate::law::{
    solve_uniaxial_with, FibreHistory, FibreRate, ParamId, Params, Uniaxial, PARAMETERS,
};
use crate::scene::{LawOf, Scene, Value};
use crate::step_control::MAX_CONTROLLED_TRIES;
use std::marker::PhantomData;

/// Rest length of the paper's specimen [m].
pub const DEFAULT_L0: f64 = 0.05;

/// Default cross-section [m²]: the mean cross-section V0/L0 of the paper's
/// fusiform specimen ([`crate::specimen::MEAN_AREA`] ≈ 1.6849e-4), the same
/// stress scale as the FE muscle.
pub const DEFAULT_AREA: f64 = crate::specimen::MEAN_AREA;

/// A variable of `HillMuscle1D`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Var {
    Param(ParamId),
    L0,
    Area,
    ActivationDynamics,
    InitialActivation,
    AdaptiveSubsteps,
    SubstepTolerance,
    Activation,
    Length,
    Out(Output),
}

/// The outputs, in table order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    Force,
    Stress,
    CauchyStress,
    ActivationLevel,
    FibreStretch,
    CeStretch,
    SeeStretch,
    ActiveStress,
    PassiveStress,
    /// d force / d length of the step map (scenes only: not in the full
    /// `HillMuscle1D`, whose masters call fmi2GetDirectionalDerivative).
    Stiffness,
}

const OUTPUTS: [(Output, &str, &str, Option<&str>); 9] = [
    (
        Output::Force,
        "force",
        "Axial muscle force, tension positive",
        Some("N"),
    ),
    (
        Output::Stress,
        "stress",
        "Engineering (nominal) stress: force / area",
        Some("Pa"),
    ),
    (
        Output::CauchyStress,
        "cauchy_stress",
        "Axial Cauchy (true) stress",
        Some("Pa"),
    ),
    (
        Output::ActivationLevel,
        "activation_level",
        "Activation level a",
        Some("1"),
    ),
    (
        Output::FibreStretch,
        "fibre_stretch",
        "Modified fibre stretch J^(-1/3) lambda",
        Some("1"),
    ),
    (
        Output::CeStretch,
        "ce_stretch",
        "Contractile element stretch lambda_m",
        Some("1"),
    ),
    (
        Output::SeeStretch,
        "see_stretch",
        "Series elastic element stretch lambda_s",
        Some("1"),
    ),
    (
        Output::ActiveStress,
        "active_stress",
        "SEE (= CE) nominal stress sigma_s",
        Some("Pa"),
    ),
    (
        Output::PassiveStress,
        "passive_stress",
        "Rest of the nominal stress: stress - active_stress",
        Some("Pa"),
    ),
];
const N_OUT: usize = OUTPUTS.len();

/// The two inputs, as indices into the sensitivity table.
const IN_ACTIVATION: usize = 0;
const IN_LENGTH: usize = 1;

/// Estimated local error of the backward-Euler CE–SEE update over a piece of
/// length `hs`, as SEE stress [Pa]. `start` is the piece's start: the CE
/// rate of the piece before it and the activation level; `u` and `a` the
/// solution at the piece's end, `stretch_rate` the stretch rate λ̇ over it.
///
/// The CE stretch λm obeys the ODE λ̇m = r(t, λm) defined by
/// σ_s(λs) = σ0 a f_λ f_v(λ̇m) with λs = ((1 + k) λ̄f − λm)/k; each piece
/// takes one backward-Euler step of it. The local error of backward Euler is
/// (hs/2)(r(end) − r(start)) + O(hs³) (its difference from the trapezoidal
/// rule). The rate at the end is the piece's backward-Euler rate; the rate at
/// the start is the previous piece's, which satisfies the ODE at the start
/// exactly. λ̄f is given, so the error of λs is that of λm over k, and of
/// σ_s, σ_s' = alpha (σ_s + beta) times that. The special cases:
/// - the CE can carry nothing at the end (σ0 a f_λ = 0): σ_s = 0 there,
///   exactly as in the exact solution: no error;
/// - the SEE ends the piece slack (σ_s = 0 with σ0 a f_λ > 0: the fibre
///   shortens faster than the CE can, lambda_dot_min): exact if it is still
///   slack at the end, i.e. if the CE rate the kinematics ask for there,
///   (1 + k) dλ̄f/dt = (1 + k) (dλ̄f/dλ) λ̇ (`stretch_rate` = λ̇ over the
///   piece), is still below lambda_dot_min. If not — the shortening stopped
///   inside the piece, as when the volume takes up the length change — the
///   SEE has taken up load again by the end, and the error is estimated as
///   below with that kinematic rate in place of the backward-Euler one;
/// - a piece that starts from a slack SEE takes the rate the kinematics set
///   there ((1 + k) dλ̄f/dt, below lambda_dot_min) as its start rate: where
///   the SEE takes up load inside the piece the estimate is large, and the
///   piece is cut until that moment is resolved (the rate is continuous
///   there when λ̄f(t) is smooth);
/// - σ_s stays within [0, f_v,max σ0 a], so no error exceeds that range.
pub fn piece_error(
    p: &Params,
    start: (f64, f64),
    u: &Uniaxial,
    a: f64,
    stretch_rate: f64,
    hs: f64,
) -> f64 {
    let (start_rate, start_a) = start;
    let f = &u.fibre;
    let mut rate = f.lambda_dot_m;
    if f.sigma_see == 0.0 {
        let drive = p.sigma0 * a * force_length(u.lambda_f, p.lambda_opt).0;
        if drive == 0.0 {
            return 0.0;
        }
        let kinematic = (1.0 + p.k) * u.d_dlambda.lambda_f * stretch_rate;
        if kinematic <= p.lambda_dot_min {
            return 0.0;
        }
        rate = kinematic;
    }
    // The largest SEE stress the CE can hold over the piece.
    let cap = p.fv_max() * p.sigma0 * a.max(start_a);
    backward_euler_error(p, cap, start_rate, rate, hs)
}

/// How many halvings bring a piece within `factor` (< 1) of its length:
/// the smallest n with 2^(−n) ≤ factor.
fn halvings(factor: f64) -> u32 {
    let mut n = 0;
    let mut f = 1.0;
    while f > factor && n < 64 {
        f *= 0.5;
        n += 1;
    }
    n
}

/// How many doublings fit in `factor` (≥ 0): the largest n with 2^n ≤ factor.
fn doublings(factor: f64) -> u32 {
    let mut n = 0;
    let mut f = 2.0;
    while f <= factor && n < 64 {
        f *= 2.0;
        n += 1;
    }
    n
}

/// Σ cᵢ sᵢ over the terms with cᵢ ≠ 0.
fn combine(terms: &[(&Sensitivity, f64)]) -> Sensitivity {
    let mut r = Sensitivity::default();
    for &(s, c) in terms {
        if c != 0.0 {
            r.q += c * s.q;
            r.j += c * s.j;
            r.mu += c * s.mu;
            r.tau11 += c * s.tau11;
            r.lambda_f += c * s.lambda_f;
            r.lambda_s += c * s.lambda_s;
        }
    }
    r
}

/// A solved step ([`Hill1D::solve_step`]): the state at its end, the level
/// and ∂a/∂u there, the total sensitivities of the end state with respect to
/// the inputs (activation, length), and the solver counts.
struct Stepped {
    u: Uniaxial,
    a: f64,
    da_du: f64,
    sens: [Sensitivity; 2],
    stats: StepStatistics,
}

/// The full `HillMuscle1D`: every component, input and output of the 1D
/// model (the scene `fmu_build/scenes/hill_muscle_1d.toml`).
pub type Hill1D = Hill1DModel<crate::scene::shipped::HillMuscle1D>;

/// The 1D Hill muscle FMU model of scene `S` ([`crate::scene`]): the
/// scene's components are compile-time constants here and in the law
/// ([`LawOf`]), so an absent component's code is not in its binary.
#[derive(Clone, Debug, PartialEq)]
pub struct Hill1DModel<S: Scene> {
    scene: PhantomData<S>,
    params: Params,
    l0: f64,
    area: f64,
    activation_dynamics: bool,
    initial_activation: f64,
    /// Cut steps into substeps by the error estimate of the CE–SEE update
    /// (false: one backward-Euler step per communication step).
    adaptive_substeps: bool,
    /// Tolerance of that estimate, relative to sigma0.
    substep_tolerance: f64,
    // Inputs and their derivatives for the next step.
    command: f64,
    /// The length input; `None` until the importer sets it, when the length is
    /// `L0` (the input's start value "= L0" of issue 2, also after `L0` is
    /// changed).
    length: Option<f64>,
    command_rate: f64,
    length_rate: f64,
    // Committed state.
    activation_level: f64,
    history: FibreHistory,
    /// The CE stretch rate λ̇m of the last (sub)step: the rate at the start of
    /// the next step, for the error estimate of its CE–SEE update (0 at the
    /// isometric start).
    ce_rate: f64,
    lambda: f64,
    /// q = J^(1/3) of the last solve.
    q: f64,
    /// Predictors of the next step's q and λs (the solvers' starting points
    /// only: they change the cost, not the converged result).
    predict: Predictor,
    /// The stretches length/L0 the law can evaluate (from `b`, fixed after
    /// initialization; derived, recomputed on restore).
    stretch_range: (f64, f64),
    /// e^(−S h) of the last step (a cache: S is fixed, h usually repeats).
    decay: Option<Decay>,
    // Outputs of the last solve and what their partials d out / d input need.
    outputs: [f64; N_OUT],
    jacobian: Jacobian,
    /// Solver counts of the last completed step or initialization.
    statistics: Diagnostics,
    /// Whether steps at rest take the shortcut (on; off only to test that
    /// it changes nothing). Not state: not serialized, not compared.
    rest_shortcut: Switch,
}

/// A switch that is not part of the model's state: equal to every other.
#[derive(Clone, Copy, Debug)]
struct Switch(bool);

impl PartialEq for Switch {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Solver counts of the last completed step (or of the initialization), for
/// diagnostics such as the stability matrix (`cargo run --release --example
/// stability`). Not part of the FMU's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepStatistics {
    /// Substeps the step was solved in (1: in one piece; see the module
    /// docs).
    pub substeps: u32,
    /// Substeps tried and rejected by the error estimate (their solves are
    /// counted in the iterations below).
    pub rejected_substeps: u32,
    /// Newton iterations of the lateral solve, summed over the substeps
    /// (each one evaluation of the law; a count above 100 in one solve means
    /// the bracketed fallback ran).
    pub lateral_iterations: u32,
    /// Iterations of the CE–SEE solve, summed over every evaluation of the law.
    pub ce_iterations: u32,
    /// The step was taken at rest ([`Hill1DModel::set_rest_shortcut`]):
    /// activation command and level exactly 0, no CE–SEE solve, one piece.
    pub at_rest: bool,
}

/// [`StepStatistics`] held by the model: diagnostics, not state. Not
/// serialized, and equal to every other, so that two models in the same state
/// compare equal whatever their solvers took to get there.
#[derive(Clone, Copy, Debug, Default)]
struct Diagnostics(StepStatistics);

impl PartialEq for Diagnostics {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// What the partial derivatives of the outputs with respect to the inputs
/// need from the last solve. The 18 partials are formed on demand in
/// [`Jacobian::partial`]: forming them every step would cost more than the
/// rest of the step's bookkeeping, and only masters that call
/// fmi2GetDirectionalDerivative use them.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Jacobian {
    /// Per input (activation, length): total sensitivities of the uniaxial
    /// state at the end of the step with respect to the input (through every
    /// substep of the step).
    sens: [Sensitivity; 2],
    /// dP/d(input).
    dnominal: [f64; 2],
    /// d(activation level)/d(input): ∂a/∂u and 0.
    dlevel: [f64; 2],
    tau11: f64,
    j: f64,
    /// dσ_s/dλs.
    dsigma_see: f64,
}

impl Jacobian {
    /// ∂ output / ∂ input (`column` is IN_ACTIVATION or IN_LENGTH).
    fn partial(&self, out: Output, column: usize, k: f64, area: f64) -> f64 {
        let s = &self.sens[column];
        let dnom = self.dnominal[column];
        let dsee = self.dsigma_see * s.lambda_s;
        match out {
            Output::Force => dnom * area,
            Output::Stress => dnom,
            // σ11 = τ11 / J.
            Output::CauchyStress => cauchy_sensitivity(self.tau11, self.j, s),
            Output::ActivationLevel => self.dlevel[column],
            Output::FibreStretch => s.lambda_f,
            // λm = (1 + k) λ̄f − k λs.
            Output::CeStretch => ce_stretch(k, s.lambda_f, s.lambda_s),
            Output::SeeStretch => s.lambda_s,
            Output::ActiveStress => dsee,
            Output::PassiveStress => dnom - dsee,
            // A second derivative: not provided (partial_derivative refuses).
            Output::Stiffness => f64::NAN,
        }
    }

    /// Whether every value of [`Jacobian::to_values`] is finite (without
    /// collecting them: this runs every step).
    fn all_finite(&self) -> bool {
        self.sens.iter().all(|s| {
            [s.q, s.j, s.mu, s.tau11, s.lambda_f, s.lambda_s]
                .iter()
                .all(|x| x.is_finite())
        }) && self
            .dnominal
            .iter()
            .chain(&self.dlevel)
            .chain(&[self.tau11, self.j, self.dsigma_see])
            .all(|x| x.is_finite())
    }

    fn to_values(self) -> Vec<f64> {
        let mut v = Vec::with_capacity(19);
        for s in &self.sens {
            v.extend([s.q, s.j, s.mu, s.tau11, s.lambda_f, s.lambda_s]);
        }
        v.extend(self.dnominal);
        v.extend(self.dlevel);
        v.extend([self.tau11, self.j, self.dsigma_see]);
        v
    }

    fn from_values(v: &[f64]) -> Option<Jacobian> {
        if v.len() != 19 {
            return None;
        }
        let sens = |o: usize| Sensitivity {
            q: v[o],
            j: v[o + 1],
            mu: v[o + 2],
            tau11: v[o + 3],
            lambda_f: v[o + 4],
            lambda_s: v[o + 5],
        };
        Some(Jacobian {
            sens: [sens(0), sens(6)],
            dnominal: [v[12], v[13]],
            dlevel: [v[14], v[15]],
            tau11: v[16],
            j: v[17],
            dsigma_see: v[18],
        })
    }
}

/// Prediction of a solved quantity x (q or λs) for the next step:
/// x + s_λ Δλ + s_a Δa + (2 ẋ_h − ẋ_h,prev) h, where s are the total
/// sensitivities of the last solve and ẋ_h is the history-driven rate of the
/// last step (its change not explained by Δλ and Δa, per unit time),
/// extrapolated linearly from the step before. A smooth input is predicted to
/// O(h³) and a jump in λ or a to first order. Measured on the benchmark's
/// stretch-and-release: 1.000 lateral evaluations and 1.15 CE–SEE iterations
/// per step (2.16 with the rate held constant). Only the solvers' starting
/// points depend on it, not the converged result.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Predictor {
    /// (dq/dλ, dq/da, history rate of q, the step before's)
    q: [f64; 4],
    /// (dλs/dλ, dλs/da, history rate of λs, the step before's)
    lambda_s: [f64; 4],
}

impl Predictor {
    fn predict(s: &[f64; 4], x: f64, dlambda: f64, da: f64, h: f64) -> f64 {
        // The history rate extrapolated linearly from the last two steps.
        x + s[0] * dlambda + s[1] * da + (2.0 * s[2] - s[3]) * h
    }

    /// The predictor after a step (h, Δλ, Δa, Δq, Δλs) that ended at `u`
    /// (`None`: initialization, no history rate yet).
    fn after(&self, u: &Uniaxial, step: Option<(f64, f64, f64, f64, f64)>) -> Predictor {
        // Only a solver's starting point: a rate that overflows (a step of a
        // few ulps) is dropped rather than committed.
        let rate = |s: &[f64; 4], dx: f64, dl: f64, da: f64, h: f64| {
            let r = (dx - s[0] * dl - s[1] * da) / h;
            if r.is_finite() {
                r
            } else {
                0.0
            }
        };
        let (rq, rls) = match step {
            Some((h, dl, da, dq, dls)) => (
                rate(&self.q, dq, dl, da, h),
                rate(&self.lambda_s, dls, dl, da, h),
            ),
            None => (0.0, 0.0),
        };
        let (pq, pls) = match step {
            Some(_) => (self.q[2], self.lambda_s[2]),
            None => (0.0, 0.0),
        };
        Predictor {
            q: [
                u.d_dlambda.q,
                u.d_dactivation.q,
                rq,
                if step.is_some() { pq } else { rq },
            ],
            lambda_s: [
                u.d_dlambda.lambda_s,
                u.d_dactivation.lambda_s,
                rls,
                if step.is_some() { pls } else { rls },
            ],
        }
    }
}

impl<S: Scene> Hill1DModel<S> {
    /// Whether the scene has the contractile (and series) element.
    const CE: bool = S::SPEC.components.contractile;
    /// Whether the scene has the activation input (then also the CE).
    const ACTIVATION: bool = S::SPEC.inputs.activation;

    /// Outputs and the data of their partials (the Jacobian) from a solved
    /// uniaxial state; `sens` are its total sensitivities with respect to the
    /// inputs (activation, length) and `da_du` is ∂a/∂u of the step map.
    fn evaluate(
        &self,
        u: &Uniaxial,
        a: f64,
        sens: [Sensitivity; 2],
        da_du: f64,
    ) -> ([f64; N_OUT], Jacobian) {
        let fibre = &u.fibre;
        let sigma_s = fibre.sigma_see;
        let nominal = u.nominal_stress();
        let values = [
            nominal * self.area,
            nominal,
            u.cauchy_stress(),
            a,
            u.lambda_f,
            fibre.history.lambda_m,
            fibre.history.lambda_s,
            sigma_s,
            nominal - sigma_s,
        ];
        let mut jacobian = Jacobian {
            tau11: u.tau11,
            j: u.j,
            // dσ_s/dλs = α (σ_s + β) (eq 31).
            dsigma_see: see_stiffness(sigma_s, self.params.alpha, self.params.beta),
            ..Jacobian::default()
        };
        // P = τ11 / λ: dP = dτ11 / λ − τ11 dλ / λ², with dλ/dL = 1/L0 (the
        // stretch at the end of the step is L/L0) and dλ/du = 0.
        let dlambda = [0.0, 1.0 / self.l0];
        for c in [IN_ACTIVATION, IN_LENGTH] {
            if c == IN_ACTIVATION && !Self::ACTIVATION {
                continue; // no activation input: no such partial
            }
            jacobian.dnominal[c] =
                sens[c].tau11 / u.lambda - u.tau11 * dlambda[c] / (u.lambda * u.lambda);
        }
        jacobian.sens = sens;
        jacobian.dlevel = [da_du, 0.0];
        (values, jacobian)
    }

    /// Make a solved state the committed one.
    /// `h` is the step length (`None` at initialization).
    fn commit(
        &mut self,
        u: &Uniaxial,
        a: f64,
        h: Option<f64>,
        outputs: [f64; N_OUT],
        jacobian: Jacobian,
        statistics: StepStatistics,
    ) {
        let step = h.map(|h| {
            (
                h,
                u.lambda - self.lambda,
                a - self.activation_level,
                u.q - self.q,
                u.fibre.history.lambda_s - self.history.lambda_s,
            )
        });
        self.predict = self.predict.after(u, step);
        self.activation_level = a;
        self.history = u.fibre.history;
        // A step of a few ulps makes the rate overflow; only the error
        // estimate of the next step reads it, and ±f64::MAX says the same.
        self.ce_rate = match u.fibre.lambda_dot_m {
            r if r.is_nan() => 0.0,
            r => r.clamp(-f64::MAX, f64::MAX),
        };
        self.lambda = u.lambda;
        self.q = u.q;
        self.outputs = outputs;
        self.jacobian = jacobian;
        self.statistics = Diagnostics(statistics);
    }

    /// The activation level `tau` into the step and ∂a/∂u ([`level_at`]:
    /// the exact dynamics for the command held (or linear) over the step, or
    /// without dynamics the command itself). `decay` is e^(−S tau).
    fn level(&self, tau: f64, decay: f64) -> (f64, f64) {
        if !Self::CE {
            // No contractile element: no activation (the command is 0 and
            // nothing reads the level).
            return (0.0, 0.0);
        }
        level_at(
            S::SPEC.components.activation_dynamics && self.activation_dynamics,
            self.activation_level,
            self.command,
            self.command_rate,
            self.params.s,
            tau,
            decay,
        )
    }

    /// The step from the committed state to stretch `lambda_end` over `h`,
    /// in substeps whose size the error estimate of the CE–SEE update
    /// controls ([`piece_error`]). Within the step the stretch moves linearly
    /// to `lambda_end` (the co-simulation convention) and the activation level
    /// follows [`Hill1D::level`]; each substep is the backward-Euler step of
    /// MODEL_NOTES over its own length. The first try is the whole step. A
    /// substep whose estimate exceeds [`SUBSTEP_RTOL`]·sigma0 is tried again
    /// shorter, and after an accepted one the next may be longer: the usual
    /// controller of a first-order method, h_new = h · 0.9 (tol/err)^(1/2),
    /// rounded down to the dyadic sizes h/2^k that fit the dyadic grid of the
    /// step, so that the substeps tile the step exactly and are piecewise
    /// constant in the inputs (the step map is then smooth between switches
    /// of the pattern, and its partial derivatives — chained through the
    /// substeps — are those of the map). After [`MAX_CONTROLLED_TRIES`] tries the rest
    /// of the step is taken in one piece (backward Euler is stable for any
    /// length: the result stays bounded, only less accurate). `a_end` is the
    /// level at the end of the step. Changes nothing (the caller commits).
    #[inline(always)]
    fn solve_step(&self, h: f64, lambda_end: f64, a_end: (f64, f64)) -> Result<Stepped, StepError> {
        if !Self::CE {
            return self.solve_passive(h, lambda_end);
        }
        // At rest — command 0 (not rising) and level 0, so the level is 0
        // throughout the step — the CE carries nothing (σ0 a f_λ = 0): no
        // CE–SEE solve and an error estimate of exactly 0, hence one piece.
        if self.rest_shortcut.0
            && self.command == 0.0
            && self.command_rate <= 0.0
            && self.activation_level == 0.0
            && a_end.0 == 0.0
        {
            return self.solve_rest(h, lambda_end, a_end.1);
        }
        // Positions within the step in units of h / 2^FINEST.
        const FINEST: u32 = 40;
        const WHOLE: u64 = 1 << FINEST;
        let p = &self.params;
        let tol = self.substep_tolerance * p.sigma0;
        let (lambda0, a0) = (self.lambda, self.activation_level);
        let mut stats = StepStatistics::default();
        // The start of the current piece: position in the step, stretch,
        // level, fibre history, CE rate and the last accepted solve.
        let (mut pos, mut lam, mut a) = (0u64, lambda0, a0);
        let (mut hist, mut rate) = (self.history, self.ce_rate);
        // The last accepted piece: (q, λs) at its start and end, its length.
        let mut prev: Option<([f64; 2], [f64; 2], f64)> = None;
        // d λm / d(input) of the history (the start of the piece): how the
        // earlier pieces made it depend on this step's inputs.
        let mut chain = [0.0; 2];
        // The piece is h / 2^level long.
        let mut level = 0u32;
        let mut tries = 0u32;
        loop {
            tries += 1;
            let forced = tries >= MAX_CONTROLLED_TRIES;
            let end = if forced {
                WHOLE
            } else {
                pos + (WHOLE >> level)
            };
            let last = end == WHOLE;
            let frac = end as f64 / WHOLE as f64;
            let hs_j = if forced {
                h - h * (pos as f64 / WHOLE as f64)
            } else {
                h / (1u64 << level) as f64
            };
            let lam_j = if last {
                lambda_end
            } else {
                lambda0 + (lambda_end - lambda0) * frac
            };
            let (a_j, da_du_j) = if last {
                a_end
            } else {
                let tau = h * frac;
                self.level(tau, (-p.s * tau).exp())
            };
            let (dl, da) = (lam_j - lam, a_j - a);
            // Starting points only (they change the cost, not the result).
            let (q_guess, ls_guess) = match &prev {
                None => (
                    Predictor::predict(&self.predict.q, self.q, dl, da, hs_j),
                    Predictor::predict(&self.predict.lambda_s, hist.lambda_s, dl, da, hs_j),
                ),
                // Linear in time from the last piece.
                Some((x0, x1, hp)) => {
                    let r = hs_j / hp;
                    (x1[0] + (x1[0] - x0[0]) * r, x1[1] + (x1[1] - x0[1]) * r)
                }
            };
            let start = FibreHistory {
                // The CE–SEE solve's starting point (module docs of hill_fibre).
                lambda_s: ls_guess.max(1.0),
                lambda_m: hist.lambda_m,
            };
            let u = solve_uniaxial_with::<LawOf<S>>(
                p,
                lam_j,
                a_j,
                &start,
                FibreRate::Step { h: hs_j },
                q_guess,
            )
            .map_err(|e| {
                StepError::Discard(self.unsolvable_step(lam_j * self.l0, lam_j - lam, hs_j, &e.0))
            })?;
            stats.lateral_iterations = stats.lateral_iterations.saturating_add(u.iterations);
            stats.ce_iterations = stats.ce_iterations.saturating_add(u.ce_iterations);
            // Without the CE the step map has no history: one piece, exact.
            let err = if Self::CE {
                piece_error(p, (rate, a), &u, a_j, dl / hs_j, hs_j)
            } else {
                0.0
            };
            // A piece of h/2^FINEST is taken whatever its estimate (an event
            // faster than that, like a SEE snapping slack, is not resolved by
            // shorter pieces), and so is one that cannot be halved in binary64
            // (a step of a few ulps).
            // Without substeps every step is one piece.
            let acceptable = err <= tol || !self.adaptive_substeps; // false for NaN
            if !forced && level < FINEST && hs_j * 0.5 >= f64::MIN_POSITIVE && !acceptable {
                // Too large (or not finite): the same start, a shorter piece,
                // at least half as long.
                stats.rejected_substeps += 1;
                level += if err.is_finite() {
                    halvings(0.9 * (tol / err).sqrt()).max(1)
                } else {
                    4
                };
                level = level.min(FINEST);
                continue;
            }
            u.fibre
                .history
                .check_physical(p.k, u.lambda_f)
                .map_err(|e| StepError::Discard(format!("length = {} m: {e}", lam_j * self.l0)))?;
            // Chain rule through the piece: its state depends on the inputs
            // through its stretch (d λ_j/dL = frac/L0), its level (∂a_j/∂u)
            // and the history's CE stretch (`chain`).
            self.check_fv_branch(&u)?;
            let drivers = [[da_du_j, 0.0], [0.0, frac / self.l0]];
            let mut sens = [Sensitivity::default(); 2];
            for c in [IN_ACTIVATION, IN_LENGTH] {
                if c == IN_ACTIVATION && !Self::ACTIVATION {
                    continue; // the scene has no activation input
                }
                sens[c] = combine(&[
                    (&u.d_dactivation, drivers[c][0]),
                    (&u.d_dlambda, drivers[c][1]),
                    (&u.d_dhistory, chain[c]),
                ]);
                chain[c] = ce_stretch(p.k, sens[c].lambda_f, sens[c].lambda_s);
            }
            stats.substeps += 1;
            if last {
                return Ok(Stepped {
                    u,
                    a: a_j,
                    da_du: da_du_j,
                    sens,
                    stats,
                });
            }
            // The next piece: up to 4x longer, as far as the estimate allows
            // and the grid of its size admits (its start a multiple of it).
            let factor = if err > 0.0 {
                0.9 * (tol / err).sqrt()
            } else {
                f64::INFINITY
            };
            let mut next = level.saturating_sub(doublings(factor).min(2));
            while next < level && end % (WHOLE >> next) != 0 {
                next += 1;
            }
            level = next;
            (pos, lam, a) = (end, lam_j, a_j);
            (hist, rate) = (u.fibre.history, u.fibre.lambda_dot_m);
            if !rate.is_finite() {
                rate = if rate.is_nan() {
                    0.0
                } else {
                    rate.clamp(-f64::MAX, f64::MAX)
                };
            }
            let (q0, ls0) = match prev {
                Some((_, x1, _)) => (x1[0], x1[1]),
                None => (self.q, self.history.lambda_s),
            };
            prev = Some(([q0, ls0], [u.q, u.fibre.history.lambda_s], hs_j));
        }
    }
    /// The lateral solve of a step at zero drive (activation 0, MODEL_NOTES
    /// "Hill fibre" with σ0 a f_λ = 0) to `lambda_end`, from the committed
    /// history and the predicted q: what [`Self::solve_passive`] and
    /// [`Self::solve_rest`] share, so that both give the general path's one
    /// piece bit for bit.
    #[inline(always)]
    fn solve_at_zero_drive(&self, h: f64, lambda_end: f64) -> Result<Uniaxial, StepError> {
        let q_guess = Predictor::predict(&self.predict.q, self.q, lambda_end - self.lambda, 0.0, h);
        solve_uniaxial_with::<LawOf<S>>(
            &self.params,
            lambda_end,
            0.0,
            &self.history,
            FibreRate::Step { h },
            q_guess,
        )
        .map_err(|e| {
            StepError::Discard(self.unsolvable_step(
                lambda_end * self.l0,
                lambda_end - self.lambda,
                h,
                &e.0,
            ))
        })
    }

    /// The step of a scene without the contractile element: the fibre is the
    /// parallel element alone, so the state at the end of the step depends
    /// on the end stretch only (no history, no activation: MODEL_NOTES "Hill
    /// fibre" with σ0 a f_λ = 0) — one lateral solve on the passive law, no
    /// substeps (the error estimate of the CE–SEE update is exactly 0), no
    /// SEE predictor, no activation or history sensitivities. The lateral
    /// solve starts from the same predicted q as the general path's one
    /// piece, so the result is the complete law's at activation 0, bit for
    /// bit (tests/scenes.rs).
    #[inline(always)]
    fn solve_passive(&self, h: f64, lambda_end: f64) -> Result<Stepped, StepError> {
        let u = self.solve_at_zero_drive(h, lambda_end)?;
        let stats = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: 0,
            at_rest: true,
        };
        let sens = [
            Sensitivity::default(),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        Ok(Stepped {
            u,
            a: 0.0,
            da_du: 0.0,
            sens,
            stats,
        })
    }

    /// The step at rest (see [`Hill1DModel::solve_step`]): the general path's
    /// one piece without what cannot change it — the level within the step
    /// (0), the SEE predictor (the CE–SEE solve is not run at zero drive,
    /// so its starting point is not read), the error estimate (0), the
    /// f_v branch check (σ_s = 0). The same lateral solve from the same
    /// predicted q, hence the same result bit for bit (tests/scenes.rs,
    /// `the_rest_shortcut_changes_nothing`).
    fn solve_rest(&self, h: f64, lambda_end: f64, da_du: f64) -> Result<Stepped, StepError> {
        let p = &self.params;
        let u = self.solve_at_zero_drive(h, lambda_end)?;
        u.fibre
            .history
            .check_physical(p.k, u.lambda_f)
            .map_err(|e| StepError::Discard(format!("length = {} m: {e}", lambda_end * self.l0)))?;
        let stats = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: u.ce_iterations,
            at_rest: true,
        };
        let sens = [
            combine(&[(&u.d_dactivation, da_du)]),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        Ok(Stepped {
            u,
            a: 0.0,
            da_du,
            sens,
            stats,
        })
    }

    /// Turn the shortcut of steps at rest on (the default) or off. It changes
    /// no result (a test compares both bit for bit); off only for that test
    /// and for measuring what it saves.
    pub fn set_rest_shortcut(&mut self, on: bool) {
        self.rest_shortcut = Switch(on);
    }

    /// A scene without one of the f_v branches (eq 12) computes f_v = 1 on
    /// it ([`crate::law::force_velocity::force_velocity_with`]); a step whose
    /// CE–SEE root lies on the absent branch — the CE carrying force while
    /// moving faster than 1e-9 |lambda_dot_min| in that direction, where
    /// f_v would differ from 1 by more than ~1e-9 — is not what the scene
    /// can compute: it is discarded with a message naming the branch. (Below
    /// that rate the round-off of an isometric hold stays inside.)
    fn check_fv_branch(&self, u: &Uniaxial) -> Result<(), StepError> {
        let c = S::SPEC.components;
        if !Self::CE || (c.fv_shortening && c.fv_lengthening) {
            return Ok(());
        }
        let rate = u.fibre.lambda_dot_m;
        let p = &self.params;
        if u.fibre.sigma_see > 0.0
            && !branch_included::<LawOf<S>>(rate)
            && rate.abs() > 1e-9 * p.lambda_dot_min.abs()
        {
            let (branch, key) = if rate > 0.0 {
                ("lengthening", "fv_lengthening")
            } else {
                ("shortening", "fv_shortening")
            };
            return Err(StepError::Discard(format!(
                "the contractile element is {branch} (CE stretch rate {rate:e} 1/s) while carrying \
                 {:e} Pa, but scene {} has no {branch} branch of the force-velocity relation \
                 (components.{key} = false): use a scene with it",
                u.fibre.sigma_see,
                S::SPEC.model_identifier
            )));
        }
        Ok(())
    }

    /// Solver counts of the last completed step (or of the initialization).
    pub fn last_step_statistics(&self) -> StepStatistics {
        self.statistics.0
    }

    /// The current length input (`L0` until set).
    fn length(&self) -> f64 {
        self.length.unwrap_or(self.l0)
    }

    /// Message for a length at which the law cannot be solved: names the
    /// variables and the range of length/L0 the law can evaluate.
    fn unsolvable(&self, length: f64, why: &str) -> String {
        let (lo, hi) = self.stretch_range;
        let lambda = length / self.l0;
        if (lo..=hi).contains(&lambda) {
            // The stretch is evaluable at J = 1: the volume change is what
            // overflows the law (a soft volumetric term, large D).
            format!(
                "no finite equilibrium at length = {length} m (length/L0 = {lambda}): the volume change \
                 the law allows with D = {} 1/Pa grows until its matrix term c exp(b (I1bar - 3)) overflows; \
                 a smaller D (stiffer volumetric term) keeps J near 1; solver: {why}",
                self.params.d_comp
            )
        } else {
            format!(
                "length = {length} m with L0 = {} m (stretch length/L0 = {lambda}) is outside the range the law \
                 can evaluate: keep length/L0 within [{lo:.4}, {hi:.4}] (where the matrix term \
                 c exp(b (I1bar - 3)) is finite, b = {}); solver: {why}",
                self.l0, self.params.b
            )
        }
    }

    /// Message for a step (or substep) of length `h` that changes the stretch
    /// by `dlambda` and whose law cannot be solved: when 1/h or the stretch
    /// rate dlambda / h of the backward-Euler CE update (MODEL_NOTES "Hill
    /// fibre") is not finite, the step is too short to be evaluated and the
    /// message names `communicationStepSize`; otherwise [`Self::unsolvable`].
    fn unsolvable_step(&self, length: f64, dlambda: f64, h: f64, why: &str) -> String {
        if (1.0 / h).is_finite() && (dlambda / h).is_finite() {
            return self.unsolvable(length, why);
        }
        format!(
            "communicationStepSize too short: a step of {h:e} s to length = {length} m (length/L0 changes by \
             {dlambda}) has a non-finite 1/h or stretch rate, so the CE update (backward Euler) cannot be \
             evaluated; use a longer step; solver: {why}"
        )
    }

    fn check_setup(&self) -> Result<(), ModelError> {
        self.params
            .validate()
            .map_err(|e| ModelError(e.to_string()))?;
        check_range("L0", self.l0, L0_RANGE)?;
        check_range("area", self.area, AREA_RANGE)?;
        check_unit_interval("initial_activation", self.initial_activation)?;
        check_range("length", self.length(), LENGTH_RANGE)?;
        Ok(())
    }
}

impl<S: Scene> Model for Hill1DModel<S> {
    type Var = Var;

    /// The scene's identifier, description and DefaultExperiment; the unit
    /// N/m only when the scene exposes `stiffness` (so the full FMU's
    /// interface, and its GUID, are unchanged).
    fn info() -> ModelInfo {
        info_for(&S::SPEC)
    }
    /// The scene's variables: [`all_variables`] restricted to what the scene
    /// exposes ([`crate::scene::SceneSpec::variables`]).
    fn variables() -> Vec<ScalarVariable<Var>> {
        S::SPEC.variables(all_variables())
    }

    fn new() -> Self {
        let mut m = Hill1DModel {
            scene: PhantomData,
            params: Params::default(),
            l0: DEFAULT_L0,
            area: DEFAULT_AREA,
            // Without the component: a = u (its switch compiled in as false).
            activation_dynamics: S::SPEC.components.activation_dynamics,
            initial_activation: 0.0,
            adaptive_substeps: true,
            substep_tolerance: SUBSTEP_RTOL,
            command: 0.0,
            length: None,
            command_rate: 0.0,
            length_rate: 0.0,
            activation_level: 0.0,
            history: FibreHistory::REST,
            ce_rate: 0.0,
            lambda: 1.0,
            q: 1.0,
            predict: Predictor::default(),
            decay: None,
            stretch_range: (0.0, f64::INFINITY),
            outputs: [0.0; N_OUT],
            jacobian: Jacobian::default(),
            statistics: Diagnostics::default(),
            rest_shortcut: Switch(true),
        };
        // Outputs at the start values are those of the initial equilibrium.
        // The scene's start values and constants (checked when the scene was
        // resolved; the setters check them again).
        let all = all_variables();
        crate::scene::apply_settings(&S::SPEC, &all, |var, value| {
            match value {
                Value::Real(x) => m.set_real(var, x),
                Value::Integer(i) => m.set_integer(var, i),
                Value::Boolean(b) => m.set_boolean(var, b),
            }
            .map(|_| ())
            .map_err(|e| e.0)
        })
        .expect("the scene's settings are valid");
        m.initialize().expect("the scene's start values are valid");
        m
    }

    fn get_real(&self, var: Var) -> f64 {
        match var {
            Var::Param(id) => self.params.get(id),
            Var::L0 => self.l0,
            Var::Area => self.area,
            Var::InitialActivation => self.initial_activation,
            Var::Activation => self.command,
            Var::Length => self.length(),
            // d force / d length of the last step map: the same number as
            // fmi2GetDirectionalDerivative(force, length).
            Var::Out(Output::Stiffness) => {
                self.jacobian
                    .partial(Output::Force, IN_LENGTH, self.params.k, self.area)
            }
            Var::Out(o) => self.outputs[o as usize],
            Var::SubstepTolerance => self.substep_tolerance,
            Var::ActivationDynamics | Var::AdaptiveSubsteps => f64::NAN,
        }
    }

    fn get_integer(&self, _var: Var) -> i32 {
        0
    }

    fn get_boolean(&self, var: Var) -> bool {
        match var {
            Var::ActivationDynamics => self.activation_dynamics,
            Var::AdaptiveSubsteps => self.adaptive_substeps,
            _ => false,
        }
    }

    fn set_real(&mut self, var: Var, value: f64) -> Result<SetOutcome, ModelError> {
        match var {
            Var::Param(id) => self
                .params
                .set(id, value)
                .map_err(|e| ModelError(e.to_string()))?,
            Var::L0 => {
                check_range("L0", value, L0_RANGE)?;
                self.l0 = value;
            }
            Var::Area => {
                check_range("area", value, AREA_RANGE)?;
                self.area = value;
            }
            Var::InitialActivation => {
                check_unit_interval("initial_activation", value)?;
                self.initial_activation = value;
            }
            Var::SubstepTolerance => {
                check_range("substep_tolerance", value, SUBSTEP_TOLERANCE_RANGE)?;
                self.substep_tolerance = value;
            }
            Var::Length => {
                check_range("length", value, LENGTH_RANGE)?;
                self.length = Some(value);
            }
            Var::Activation => {
                if value.is_nan() {
                    return Err(ModelError(format!(
                        "activation = {value} is out of range: must be in [0, 1]"
                    )));
                }
                let clamped = value.clamp(0.0, 1.0);
                self.command = clamped;
                if clamped != value {
                    return Ok(SetOutcome::Warning {
                        message: format!("activation = {value} is outside [0, 1]; clamped to {clamped} (logged once per instance)"),
                        log_once: true,
                    });
                }
            }
            Var::ActivationDynamics | Var::AdaptiveSubsteps | Var::Out(_) => {
                return Err(ModelError("not a Real input or parameter".into()));
            }
        }
        Ok(SetOutcome::Ok)
    }

    fn set_integer(&mut self, _var: Var, _value: i32) -> Result<SetOutcome, ModelError> {
        Err(ModelError("HillMuscle1D has no Integer variables".into()))
    }

    fn set_boolean(&mut self, var: Var, value: bool) -> Result<SetOutcome, ModelError> {
        match var {
            Var::ActivationDynamics => {
                self.activation_dynamics = value;
                Ok(SetOutcome::Ok)
            }
            Var::AdaptiveSubsteps => {
                self.adaptive_substeps = value;
                Ok(SetOutcome::Ok)
            }
            _ => Err(ModelError("not a Boolean parameter".into())),
        }
    }

    fn set_real_input_derivative(
        &mut self,
        var: Var,
        _order: i32,
        value: f64,
    ) -> Result<(), ModelError> {
        if !value.is_finite() {
            return Err(ModelError(format!(
                "input derivative {value} must be finite"
            )));
        }
        match var {
            Var::Activation => self.command_rate = value,
            Var::Length => self.length_rate = value,
            _ => return Err(ModelError("not a Real input".into())),
        }
        Ok(())
    }

    /// Isometric equilibrium at the initial length and `initial_activation`
    /// (with `activation_dynamics = false`: at the command).
    fn initialize(&mut self) -> Result<(), ModelError> {
        self.check_setup()?;
        let (a, da_du) = if self.activation_dynamics {
            (self.initial_activation, 0.0)
        } else {
            (self.command, 1.0)
        };
        self.stretch_range = evaluable_stretch_range(&self.params);
        let length = self.length();
        let lambda = length / self.l0;
        if !(self.stretch_range.0..=self.stretch_range.1).contains(&lambda) {
            return Err(ModelError(self.unsolvable(length, "not attempted")));
        }
        let u = solve_uniaxial_with::<LawOf<S>>(
            &self.params,
            lambda,
            a,
            &FibreHistory::REST,
            FibreRate::Isometric,
            1.0,
        )
        .map_err(|e| ModelError(self.unsolvable(length, &e.0)))?;
        u.fibre
            .history
            .check_physical(self.params.k, u.lambda_f)
            .map_err(|e| ModelError(format!("length = {length} m: {e}")))?;
        let sens = [
            combine(&[(&u.d_dactivation, da_du)]),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        let (outputs, jacobian) = self.evaluate(&u, a, sens, da_du);
        if outputs.iter().any(|x| !x.is_finite()) {
            return Err(ModelError(self.unsolvable(length, "a non-finite output")));
        }
        let statistics = StepStatistics {
            substeps: 1,
            rejected_substeps: 0,
            lateral_iterations: u.iterations,
            ce_iterations: u.ce_iterations,
            at_rest: false,
        };
        self.commit(&u, a, None, outputs, jacobian, statistics);
        Ok(())
    }

    fn do_step(&mut self, _t: f64, h: f64) -> Result<(), StepError> {
        let end_length = self.length() + h * self.length_rate;
        if !(end_length.is_finite() && end_length > 0.0) {
            return Err(StepError::Discard(format!(
                "length at the end of the step, length + h * der(length) = {end_length}, must be finite and > 0"
            )));
        }
        // Kept only when the step is accepted: on a discard the model must
        // stay unchanged.
        // Kept only when the step is accepted (no activation without the CE).
        let decay = if Self::CE {
            Some(Decay::for_step(self.decay, self.params.s, h))
        } else {
            None
        };
        let a_end = self.level(h, decay.map_or(1.0, |d| d.value));
        let lambda = end_length / self.l0;
        if !(self.stretch_range.0..=self.stretch_range.1).contains(&lambda) {
            return Err(StepError::Discard(
                self.unsolvable(end_length, "not attempted"),
            ));
        }
        let Stepped {
            u,
            a,
            da_du,
            sens,
            stats,
        } = self.solve_step(h, lambda, a_end)?;
        let (outputs, jacobian) = self.evaluate(&u, a, sens, da_du);
        if outputs.iter().any(|x| !x.is_finite()) {
            return Err(StepError::Discard(format!(
                "non-finite output at stretch {lambda}"
            )));
        }
        if !jacobian.all_finite() {
            return Err(StepError::Discard(format!(
                "non-finite partial derivative at stretch {lambda} with h = {h:e} s \
                 (a step this short cannot be resolved)"
            )));
        }
        self.commit(&u, a, Some(h), outputs, jacobian, stats);
        self.decay = decay;
        // Input derivatives hold for one step (they describe the input at the
        // communication point they were set at).
        self.command_rate = 0.0;
        self.length_rate = 0.0;
        Ok(())
    }

    fn partial_derivative(&self, unknown: Var, known: Var) -> Result<f64, ModelError> {
        let column = match known {
            Var::Activation => IN_ACTIVATION,
            Var::Length => IN_LENGTH,
            _ => {
                return Err(ModelError(
                    "directional derivatives are taken with respect to the inputs".into(),
                ))
            }
        };
        match unknown {
            Var::Out(Output::Stiffness) => Err(ModelError(
                "stiffness is itself d force / d length: its derivatives are not provided".into(),
            )),
            Var::Out(o) => Ok(self.jacobian.partial(o, column, self.params.k, self.area)),
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        let params: Vec<f64> = PARAMETERS
            .iter()
            .map(|info| self.params.get(info.id))
            .collect();
        let mut w = ByteWriter::new(out);
        w.f64s(&params)
            .f64(self.l0)
            .f64(self.area)
            .bool(self.activation_dynamics)
            .f64(self.initial_activation)
            .f64(self.command)
            .f64s(self.length.as_slice())
            .f64(self.command_rate)
            .f64(self.length_rate)
            .f64(self.activation_level)
            .f64(self.history.lambda_s)
            .f64(self.history.lambda_m)
            .f64(self.lambda)
            .f64(self.q)
            .f64s(&self.predict.q)
            .f64s(&self.predict.lambda_s)
            // The decay cache is derived: only its step size is kept, and the
            // value is recomputed from S on restore.
            .f64s(self.decay.as_ref().map(|d| d.h).as_slice())
            .f64s(&self.outputs)
            .f64s(&self.jacobian.to_values())
            .f64(self.ce_rate)
            .bool(self.adaptive_substeps)
            .f64(self.substep_tolerance);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        let bad = |e: String| ModelError(format!("HillMuscle1D state: {e}"));
        let mut r = ByteReader::new(input);
        let mut m = Self::new();
        let params = r.f64s()?;
        if params.len() != PARAMETERS.len() {
            return Err(bad(format!(
                "{} parameters, expected {}",
                params.len(),
                PARAMETERS.len()
            )));
        }
        for (info, &v) in PARAMETERS.iter().zip(&params) {
            m.params.set(info.id, v).map_err(|e| bad(e.to_string()))?;
        }
        m.l0 = r.f64()?;
        m.area = r.f64()?;
        m.activation_dynamics = r.bool()?;
        m.initial_activation = r.f64()?;
        m.command = r.f64()?;
        m.length = match r.f64s()?.as_slice() {
            [] => None,
            &[l] => Some(l),
            other => return Err(bad(format!("bad length {other:?}"))),
        };
        m.command_rate = r.f64()?;
        m.length_rate = r.f64()?;
        m.activation_level = r.f64()?;
        m.history = FibreHistory {
            lambda_s: r.f64()?,
            lambda_m: r.f64()?,
        };
        m.lambda = r.f64()?;
        m.q = r.f64()?;
        let four = |r: &mut ByteReader| -> Result<[f64; 4], ModelError> {
            let v = r.f64s()?;
            let n = v.len();
            v.try_into()
                .map_err(|_| bad(format!("{n} predictor values, expected 4")))
        };
        m.predict = Predictor {
            q: four(&mut r)?,
            lambda_s: four(&mut r)?,
        };
        m.decay = match r.f64s()?.as_slice() {
            [] => None,
            &[h] if h.is_finite() && h > 0.0 => Some(Decay::new(m.params.s, h)),
            other => return Err(bad(format!("bad activation decay step {other:?}"))),
        };
        let fill = |r: &mut ByteReader, dst: &mut [f64; N_OUT]| -> Result<(), ModelError> {
            let v = r.f64s()?;
            if v.len() != N_OUT {
                return Err(bad(format!("{} outputs, expected {N_OUT}", v.len())));
            }
            dst.copy_from_slice(&v);
            Ok(())
        };
        fill(&mut r, &mut m.outputs)?;
        let jacobian = r.f64s()?;
        m.jacobian = Jacobian::from_values(&jacobian)
            .ok_or_else(|| bad(format!("{} Jacobian values, expected 19", jacobian.len())))?;
        m.ce_rate = r.f64()?;
        m.adaptive_substeps = r.bool()?;
        m.substep_tolerance = r.f64()?;
        if !SUBSTEP_TOLERANCE_RANGE.contains(m.substep_tolerance) {
            return Err(bad(format!(
                "substep_tolerance = {} outside {SUBSTEP_TOLERANCE_RANGE}",
                m.substep_tolerance
            )));
        }
        let state = [
            m.command,
            m.command_rate,
            m.length_rate,
            m.activation_level,
            m.history.lambda_s,
            m.history.lambda_m,
            m.lambda,
            m.q,
            m.ce_rate,
        ];
        if state
            .iter()
            .chain(&m.predict.q)
            .chain(&m.predict.lambda_s)
            .chain(&m.outputs)
            .chain(&m.jacobian.to_values())
            .any(|x| !x.is_finite())
        {
            return Err(bad("a non-finite value".into()));
        }
        m.check_setup().map_err(|e| bad(e.0))?;
        check_restored_drive(m.command, m.activation_level)
            .and_then(|()| check_restored_history(&[m.history]))
            .map_err(|e| bad(e.0))?;
        if m.lambda <= 0.0 {
            return Err(bad(format!("stretch {} must be > 0", m.lambda)));
        }
        m.stretch_range = evaluable_stretch_range(&m.params);
        Ok(m)
    }
}

/// The [`ModelInfo`] of the 1D model of scene `spec`: its identifier,
/// description and DefaultExperiment; the unit N/m only when the scene
/// exposes `stiffness` (so the full FMU's interface, and GUID, are unchanged).
pub fn info_for(spec: &crate::scene::SceneSpec) -> ModelInfo {
    let mut units = units();
    if spec.outputs.contains(&"stiffness") {
        units.push(crate::fmi2::Unit {
            name: "N/m",
            kg: 1,
            m: 0,
            s: -2,
        });
    }
    ModelInfo {
        model_identifier: spec.model_identifier,
        description: spec.description,
        version: env!("CARGO_PKG_VERSION"),
        units,
        default_experiment: spec.default_experiment,
        max_input_derivative_order: 1,
        direct_feedthrough: false,
    }
}

/// Every variable the 1D model can expose, in table order: the law's
/// parameters, geometry and activation options, the inputs, the outputs
/// (`stiffness` last). The full `HillMuscle1D` exposes all but `stiffness`;
/// a scene exposes a subset ([`crate::scene::SceneSpec::variables`]).
pub fn all_variables() -> Vec<ScalarVariable<Var>> {
    let mut v: Vec<ScalarVariable<Var>> = PARAMETERS
        .iter()
        .map(|info| {
            parameter(
                info.name,
                info.description,
                real(
                    info.unit,
                    Some(info.default),
                    Some(info.range.min),
                    Some(info.range.max),
                ),
                Var::Param(info.id),
            )
        })
        .collect();
    v.push(parameter(
        "L0",
        "Rest length of the muscle",
        real(
            "m",
            Some(DEFAULT_L0),
            Some(L0_RANGE.min),
            Some(L0_RANGE.max),
        ),
        Var::L0,
    ));
    v.push(parameter(
        "area",
        "Reference cross-section area (default: the mean cross-section V0/L0 of the paper's fusiform specimen)",
        real("m2", Some(DEFAULT_AREA), Some(AREA_RANGE.min), Some(AREA_RANGE.max)),
        Var::Area,
    ));
    v.push(parameter(
        "activation_dynamics",
        "Use first-order activation dynamics da/dt = S (u - a); false: a = u",
        VarType::Boolean { start: Some(true) },
        Var::ActivationDynamics,
    ));
    v.push(parameter(
        "initial_activation",
        "Activation level at the start time",
        real("1", Some(0.0), Some(0.0), Some(1.0)),
        Var::InitialActivation,
    ));
    v.push(parameter(
        "adaptive_substeps",
        "Cut a step into substeps where the error estimate of the CE-SEE update exceeds substep_tolerance; false: one backward-Euler step per communication step (first order in h)",
        VarType::Boolean { start: Some(true) },
        Var::AdaptiveSubsteps,
    ));
    v.push(parameter(
        "substep_tolerance",
        "Tolerance of the estimated local error of the SEE stress per substep, as a fraction of sigma0",
        substep_tolerance_type(),
        Var::SubstepTolerance,
    ));
    let input = |name, description, ty, id| ScalarVariable {
        name,
        description,
        causality: Causality::Input,
        variability: Variability::Continuous,
        initial: None,
        ty,
        depends_on: vec![],
        id,
    };
    v.push(input(
        "activation",
        "Activation command u in [0, 1] (values outside are clamped with a warning)",
        real("1", Some(0.0), Some(0.0), Some(1.0)),
        Var::Activation,
    ));
    v.push(input(
        "length",
        "Muscle length reached at the end of the step",
        real(
            "m",
            Some(DEFAULT_L0),
            Some(LENGTH_RANGE.min),
            Some(LENGTH_RANGE.max),
        ),
        Var::Length,
    ));
    // Dependencies at initialization (the isometric equilibrium, f_v = 1:
    // S, kc, ke, d and lambda_dot_min play no part). The activation level
    // is initial_activation, or the command without dynamics; everything
    // else also depends on the length, L0 and the static law; only the
    // force depends on the area. Outputs have no direct feedthrough
    // (`ModelInfo::direct_feedthrough`).
    let activation_deps = ["activation", "activation_dynamics", "initial_activation"];
    let static_law = [
        ParamId::B,
        ParamId::C,
        ParamId::Alpha,
        ParamId::Beta,
        ParamId::A,
        ParamId::Sigma0,
        ParamId::LambdaOpt,
        ParamId::Dcomp,
        ParamId::K,
    ];
    let mut state_deps: Vec<&'static str> = activation_deps.to_vec();
    state_deps.extend(["length", "L0"]);
    state_deps.extend(static_law.map(|id| Params::info(id).name));
    let deps = |out: Output| -> Vec<&'static str> {
        match out {
            Output::ActivationLevel => activation_deps.to_vec(),
            Output::Force => [state_deps.as_slice(), &["area"]].concat(),
            _ => state_deps.clone(),
        }
    };
    for (out, name, description, unit) in OUTPUTS {
        v.push(ScalarVariable {
            name,
            description,
            causality: Causality::Output,
            variability: Variability::Continuous,
            initial: Some(Initial::Calculated),
            ty: VarType::Real {
                unit,
                start: None,
                min: None,
                max: None,
            },
            depends_on: deps(out),
            id: Var::Out(out),
        });
    }
    v.push(ScalarVariable {
        name: "stiffness",
        description: "Stiffness d force / d length of the step map that produced the current outputs (the tangent of the last step, fibre history fixed; for masters that cannot call fmi2GetDirectionalDerivative)",
        causality: Causality::Output,
        variability: Variability::Continuous,
        initial: Some(Initial::Calculated),
        ty: VarType::Real {
            unit: Some("N/m"),
            start: None,
            min: None,
            max: None,
        },
        depends_on: deps(Output::Force),
        id: Var::Out(Output::Stiffness),
    });
    v
}

/// The law and the conventions, for the FMU's `documentation/index.html`.
pub const LAW_HTML: &str = r#"<h2>The law</h2>
<p>Hill-type hyperelastic skeletal muscle after Lu, Beldie, Walker, Richmond &amp; Middleton (2011).
Strain energy U = U<sub>I</sub>(&#298;<sub>1</sub>) + U<sub>f</sub>(&lambda;&#772;<sub>f</sub>, &lambda;<sub>s</sub>) + U<sub>J</sub>(J):</p>
<ul>
<li>isotropic matrix U<sub>I</sub> = c (exp(b (&#298;<sub>1</sub> &minus; 3)) &minus; 1);</li>
<li>volumetric penalty U<sub>J</sub> = (J &minus; 1)&sup2; / D (bulk modulus 2/D);</li>
<li>Hill fibre along the muscle axis, nominal stress W = &sigma;<sub>s</sub> + &sigma;<sub>p</sub>:
 a contractile element (activation a, force-length f<sub>&lambda;</sub>, force-velocity f<sub>v</sub>) in series with
 the elastic element &sigma;<sub>s</sub> = &beta; (exp(&alpha; (&lambda;<sub>s</sub> &minus; 1)) &minus; 1), in parallel with
 &sigma;<sub>p</sub> = &sigma;<sub>0</sub> A (&lambda;&#772;<sub>f</sub> &minus; 1)&sup2; (&lambda;&#772;<sub>f</sub> &gt; 1).
 Series kinematics (1 + k) &lambda;&#772;<sub>f</sub> = &lambda;<sub>m</sub> + k &lambda;<sub>s</sub>; each step solves
 &sigma;<sub>s</sub> = &sigma;<sub>0</sub> a f<sub>&lambda;</sub>(&lambda;&#772;<sub>f</sub>) f<sub>v</sub>(&lambda;&#775;<sub>m</sub>) for the SEE stretch
 (bracketed, safeguarded Newton), f<sub>&lambda;</sub> evaluated at the end of the step.</li>
<li>activation dynamics da/dt = S (u &minus; a), integrated exactly over each step.</li>
</ul>
<h2>The 1D reduction</h2>
<p>A prism of rest length L0 and area A0 in homogeneous uniaxial stress: F = diag(&lambda;, &mu;, &mu;) with
&lambda; = L / L0 and the lateral stretch &mu; solved so that the lateral Cauchy stress is zero (finite D).
force = &sigma;<sub>11</sub> A0 &mu;&sup2;, stress = force / A0, cauchy_stress = &sigma;<sub>11</sub>.
Each step of the 1D FMU solves this state at its end with the backward-Euler CE&ndash;SEE update, cut into substeps wherever
its error estimate asks for them (a stiff SEE, fast activation, length jumps), so that the estimated local error of the SEE
stress stays below substep_tolerance &middot; &sigma;<sub>0</sub> (default 1e-3); with smooth inputs a step is one piece.
With adaptive_substeps = false every step is one backward-Euler step (the plain first-order scheme).</p>
<h2>Co-simulation conventions</h2>
<ul>
<li>Inputs set before fmi2DoStep(t, h) hold over the step. The muscle moves from its length to the input length during the
step and the step ends there (CE rate from the change over h); outputs after the step are at t + h. With an order-1 input
derivative (fmi2SetRealInputDerivatives) the step ends at length + h &middot; dlength/dt instead, and the activation command is
taken linear over the step. Input derivatives hold for one step.</li>
<li>At initialization the muscle is in isometric equilibrium at its initial length and initial_activation
(with activation_dynamics = false: at the activation input).</li>
<li>Force is positive in tension. SI units throughout.</li>
<li>Bad input: NaN, infinite or non-positive length and NaN activation are rejected with fmi2Error and a log message naming the
variable and its valid range; the instance keeps its last good state. Activation outside [0, 1] is clamped, with fmi2Warning
(logged once per instance). Parameters out of range are rejected when set, and the whole set is checked again at
fmi2ExitInitializationMode.</li>
<li>fmi2GetDirectionalDerivative gives the partial derivatives of every output with respect to both inputs for the step map
that produced the current outputs (consistent tangent, history fixed).</li>
</ul>
"#;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmus::common::{assert_restore_refuses, restored};

    /// A restored state is checked as strictly as the calls that produce
    /// its values: an activation command or level outside [0, 1], a
    /// non-positive CE or SEE stretch, a non-positive stretch or a length
    /// outside its range is refused naming it (a crafted state: the
    /// layer's checksum is not a signature), while the unmodified state
    /// round-trips.
    #[test]
    fn a_restored_state_with_unphysical_values_is_refused() {
        let mut m = Hill1D::new();
        m.set_real(Var::Activation, 0.6).unwrap();
        m.set_real(Var::Length, 1.05 * DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        for _ in 0..3 {
            m.do_step(0.0, 1e-3).unwrap();
        }
        let force = Var::Out(Output::Force);
        let back = restored(&m).expect("an unmodified state");
        assert_eq!(back.get_real(force), m.get_real(force));
        assert_restore_refuses(&m, |f| f.command = 5.0, "activation = 5");
        assert_restore_refuses(&m, |f| f.command = -3.0, "activation = -3");
        assert_restore_refuses(&m, |f| f.activation_level = 4.0, "activation level = 4");
        assert_restore_refuses(&m, |f| f.history.lambda_m = -1.0, "CE stretch -1");
        assert_restore_refuses(&m, |f| f.history.lambda_s = 0.0, "SEE stretch 0");
        assert_restore_refuses(&m, |f| f.lambda = -0.5, "stretch -0.5 must be > 0");
        assert_restore_refuses(&m, |f| f.length = Some(1e3), "length = 1000");
    }

    /// A step so short that 1/h overflows (h = 5e-324, finite and > 0, so
    /// the layer accepts it) after a length change is discarded with a
    /// message that names the step size, not the volumetric term D, and the
    /// model is unchanged.
    #[test]
    fn a_step_too_short_to_evaluate_is_discarded_naming_the_step_size() {
        let mut m = Hill1D::new();
        m.set_real(Var::Activation, 1.0).unwrap();
        m.initialize().unwrap();
        m.do_step(0.0, 1e-3).unwrap();
        m.set_real(Var::Length, 1.2 * DEFAULT_L0).unwrap();
        let before = m.clone();
        match m.do_step(1e-3, 5e-324) {
            Err(StepError::Discard(msg)) => {
                assert!(msg.starts_with("communicationStepSize too short"), "{msg}");
                assert!(!msg.contains("D ="), "{msg}");
            }
            other => panic!("expected a discard, got {other:?}"),
        }
        assert_eq!(m, before);
        // A normal short step from the same state goes through.
        m.do_step(1e-3, 1e-9).unwrap();
    }
}
