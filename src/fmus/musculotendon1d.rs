//! `HillMusculotendon1D`: the 1D musculotendon unit
//! ([`crate::muscle1d::Musculotendon1D`]) as an FMI 2.0 Co-Simulation model.
//! This file only maps: the variable table (one row a variable,
//! [`variables!`]: [`Var`], [`all_variables`]), the unit's errors onto the
//! layer's (the 1D muscle's messages), and the state codec. What a step
//! computes is the unit's (MODEL_NOTES "Musculotendon unit"; the FMU's
//! documentation, [`MT_HTML`]).
//!
//! Names: MODEL_NOTES calls both the parameter α0 (the angle at fibre length
//! `L0`) and the output α `pennation_angle`. The parameter keeps the name
//! (the law's table, [`TENDON_PARAMETERS`], and the parameter list
//! use it), the output is `pennation`: the angle now, as `fibre_length` is
//! the length now and `L0` the one at rest.
//!
//! Invariant: the `length` input is the path length, origin to insertion;
//! its start is the rest path L_TS + L0 cos α0 of the scene's parameters
//! ([`scene_variables`]), the value the model reads before one is set.

use super::common::info_for as muscle_info_for;
pub use super::common::SUBSTEP_RTOL;
use super::hill1d::discard_message;
use super::table::{
    self, boolean, input, model_access, output, parameter, real, variables, Check, Family, Row,
    STATIC_LAW,
};
use crate::fmi2::{Model, ModelError, ModelInfo, ScalarVariable, StepError, Unit, VarType};
use crate::law::musculotendon::UnitParams;
use crate::law::params::{ParamInfo, TendonParamId, LENGTH_RANGE, TENDON_PARAMETERS};
use crate::law::ParamId;
use crate::muscle1d::{Input, Muscle1D, Musculotendon1D, Output, UnitOutput};
pub use crate::muscle1d::{DEFAULT_AREA, DEFAULT_L0};
use crate::scene::{LawOf, Scene, SceneSpec, Value};

pub(crate) mod state;

/// An output of the FMU: the unit's ([`UnitOutput`]) and the muscle's
/// activation level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MtOutput {
    Unit(UnitOutput),
    ActivationLevel,
}

