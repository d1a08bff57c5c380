//! `HillMusculotendonFE`: the FE musculotendon unit
//! ([`crate::fe::musculotendon::MusculotendonFE`]) as an FMI 2.0
//! Co-Simulation model, with the inputs and outputs of
//! `HillMusculotendon1D` ([`super::musculotendon1d`]) and the mesh
//! parameters of `HillMuscleFE` ([`super::hillfe`]). This file only maps:
//! the variable table ([`variables!`]: [`Var`], [`all_variables`]), the FMI
//! calls onto the unit and the state codec (`state`). What a step computes
//! is the unit's (MODEL_NOTES "Musculotendon unit"; [`MTFE_HTML`]).
//!
//! Invariant: the `length` input is the path length, origin to insertion;
//! its start is the rest path L_TS + L0 cos α0 of the scene's parameters
//! ([`scene_variables`]).

use std::marker::PhantomData;
use std::sync::Arc;

use super::common::{check_range, check_unit_interval, SUBSTEP_RTOL};
use super::hillfe::{
    check_mesh, mesh_rows, DEFAULT_AREA, DEFAULT_GRADING, DEFAULT_L0, DEFAULT_MESH,
};
use super::musculotendon1d::{info_for, MtOutput, TendonParameters};
use super::table::{
    self, boolean, input, model_access, output, parameter, real, variables, Check, Row, STATIC_LAW,
};
use crate::fe::discretization::Discretization;
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::musculotendon::{MusculotendonFE, Setup, UnitOutput as FeOutput};
use crate::fe::step_map::{built_with, discretization, StepLevel};
use crate::fe::threads::Threads;
use crate::fmi2::{Model, ModelError, ModelInfo, ScalarVariable, StepError, VarType};
use crate::law::activation::Decay;
use crate::law::musculotendon::{Unit, UnitParams};
use crate::law::params::{TendonParamId, AREA_RANGE, L0_RANGE, LENGTH_RANGE, TENDON_PARAMETERS};
use crate::law::{ParamId, Params};
use crate::muscle1d::UnitOutput;
use crate::scene::{Scene, SceneSpec, Value};

mod state;

