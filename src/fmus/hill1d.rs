//! `HillMuscle1D`: the 1D muscle ([`crate::muscle1d`]) as an FMI 2.0
//! Co-Simulation model. This file only maps: the variable table
//! ([`all_variables`], [`info_for`]), get/set of the variables onto the
//! muscle's parameters and inputs with their range checks, the muscle's
//! errors onto the layer's (same messages), and the state codec. What a step
//! computes, and the conventions, are the muscle's (MODEL_NOTES "The 1D Hill
//! reduction" and "Co-simulation conventions"; the FMU's documentation,
//! [`LAW_HTML`]).

use super::common::{
    check_range, check_unit_interval, input, parameter, real, substep_tolerance_type, units,
};
pub use super::common::{SUBSTEP_RTOL, SUBSTEP_TOLERANCE_RANGE};
use crate::fmi2::{
    Causality, Initial, Model, ModelError, ModelInfo, ScalarVariable, SetOutcome, StepError,
    VarType, Variability,
};
use crate::law::params::{AREA_RANGE, L0_RANGE, LENGTH_RANGE};
use crate::law::{ParamId, Params, PARAMETERS};
pub use crate::muscle1d::{piece_error, Output, StepStatistics, DEFAULT_AREA, DEFAULT_L0};
use crate::muscle1d::{Discard, Input, Muscle1D, N_OUT};
use crate::scene::{LawOf, Scene, Value};

mod state;

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

/// The stored outputs' names, descriptions and units, in [`Output`] order
/// (`stiffness`, a partial, has its own row in [`all_variables`]).
const OUTPUTS: [(Output, &str, &str, Option<&str>); N_OUT] = [
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
fn discard_message<S: Scene>(d: Discard) -> String {
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
            muscle: Muscle1D::new(SUBSTEP_RTOL),
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
            Var::Param(id) => self.muscle.params.get(id),
            Var::L0 => self.muscle.l0,
            Var::Area => self.muscle.area,
            Var::InitialActivation => self.muscle.initial_activation,
            Var::Activation => self.muscle.command,
            Var::Length => self.muscle.length(),
            // d force / d length of the last step map: the same number as
            // fmi2GetDirectionalDerivative(force, length).
            Var::Out(o) => self.muscle.output(o),
            Var::SubstepTolerance => self.muscle.substep_tolerance,
            Var::ActivationDynamics | Var::AdaptiveSubsteps => f64::NAN,
        }
    }

    fn get_integer(&self, _var: Var) -> i32 {
        0
    }

    fn get_boolean(&self, var: Var) -> bool {
        match var {
            Var::ActivationDynamics => self.muscle.activation_dynamics,
            Var::AdaptiveSubsteps => self.muscle.adaptive_substeps,
            _ => false,
        }
    }

    fn set_real(&mut self, var: Var, value: f64) -> Result<SetOutcome, ModelError> {
        match var {
            Var::Param(id) => self
                .muscle
                .params
                .set(id, value)
                .map_err(|e| ModelError(e.to_string()))?,
            Var::L0 => {
                check_range("L0", value, L0_RANGE)?;
                self.muscle.l0 = value;
            }
            Var::Area => {
                check_range("area", value, AREA_RANGE)?;
                self.muscle.area = value;
            }
            Var::InitialActivation => {
                check_unit_interval("initial_activation", value)?;
                self.muscle.initial_activation = value;
            }
            Var::SubstepTolerance => {
                check_range("substep_tolerance", value, SUBSTEP_TOLERANCE_RANGE)?;
                self.muscle.substep_tolerance = value;
            }
            Var::Length => {
                check_range("length", value, LENGTH_RANGE)?;
                self.muscle.length = Some(value);
            }
            Var::Activation => {
                if value.is_nan() {
                    return Err(ModelError(format!(
                        "activation = {value} is out of range: must be in [0, 1]"
                    )));
                }
                let clamped = value.clamp(0.0, 1.0);
                self.muscle.command = clamped;
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
                self.muscle.activation_dynamics = value;
                Ok(SetOutcome::Ok)
            }
            Var::AdaptiveSubsteps => {
                self.muscle.adaptive_substeps = value;
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
            Var::Activation => self.muscle.command_rate = value,
            Var::Length => self.muscle.length_rate = value,
            _ => return Err(ModelError("not a Real input".into())),
        }
        Ok(())
    }

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
            Var::Out(Output::Stiffness) => Err(ModelError(
                "stiffness is itself d force / d length: its derivatives are not provided".into(),
            )),
            Var::Out(o) => Ok(self.muscle.partial(o, column)),
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        state::encode(self, out);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        state::decode(input)
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
pub const LAW_HTML: &str = include_str!("doc/hill1d.html");

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
        assert_restore_refuses(&m, |f| f.muscle.command = 5.0, "activation = 5");
        assert_restore_refuses(&m, |f| f.muscle.command = -3.0, "activation = -3");
        assert_restore_refuses(
            &m,
            |f| f.muscle.activation_level = 4.0,
            "activation level = 4",
        );
        assert_restore_refuses(&m, |f| f.muscle.history.lambda_m = -1.0, "CE stretch -1");
        assert_restore_refuses(&m, |f| f.muscle.history.lambda_s = 0.0, "SEE stretch 0");
        assert_restore_refuses(&m, |f| f.muscle.lambda = -0.5, "stretch -0.5 must be > 0");
        assert_restore_refuses(&m, |f| f.muscle.length = Some(1e3), "length = 1000");
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
