//! `HillMuscleFE`: the lumped 3D finite-element muscle as an FMI 2.0
//! Co-Simulation model: the paper's fusiform specimen ([`crate::fe`]), same
//! inputs and outputs as `HillMuscle1D` plus field diagnostics. This module
//! maps the FMI variables, calls and state to the FE muscle's step map
//! ([`crate::fe::step_map`]).
//!
//! Each step, with the conventions of MODEL_NOTES "Co-simulation
//! conventions":
//! 1. the activation level follows da/dt = S (u − a) exactly (or equals the
//!    command `u + τ du/dt` when `activation_dynamics = false`, at every
//!    substep as at the step's end);
//! 2. the moved end face goes from where it is to the input `length` (or
//!    `length + h · dlength/dt` with an input derivative), the fixed face
//!    stays; quasi-static equilibrium is solved at the end of the step with
//!    the CE–SEE history of every element advanced over h, substepping when
//!    Newton does not converge; nothing is committed unless the whole step
//!    converges (else `fmi2Discard`, instance unchanged).
//!
//! Geometry: the paper's fusiform muscle scaled to rest length `L0` and mean
//! cross-section `area` = V0/L0 (defaults: the paper's 5 cm specimen and its
//! mean section, the same default `area` as `HillMuscle1D`). The mesh
//! (`n_axial` × `n_radial`, [`crate::fe::mesh`]) is built at initialization.
//!
//! The outputs are the FE muscle's [`Output`] (its `Quantity`) values, in
//! table order.

use std::sync::Arc;

use crate::fe::discretization::Discretization;
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::step_map::{
    built_with, discretization, Committed, Outputs, StepLevel, Stepped, N_QUANTITIES,
};
use crate::fmi2::{Model, ModelError, ModelInfo, ScalarVariable, StepError, VarType, Variability};
use crate::fmus::common::{check_range, check_unit_interval, units, SUBSTEP_RTOL};
use crate::fmus::table::{
    self, integer, model_access, output, parameter, real, variables, Check, Row, STATIC_LAW,
};
use crate::law::activation::Decay;
use crate::law::params::{Range, AREA_RANGE, L0_RANGE, LENGTH_RANGE};
use crate::law::uniaxial::evaluable_stretch_range;
use crate::law::{ParamId, Params};
use crate::scene::Scene;
use std::marker::PhantomData;

/// Default rest length: the paper's specimen.
pub const DEFAULT_L0: f64 = crate::specimen::LENGTH;
/// Default mean cross-section V0/L0 of the paper's specimen.
pub const DEFAULT_AREA: f64 = crate::specimen::MEAN_AREA;
/// Mesh resolution limits (the finest verification level is 48 × 8).
const N_AXIAL_RANGE: (i32, i32) = (1, 96);
const N_RADIAL_RANGE: (i32, i32) = (1, 16);
/// The default ("lumped") mesh and its grading toward the clamped faces'
/// rims, chosen by the convergence study of docs/fe.md
/// ([`crate::fe::mesh::LUMPED`], [`crate::fe::mesh::LUMPED_GRADING`]).
pub const DEFAULT_MESH: Resolution = crate::fe::mesh::LUMPED;
/// See [`DEFAULT_MESH`].
pub const DEFAULT_GRADING: Grading = crate::fe::mesh::LUMPED_GRADING;
/// Valid axial and radial grading ([`crate::fe::mesh::graded_slice`],
/// [`crate::fe::mesh::graded_ring`]).
const GRADING_RANGE: Range = Range {
    min: 0.0,
    max: crate::fe::mesh::MAX_GRADING,
};