variables! {
    /// A variable of `HillMusculotendonFE`, in table order: the law's
    /// parameters, the muscle's geometry, the tendon and pennation, the
    /// activation and substep options, the mesh, the inputs, the outputs.
    pub enum Var;
    impl[S: Scene] MusculotendonFEModel<S> as (m, v) {
        /// A parameter of the law (MODEL_NOTES "Parameters").
        Param(id: ParamId) = table::LawParameters
            => Real(get m.params.get(id), set m.params.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        L0 = table::l0(
            "Rest length L0 of the muscle (the fusiform specimen is scaled to it; the fibre length at which the pennation angle is pennation_angle)",
            DEFAULT_L0,
        ) => Real(m.l0);
        Area = table::area(
            "Mean cross-section V0/L0 of the fusiform muscle: its maximum isometric force is F0 = sigma0 * area",
            DEFAULT_AREA,
        ) => Real(m.area);
        /// A parameter of the tendon or the pennation (MODEL_NOTES
        /// "Musculotendon unit").
        Tendon(id: TendonParamId) = TendonParameters
            => Real(get m.unit.get(id), set m.unit.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        CompliantTendon = parameter(
            "compliant_tendon",
            "Compliant tendon (Thelen's force-strain curve, in equilibrium with the muscle at the end of every step); false: a rigid tendon of length tendon_slack_length",
            boolean(true),
            Check::None,
        ) => Boolean(m.unit.compliant_tendon);
        ActivationDynamics = table::activation_dynamics() => Boolean(m.activation_dynamics);
        InitialActivation = table::initial_activation() => Real(m.initial_activation);
        AdaptiveSubsteps = table::adaptive_substeps(
            "Cut the FE step into pieces where the error estimate of the CE-SEE update exceeds substep_tolerance (each trial of the tendon's equilibrium then the controlled step); false: one backward-Euler step per communication step",
            false,
        ) => Boolean(m.adaptive_substeps);
        SubstepTolerance = table::substep_tolerance(
            "Tolerance of the estimated local error of the SEE stress per piece (largest over the elements), as a fraction of sigma0",
        ) => Real(m.substep_tolerance);
        NAxial = mesh_rows::n_axial() => Integer(m.n_axial);
        NRadial = mesh_rows::n_radial() => Integer(m.n_radial);
        AxialGrading = mesh_rows::axial_grading() => Real(m.grading.axial);
        RadialGrading = mesh_rows::radial_grading() => Real(m.grading.radial);
        FibreLayout = mesh_rows::fibre_layout() => Integer(m.fibre_layout);
        Activation = table::activation() => Real(m.command), der m.command_rate;
        Length = path_length()
            => Real(get m.path(), set m.path = Some(v)), der m.path_rate;
        /// An output ([`OUTPUTS`]); `stiffness` is d force / d length of the
        /// last step map, the same number as
        /// fmi2GetDirectionalDerivative(force, length).
        Out(o: MtOutput) = OUTPUTS => Real(get m.output(o));
        Threads = mesh_rows::threads() => Integer(m.threads);
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
            "Engineering (nominal) stress of the muscle: its axial reaction force F_M / area (the tendon force is F_M cos(pennation))",
            "Pa",
            unit_deps,
        ),
    ),
    (
        MtOutput::Unit(UnitOutput::FibreLength),
        output(
            "fibre_length",
            "Fibre length L_M of the muscle (the FE muscle's length), along its fibres",
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
            "Series stiffness d force / d length of the step map that produced the current outputs (tendon and FE muscle in series through the pennation, history fixed; formed when first read after a step)",
            "N/m",
            unit_deps,
        ),
    ),
];

// Dependencies at initialization (the static equilibrium of tendon and FE
// muscle at the initial path length and activation level): the activation
// level on the activation options; everything else also on the path, the
// geometry, the tendon and pennation, the mesh and the static law. Outputs
// have no direct feedthrough.

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
    deps.extend([
        Var::AdaptiveSubsteps,
        Var::SubstepTolerance,
        Var::Length,
        Var::L0,
        Var::Area,
    ]);
    deps.extend(TENDON_PARAMETERS.map(|i| Var::Tendon(i.id)));
    deps.extend([
        Var::CompliantTendon,
        Var::NAxial,
        Var::NRadial,
        Var::AxialGrading,
        Var::RadialGrading,
        Var::FibreLayout,
    ]);
    deps.extend(STATIC_LAW.map(Var::Param));
    deps
}

/// The variables of scene `spec` ([`SceneSpec::variables`]), the `length`
/// input starting at the scene's rest path L_TS + L0 cos α0
/// ([`UnitParams::rest_path`]).
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

/// The full `HillMusculotendonFE` (the scene
/// `fmu_build/scenes/musculotendon_fe.toml`).
pub type MusculotendonFe = MusculotendonFEModel<crate::scene::shipped::HillMusculotendonFE>;

/// The FE musculotendon FMU model of scene `S` ([`crate::scene`]; the FE
/// solver always evaluates the complete law).
#[derive(Clone, Debug)]
pub struct MusculotendonFEModel<S: Scene> {
    scene: PhantomData<S>,
    params: Params,
    l0: f64,
    area: f64,
    unit: UnitParams,
    activation_dynamics: bool,
    initial_activation: f64,
    adaptive_substeps: bool,
    substep_tolerance: f64,
    n_axial: i32,
    n_radial: i32,
    grading: Grading,
    fibre_layout: i32,
    /// The element loops' threads (`mesh_rows::threads`), handed to the
    /// discretization before each call that evaluates it.
    threads: i32,
    command: f64,
    command_rate: f64,
    /// The path length input; `None` until set (the rest path).
    path: Option<f64>,
    path_rate: f64,
    decay: Option<Decay>,
    /// The committed unit (`None` before the first initialization).
    state: Option<MusculotendonFE>,
}

/// The unit's output of the FMU's.
fn fe_output(o: UnitOutput) -> FeOutput {
    match o {
        UnitOutput::Force | UnitOutput::Stiffness => FeOutput::Force,
        UnitOutput::Stress => FeOutput::Stress,
        UnitOutput::FibreLength => FeOutput::FibreLength,
        UnitOutput::TendonStrain => FeOutput::TendonStrain,
        UnitOutput::PennationAngle => FeOutput::PennationAngle,
    }
}

