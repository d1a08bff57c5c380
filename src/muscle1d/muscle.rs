//! The 1D muscle's parameters, inputs and committed state
//! ([`Muscle1D`]): its initialization to the isometric equilibrium
//! ([`Muscle1D::initialize`]) and the step's entry point ([`Muscle1D::step`]),
//! which solves the step ([`super::step`]) and commits it only on success.

use super::error::{Discard, SetupError};
use super::outputs::{Jacobian, N_OUT};
use super::predictor::Predictor;
use super::step::{combine, StepStatistics, Stepped};
use crate::law::activation::{level_at, Decay};
use crate::law::uniaxial::evaluable_stretch_range;
use crate::law::{solve_uniaxial_with, Components, FibreHistory, FibreRate, Params, Uniaxial};
use std::marker::PhantomData;

/// Rest length of the paper's specimen, m.
pub const DEFAULT_L0: f64 = 0.05;

/// Default cross-section, m²: the mean cross-section V0/L0 of the paper's
/// fusiform specimen ([`crate::specimen::MEAN_AREA`] ≈ 1.6849e-4), the same
/// stress scale as the FE muscle.
pub const DEFAULT_AREA: f64 = crate::specimen::MEAN_AREA;

/// The 1D Hill muscle with the law's components `C`: its parameters, the
/// inputs for the next step and the state committed by the last step or
/// initialization. The fields are the crate's (the FMI layer sets the
/// parameters and inputs after checking them, and encodes the state); a
/// state written into them is checked by [`Muscle1D::check_setup`] before
/// use.
#[derive(Clone, Debug, PartialEq)]
pub struct Muscle1D<C: Components> {
    law: PhantomData<C>,
    pub(crate) params: Params,
    pub(crate) l0: f64,
    pub(crate) area: f64,
    /// First-order activation dynamics (only with
    /// [`Components::ACTIVATION_DYNAMICS`]); false: a = u.
    pub(crate) activation_dynamics: bool,
    pub(crate) initial_activation: f64,
    /// Cut steps into substeps by the error estimate of the CE–SEE update
    /// (false: one backward-Euler step per step).
    pub(crate) adaptive_substeps: bool,
    /// Tolerance of that estimate, relative to sigma0.
    pub(crate) substep_tolerance: f64,
    // Inputs and their derivatives for the next step.
    /// The activation command u, in [0, 1].
    pub(crate) command: f64,
    /// The length input; `None` until set, when the length is `L0` (also
    /// after `L0` is changed).
    pub(crate) length: Option<f64>,
    pub(crate) command_rate: f64,
    pub(crate) length_rate: f64,
    // Committed state.
    pub(crate) activation_level: f64,
    pub(crate) history: FibreHistory,
    /// The CE stretch rate λ̇m of the last (sub)step: the rate at the start of
    /// the next step, for the error estimate of its CE–SEE update (0 at the
    /// isometric start).
    pub(crate) ce_rate: f64,
    pub(crate) lambda: f64,
    /// q = J^(1/3) of the last solve.
    pub(crate) q: f64,
    /// Predictors of the next step's q and λs (the solvers' starting points
    /// only: they change the cost, not the converged result).
    pub(crate) predict: Predictor,
    /// The stretches length/L0 the law can evaluate (from `b`, fixed after
    /// initialization; derived: [`Muscle1D::refresh_stretch_range`]).
    pub(crate) stretch_range: (f64, f64),
    /// e^(−S h) of the last step (a cache: S is fixed, h usually repeats).
    pub(crate) decay: Option<Decay>,
    // Outputs of the last solve and what their partials d out / d input need.
    pub(crate) outputs: [f64; N_OUT],
    pub(crate) jacobian: Jacobian,
    /// Solver counts of the last completed step or initialization.
    statistics: Diagnostics,
    /// Whether steps at rest take the shortcut (on; off only to test that
    /// it changes nothing). Not state: not serialized, not compared.
    pub(crate) rest_shortcut: Switch,
}

/// A switch that is not part of the model's state: equal to every other.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Switch(pub(crate) bool);

impl PartialEq for Switch {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// [`StepStatistics`] held by the muscle: diagnostics, not state. Equal to
/// every other, so that two muscles in the same state compare equal whatever
/// their solvers took to get there.
#[derive(Clone, Copy, Debug, Default)]
struct Diagnostics(StepStatistics);

impl PartialEq for Diagnostics {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<C: Components> Muscle1D<C> {
    /// The muscle at the law's default parameters, `DEFAULT_L0`,
    /// `DEFAULT_AREA`, activation dynamics as the components allow, at rest
    /// with its length input unset; `substep_tolerance` relative to sigma0.
    /// Not yet initialized: [`Muscle1D::initialize`] solves its state.
    pub fn new(substep_tolerance: f64) -> Self {
        Muscle1D {
            law: PhantomData,
            params: Params::default(),
            l0: DEFAULT_L0,
            area: DEFAULT_AREA,
            // Without the component: a = u (its switch compiled in as false).
            activation_dynamics: C::ACTIVATION_DYNAMICS,
            initial_activation: 0.0,
            adaptive_substeps: true,
            substep_tolerance,
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
        }
    }

    /// The current length input (`L0` until set).
    pub fn length(&self) -> f64 {
        self.length.unwrap_or(self.l0)
    }

    /// Recompute what is derived from the parameters (the evaluable stretch
    /// range), after a state was written into the fields.
    pub(crate) fn refresh_stretch_range(&mut self) {
        self.stretch_range = evaluable_stretch_range(&self.params);
    }

    /// Solver counts of the last completed step (or of the initialization).
    pub fn last_step_statistics(&self) -> StepStatistics {
        self.statistics.0
    }