variables! {
    /// A variable of `HillMuscleFE`, in table order: the law's parameters,
    /// geometry, activation, substep and mesh options, the inputs, the
    /// outputs.
    pub enum Var;
    impl[S: Scene] HillFEModel<S> as (m, v) {
        /// A parameter of the law (MODEL_NOTES "Parameters").
        Param(id: ParamId) = table::law_parameters()
            => Real(get m.params.get(id), set m.params.set(id, v).map_err(|e| ModelError(e.to_string()))?);
        L0 = table::l0(
            "Rest length of the muscle (the fusiform specimen is scaled to it)",
            DEFAULT_L0,
        ) => Real(m.l0);
        Area = table::area(
            "Mean cross-section V0/L0 of the fusiform muscle (radii scaled to it); stress = force / area",
            DEFAULT_AREA,
        ) => Real(m.area);
        ActivationDynamics = table::activation_dynamics() => Boolean(m.activation_dynamics);
        InitialActivation = table::initial_activation() => Real(m.initial_activation);
        AdaptiveSubsteps = table::adaptive_substeps(
            "Cut a step into pieces where the error estimate of the CE-SEE update exceeds substep_tolerance (each piece a full equilibrium solve); false: one backward-Euler step per communication step (first order in h)",
            false,
        ) => Boolean(m.adaptive_substeps);
        SubstepTolerance = table::substep_tolerance(
            "Tolerance of the estimated local error of the SEE stress per piece (largest over the elements), as a fraction of sigma0",
        ) => Real(m.substep_tolerance);
        NAxial = parameter(
            "n_axial",
            "Mesh: element layers along the axis",
            integer(DEFAULT_MESH.n_axial as i32, N_AXIAL_RANGE),
            Check::Closed,
        ) => Integer(m.n_axial);
        NRadial = parameter(
            "n_radial",
            "Mesh: rings in the cross-section",
            integer(DEFAULT_MESH.n_radial as i32, N_RADIAL_RANGE),
            Check::Closed,
        ) => Integer(m.n_radial);
        AxialGrading = parameter(
            "axial_grading",
            "Mesh: slices graded toward the clamped end faces, x = L (u - g sin(2 pi u)/(2 pi)); end layers (1 - g) times the uniform spacing",
            real("1", Some(DEFAULT_GRADING.axial), Some(GRADING_RANGE)),
            Check::Finite,
        ) => Real(m.grading.axial);
        RadialGrading = parameter(
            "radial_grading",
            "Mesh: rings of the cross-section graded toward the lateral surface, radius u + g u (1 - u) of the section's radius, u = i / n_radial; outer ring about (1 - g) times the uniform width",
            real("1", Some(DEFAULT_GRADING.radial), Some(GRADING_RANGE)),
            Check::Finite,
        ) => Real(m.grading.radial);
        FibreLayout = parameter(
            "fibre_layout",
            "Fibre directions: 0 along the axis (the paper), 1 along the profile's meridians",
            integer(0, (0, 1)),
            Check::Closed,
        ) => Integer(m.fibre_layout);
        Activation = table::activation() => Real(m.command), der m.command_rate;
        Length = table::length(DEFAULT_L0)
            => Real(get m.length(), set m.length = Some(v)), der m.length_rate;
        /// An output ([`OUTPUTS`]).
        Out(o: Output) = OUTPUTS => Real(get m.outputs[o as usize]);
        NewtonIterations = Row {
            variability: Variability::Discrete,
            ty: VarType::Integer {
                start: None,
                min: None,
                max: None,
            },
            ..output(
                "newton_iterations",
                "Newton iterations of the last step (all substeps, including the predictor), after initialization of the whole initialization",
                "1",
                state_deps,
            )
        } => Integer(get m.newton_iterations);
    }
}

// Dependencies at initialization: the activation level on the activation
// options (and, through the substeps, their control), everything else also
// on the length, the geometry, the mesh and the static law. Outputs have no
// direct feedthrough (`ModelInfo::direct_feedthrough`).

/// What the activation level depends on.
fn activation_deps() -> Vec<Var> {
    vec![
        Var::Activation,
        Var::ActivationDynamics,
        Var::InitialActivation,
        Var::AdaptiveSubsteps,
        Var::SubstepTolerance,
    ]
}

/// What every other output depends on.
fn state_deps() -> Vec<Var> {
    let mut deps = activation_deps();
    deps.extend([
        Var::Length,
        Var::L0,
        Var::Area,
        Var::NAxial,
        Var::NRadial,
        Var::AxialGrading,
        Var::RadialGrading,
        Var::FibreLayout,
    ]);
    deps.extend(STATIC_LAW.map(Var::Param));
    deps
}

/// The Real outputs: the FE muscle's quantities, in table order.
pub use crate::fe::step_map::Quantity as Output;

mod state;

/// The outputs' rows, in [`Output`] order.
const OUTPUTS: [(Output, Row<Var>); N_QUANTITIES] = [
    (
        Output::Force,
        table::force(
            "Axial reaction force on the moved end face, tension positive",
            state_deps,
        ),
    ),
    (Output::Stress, table::stress(state_deps)),
    (
        Output::CauchyStress,
        table::cauchy_stress(
            "Mean axial Cauchy stress: force * length / current volume",
            state_deps,
        ),
    ),
    (
        Output::ActivationLevel,
        table::activation_level(activation_deps),
    ),
    (
        Output::FibreStretch,
        table::fibre_stretch("Volume average of the modified fibre stretch", state_deps),
    ),
    (
        Output::CeStretch,
        table::ce_stretch(
            "Volume average of the contractile element stretch lambda_m",
            state_deps,
        ),
    ),
    (
        Output::SeeStretch,
        table::see_stretch(
            "Volume average of the series elastic element stretch lambda_s",
            state_deps,
        ),
    ),
    (
        Output::ActiveStress,
        table::active_stress("Volume average of the SEE (= CE) stress sigma_s", state_deps),
    ),
    (
        Output::PassiveStress,
        table::passive_stress("stress - active_stress", state_deps),
    ),
    (
        Output::VolumeRatioMin,
        output(
            "volume_ratio_min",
            "Smallest element volume ratio (mean of its nodal J, the ratio the volume constraint acts on)",
            "1",
            state_deps,
        ),
    ),
    (
        Output::VolumeRatioMax,
        output(
            "volume_ratio_max",
            "Largest element volume ratio (mean of its nodal J, the ratio the volume constraint acts on)",
            "1",
            state_deps,
        ),
    ),
    (
        Output::MaxFibreStretch,
        output(
            "max_fibre_stretch",
            "Largest element modified fibre stretch",
            "1",
            state_deps,
        ),
    ),
];
/// The mesh parameters of a setup ([`Model::initialize`]) or of a restored
/// state's muscle, checked in one place before any mesh is built: the counts and the fibre layout in their
/// declared ranges, both gradings in theirs (the message naming the
/// parameter), and the mesh's estimated peak memory within the FE muscle's
/// budget ([`crate::fe::memory`]).
fn check_mesh(
    n_axial: i32,
    n_radial: i32,
    fibre_layout: i32,
    grading: Grading,
) -> Result<(Resolution, FibreLayout), ModelError> {
    let in_range = |v: i32, (lo, hi): (i32, i32)| (lo..=hi).contains(&v);
    if !(in_range(n_axial, N_AXIAL_RANGE)
        && in_range(n_radial, N_RADIAL_RANGE)
        && in_range(fibre_layout, (0, 1)))
    {
        return Err(ModelError(format!(
            "bad mesh {n_axial} x {n_radial}, fibre layout {fibre_layout}"
        )));
    }
    check_range("axial_grading", grading.axial, GRADING_RANGE)?;
    check_range("radial_grading", grading.radial, GRADING_RANGE)?;
    let resolution = Resolution {
        n_axial: n_axial as usize,
        n_radial: n_radial as usize,
    };
    crate::fe::memory::check(resolution, crate::fe::memory::BUDGET).map_err(ModelError)?;
    let layout = if fibre_layout == 1 {
        FibreLayout::Meridian
    } else {
        FibreLayout::Axial
    };
    Ok((resolution, layout))
}