impl<S: Scene> MusculotendonFEModel<S> {
    /// The path length input (L_TS + L0 cos α0 until set).
    fn path(&self) -> f64 {
        self.path.unwrap_or_else(|| self.unit.rest_path(self.l0))
    }

    fn layout(&self) -> FibreLayout {
        if self.fibre_layout == 1 {
            FibreLayout::Meridian
        } else {
            FibreLayout::Axial
        }
    }

    fn resolution(&self) -> Resolution {
        Resolution {
            n_axial: self.n_axial as usize,
            n_radial: self.n_radial as usize,
        }
    }

    /// The tendon and pennation of the current parameters; F0 = σ0 · area.
    fn tendon_unit(&self) -> Unit {
        Unit::new(&self.unit, self.l0, self.params.sigma0 * self.area)
    }

    /// The `threads` parameter (its row's check keeps it in range).
    fn threads(&self) -> Threads {
        Threads::new(usize::try_from(self.threads).unwrap_or(1)).unwrap_or_default()
    }

    fn check_setup(&self) -> Result<(), ModelError> {
        self.params
            .validate()
            .map_err(|e| ModelError(e.to_string()))?;
        self.unit
            .validate()
            .map_err(|e| ModelError(e.to_string()))?;
        check_range("L0", self.l0, L0_RANGE)?;
        check_range("area", self.area, AREA_RANGE)?;
        check_unit_interval("initial_activation", self.initial_activation)?;
        check_range("length", self.path(), LENGTH_RANGE)?;
        Ok(())
    }

    /// The discretization for the current parameters (reused when the
    /// geometry and mesh are those of the committed muscle).
    fn discretization(&self) -> Result<Arc<Discretization>, ModelError> {
        let reuse = self.state.as_ref().map(|c| &c.muscle.muscle.disc);
        discretization(
            reuse,
            self.l0,
            self.area,
            self.resolution(),
            self.grading,
            self.layout(),
        )
        .map_err(ModelError)
    }

    /// The value of output `o` after the last step or initialization (NaN
    /// before one, or for a stiffness whose tangent cannot be formed).
    fn output(&self, o: MtOutput) -> f64 {
        let Some(st) = &self.state else {
            return f64::NAN;
        };
        match o {
            MtOutput::Unit(UnitOutput::Stiffness) => {
                let unit = self.tendon_unit();
                st.partial(&self.setup(&unit), FeOutput::Force, true)
                    .unwrap_or(f64::NAN)
            }
            MtOutput::Unit(u) => st.output(fe_output(u)),
            MtOutput::ActivationLevel => st.muscle.last.activation,
        }
    }

    fn setup<'a>(&'a self, unit: &'a Unit) -> Setup<'a> {
        Setup {
            params: &self.params,
            l0: self.l0,
            area: self.area,
            unit,
        }
    }

    /// Every field at its default, before the scene's settings or a
    /// restored state's values are applied.
    fn blank() -> Self {
        MusculotendonFEModel {
            scene: PhantomData,
            params: Params::default(),
            l0: DEFAULT_L0,
            area: DEFAULT_AREA,
            unit: UnitParams::default(),
            activation_dynamics: S::SPEC.components.activation_dynamics,
            initial_activation: 0.0,
            adaptive_substeps: false,
            substep_tolerance: SUBSTEP_RTOL,
            n_axial: DEFAULT_MESH.n_axial as i32,
            n_radial: DEFAULT_MESH.n_radial as i32,
            grading: DEFAULT_GRADING,
            fibre_layout: 0,
            threads: 1,
            command: 0.0,
            command_rate: 0.0,
            path: None,
            path_rate: 0.0,
            decay: None,
            state: None,
        }
    }

    /// FE Newton iterations (linear solves) and equilibrium trials of the
    /// last step (a diagnostic).
    pub fn last_step_work(&self) -> (usize, u32) {
        self.state
            .as_ref()
            .map_or((0, 0), |s| (s.iterations, s.trials))
    }

    /// The committed unit (`None` before initialization).
    pub fn unit(&self) -> Option<&MusculotendonFE> {
        self.state.as_ref()
    }
}

impl<S: Scene> Model for MusculotendonFEModel<S> {
    type Var = Var;