variables! {
    /// A variable of `HillMusculotendon1D`, in table order: the law's
    /// parameters, the muscle's geometry, the tendon and pennation, the
    /// activation and substep options, the inputs, the outputs.
    pub enum Var;
    impl[S: Scene] MusculotendonModel<S> as (m, v) {
        /// A parameter of the law (MODEL_NOTES "Parameters").
        Param(id: ParamId) = table::LawParameters
            => Real(get m.mt.muscle.params.get(id), set m.mt.muscle.params.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        L0 = table::l0(
            "Rest length L0 of the muscle fibres (the fibre length at which the pennation angle is pennation_angle)",
            DEFAULT_L0,
        ) => Real(m.mt.muscle.l0);
        Area = table::area(
            "Reference cross-section area of the muscle: its maximum isometric force is F0 = sigma0 * area",
            DEFAULT_AREA,
        ) => Real(m.mt.muscle.area);
        /// A parameter of the tendon or the pennation (MODEL_NOTES
        /// "Musculotendon unit").
        Tendon(id: TendonParamId) = TendonParameters
            => Real(get m.mt.unit.get(id), set m.mt.unit.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        CompliantTendon = parameter(
            "compliant_tendon",
            "Compliant tendon (Thelen's force-strain curve, in equilibrium with the muscle at the end of every substep); false: a rigid tendon of length tendon_slack_length",
            boolean(true),
            Check::None,
        ) => Boolean(m.mt.unit.compliant_tendon);
        ActivationDynamics = table::activation_dynamics() => Boolean(m.mt.muscle.activation_dynamics);
        InitialActivation = table::initial_activation() => Real(m.mt.muscle.initial_activation);
        AdaptiveSubsteps = table::adaptive_substeps(
            "Cut a step into substeps where the error estimate of the CE-SEE update exceeds substep_tolerance (the tendon's equilibrium is solved at the end of each); false: one backward-Euler step per communication step",
            true,
        ) => Boolean(m.mt.muscle.adaptive_substeps);
        SubstepTolerance = table::substep_tolerance(
            "Tolerance of the estimated local error of the SEE stress per substep, as a fraction of sigma0",
        ) => Real(m.mt.muscle.substep_tolerance);
        Activation = table::activation() => Real(m.mt.muscle.command), der m.mt.muscle.command_rate;
        Length = path_length()
            => Real(get m.mt.path(), set m.mt.set_path(v)), der m.mt.path_rate;
        /// An output ([`OUTPUTS`]); `stiffness` is d force / d length of the
        /// last step map, the same number as
        /// fmi2GetDirectionalDerivative(force, length).
        Out(o: MtOutput) = OUTPUTS => Real(get m.output(o));
    }
}

/// The tendon's and the pennation's parameters as a family of rows, in
/// [`TENDON_PARAMETERS`] order (name, unit, default, range, description
/// from the law's table; refused values get the law's message).
pub struct TendonParameters;

/// The row of the unit's parameter `info`.
const fn tendon_parameter<V>(info: &ParamInfo<TendonParamId>) -> Row<V> {
    parameter(
        info.name,
        info.description,
        real(info.unit, Some(info.default), Some(info.range)),
        Check::LawParameter,
    )
}

impl<V> Family<TendonParamId, V> for TendonParameters {
    fn rows(&self) -> Vec<(TendonParamId, Row<V>)> {
        TENDON_PARAMETERS
            .iter()
            .map(|info| (info.id, tendon_parameter(info)))
            .collect()
    }

    /// The row of `id`: [`TENDON_PARAMETERS`] is in [`TendonParamId`] order.
    fn row(&self, id: TendonParamId) -> Row<V> {
        tendon_parameter(&TENDON_PARAMETERS[id as usize])
    }
}

/// The input `length`: the path length. Its start here is the rest path of
/// the default parameters without pennation; a scene's is its own
/// ([`scene_variables`]).
const fn path_length<V>() -> Row<V> {
    input(
        "length",
        "Path length of the musculotendon unit, origin to insertion (tendon plus the fibres' projection on the line of action), reached at the end of the step",
        real(
            "m",
            Some(TENDON_PARAMETERS[TendonParamId::TendonSlackLength as usize].default + DEFAULT_L0),
            Some(LENGTH_RANGE),
        ),
        Check::Finite,
    )
}

/// The outputs, in table order (`stiffness`, a partial, last).
const OUTPUTS: [(MtOutput, Row<Var>); 7] = [
    (
        MtOutput::Unit(UnitOutput::Force),
        table::force(
            "Tendon force F_T: the force along the path, tension positive",
            unit_deps,
        ),
    ),
    (
        MtOutput::Unit(UnitOutput::Stress),
        output(
            "stress",
            "Engineering (nominal) stress of the muscle: its axial force F_M / area (the tendon force is F_M cos(pennation))",
            "Pa",
            unit_deps,
        ),
    ),
    (
        MtOutput::Unit(UnitOutput::FibreLength),
        output(
            "fibre_length",
            "Fibre length L_M of the muscle, along its fibres",
            "m",
            unit_deps,
        ),
    ),
    (
        MtOutput::Unit(UnitOutput::TendonStrain),
        output(
            "tendon_strain",
            "Tendon strain eps = L_T / tendon_slack_length - 1 (negative: slack; 0 for a rigid tendon)",
            "1",
            unit_deps,
        ),
    ),
    (
        MtOutput::Unit(UnitOutput::PennationAngle),
        output(
            "pennation",
            "Pennation angle alpha of the fibres at the current fibre length (constant thickness: L_M sin(alpha) = L0 sin(pennation_angle))",
            "rad",
            unit_deps,
        ),
    ),
    (
        MtOutput::ActivationLevel,
        table::activation_level(activation_deps),
    ),
    (
        MtOutput::Unit(UnitOutput::Stiffness),
        output(
            "stiffness",
            "Series stiffness d force / d length of the step map that produced the current outputs (tendon and muscle in series through the pennation, fibre history fixed; for masters that cannot call fmi2GetDirectionalDerivative)",
            "N/m",
            unit_deps,
        ),
    ),
];

// Dependencies at initialization (the static equilibrium of tendon and
// muscle at the initial path length and activation level, f_v = 1): the
// activation level as the 1D muscle's; everything else on the path, the
// geometry, F0 (sigma0 and the area), the tendon and pennation and the
// static law. Outputs have no direct feedthrough.

/// What the activation level depends on.
fn activation_deps() -> Vec<Var> {
    vec![
        Var::Activation,
        Var::ActivationDynamics,
        Var::InitialActivation,
    ]
}

/// What the unit's outputs depend on.
fn unit_deps() -> Vec<Var> {
    let mut deps = activation_deps();
    deps.extend([Var::Length, Var::L0, Var::Area]);
    deps.extend(TENDON_PARAMETERS.map(|i| Var::Tendon(i.id)));
    deps.push(Var::CompliantTendon);
    deps.extend(STATIC_LAW.map(Var::Param));
    deps
}

/// The unit N/m of `stiffness` (declared by [`muscle_info_for`] when the
/// scene exposes it) and rad of the angles.
const RAD: Unit = Unit {
    name: "rad",
    kg: 0,
    m: 0,
    s: 0,
};

/// The [`ModelInfo`] of the musculotendon FMU of scene `spec`: the muscle
/// FMUs' ([`muscle_info_for`]) with the unit rad.
pub fn info_for(spec: &SceneSpec) -> ModelInfo {
    let mut info = muscle_info_for(spec);
    info.units.push(RAD);
    info
}

/// The variables of scene `spec` ([`SceneSpec::variables`]), the `length`
/// input starting at the scene's rest path L_TS + L0 cos α0
/// ([`UnitParams::rest_path`], the path the model reads until one is set).
pub fn scene_variables(spec: &SceneSpec) -> Vec<ScalarVariable<Var>> {
    let mut vars = spec.variables(all_variables());
    let real = |name: &str, default: f64| match spec.setting(name).map(|s| s.value) {
        Some(Value::Real(x)) => x,
        _ => default,
    };
    let default = |id: TendonParamId| TENDON_PARAMETERS[id as usize].default;
    let unit = UnitParams {
        tendon_slack_length: real(
            "tendon_slack_length",
            default(TendonParamId::TendonSlackLength),
        ),
        pennation_angle: real("pennation_angle", default(TendonParamId::PennationAngle)),
        ..UnitParams::default()
    };
    let path = unit.rest_path(real("L0", DEFAULT_L0));
    for v in &mut vars {
        if let (true, VarType::Real { start, .. }) = (v.id == Var::Length, &mut v.ty) {
            *start = Some(path);
        }
    }
    vars
}

/// The full `HillMusculotendon1D` (the scene
/// `fmu_build/scenes/musculotendon_1d.toml`).
pub type Musculotendon = MusculotendonModel<crate::scene::shipped::HillMusculotendon1D>;

/// The 1D musculotendon FMU model of scene `S` ([`crate::scene`]): the
/// [`Musculotendon1D`] with the scene's components as compile-time constants
/// ([`LawOf`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MusculotendonModel<S: Scene> {
    mt: Musculotendon1D<LawOf<S>>,
}

impl<S: Scene> MusculotendonModel<S> {
    /// The value of output `o` after the last step or initialization.
    fn output(&self, o: MtOutput) -> f64 {
        match o {
            MtOutput::Unit(u) => self.mt.output(u),
            MtOutput::ActivationLevel => self.mt.muscle.output(Output::ActivationLevel),
        }
    }

    /// Evaluations of the muscle's piece law in the last step (a
    /// diagnostic: [`Musculotendon1D::last_step_evaluations`]).
    pub fn last_step_evaluations(&self) -> u32 {
        self.mt.last_step_evaluations()
    }
}

impl<S: Scene> Model for MusculotendonModel<S> {
    type Var = Var;

    fn info() -> ModelInfo {
        info_for(&S::SPEC)
    }

    fn variables() -> Vec<ScalarVariable<Var>> {
        scene_variables(&S::SPEC)
    }

    fn new() -> Self {
        let mut m = MusculotendonModel {
            mt: Musculotendon1D::new(Muscle1D::new(SUBSTEP_RTOL), UnitParams::default()),
        };
        m.table_apply_scene(&S::SPEC);
        // Outputs at the start values are those of the initial equilibrium.
        m.initialize().expect("the scene's start values are valid");
        m
    }

    model_access!();

    /// Static equilibrium of tendon and muscle at the initial path length
    /// and activation level ([`Musculotendon1D::initialize`]).
    fn initialize(&mut self) -> Result<(), ModelError> {
        self.mt.initialize().map_err(|e| ModelError(e.0))
    }

    /// The unit's step ([`Musculotendon1D::step`]); a step it cannot take
    /// is discarded, the model unchanged.
    fn do_step(&mut self, _t: f64, h: f64) -> Result<(), StepError> {
        self.mt
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
            Var::Out(MtOutput::Unit(UnitOutput::Stiffness)) => {
                Err(super::common::stiffness_not_differentiated())
            }
            Var::Out(MtOutput::Unit(o)) => Ok(self.mt.partial(o, column)),
            Var::Out(MtOutput::ActivationLevel) => {
                Ok(self.mt.muscle.partial(Output::ActivationLevel, column))
            }
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    fn check_stepping_outputs(&self) -> Result<(), String> {
        state::check_stepping(&self.mt)
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        state::encode(self, out);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        state::decode(input)
    }
}

/// The unit and the conventions, for the FMU's `documentation/index.html`
/// (followed by the law's, [`super::hill1d::LAW_HTML`]).
pub const MT_HTML: &str = include_str!("doc/musculotendon1d.html");