/// The full `HillMuscleFE` (the scene `fmu_build/scenes/hill_muscle_fe.toml`).
pub type HillFE = HillFEModel<crate::scene::shipped::HillMuscleFE>;

/// The FE muscle FMU model of scene `S` ([`crate::scene`]). A scene changes
/// only the interface: which inputs, outputs and parameters are exposed,
/// the start values and constants, the mesh. The solver (`crate::fe`)
/// always evaluates the complete law; a scene without the contractile
/// element runs it at activation 0, where the CE carries nothing.
#[derive(Clone, Debug)]
pub struct HillFEModel<S: Scene> {
    scene: PhantomData<S>,
    params: Params,
    l0: f64,
    area: f64,
    activation_dynamics: bool,
    initial_activation: f64,
    /// Error-controlled pieces per step ([`Muscle::advance_controlled`]).
    adaptive_substeps: bool,
    /// Their tolerance, a fraction of sigma0.
    substep_tolerance: f64,
    n_axial: i32,
    n_radial: i32,
    grading: Grading,
    fibre_layout: i32,
    command: f64,
    length: Option<f64>,
    command_rate: f64,
    length_rate: f64,
    activation_level: f64,
    /// The committed muscle (`None` before the first initialization).
    state: Option<Committed>,
    decay: Option<Decay>,
    /// In [`Output`] order.
    outputs: Outputs,
    newton_iterations: i32,
}

impl<S: Scene> HillFEModel<S> {
    fn length(&self) -> f64 {
        self.length.unwrap_or(self.l0)
    }

    fn layout(&self) -> FibreLayout {
        if self.fibre_layout == 1 {
            FibreLayout::Meridian
        } else {
            FibreLayout::Axial
        }
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

    /// The discretization for the current parameters (reused when the
    /// geometry and mesh are those of the committed muscle).
    fn discretization(&self) -> Result<Arc<Discretization>, ModelError> {
        let resolution = Resolution {
            n_axial: self.n_axial as usize,
            n_radial: self.n_radial as usize,
        };
        let reuse = self.state.as_ref().map(|c| &c.muscle.disc);
        discretization(
            reuse,
            self.l0,
            self.area,
            resolution,
            self.grading,
            self.layout(),
        )
        .map_err(ModelError)
    }

    fn check_stretch(&self, length: f64) -> Result<(), String> {
        let (lo, hi) = evaluable_stretch_range(&self.params);
        let lambda = length / self.l0;
        if (lo..=hi).contains(&lambda) {
            Ok(())
        } else {
            Err(format!(
                "length = {length} m with L0 = {} m (stretch {lambda}) is outside the range the law can evaluate, [{lo:.4}, {hi:.4}]",
                self.l0
            ))
        }
    }

    /// Commit a step's (or the initialization's) result.
    fn commit(&mut self, stepped: Stepped) {
        self.outputs = stepped.outputs;
        self.activation_level = stepped.state.last.activation;
        self.newton_iterations = i32::try_from(stepped.iterations).unwrap_or(i32::MAX);
        self.state = Some(stepped.state);
    }

    /// The committed muscle, or the error of a call that needs one.
    fn committed(&self) -> Result<&Committed, ModelError> {
        self.state
            .as_ref()
            .ok_or_else(|| ModelError("the model is not initialized".into()))
    }
}

impl<S: Scene> HillFEModel<S> {
    /// Every field at its default, before the scene's settings ([`Model::new`])
    /// or a restored state's values (`state::decode`) are applied.
    fn blank() -> Self {
        HillFEModel {
            scene: PhantomData,
            params: Params::default(),
            l0: DEFAULT_L0,
            area: DEFAULT_AREA,
            // Without the component: a = u (its switch compiled in as false).
            activation_dynamics: S::SPEC.components.activation_dynamics,
            initial_activation: 0.0,
            adaptive_substeps: false,
            substep_tolerance: SUBSTEP_RTOL,
            n_axial: DEFAULT_MESH.n_axial as i32,
            n_radial: DEFAULT_MESH.n_radial as i32,
            grading: DEFAULT_GRADING,
            fibre_layout: 0,
            command: 0.0,
            length: None,
            command_rate: 0.0,
            length_rate: 0.0,
            activation_level: 0.0,
            state: None,
            decay: None,
            outputs: [0.0; N_QUANTITIES],
            newton_iterations: 0,
        }
    }
}

impl<S: Scene> Model for HillFEModel<S> {
    type Var = Var;