    fn info() -> ModelInfo {
        info_for(&S::SPEC)
    }

    fn variables() -> Vec<ScalarVariable<Var>> {
        scene_variables(&S::SPEC)
    }

    fn new() -> Self {
        let mut m = Self::blank();
        m.table_apply_scene(&S::SPEC);
        m.initialize().expect("the scene's start values are valid");
        m
    }

    model_access!();

    /// Static equilibrium of tendon and FE muscle at the initial path
    /// length and activation level ([`MusculotendonFE::initialize`]; with
    /// `activation_dynamics = false` at the command).
    fn initialize(&mut self) -> Result<(), ModelError> {
        self.check_setup()?;
        check_mesh(self.n_axial, self.n_radial, self.fibre_layout, self.grading)?;
        let (a, da_du) = if self.activation_dynamics {
            (self.initial_activation, 0.0)
        } else {
            (self.command, 1.0)
        };
        let disc = self.discretization()?;
        disc.set_threads(self.threads());
        let unit = self.tendon_unit();
        let state = MusculotendonFE::initialize(disc, &self.setup(&unit), self.path(), a, da_du)
            .map_err(|e| ModelError(format!("initialization: {e}")))?;
        self.state = Some(state);
        self.decay = None;
        Ok(())
    }

    /// The unit's step ([`MusculotendonFE::step`]); a step it cannot take
    /// is discarded, the model unchanged.
    fn do_step(&mut self, _t: f64, h: f64) -> Result<(), StepError> {
        let state = self
            .state
            .as_ref()
            .ok_or_else(|| StepError::Error("the model is not initialized".into()))?;
        let path = self.path() + h * self.path_rate;
        if !(path.is_finite() && path > 0.0) {
            return Err(StepError::Discard(format!(
                "path length at the end of the step, length + h * der(length) = {path}, must be finite and > 0"
            )));
        }
        let decay = Decay::for_step(self.decay, self.params.s, h);
        let level = StepLevel::new(
            self.activation_dynamics,
            self.params.s,
            state.muscle.last.activation,
            self.command,
            self.command_rate,
            h,
            decay.value,
        );
        let tolerance = self.adaptive_substeps.then_some(self.substep_tolerance);
        let unit = self.tendon_unit();
        state.muscle.muscle.disc.set_threads(self.threads());
        let next = state
            .step(&self.setup(&unit), level, path, tolerance)
            .map_err(|e| StepError::Discard(e.to_string()))?;
        self.state = Some(next);
        self.decay = Some(decay);
        self.command_rate = 0.0;
        self.path_rate = 0.0;
        Ok(())
    }

    /// Partial derivatives of the outputs with respect to both inputs:
    /// those of the last step's map ([`MusculotendonFE::partial`]).
    fn partial_derivative(&self, unknown: Var, known: Var) -> Result<f64, ModelError> {
        let by_length = match known {
            Var::Length => true,
            Var::Activation => false,
            _ => {
                return Err(ModelError(
                    "directional derivatives are taken with respect to the inputs".into(),
                ))
            }
        };
        let st = self
            .state
            .as_ref()
            .ok_or_else(|| ModelError("the model is not initialized".into()))?;
        match unknown {
            Var::Out(MtOutput::Unit(UnitOutput::Stiffness)) => {
                Err(super::common::stiffness_not_differentiated())
            }
            Var::Out(MtOutput::Unit(o)) => {
                let unit = self.tendon_unit();
                st.partial(&self.setup(&unit), fe_output(o), by_length)
                    .map_err(ModelError)
            }
            Var::Out(MtOutput::ActivationLevel) => {
                Ok(if by_length { 0.0 } else { st.muscle.last.da_du })
            }
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    /// A committed unit whose muscle was built with the current geometry
    /// and mesh parameters.
    fn is_initialized(&self) -> bool {
        self.state.as_ref().is_some_and(|c| {
            built_with(
                &c.muscle.muscle.disc,
                self.l0,
                self.area,
                self.resolution(),
                self.grading,
                self.layout(),
            )
        })
    }

    fn check_stepping_outputs(&self) -> Result<(), String> {
        state::check_stepping(self)
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
pub const MTFE_HTML: &str = include_str!("doc/musculotendonfe.html");

#[cfg(test)]
mod tests;