    /// Turn the shortcut of steps at rest on (the default) or off. It changes
    /// no result (a test compares both bit for bit); off only for that test
    /// and for measuring what it saves.
    pub fn set_rest_shortcut(&mut self, on: bool) {
        self.rest_shortcut = Switch(on);
    }

    /// Isometric equilibrium at the initial length and `initial_activation`
    /// (with `activation_dynamics = false`: at the command), MODEL_NOTES
    /// "Co-simulation conventions".
    pub fn initialize(&mut self) -> Result<(), SetupError> {
        self.check_setup()?;
        let (a, da_du) = if self.activation_dynamics {
            (self.initial_activation, 0.0)
        } else {
            (self.command, 1.0)
        };
        self.refresh_stretch_range();
        let length = self.length();
        let lambda = length / self.l0;
        if !(self.stretch_range.0..=self.stretch_range.1).contains(&lambda) {
            return Err(SetupError(self.unsolvable(length, "not attempted")));
        }
        let u = solve_uniaxial_with::<C>(
            &self.params,
            lambda,
            a,
            &FibreHistory::REST,
            FibreRate::Isometric,
            1.0,
        )
        .map_err(|e| SetupError(self.unsolvable(length, &e.0)))?;
        u.fibre
            .history
            .check_physical(self.params.k, u.lambda_f)
            .map_err(|e| SetupError(format!("length = {length} m: {e}")))?;
        let sens = [
            combine(&[(&u.d_dactivation, da_du)]),
            combine(&[(&u.d_dlambda, 1.0 / self.l0)]),
        ];
        let (outputs, jacobian) = self.evaluate(&u, a, sens, da_du);
        if outputs.iter().any(|x| !x.is_finite()) {
            return Err(SetupError(self.unsolvable(length, "a non-finite output")));
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

    /// One step of length `h` from the committed state to the length input
    /// (plus `h` times its derivative), the command held (or linear) over it
    /// (its step map, `solve_step`). Committed only on success; the input
    /// derivatives hold for this one step.
    pub fn step(&mut self, h: f64) -> Result<(), Discard> {
        let end_length = self.length() + h * self.length_rate;
        if !(end_length.is_finite() && end_length > 0.0) {
            return Err(Discard::Unsolvable(format!(
                "length at the end of the step, length + h * der(length) = {end_length}, must be finite and > 0"
            )));
        }
        let (decay, a_end) = self.end_level(h);
        let lambda = end_length / self.l0;
        if !(self.stretch_range.0..=self.stretch_range.1).contains(&lambda) {
            return Err(Discard::Unsolvable(
                self.unsolvable(end_length, "not attempted"),
            ));
        }
        let Stepped {
            u,
            a,
            da_du,
            sens,
            stats,
            ..
        } = self.solve_step(h, lambda, a_end)?;
        let (outputs, jacobian) = self.evaluate(&u, a, sens, da_du);
        Self::check_outputs(&outputs, &jacobian, lambda, h)?;
        self.finish_step(&u, a, h, decay, outputs, jacobian, stats);
        Ok(())
    }

    /// The decay e^(−S h) of a step of length `h` (kept only when the step
    /// is accepted; none without the CE) and the level at its end with
    /// ∂a/∂u ([`Self::level`]).
    pub(super) fn end_level(&self, h: f64) -> (Option<Decay>, (f64, f64)) {
        let decay = if C::CONTRACTILE {
            Some(Decay::for_step(self.decay, self.params.s, h))
        } else {
            None
        };
        (decay, self.level(h, decay.map_or(1.0, |d| d.value)))
    }

    /// A step's outputs and partials are finite, else the discard that says
    /// so (at end stretch `lambda`, step `h`).
    pub(super) fn check_outputs(
        outputs: &[f64; N_OUT],
        jacobian: &Jacobian,
        lambda: f64,
        h: f64,
    ) -> Result<(), Discard> {
        if outputs.iter().any(|x| !x.is_finite()) {
            return Err(Discard::Unsolvable(format!(
                "non-finite output at stretch {lambda}"
            )));
        }
        if !jacobian.all_finite() {
            return Err(Discard::Unsolvable(format!(
                "non-finite partial derivative at stretch {lambda} with h = {h:e} s \
                 (a step this short cannot be resolved)"
            )));
        }
        Ok(())
    }

    /// Commit a solved step of length `h` with its decay; the input
    /// derivatives are spent.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn finish_step(
        &mut self,
        u: &Uniaxial,
        a: f64,
        h: f64,
        decay: Option<Decay>,
        outputs: [f64; N_OUT],
        jacobian: Jacobian,
        stats: StepStatistics,
    ) {
        self.commit(u, a, Some(h), outputs, jacobian, stats);
        self.decay = decay;
        // Input derivatives hold for one step (they describe the input at the
        // communication point they were set at).
        self.command_rate = 0.0;
        self.length_rate = 0.0;
    }

    /// Make a solved state the committed one.
    /// `h` is the step length (`None` at initialization).
    pub(super) fn commit(
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
    /// without dynamics the command itself; MODEL_NOTES "Activation"). `decay`
    /// is e^(−S tau).
    pub(crate) fn level(&self, tau: f64, decay: f64) -> (f64, f64) {
        if !C::CONTRACTILE {
            // No contractile element: no activation (the command is 0 and
            // nothing reads the level).
            return (0.0, 0.0);
        }
        level_at(
            C::ACTIVATION_DYNAMICS && self.activation_dynamics,
            self.activation_level,
            self.command,
            self.command_rate,
            self.params.s,
            tau,
            decay,
        )
    }
}