    fn info() -> ModelInfo {
        info_for(&S::SPEC)
    }

    /// The scene's variables: [`all_variables`] restricted to what the scene
    /// exposes ([`crate::scene::SceneSpec::variables`]).
    fn variables() -> Vec<ScalarVariable<Var>> {
        S::SPEC.variables(all_variables())
    }

    fn new() -> Self {
        let mut m = Self::blank();
        // The scene's start values and constants (checked when the scene was
        // resolved; the setters check them again).
        let all = all_variables();
        crate::scene::apply_settings(&S::SPEC, &all, |var, value| {
            m.table_set(var, value).map(|_| ()).map_err(|e| e.0)
        })
        .expect("the scene's settings are valid");
        m.initialize().expect("the scene's start values are valid");
        m
    }

    model_access!();

    /// Isometric equilibrium at the initial length and `initial_activation`
    /// (with `activation_dynamics = false`: at the command).
    fn initialize(&mut self) -> Result<(), ModelError> {
        self.check_setup()?;
        check_mesh(self.n_axial, self.n_radial, self.fibre_layout, self.grading)?;
        let (a, da_du) = if self.activation_dynamics {
            (self.initial_activation, 0.0)
        } else {
            (self.command, 1.0)
        };
        let length = self.length();
        self.check_stretch(length).map_err(ModelError)?;
        let disc = self.discretization()?;
        let stepped = Committed::initialize(disc, &self.params, self.area, length, a, da_du)
            .map_err(|e| ModelError(format!("initialization: {e}")))?;
        self.commit(stepped);
        self.decay = None;
        Ok(())
    }

    fn do_step(&mut self, _t: f64, h: f64) -> Result<(), StepError> {
        let state = self
            .state
            .as_ref()
            .ok_or_else(|| StepError::Error("the model is not initialized".into()))?;
        let end_length = self.length() + h * self.length_rate;
        if !(end_length.is_finite() && end_length > 0.0) {
            return Err(StepError::Discard(format!(
                "length at the end of the step, length + h * der(length) = {end_length}, must be finite and > 0"
            )));
        }
        self.check_stretch(end_length).map_err(StepError::Discard)?;
        let decay = Decay::for_step(self.decay, self.params.s, h);
        let level = StepLevel::new(
            self.activation_dynamics,
            self.params.s,
            self.activation_level,
            self.command,
            self.command_rate,
            h,
            decay.value,
        );
        let tolerance = self.adaptive_substeps.then_some(self.substep_tolerance);
        let stepped = state
            .step(&self.params, self.area, level, end_length, tolerance)
            .map_err(|e| StepError::Discard(e.to_string()))?;
        self.commit(stepped);
        self.decay = Some(decay);
        self.command_rate = 0.0;
        self.length_rate = 0.0;
        Ok(())
    }

    /// Partial derivatives of every output with respect to both inputs:
    /// those of the last step's map; of `force` and `stress` from
    /// [`Committed::force_derivatives`], of `activation_level` exactly, of
    /// the others from [`Committed::output_jacobian`].
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
        let da_du = self.state.as_ref().map_or(0.0, |c| c.last.da_du);
        let (p, l0, area) = (&self.params, self.l0, self.area);
        match unknown {
            Var::Out(Output::ActivationLevel) => Ok(if by_length { 0.0 } else { da_du }),
            Var::Out(o @ (Output::Force | Output::Stress)) => {
                let (dl, du) = self
                    .committed()?
                    .force_derivatives(p, l0, area)
                    .map_err(ModelError)?;
                let d = if by_length { dl } else { du };
                Ok(if o == Output::Force { d } else { d / self.area })
            }
            Var::Out(o) => {
                let jacobian = self
                    .committed()?
                    .output_jacobian(p, l0, area)
                    .map_err(ModelError)?;
                Ok(jacobian[o as usize][usize::from(!by_length)])
            }
            _ => Err(ModelError(
                "directional derivatives are provided for the outputs".into(),
            )),
        }
    }

    /// A committed muscle and step, built with the current geometry and
    /// mesh parameters: after initialization these are fixed, so a state
    /// in which they differ from the muscle's was not written by
    /// [`Model::serialize`] of a stepping instance.
    fn is_initialized(&self) -> bool {
        self.state.as_ref().is_some_and(|c| {
            built_with(
                &c.muscle.disc,
                self.l0,
                self.area,
                Resolution {
                    n_axial: self.n_axial as usize,
                    n_radial: self.n_radial as usize,
                },
                self.grading,
                self.layout(),
            )
        })
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        state::encode(self, out);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        state::decode(input)
    }
}

