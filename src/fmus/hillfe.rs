//! `HillMuscleFE`: the lumped 3D finite-element muscle ([`crate::fe`]: the
//! paper's fusiform specimen scaled to rest length `L0` and mean
//! cross-section `area`, meshed `n_axial` × `n_radial` at initialization)
//! as an FMI 2.0 Co-Simulation model, with the inputs and outputs of
//! `HillMuscle1D` plus field diagnostics. This file only maps: the variable
//! table ([`variables!`]: [`Var`], [`all_variables`]), the FMI calls onto the
//! FE step map ([`crate::fe::step_map`]) and the state codec (`state`). How
//! a step reads its inputs and reports its outputs:
//! docs/reference/conventions.md.

use std::sync::Arc;

use crate::fe::discretization::Discretization;
use crate::fe::mesh::{FibreLayout, Grading, Resolution};
use crate::fe::step_map::{
    built_with, check_stretch, discretization, end_length, Committed, Outputs, StepLevel, Stepped,
    N_QUANTITIES,
};
use crate::fe::threads::Threads;
use crate::fmi2::{Model, ModelError, StepError, VarType, Variability};
use crate::fmus::common::{check_range, check_unit_interval, SUBSTEP_RTOL};
use crate::fmus::table::{self, model_access, output, scene_interface, variables, Row, STATIC_LAW};
use crate::law::activation::Decay;
use crate::law::params::{Range, AREA_RANGE, L0_RANGE, LENGTH_RANGE};
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

/// The mesh parameters' rows, shared by the FE models (`HillMuscleFE` and
/// the FE musculotendon unit): one declaration of each name, range and
/// description.
pub(crate) mod mesh_rows {
    use super::{DEFAULT_GRADING, DEFAULT_MESH, GRADING_RANGE, N_AXIAL_RANGE, N_RADIAL_RANGE};
    use crate::fe::threads::MAX_THREADS;
    use crate::fmi2::Variability;
    use crate::fmus::table::{integer, parameter, real, Check, Row};

    /// `n_axial`.
    pub(crate) const fn n_axial<V>() -> Row<V> {
        parameter(
            "n_axial",
            "Mesh: element layers along the axis",
            integer(DEFAULT_MESH.n_axial as i32, N_AXIAL_RANGE),
            Check::Closed,
        )
    }

    /// `n_radial`.
    pub(crate) const fn n_radial<V>() -> Row<V> {
        parameter(
            "n_radial",
            "Mesh: rings in the cross-section",
            integer(DEFAULT_MESH.n_radial as i32, N_RADIAL_RANGE),
            Check::Closed,
        )
    }

    /// `axial_grading`.
    pub(crate) const fn axial_grading<V>() -> Row<V> {
        parameter(
        "axial_grading",
        "Mesh: slices graded toward the clamped end faces, x = L (u - g sin(2 pi u)/(2 pi)); end layers (1 - g) times the uniform spacing",
        real("1", Some(DEFAULT_GRADING.axial), Some(GRADING_RANGE)),
        Check::Finite,
        )
    }

    /// `radial_grading`.
    pub(crate) const fn radial_grading<V>() -> Row<V> {
        parameter(
        "radial_grading",
        "Mesh: rings of the cross-section graded toward the lateral surface, radius u + g u (1 - u) of the section's radius, u = i / n_radial; outer ring about (1 - g) times the uniform width",
        real("1", Some(DEFAULT_GRADING.radial), Some(GRADING_RANGE)),
        Check::Finite,
        )
    }

    /// `threads`: tunable, as it changes no result ([`crate::fe::threads`]);
    /// not part of the serialized state (a restored instance runs on one
    /// thread until set).
    pub(crate) const fn threads<V>() -> Row<V> {
        Row {
            variability: Variability::Tunable,
            ..parameter(
                "threads",
                "Threads the FE element loops may use, started and ended within each call (results are the same for every count); 1: the calling thread only",
                integer(1, (1, MAX_THREADS as i32)),
                Check::Closed,
            )
        }
    }

    /// `fibre_layout`.
    pub(crate) const fn fibre_layout<V>() -> Row<V> {
        parameter(
            "fibre_layout",
            "Fibre directions: 0 along the axis (the paper), 1 along the profile's meridians",
            integer(0, (0, 1)),
            Check::Closed,
        )
    }
}

variables! {
    /// A variable of `HillMuscleFE`, in table order: the law's parameters,
    /// geometry, activation, substep and mesh options, the inputs, the
    /// outputs.
    pub enum Var;
    impl[S: Scene] HillFEModel<S> as (m, v) {
        /// A parameter of the law (MODEL_NOTES "Parameters").
        Param(id: ParamId) = table::LawParameters
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
        NAxial = mesh_rows::n_axial() => Integer(m.n_axial);
        NRadial = mesh_rows::n_radial() => Integer(m.n_radial);
        AxialGrading = mesh_rows::axial_grading() => Real(m.grading.axial);
        RadialGrading = mesh_rows::radial_grading() => Real(m.grading.radial);
        FibreLayout = mesh_rows::fibre_layout() => Integer(m.fibre_layout);
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
        Threads = mesh_rows::threads() => Integer(m.threads);
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

pub(crate) mod state;

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
pub(crate) fn check_mesh(
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
    /// The element loops' threads (`mesh_rows::threads`), handed to the
    /// discretization before each call that evaluates it.
    threads: i32,
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

    /// The `threads` parameter (its row's check keeps it in range).
    fn threads(&self) -> Threads {
        Threads::new(usize::try_from(self.threads).unwrap_or(1)).unwrap_or_default()
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
            threads: 1,
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

    scene_interface!();

    fn new() -> Self {
        let mut m = Self::blank();
        m.table_apply_scene(&S::SPEC);
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
        check_stretch(&self.params, self.l0, length).map_err(ModelError)?;
        let disc = self.discretization()?;
        disc.set_threads(self.threads());
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
        let end_length = end_length(self.length(), self.length_rate, h, &self.params, self.l0)
            .map_err(StepError::Discard)?;
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
        state.muscle.disc.set_threads(self.threads());
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
    /// those of the last step's map ([`Committed::partial`]).
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
        match unknown {
            // Before initialization the level's derivative is 0.
            Var::Out(Output::ActivationLevel) if self.state.is_none() => Ok(0.0),
            Var::Out(o) => self
                .committed()?
                .partial(o, by_length, &self.params, self.l0, self.area)
                .map_err(ModelError),
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

    fn check_stepping_outputs(&self) -> Result<(), String> {
        state::check_law_outputs(self)
    }

    fn serialize(&self, out: &mut Vec<u8>) {
        state::encode(self, out);
    }

    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError> {
        state::decode(input)
    }
}

/// The model, for the FMU's `documentation/index.html`.
pub const FE_HTML: &str = include_str!("doc/hillfe.html");

#[cfg(test)]
mod tests;
