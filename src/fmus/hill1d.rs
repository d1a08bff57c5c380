//! `HillMuscle1D`: the 1D muscle ([`crate::muscle1d`]) as an FMI 2.0
//! Co-Simulation model. This file only maps: the variable table (one row a
//! variable, [`variables!`]: [`Var`], [`all_variables`]), the muscle's
//! errors onto the layer's (same messages), and the state codec. What a step
//! computes, and the conventions, are the muscle's (MODEL_NOTES "The 1D Hill
//! reduction" and "Co-simulation conventions"; the FMU's documentation,
//! [`LAW_HTML`]).

pub use super::common::{SUBSTEP_RTOL, SUBSTEP_TOLERANCE_RANGE};
use super::table::{self, model_access, output, scene_interface, variables, Row, STATIC_LAW};
use crate::fmi2::{Model, ModelError, StepError};
use crate::law::ParamId;
pub use crate::muscle1d::{piece_error, Output, StepStatistics, DEFAULT_AREA, DEFAULT_L0};
use crate::muscle1d::{Discard, Input, Muscle1D, N_OUT};
use crate::scene::{LawOf, Scene};

pub(crate) mod state;

variables! {
    /// A variable of `HillMuscle1D`, in table order: the law's parameters,
    /// geometry and activation options, the inputs, the outputs.
    pub enum Var;
    impl[S: Scene] Hill1DModel<S> as (m, v) {
        /// A parameter of the law (MODEL_NOTES "Parameters").
        Param(id: ParamId) = table::LawParameters
            => Real(get m.muscle.params.get(id), set m.muscle.params.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        L0 = table::l0("Rest length of the muscle", DEFAULT_L0) => Real(m.muscle.l0);
        Area = table::area(
            "Reference cross-section area (default: the mean cross-section V0/L0 of the paper's fusiform specimen)",
            DEFAULT_AREA,
        ) => Real(m.muscle.area);
        ActivationDynamics = table::activation_dynamics() => Boolean(m.muscle.activation_dynamics);
        InitialActivation = table::initial_activation() => Real(m.muscle.initial_activation);
        AdaptiveSubsteps = table::adaptive_substeps(
            "Cut a step into substeps where the error estimate of the CE-SEE update exceeds substep_tolerance; false: one backward-Euler step per communication step (first order in h)",
            true,
        ) => Boolean(m.muscle.adaptive_substeps);
        SubstepTolerance = table::substep_tolerance(
            "Tolerance of the estimated local error of the SEE stress per substep, as a fraction of sigma0",
        ) => Real(m.muscle.substep_tolerance);
        Activation = table::activation() => Real(m.muscle.command), der m.muscle.command_rate;
        Length = table::length(DEFAULT_L0)
            => Real(get m.muscle.length(), set m.muscle.length = Some(v)), der m.muscle.length_rate;
        /// An output ([`OUTPUTS`]); `stiffness` is d force / d length of the
        /// last step map, the same number as
        /// fmi2GetDirectionalDerivative(force, length).
        Out(o: Output) = OUTPUTS => Real(get m.muscle.output(o));
    }
}

/// The outputs, in [`Output`] order (`stiffness`, a partial, last: the full
/// `HillMuscle1D` does not expose it).
const OUTPUTS: [(Output, Row<Var>); N_OUT + 1] = [
    (
        Output::Force,
        table::force("Axial muscle force, tension positive", force_deps),
    ),
    (Output::Stress, table::stress(state_deps)),
    (
        Output::CauchyStress,
        table::cauchy_stress("Axial Cauchy (true) stress", state_deps),
    ),
    (
        Output::ActivationLevel,
        table::activation_level(activation_deps),
    ),
    (
        Output::FibreStretch,
        table::fibre_stretch("Modified fibre stretch J^(-1/3) lambda", state_deps),
    ),
    (
        Output::CeStretch,
        table::ce_stretch("Contractile element stretch lambda_m", state_deps),
    ),
    (
        Output::SeeStretch,
        table::see_stretch("Series elastic element stretch lambda_s", state_deps),
    ),
    (
        Output::ActiveStress,
        table::active_stress("SEE (= CE) nominal stress sigma_s", state_deps),
    ),
    (
        Output::PassiveStress,
        table::passive_stress(
            "Rest of the nominal stress: stress - active_stress",
            state_deps,
        ),
    ),
    (
        Output::Stiffness,
        output(
            "stiffness",
            "Stiffness d force / d length of the step map that produced the current outputs (the tangent of the last step, fibre history fixed; for masters that cannot call fmi2GetDirectionalDerivative)",
            "N/m",
            force_deps,
        ),
    ),
];

// Dependencies at initialization (the isometric equilibrium, f_v = 1: S,
// kc, ke, d and lambda_dot_min play no part). The activation level is
// initial_activation, or the command without dynamics; everything else also
// depends on the length, L0 and the static law; only the force depends on
// the area. Outputs have no direct feedthrough
// (`ModelInfo::direct_feedthrough`).

/// What the activation level depends on.
fn activation_deps() -> Vec<Var> {
    vec![
        Var::Activation,
        Var::ActivationDynamics,
        Var::InitialActivation,
    ]
}

/// What the state outputs depend on.
fn state_deps() -> Vec<Var> {
    let mut deps = activation_deps();
    deps.extend([Var::Length, Var::L0]);
    deps.extend(STATIC_LAW.map(Var::Param));
    deps
}

/// What the force (and `stiffness`) depend on.
fn force_deps() -> Vec<Var> {
    let mut deps = state_deps();
    deps.push(Var::Area);
    deps
}

/// The full `HillMuscle1D`: every component, input and output of the 1D
/// model (the scene `fmu_build/scenes/hill_muscle_1d.toml`).
pub type Hill1D = Hill1DModel<crate::scene::shipped::HillMuscle1D>;

/// The 1D Hill muscle FMU model of scene `S` ([`crate::scene`]): the
/// [`Muscle1D`] with the scene's components as compile-time constants
/// ([`LawOf`]), so an absent component's code is not in its binary.
#[derive(Clone, Debug, PartialEq)]
pub struct Hill1DModel<S: Scene> {
    muscle: Muscle1D<LawOf<S>>,
}

impl<S: Scene> Hill1DModel<S> {
    /// Turn the shortcut of steps at rest on (the default) or off
    /// ([`Muscle1D::set_rest_shortcut`]: it changes no result).
    pub fn set_rest_shortcut(&mut self, on: bool) {
        self.muscle.set_rest_shortcut(on);
    }

    /// Solver counts of the last completed step (or of the initialization).
    pub fn last_step_statistics(&self) -> StepStatistics {
        self.muscle.last_step_statistics()
    }
}

/// The message of a discarded step of scene `S`: the muscle's own, or for a
/// CE–SEE root on an f_v branch the scene leaves out, the branch and the
/// scene's component that would include it.
pub(crate) fn discard_message<S: Scene>(d: Discard) -> String {
    match d {
        Discard::Unsolvable(msg) => msg,
        Discard::AbsentFvBranch { rate, sigma_see } => {
            let (branch, key) = if rate > 0.0 {
                ("lengthening", "fv_lengthening")
            } else {
                ("shortening", "fv_shortening")
            };
            format!(
                "the contractile element is {branch} (CE stretch rate {rate:e} 1/s) while carrying \
                 {sigma_see:e} Pa, but scene {} has no {branch} branch of the force-velocity relation \
                 (components.{key} = false): use a scene with it",
                S::SPEC.model_identifier
            )
        }
    }
}

impl<S: Scene> Model for Hill1DModel<S> {
    type Var = Var;

    scene_interface!();

    fn new() -> Self {
        let mut m = Hill1DModel {
            muscle: Muscle1D::new(SUBSTEP_RTOL),
        };
        m.table_apply_scene(&S::SPEC);
        // Outputs at the start values are those of the initial equilibrium.
        m.initialize().expect("the scene's start values are valid");
        m
    }

    model_access!();

    /// Isometric equilibrium at the initial length and `initial_activation`
    /// (with `activation_dynamics = false`: at the command).
    fn initialize(&mut self) -> Result<(), ModelError> {
        self.muscle.initialize().map_err(|e| ModelError(e.0))
    }

    /// The muscle's step ([`Muscle1D::step`]); a step it cannot take is
    /// discarded, the model unchanged.
    fn do_step(&mut self, _t: f64, h: f64) -> Result<(), StepError> {
        self.muscle
            .step(h)
            .map_err(|d| StepError::Discard(discard_message::<S>(d)))
    }

    fn partial_derivative(&self, unknown: Var, known: Var) -> Result<f64, ModelError> {
        let column = match known {
            Var::Activation => Input::Activation,
            Var::Length => Input::Length,
            _ => {
                return Err(ModelError(
                    "directional derivatives are taken with respect to the inputs".into(),
                ))
            }
        };
        match unknown {
            Var::Out(Output::Stiffness) => Err(super::common::stiffness_not_differentiated()),
            Var::Out(o) => Ok(self.muscle.partial(o, column)),
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    fn check_stepping_outputs(&self) -> Result<(), String> {
        state::check_force(&self.muscle)
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        state::encode(self, out);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        state::decode(input)
    }
}

/// The law and the conventions, for the FMU's `documentation/index.html`.
pub const LAW_HTML: &str = include_str!("doc/hill1d.html");

#[cfg(test)]
mod tests {
    use super::*;

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