/// The [`ModelInfo`] of the FE model of scene `spec`: its identifier,
/// description and DefaultExperiment.
pub fn info_for(spec: &crate::scene::SceneSpec) -> ModelInfo {
    ModelInfo {
        model_identifier: spec.model_identifier,
        description: spec.description,
        version: env!("CARGO_PKG_VERSION"),
        units: units(),
        default_experiment: spec.default_experiment,
        max_input_derivative_order: 1,
        direct_feedthrough: false,
    }
}

/// The model, for the FMU's `documentation/index.html`.
pub const FE_HTML: &str = include_str!("doc/hillfe.html");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::step_map::{outputs, Quantity, Substepped};
    use crate::fmus::common::{assert_restore_refuses, restored};

    /// The last step's map when it took substeps.
    fn substepped(m: &HillFE) -> Option<&Substepped> {
        m.state.as_ref().and_then(|c| c.substepped.as_ref())
    }

    /// The output table lists the FE muscle's quantities in their order:
    /// the serialized outputs are in that order.
    #[test]
    fn the_output_table_is_in_the_order_of_the_fe_quantities() {
        for (i, &(o, ..)) in OUTPUTS.iter().enumerate() {
            assert_eq!(o as usize, i, "{o:?}");
        }
    }

    /// The scenes' mesh levels (src/scene, compiled without the FE code) are
    /// the FE module's: `lumped` the default mesh and its grading, `level0`
    /// … `level4` the refinement levels, ungraded.
    #[test]
    fn the_scene_mesh_levels_are_the_fe_meshes() {
        let as_mesh = |l: &crate::scene::MeshLevel| {
            (
                Resolution {
                    n_axial: l.n_axial as usize,
                    n_radial: l.n_radial as usize,
                },
                Grading {
                    axial: l.axial_grading,
                    radial: l.radial_grading,
                },
            )
        };
        let levels = crate::scene::MESH_LEVELS;
        assert_eq!(levels[0].name, "lumped");
        assert_eq!(as_mesh(&levels[0]), (DEFAULT_MESH, DEFAULT_GRADING));
        for (i, (level, res)) in levels[1..].iter().zip(crate::fe::mesh::LEVELS).enumerate() {
            assert_eq!(level.name, format!("level{i}"));
            assert_eq!(as_mesh(level), (res, Grading::UNIFORM));
        }
    }

    /// A 6 × 1 muscle at `stretch` L0 and activation level `level`, with or
    /// without `adaptive_substeps`.
    fn muscle(stretch: f64, level: f64, adaptive: bool) -> HillFE {
        let mut m = HillFE::new();
        m.set_integer(Var::NAxial, 6).unwrap();
        m.set_integer(Var::NRadial, 1).unwrap();
        m.set_boolean(Var::AdaptiveSubsteps, adaptive).unwrap();
        m.set_real(Var::InitialActivation, level).unwrap();
        m.set_real(Var::Activation, level).unwrap();
        m.set_real(Var::Length, stretch * DEFAULT_L0).unwrap();
        m.initialize().unwrap();
        m
    }

    fn force(m: &HillFE) -> f64 {
        m.get_real(Var::Out(Output::Force))
    }

    /// `n` steps of `h` to length `l` under command `u`.
    fn run(m: &HillFE, l: f64, u: f64, h: f64, n: usize) -> HillFE {
        let mut m = m.clone();
        m.set_real(Var::Length, l).unwrap();
        m.set_real(Var::Activation, u).unwrap();
        for _ in 0..n {
            m.do_step(0.0, h).unwrap();
        }
        m
    }

    /// (dF/dL, dF/du) through the FMU's partial derivatives.
    fn derivatives(m: &HillFE) -> (f64, f64) {
        let d = |known| {
            m.partial_derivative(Var::Out(Output::Force), known)
                .unwrap()
        };
        (d(Var::Length), d(Var::Activation))
    }

    /// The outputs at the end of the step map of `start` in the fixed
    /// pieces `pieces` (the map a substepped step's derivatives
    /// differentiate).
    fn map_outputs(start: &HillFE, pieces: &[(f64, usize)], l: f64, u: f64, h: f64) -> Outputs {
        let s = start.params.s;
        let a0 = start.activation_level;
        let level = StepLevel::new(true, s, a0, u, 0.0, h, Decay::new(s, h).value);
        let adv = start
            .state
            .as_ref()
            .unwrap()
            .muscle
            .advance_pieces(&start.params, l, h, &|t| level.at(t), pieces)
            .unwrap();
        let m = &adv.muscle;
        outputs(
            &m.disc,
            start.area,
            m.length,
            &adv.solution.evaluation,
            level.end,
        )
    }

    /// The force of [`map_outputs`].
    fn map_force(start: &HillFE, pieces: &[(f64, usize)], l: f64, u: f64, h: f64) -> f64 {
        map_outputs(start, pieces, l, u, h)[Quantity::Force as usize]
    }

    /// A restored state is checked as strictly as the calls that produce
    /// its values: an activation command or level outside [0, 1], or a
    /// non-positive CE or SEE stretch in the history, is refused naming it
    /// (a crafted state: the layer's checksum is not a signature), while the
    /// unmodified state round-trips.
    #[test]
    fn a_restored_state_with_unphysical_values_is_refused() {
        let m = run(&muscle(1.05, 0.3, false), 1.06 * DEFAULT_L0, 0.6, 1e-3, 2);
        let back = restored(&m).expect("an unmodified state");
        assert_eq!(force(&back), force(&m));
        assert_restore_refuses(&m, |f| f.command = 5.0, "activation = 5");
        assert_restore_refuses(&m, |f| f.command = -3.0, "activation = -3");
        assert_restore_refuses(&m, |f| f.activation_level = 4.0, "activation level = 4");
        assert_restore_refuses(
            &m,
            |f| f.state.as_mut().unwrap().muscle.history[3].lambda_m = -1.0,
            "fibre history 3: CE stretch -1",
        );
        assert_restore_refuses(
            &m,
            |f| f.state.as_mut().unwrap().muscle.history[0].lambda_s = 0.0,
            "and SEE stretch 0 must be finite and > 0",
        );
        assert_restore_refuses(&m, |f| f.length = Some(1e3), "length = 1000");
    }

    /// After initialization the partial derivatives are those of the
    /// isometric equilibrium (FibreRate::Isometric; activation dynamics off,
    /// so the level is the command): dF/dL and dF/du against central
    /// differences of re-initializing at L ± δ and u ± δ, passive-stretched
    /// and active (measured agreement 5e-7 and better; held to 1e-5).
    #[test]
    fn initial_derivatives_match_finite_differences_of_the_initialization() {
        let init = |stretch: f64, u: f64| {
            let mut m = HillFE::new();
            m.set_integer(Var::NAxial, 6).unwrap();
            m.set_integer(Var::NRadial, 1).unwrap();
            m.set_boolean(Var::ActivationDynamics, false).unwrap();
            m.set_real(Var::Activation, u).unwrap();
            m.set_real(Var::Length, stretch * DEFAULT_L0).unwrap();
            m.initialize().unwrap();
            m
        };
        for (stretch, u) in [(1.1, 0.0), (1.05, 0.5)] {
            let m = init(stretch, u);
            let (d_l, d_u) = derivatives(&m);
            let (el, eu) = (1e-5, 1e-4);
            let fd_l = (force(&init(stretch + el, u)) - force(&init(stretch - el, u)))
                / (2.0 * el * DEFAULT_L0);
            let fd_u = if u > 0.0 {
                (force(&init(stretch, u + eu)) - force(&init(stretch, u - eu))) / (2.0 * eu)
            } else {
                let f = |u| force(&init(stretch, u));
                (-3.0 * f(0.0) + 4.0 * f(eu) - f(2.0 * eu)) / (2.0 * eu)
            };
            assert!(d_l > 0.0, "dF/dL {d_l}");
            assert!(
                ((d_l - fd_l) / fd_l).abs() < 1e-5,
                "L0 x {stretch}, u {u}: dF/dL {d_l} vs {fd_l}"
            );
            assert!(
                ((d_u - fd_u) / fd_u).abs() < 1e-5,
                "L0 x {stretch}, u {u}: dF/du {d_u} vs {fd_u}"
            );
        }
    }

    /// A step cut into pieces (level 0.3 -> command 0.6, 1.10 -> 1.12 L0,
    /// 5 ms, adaptive): its directional derivatives are those of the whole
    /// step's map (central differences of the same pieces from the same
    /// start, steps 10x and 5x the model's, extrapolated), not those of the last piece's
    /// tangent, which holds that piece's start history fixed and is
    /// distinctly off here; a restored copy of the state gives the same
    /// derivatives bit for bit; a step in one piece clears the record.
    #[test]
    fn a_substepped_step_has_the_derivatives_of_its_step_map() {
        let before = muscle(1.1, 0.3, true);
        let (l, u, h) = (1.12 * DEFAULT_L0, 0.6, 5e-3);
        let m = run(&before, l, u, h, 1);
        let pieces = substepped(&m).unwrap().pieces.clone();
        assert!(pieces.len() > 1, "{pieces:?}");
        // The map differentiated below is the step's own: replaying its
        // pieces gives the error-controlled step's force bit for bit.
        assert_eq!(map_force(&before, &pieces, l, u, h), force(&m));
        let (d_l, d_u) = derivatives(&m);
        // Central differences with steps 10x and 5x the model's, Richardson
        // extrapolated (their δ² terms cancel): this step's map is curved
        // enough that the 10x difference alone is 1.3e-5 off.
        let f = |l, u| map_force(&before, &pieces, l, u, h);
        let richardson = |d: &dyn Fn(f64) -> f64, e: f64| (4.0 * d(e / 2.0) - d(e)) / 3.0;
        let fd_l = richardson(
            &|e| (f(l + e, u) - f(l - e, u)) / (2.0 * e),
            1e-4 * DEFAULT_L0,
        );
        let fd_u = richardson(&|e| (f(l, u + e) - f(l, u - e)) / (2.0 * e), 1e-4);
        assert!(((d_l - fd_l) / fd_l).abs() < 1e-5, "dF/dL {d_l} vs {fd_l}");
        assert!(((d_u - fd_u) / fd_u).abs() < 1e-5, "dF/du {d_u} vs {fd_u}");

        // The last piece's tangent alone (what the derivatives were
        // before): off by more than 1 % in the command.
        let c = m.state.clone().unwrap();
        let last_only = Committed::new(c.muscle, c.last, None);
        let (_, d_u_last) = last_only
            .force_derivatives(&m.params, m.l0, m.area)
            .unwrap();
        assert!(
            ((d_u_last - fd_u) / fd_u).abs() > 1e-2,
            "the last piece's tangent {d_u_last} is as good as the map's {fd_u}: the test shows nothing"
        );

        let mut bytes = Vec::new();
        m.serialize(&mut bytes);
        let restored = HillFE::deserialize(&mut bytes.as_slice()).unwrap();
        assert!(substepped(&restored).is_some());
        let (r_l, r_u) = derivatives(&restored);
        assert_eq!(r_l.to_bits(), d_l.to_bits());
        assert_eq!(r_u.to_bits(), d_u.to_bits());
        let mut one_piece = m.clone();
        one_piece.set_boolean(Var::AdaptiveSubsteps, false).unwrap();
        assert!(substepped(&run(&one_piece, l, u, h, 1)).is_none());
    }

    /// A fast length ramp of the active muscle in one step (L0 → 2 L0 in
    /// 0.1 s, alpha = 10, S = 50, D = 1e-6): the CE yields under the fast
    /// lengthening (f_v near its plateau), where the error control needs
    /// pieces of ~10 µs, hundreds in the step. Its active stress is within
    /// 1e-3 sigma0 of the same ramp in 100 steps of 1 ms. Under the earlier
    /// work bound (256 tries, pieces ≥ h/4096) the step took its rest in one
    /// piece and was 8e-2 sigma0 off (docs/fe.md). `-- --nocapture` prints
    /// the figures.
    #[test]
    fn adaptive_substeps_follow_a_yielding_ce_through_a_fast_ramp() {
        let start = || {
            let mut m = HillFE::new();
            m.set_integer(Var::NAxial, 6).unwrap();
            m.set_integer(Var::NRadial, 1).unwrap();
            m.set_boolean(Var::AdaptiveSubsteps, true).unwrap();
            for (id, v) in [
                (ParamId::Alpha, 10.0),
                (ParamId::S, 50.0),
                (ParamId::Dcomp, 1e-6),
            ] {
                m.set_real(Var::Param(id), v).unwrap();
            }
            m.set_real(Var::InitialActivation, 1.0).unwrap();
            m.set_real(Var::Activation, 1.0).unwrap();
            m.set_real(Var::Length, DEFAULT_L0).unwrap();
            m.initialize().unwrap();
            m
        };
        let h = 0.1;
        let mut reference = start();
        for k in 1..=100 {
            reference
                .set_real(Var::Length, DEFAULT_L0 * (1.0 + f64::from(k) / 100.0))
                .unwrap();
            reference.do_step(0.0, h / 100.0).unwrap();
        }
        let adaptive = run(&start(), 2.0 * DEFAULT_L0, 1.0, h, 1);
        let active = |m: &HillFE| m.get_real(Var::Out(Output::ActiveStress));
        let error = (active(&adaptive) - active(&reference)).abs() / adaptive.params.sigma0;
        let pieces = &substepped(&adaptive).unwrap().pieces;
        let shortest = pieces
            .iter()
            .scan(0.0, |t, &(end, _)| Some(end - std::mem::replace(t, end)))
            .fold(f64::INFINITY, f64::min);
        eprintln!(
            "{} pieces, the shortest {shortest:e} s; active stress error / sigma0 {error:e}",
            pieces.len()
        );
        assert!(error < 1e-3, "active stress error / sigma0 {error:e}");
    }

    /// An activation jump 0 → 1 in one step of 20 ms (S h = 1): with
    /// `adaptive_substeps` the step is cut into pieces by the error estimate
    /// and its force is within 1e-2 sigma0 A of the reference (the same step
    /// in 200 steps of 0.1 ms), at least 5x closer than the one
    /// backward-Euler step without it; its derivatives are those of its
    /// step map, one-sided in the command at u = 1 (so first order in the
    /// difference step). (Differences of whole adaptive steps are no check:
    /// the pieces the control picks change with the inputs, by jumps of the
    /// order of its tolerance — here as large as the force change of the
    /// difference.) `-- --nocapture` prints the figures.
    #[test]
    fn adaptive_substeps_control_the_time_error_of_an_activation_jump() {
        let (l, h) = (1.05 * DEFAULT_L0, 0.02);
        let reference = force(&run(&muscle(1.05, 0.0, false), l, 1.0, h / 200.0, 200));
        let coarse = force(&run(&muscle(1.05, 0.0, false), l, 1.0, h, 1));
        let start = muscle(1.05, 0.0, true);
        let adaptive = run(&start, l, 1.0, h, 1);
        let scale = adaptive.params.sigma0 * adaptive.area;
        let (e_adaptive, e_coarse) = (
            (force(&adaptive) - reference).abs() / scale,
            (coarse - reference).abs() / scale,
        );
        let pieces = substepped(&adaptive).unwrap().pieces.clone();
        eprintln!(
            "{} pieces; force error / (sigma0 A): adaptive {e_adaptive:e}, one step {e_coarse:e}",
            pieces.len()
        );
        assert!(pieces.len() > 2, "{pieces:?}");
        assert!(
            e_adaptive < 1e-2 && e_adaptive < 0.2 * e_coarse,
            "adaptive {e_adaptive:e}, one step {e_coarse:e}"
        );

        let (d_l, d_u) = derivatives(&adaptive);
        let (el, eu) = (1e-4 * DEFAULT_L0, 1e-4);
        let f = |l, u| map_force(&start, &pieces, l, u, h);
        let fd_l = (f(l + el, 1.0) - f(l - el, 1.0)) / (2.0 * el);
        let fd_u = (f(l, 1.0) - f(l, 1.0 - eu)) / eu;
        assert!(((d_l - fd_l) / fd_l).abs() < 1e-5, "dF/dL {d_l} vs {fd_l}");
        assert!(((d_u - fd_u) / fd_u).abs() < 1e-3, "dF/du {d_u} vs {fd_u}");
    }

    /// Every output's directional derivatives (a step in one piece, and one
    /// cut into pieces by the error control) against central differences of
    /// the step map: the step taken again from the same start with the
    /// inputs moved, in the same pieces ([`map_force`]; steps 1e-4 L0 and
    /// 1e-4, Richardson extrapolated),
    /// within 1e-4 of the larger of the two (or of the output's scale per
    /// unit input, for derivatives that vanish). `-- --nocapture` prints
    /// them.
    #[test]
    fn every_output_has_the_derivatives_of_its_step_map() {
        for adaptive in [false, true] {
            let before = muscle(1.1, 0.3, adaptive);
            let (l, u, h) = (1.12 * DEFAULT_L0, 0.6, 5e-3);
            let m = run(&before, l, u, h, 1);
            assert_eq!(substepped(&m).is_some(), adaptive);
            let richardson = |d: &dyn Fn(f64) -> f64, e: f64| (4.0 * d(e / 2.0) - d(e)) / 3.0;
            let pieces = substepped(&m).map(|s| s.pieces.clone());
            for &(o, Row { name, .. }) in OUTPUTS.iter() {
                let out = |l, u| match &pieces {
                    None => run(&before, l, u, h, 1).get_real(Var::Out(o)),
                    Some(pieces) => map_outputs(&before, pieces, l, u, h)[o as usize],
                };
                let d = |known| m.partial_derivative(Var::Out(o), known).unwrap();
                let (d_l, d_u) = (d(Var::Length), d(Var::Activation));
                let fd_l = richardson(
                    &|e| (out(l + e, u) - out(l - e, u)) / (2.0 * e),
                    1e-4 * DEFAULT_L0,
                );
                let fd_u = richardson(&|e| (out(l, u + e) - out(l, u - e)) / (2.0 * e), 1e-4);
                let value = m
                    .get_real(Var::Out(o))
                    .abs()
                    .max(1e-3 * m.params.sigma0 * m.area);
                eprintln!("{name} (adaptive {adaptive}): d/dL {d_l:e} vs {fd_l:e}, d/du {d_u:e} vs {fd_u:e}");
                let close = |an: f64, fd: f64, scale: f64| {
                    (an - fd).abs() <= 1e-4 * an.abs().max(fd.abs()).max(scale)
                };
                assert!(
                    close(d_l, fd_l, value / DEFAULT_L0),
                    "{name}: d/dL {d_l:e} vs {fd_l:e}"
                );
                assert!(close(d_u, fd_u, value), "{name}: d/du {d_u:e} vs {fd_u:e}");
            }
        }
    }

    /// Without activation dynamics the level is the command, held over the
    /// step (MODEL_NOTES "Co-simulation conventions"), in every substep: a
    /// command jump 0 → 1 in one 20 ms step cut into pieces by the error
    /// control has the force of the same jump in 200 steps of 0.1 ms, to
    /// 1e-2 sigma0 A (isometric at 1.05 L0). A level ramped across the
    /// step's pieces instead (as the substeps did before) activates the
    /// muscle late and is 0.15 sigma0 A low. `-- --nocapture` prints the
    /// figures.
    #[test]
    fn without_dynamics_every_substep_sees_the_held_command() {
        let start = |adaptive| {
            let mut m = muscle(1.05, 0.0, adaptive);
            m.set_boolean(Var::ActivationDynamics, false).unwrap();
            m
        };
        let (l, h) = (1.05 * DEFAULT_L0, 0.02);
        let reference = force(&run(&start(false), l, 1.0, h / 200.0, 200));
        let adaptive = run(&start(true), l, 1.0, h, 1);
        let pieces = substepped(&adaptive).unwrap().pieces.len();
        let error = (force(&adaptive) - reference).abs() / (adaptive.params.sigma0 * adaptive.area);
        eprintln!("{pieces} pieces; force error / (sigma0 A) {error:e}");
        assert!(pieces > 1, "the step was not cut: the test shows nothing");
        assert!(error < 1e-2, "force error / (sigma0 A) {error:e}");
    }
}
