//! Scenes (issue 6): one use of the muscle, and the FMU built for exactly it.
//!
//! A scene fixes the model variant (the 1D reduction or the FE muscle), the
//! components of the law it includes (MODEL_NOTES "Energy and stress" and
//! "Hill fibre": activation dynamics, the contractile element with its f_v
//! branches, the series and parallel elements, the matrix, the volumetric
//! term), the inputs and outputs it exposes, every parameter's value and
//! whether it is a parameter of the FMU or a constant compiled into it, the
//! FE mesh, and the DefaultExperiment.
//!
//! - [`SceneSpec`]: a resolved scene, plain `const` data. A [`Scene`] type
//!   carries one as an associated constant; the models are generic over it
//!   ([`crate::fmus::hill1d::Hill1DModel`], `fmus::hillfe::HillFEModel`), so
//!   a component the scene leaves out is a `false` constant in the compiled
//!   code and its branch — the CE–SEE solve, an f_v branch, the activation
//!   dynamics — is not in the binary (the law is generic over
//!   [`crate::law::Components`], [`LawOf`]).
//! - [`Draft`]: a scene as written (fmu_build parses the TOML files of
//!   `fmu_build/scenes/` into it); [`Draft::resolve`] checks it against the
//!   variant's variable table and returns the [`SceneSpec`] or every problem,
//!   each naming what is wrong.
//! - [`rust_source`]: the Rust text of a `Scene` type for a spec, which
//!   fmu_build hands to the crate's build script (`build.rs`) for the FMU
//!   binary, and which [`shipped`] holds for every shipped scene.
//! - [`shipped`]: the shipped scenes (generated from `fmu_build/scenes/`, a
//!   test keeps it equal to the generator's output). The full FMUs
//!   `HillMuscle1D` and `HillMuscleFE` are two of them.

use std::fmt::Write as _;

use crate::fmi2::{Causality, ScalarVariable, VarType};
use crate::law::params::Bound;

// Generated (one line per setting), so rustfmt leaves it as the generator
// writes it.
#[rustfmt::skip]
pub mod shipped;

/// The model a scene is built on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// The 1D Hill reduction (MODEL_NOTES "The 1D Hill reduction").
    OneD,
    /// The lumped 3D finite-element muscle (`crate::fe`).
    Fe,
}

impl Variant {
    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Variant::OneD => "1d",
            Variant::Fe => "fe",
        }
    }
}

/// The components of the law a scene includes (MODEL_NOTES "Energy and
/// stress", "Hill fibre", "Activation").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Components {
    /// da/dt = S (u − a) (eq 9–10); without it a = u.
    pub activation_dynamics: bool,
    /// The contractile element (eq 8–12).
    pub contractile: bool,
    /// f_v for shortening, λ̇m ≤ 0 (eq 12).
    pub fv_shortening: bool,
    /// f_v for lengthening, λ̇m > 0 (eq 12).
    pub fv_lengthening: bool,
    /// The series elastic element (eq 6–7).
    pub series: bool,
    /// The parallel element (eq 22–23).
    pub parallel: bool,
    /// The isotropic matrix U_I (eq 3).
    pub matrix: bool,
    /// The volumetric penalty U_J (eq 5).
    pub volumetric: bool,
}

impl Components {
    /// The complete law.
    pub const ALL: Components = Components {
        activation_dynamics: true,
        contractile: true,
        fv_shortening: true,
        fv_lengthening: true,
        series: true,
        parallel: true,
        matrix: true,
        volumetric: true,
    };

    /// The names used in scene files, with their values.
    pub fn named(&self) -> [(&'static str, bool); 8] {
        [
            ("activation_dynamics", self.activation_dynamics),
            ("contractile_element", self.contractile),
            ("fv_shortening", self.fv_shortening),
            ("fv_lengthening", self.fv_lengthening),
            ("series_element", self.series),
            ("parallel_element", self.parallel),
            ("matrix", self.matrix),
            ("volumetric", self.volumetric),
        ]
    }
}

/// A parameter value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Real(x) => write!(f, "{x:?}"),
            Value::Integer(i) => write!(f, "{i}"),
            Value::Boolean(b) => write!(f, "{b}"),
        }
    }
}

/// One parameter of a scene: its value (the start value when exposed) and
/// whether it is compiled in as a constant (then not in the
/// modelDescription).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    pub name: &'static str,
    pub value: Value,
    pub constant: bool,
}

/// The inputs a scene exposes. Without `length` the muscle is held at `L0`
/// (isometric); without `activation` the command is 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Inputs {
    pub activation: bool,
    pub length: bool,
}

/// A resolved scene ([`Draft::resolve`]): everything the model and its
/// modelDescription need, as `const`-constructible data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneSpec {
    /// `modelIdentifier` and `modelName` (the binary is `<id>.so`).
    pub model_identifier: &'static str,
    pub description: &'static str,
    pub variant: Variant,
    pub components: Components,
    pub inputs: Inputs,
    /// The exposed outputs, in the variant's table order.
    pub outputs: &'static [&'static str],
    /// Every parameter the scene's components use, in table order.
    pub parameters: &'static [Setting],
    /// DefaultExperiment (start, stop, step size).
    pub default_experiment: (f64, f64, f64),
}

impl SceneSpec {
    /// The scene's setting of parameter `name` (`None`: the scene does not
    /// use it).
    pub fn setting(&self, name: &str) -> Option<&Setting> {
        self.parameters.iter().find(|s| s.name == name)
    }

    /// Whether variable `name` of the variant's table is in the scene's
    /// modelDescription.
    pub fn exposes(&self, name: &str, causality: Causality) -> bool {
        match causality {
            Causality::Parameter => self.setting(name).is_some_and(|s| !s.constant),
            Causality::Input => match name {
                "activation" => self.inputs.activation,
                "length" => self.inputs.length,
                _ => false,
            },
            Causality::Output => self.outputs.contains(&name),
            _ => false,
        }
    }

    /// The scene's variable table: the variant's complete table (`all`)
    /// restricted to the variables the scene exposes, parameters' start
    /// values replaced by the scene's, the `length` input starting at the
    /// scene's `L0`, and each output's dependencies restricted to the
    /// variables that remain (a constant is no longer a variable).
    pub fn variables<V: Copy>(&self, all: Vec<ScalarVariable<V>>) -> Vec<ScalarVariable<V>> {
        let mut kept: Vec<ScalarVariable<V>> = all
            .into_iter()
            .filter(|v| self.exposes(v.name, v.causality))
            .collect();
        let l0 = match self.setting("L0").map(|s| s.value) {
            Some(Value::Real(x)) => Some(x),
            _ => None,
        };
        for v in &mut kept {
            let value = match (v.causality, v.name) {
                (Causality::Parameter, name) => self.setting(name).map(|s| s.value),
                (Causality::Input, "length") => l0.map(Value::Real),
                _ => None,
            };
            match (&mut v.ty, value) {
                (VarType::Real { start, .. }, Some(Value::Real(x))) => *start = Some(x),
                (VarType::Integer { start, .. }, Some(Value::Integer(i))) => *start = Some(i),
                (VarType::Boolean { start }, Some(Value::Boolean(b))) => *start = Some(b),
                _ => {}
            }
        }
        let names: Vec<&'static str> = kept.iter().map(|v| v.name).collect();
        for v in &mut kept {
            v.depends_on.retain(|d| names.contains(d));
        }
        kept
    }
}

/// A type that carries a scene; the models are generic over it.
pub trait Scene: Clone + Copy + std::fmt::Debug + PartialEq + Send + Sync + 'static {
    const SPEC: SceneSpec;
}

/// The law's components ([`crate::law::Components`]) of scene `S`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LawOf<S>(std::marker::PhantomData<S>);

impl<S: Scene> crate::law::Components for LawOf<S> {
    const MATRIX: bool = S::SPEC.components.matrix;
    const PARALLEL: bool = S::SPEC.components.parallel;
    const CONTRACTILE: bool = S::SPEC.components.contractile;
    const FV_SHORTENING: bool = S::SPEC.components.fv_shortening;
    const FV_LENGTHENING: bool = S::SPEC.components.fv_lengthening;
    const ACTIVATION_DYNAMICS: bool = S::SPEC.components.activation_dynamics;
    const ACTIVATION_INPUT: bool = S::SPEC.inputs.activation;
}

/// The components of a scene as written: `None` where the file says
/// nothing (then: present, except that the series element, the activation
/// dynamics and the f_v branches follow the contractile element).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ComponentChoice {
    pub activation_dynamics: Option<bool>,
    pub contractile: Option<bool>,
    pub fv_shortening: Option<bool>,
    pub fv_lengthening: Option<bool>,
    pub series: Option<bool>,
    pub parallel: Option<bool>,
    pub matrix: Option<bool>,
    pub volumetric: Option<bool>,
}

/// A scene as written in a scene file, before it is checked.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Draft {
    pub model_identifier: String,
    pub description: String,
    pub variant: Option<Variant>,
    pub components: ComponentChoice,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    /// Exposed parameters with their start values.
    pub parameters: Vec<(String, Value)>,
    /// Parameters compiled in, with their values.
    pub constants: Vec<(String, Value)>,
    /// FE mesh level ([`MESH_LEVELS`]).
    pub mesh: Option<String>,
    /// Whether the mesh (n_axial, n_radial, axial_grading, radial_grading) is compiled in
    /// rather than exposed (default: exposed).
    pub mesh_constant: Option<bool>,
    /// DefaultExperiment (start, stop, step size).
    pub default_experiment: Option<(f64, f64, f64)>,
}

/// An FE mesh level a scene can name ([`MESH_LEVELS`]): the mesh parameters
/// it sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshLevel {
    pub name: &'static str,
    pub n_axial: i32,
    pub n_radial: i32,
    pub axial_grading: f64,
    pub radial_grading: f64,
}

impl MeshLevel {
    const fn new(name: &'static str, n_axial: i32, n_radial: i32, grading: (f64, f64)) -> Self {
        MeshLevel {
            name,
            n_axial,
            n_radial,
            axial_grading: grading.0,
            radial_grading: grading.1,
        }
    }

    /// The level's value of mesh parameter `name` (one of [`MESH_PARAMETERS`]).
    fn value(&self, name: &str) -> Value {
        match name {
            "n_axial" => Value::Integer(self.n_axial),
            "n_radial" => Value::Integer(self.n_radial),
            "axial_grading" => Value::Real(self.axial_grading),
            _ => Value::Real(self.radial_grading),
        }
    }
}

/// The parameters a mesh level sets.
const MESH_PARAMETERS: [&str; 4] = ["n_axial", "n_radial", "axial_grading", "radial_grading"];

/// The FE mesh levels a scene can name: `lumped` (the default 16 × 3 of
/// docs/fe.md, `crate::fe::mesh::LUMPED` with its grading; a test keeps the
/// two equal) and the refinement levels `level0` … `level4`
/// (`crate::fe::mesh::LEVELS`, ungraded).
pub const MESH_LEVELS: [MeshLevel; 6] = [
    MeshLevel::new("lumped", 16, 3, (0.9, 0.6)),
    MeshLevel::new("level0", 12, 2, (0.0, 0.0)),
    MeshLevel::new("level1", 18, 3, (0.0, 0.0)),
    MeshLevel::new("level2", 24, 4, (0.0, 0.0)),
    MeshLevel::new("level3", 36, 6, (0.0, 0.0)),
    MeshLevel::new("level4", 48, 8, (0.0, 0.0)),
];

/// The complete variable table of a variant (every parameter, input and
/// output it can expose), as (name, causality, type).
fn catalogue(variant: Variant) -> Result<Vec<(&'static str, Causality, VarType)>, String> {
    fn rows<V>(t: Vec<ScalarVariable<V>>) -> Vec<(&'static str, Causality, VarType)> {
        t.into_iter().map(|v| (v.name, v.causality, v.ty)).collect()
    }
    match variant {
        Variant::OneD => Ok(rows(crate::fmus::hill1d::all_variables())),
        #[cfg(feature = "fe")]
        Variant::Fe => Ok(rows(crate::fmus::hillfe::all_variables())),
        #[cfg(not(feature = "fe"))]
        Variant::Fe => Err(
            "variant = \"fe\": this build of hill-muscle has no FE muscle (Cargo feature `fe`)"
                .into(),
        ),
    }
}

/// Why scene components `c` do not use parameter `name` (`None`: they do).
fn parameter_unused(c: &Components, name: &str) -> Option<&'static str> {
    let need = |present: bool, component: &'static str| (!present).then_some(component);
    match name {
        "b" | "c" => need(c.matrix, "the matrix (components.matrix = false)"),
        "alpha" | "beta" => need(
            c.series,
            "the series element (components.series_element = false)",
        ),
        "A" => need(
            c.parallel,
            "the parallel element (components.parallel_element = false)",
        ),
        "sigma0" => need(
            c.parallel || c.contractile,
            "the parallel and contractile elements (both absent)",
        ),
        "S" | "initial_activation" | "activation_dynamics" => need(
            c.activation_dynamics,
            "the activation dynamics (components.activation_dynamics = false)",
        ),
        "ke" | "d" => need(
            c.contractile && c.fv_lengthening,
            "the lengthening branch of f_v (components.fv_lengthening = false)",
        ),
        "kc" | "lambda_dot_min" | "lambda_opt" | "k" | "adaptive_substeps"
        | "substep_tolerance" => need(
            c.contractile,
            "the contractile element (components.contractile_element = false)",
        ),
        "D" => need(c.volumetric, "the volumetric term"),
        _ => None,
    }
}

/// Why output `name` is not available with components `c` and `inputs`.
fn output_unavailable(c: &Components, inputs: &Inputs, name: &str) -> Option<String> {
    match name {
        "activation_level" | "ce_stretch" | "see_stretch" | "active_stress" if !c.contractile => {
            Some(format!(
                "output '{name}' needs the contractile element, which the scene leaves out \
                 (components.contractile_element = false)"
            ))
        }
        "stiffness" if !inputs.length => {
            Some("output 'stiffness' (d force / d length) needs the input 'length'".to_string())
        }
        _ => None,
    }
}

fn is_identifier(s: &str) -> bool {
    let mut ch = s.chars();
    ch.next().is_some_and(|c| c.is_ascii_alphabetic())
        && ch.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Draft {
    /// Check the scene and resolve it: every problem found, each naming
    /// what is wrong, or the [`SceneSpec`]. The spec's strings and slices
    /// are leaked (`'static`): resolve is for the build tool and tests, a
    /// few per process.
    pub fn resolve(&self) -> Result<SceneSpec, Vec<String>> {
        let mut errors = Vec::new();
        if !is_identifier(&self.model_identifier) {
            errors.push(format!(
                "model_identifier = {:?}: must be a letter followed by letters, digits or '_' \
                 (it names the FMU and its binary)",
                self.model_identifier
            ));
        }
        let Some(variant) = self.variant else {
            errors.push("variant: missing (\"1d\" or \"fe\")".into());
            return Err(errors);
        };
        let table = match catalogue(variant) {
            Ok(t) => t,
            Err(e) => {
                errors.push(e);
                return Err(errors);
            }
        };
        let c = self.components(variant, &mut errors);
        // Inputs.
        let mut inputs = Inputs {
            activation: false,
            length: false,
        };
        for name in &self.inputs {
            let slot = match name.as_str() {
                "activation" => &mut inputs.activation,
                "length" => &mut inputs.length,
                other => {
                    errors.push(format!(
                        "inputs: unknown input '{other}' (known: activation, length)"
                    ));
                    continue;
                }
            };
            if *slot {
                errors.push(format!("inputs: '{name}' listed twice"));
            }
            *slot = true;
        }
        if inputs.activation && !c.contractile {
            errors.push(
                "input 'activation' needs the contractile element, which the scene leaves out \
                 (components.contractile_element = false)"
                    .into(),
            );
        }
        if c.contractile && !inputs.activation {
            errors.push(
                "the contractile element needs the input 'activation' (without it the command \
                 would be 0 and the element would never carry force)"
                    .into(),
            );
        }
        // Outputs.
        let output_names: Vec<&'static str> = table
            .iter()
            .filter(|(_, cau, _)| *cau == Causality::Output)
            .map(|(n, _, _)| *n)
            .collect();
        let mut outputs = Vec::new();
        if self.outputs.is_empty() {
            errors.push("outputs: a scene exposes at least one output".into());
        }
        for name in &self.outputs {
            match output_names.iter().find(|n| **n == name.as_str()) {
                None => {
                    let other = match variant {
                        Variant::OneD => catalogue(Variant::Fe).ok(),
                        Variant::Fe => catalogue(Variant::OneD).ok(),
                    };
                    if other.is_some_and(|t| {
                        t.iter()
                            .any(|(n, cau, _)| n == name && *cau == Causality::Output)
                    }) {
                        errors.push(format!(
                            "output '{name}' is not available in the {} variant",
                            variant.name()
                        ));
                    } else {
                        errors.push(format!(
                            "outputs: unknown output '{name}' (the {} variant has: {})",
                            variant.name(),
                            output_names.join(", ")
                        ));
                    }
                }
                Some(n) => {
                    if outputs.contains(n) {
                        errors.push(format!("outputs: '{name}' listed twice"));
                    } else if let Some(why) = output_unavailable(&c, &inputs, name) {
                        errors.push(why);
                    } else {
                        outputs.push(*n);
                    }
                }
            }
        }
        outputs.sort_by_key(|n| output_names.iter().position(|m| m == n));
        // Parameters.
        let params: Vec<&(&'static str, Causality, VarType)> = table
            .iter()
            .filter(|(_, cau, _)| *cau == Causality::Parameter)
            .collect();
        let mut given: Vec<(&'static str, Value, bool)> = Vec::new();
        for (list, constant) in [(&self.parameters, false), (&self.constants, true)] {
            let table_name = if constant {
                "[constants]"
            } else {
                "[parameters]"
            };
            for (name, value) in list {
                let Some((pname, _, ty)) = params.iter().find(|(n, _, _)| *n == name.as_str())
                else {
                    let known: Vec<&str> = params.iter().map(|(n, _, _)| *n).collect();
                    errors.push(format!(
                        "{table_name}: unknown parameter '{name}' (the {} variant has: {})",
                        variant.name(),
                        known.join(", ")
                    ));
                    continue;
                };
                if MESH_PARAMETERS.contains(pname) {
                    errors.push(format!(
                        "{table_name}: '{name}' is set by the mesh level: use [fe] mesh = \"…\" \
                         (and mesh_constant) instead"
                    ));
                    continue;
                }
                if given.iter().any(|(n, _, _)| n == pname) {
                    errors.push(format!(
                        "parameter '{name}' is given twice (in [parameters] and [constants], or repeated)"
                    ));
                    continue;
                }
                if let Some(why) = parameter_unused(&c, name) {
                    errors.push(format!(
                        "{table_name}: parameter '{name}' is not used by this scene: it belongs to {why}"
                    ));
                    continue;
                }
                match check_value(name, ty, *value) {
                    Ok(v) => given.push((pname, v, constant)),
                    Err(e) => errors.push(format!("{table_name}: {e}")),
                }
            }
        }
        // The mesh.
        let mut mesh_level: Option<MeshLevel> = None;
        match (variant, &self.mesh) {
            (Variant::OneD, Some(_)) | (Variant::OneD, None) if self.mesh_constant.is_some() => {
                errors.push("[fe] mesh_constant: the 1d variant has no mesh".into());
            }
            (Variant::OneD, Some(m)) => {
                errors.push(format!("[fe] mesh = {m:?}: the 1d variant has no mesh"));
            }
            (Variant::OneD, None) => {}
            (Variant::Fe, m) => {
                let name = m.as_deref().unwrap_or("lumped");
                match MESH_LEVELS.iter().find(|l| l.name == name) {
                    Some(&level) => mesh_level = Some(level),
                    None => errors.push(format!(
                        "[fe] mesh = {name:?}: unknown mesh level (known: {})",
                        MESH_LEVELS.map(|l| l.name).join(", ")
                    )),
                }
            }
        }
        let mut settings = Vec::new();
        for (name, _, ty) in &params {
            if parameter_unused(&c, name).is_some() {
                continue;
            }
            let (value, constant) = if let Some(&(_, v, k)) = given.iter().find(|g| g.0 == *name) {
                (v, k)
            } else if let (Some(level), true) = (mesh_level, MESH_PARAMETERS.contains(name)) {
                (level.value(name), self.mesh_constant.unwrap_or(false))
            } else {
                match start_of(ty) {
                    Some(v) => (v, false),
                    None => {
                        errors.push(format!("parameter '{name}' has no default"));
                        continue;
                    }
                }
            };
            settings.push(Setting {
                name,
                value,
                constant,
            });
        }
        self.check_law_parameters(&settings, &mut errors);
        // DefaultExperiment.
        let experiment = match self.default_experiment {
            None => {
                errors.push("[default_experiment]: missing (start, stop, step)".into());
                (0.0, 1.0, 1e-3)
            }
            Some((start, stop, step)) => {
                if !(start.is_finite() && stop.is_finite() && step.is_finite())
                    || start < 0.0
                    || stop <= start
                    || step <= 0.0
                    || step > stop - start
                {
                    errors.push(format!(
                        "[default_experiment]: start = {start}, stop = {stop}, step = {step}: \
                         need 0 <= start < stop and 0 < step <= stop - start"
                    ));
                }
                (start, stop, step)
            }
        };
        if !errors.is_empty() {
            return Err(errors);
        }
        Ok(SceneSpec {
            model_identifier: Box::leak(self.model_identifier.clone().into_boxed_str()),
            description: Box::leak(self.description.clone().into_boxed_str()),
            variant,
            components: c,
            inputs,
            outputs: Box::leak(outputs.into_boxed_slice()),
            parameters: Box::leak(settings.into_boxed_slice()),
            default_experiment: experiment,
        })
    }

    /// The components with the defaults filled in, and the rules between
    /// them and the variant checked.
    fn components(&self, variant: Variant, errors: &mut Vec<String>) -> Components {
        let ch = &self.components;
        let contractile = ch.contractile.unwrap_or(true);
        let c = Components {
            contractile,
            series: ch.series.unwrap_or(contractile),
            activation_dynamics: ch.activation_dynamics.unwrap_or(contractile),
            fv_shortening: ch.fv_shortening.unwrap_or(contractile),
            fv_lengthening: ch.fv_lengthening.unwrap_or(contractile),
            parallel: ch.parallel.unwrap_or(true),
            matrix: ch.matrix.unwrap_or(true),
            volumetric: ch.volumetric.unwrap_or(true),
        };
        if c.series != c.contractile {
            errors.push(format!(
                "components: contractile_element = {} but series_element = {}: the contractile and \
                 series elements are in series (MODEL_NOTES \"Hill fibre\") and exist only together",
                c.contractile, c.series
            ));
        }
        if !c.contractile {
            for (name, on) in [
                ("activation_dynamics", c.activation_dynamics),
                ("fv_shortening", c.fv_shortening),
                ("fv_lengthening", c.fv_lengthening),
            ] {
                if on {
                    errors.push(format!(
                        "components.{name} = true needs the contractile element, which the scene \
                         leaves out (components.contractile_element = false)"
                    ));
                }
            }
        } else if !c.fv_shortening && !c.fv_lengthening {
            errors.push(
                "components: the contractile element needs at least one f_v branch \
                 (fv_shortening, fv_lengthening)"
                    .into(),
            );
        }
        if !c.volumetric {
            errors.push(
                "components.volumetric = false is not available: the volumetric penalty \
                 (J - 1)^2 / D is the law's only volumetric stiffness; without it the lateral \
                 stretch (1d) and the pressure (fe) are undetermined (make it stiff with a small D \
                 instead)"
                    .into(),
            );
        }
        if !c.parallel && !c.matrix && !c.contractile {
            errors.push(
                "components: with no matrix, parallel or contractile element the muscle carries \
                 no axial stress"
                    .into(),
            );
        }
        if variant == Variant::Fe {
            for (name, on) in [
                ("parallel_element", c.parallel),
                ("matrix", c.matrix),
                ("fv_shortening", c.fv_shortening || !c.contractile),
                ("fv_lengthening", c.fv_lengthening || !c.contractile),
            ] {
                if !on {
                    errors.push(format!(
                        "components.{name} = false is not available in the fe variant: its solver \
                         (src/fe) evaluates the complete law (leave out the contractile element, \
                         the activation dynamics, inputs and outputs instead)"
                    ));
                }
            }
        }
        c
    }

    /// The law's parameters as a whole ([`crate::law::Params::validate`]).
    fn check_law_parameters(&self, settings: &[Setting], errors: &mut Vec<String>) {
        let mut p = crate::law::Params::default();
        for s in settings {
            if let (Some(info), Value::Real(x)) = (
                crate::law::PARAMETERS.iter().find(|i| i.name == s.name),
                s.value,
            ) {
                if p.set(info.id, x).is_err() {
                    return; // reported by check_value
                }
            }
        }
        if let Err(e) = p.validate() {
            errors.push(format!("parameters: {e}"));
        }
    }
}

/// The start value of a table row.
fn start_of(ty: &VarType) -> Option<Value> {
    match *ty {
        VarType::Real { start, .. } => start.map(Value::Real),
        VarType::Integer { start, .. } => start.map(Value::Integer),
        VarType::Boolean { start } => start.map(Value::Boolean),
    }
}

/// `value` as a value of type `ty` within its declared range.
fn check_value(name: &str, ty: &VarType, value: Value) -> Result<Value, String> {
    match (*ty, value) {
        (VarType::Real { min, max, .. }, Value::Real(_) | Value::Integer(_)) => {
            let x = match value {
                Value::Real(x) => x,
                Value::Integer(i) => f64::from(i),
                Value::Boolean(_) => unreachable!(),
            };
            let lo = min.unwrap_or(f64::NEG_INFINITY);
            let hi = max.unwrap_or(f64::INFINITY);
            if x.is_finite() && x >= lo && x <= hi {
                Ok(Value::Real(x))
            } else {
                Err(format!(
                    "parameter '{name}' = {x:?} is out of range: must be finite and in [{}, {}]",
                    Bound(lo),
                    Bound(hi)
                ))
            }
        }
        (VarType::Integer { min, max, .. }, Value::Integer(i)) => {
            let lo = min.unwrap_or(i32::MIN);
            let hi = max.unwrap_or(i32::MAX);
            if (lo..=hi).contains(&i) {
                Ok(value)
            } else {
                Err(format!(
                    "parameter '{name}' = {i} is out of range: must be in [{lo}, {hi}]"
                ))
            }
        }
        (VarType::Boolean { .. }, Value::Boolean(_)) => Ok(value),
        (ty, v) => {
            let want = match ty {
                VarType::Real { .. } => "a number",
                VarType::Integer { .. } => "an integer",
                VarType::Boolean { .. } => "true or false",
            };
            Err(format!("parameter '{name}' = {v}: must be {want}"))
        }
    }
}

/// The Rust text of a unit struct `type_name` implementing [`Scene`] with
/// `spec` (paths through `crate::`, so it compiles inside hill-muscle).
pub fn rust_source(type_name: &str, spec: &SceneSpec) -> String {
    let mut s = String::new();
    let c = &spec.components;
    let _ = writeln!(
        s,
        "/// Scene `{}`: {}",
        spec.model_identifier, spec.description
    );
    let _ = writeln!(s, "#[derive(Clone, Copy, Debug, PartialEq, Eq)]");
    let _ = writeln!(s, "pub struct {type_name};");
    let _ = writeln!(s);
    let _ = writeln!(s, "impl crate::scene::Scene for {type_name} {{");
    let _ = writeln!(
        s,
        "    const SPEC: crate::scene::SceneSpec = crate::scene::SceneSpec {{"
    );
    let _ = writeln!(s, "        model_identifier: {:?},", spec.model_identifier);
    let _ = writeln!(s, "        description: {:?},", spec.description);
    let v = match spec.variant {
        Variant::OneD => "OneD",
        Variant::Fe => "Fe",
    };
    let _ = writeln!(s, "        variant: crate::scene::Variant::{v},");
    let _ = writeln!(s, "        components: crate::scene::Components {{");
    for (field, on) in [
        ("activation_dynamics", c.activation_dynamics),
        ("contractile", c.contractile),
        ("fv_shortening", c.fv_shortening),
        ("fv_lengthening", c.fv_lengthening),
        ("series", c.series),
        ("parallel", c.parallel),
        ("matrix", c.matrix),
        ("volumetric", c.volumetric),
    ] {
        let _ = writeln!(s, "            {field}: {on},");
    }
    let _ = writeln!(s, "        }},");
    let _ = writeln!(s, "        inputs: crate::scene::Inputs {{");
    let _ = writeln!(s, "            activation: {},", spec.inputs.activation);
    let _ = writeln!(s, "            length: {},", spec.inputs.length);
    let _ = writeln!(s, "        }},");
    let _ = writeln!(s, "        outputs: &[");
    for o in spec.outputs {
        let _ = writeln!(s, "            {o:?},");
    }
    let _ = writeln!(s, "        ],");
    let _ = writeln!(s, "        parameters: &[");
    for p in spec.parameters {
        let value = match p.value {
            Value::Real(x) => format!("Real({x:?})"),
            Value::Integer(i) => format!("Integer({i})"),
            Value::Boolean(b) => format!("Boolean({b})"),
        };
        let _ = writeln!(
            s,
            "            crate::scene::Setting {{ name: {:?}, value: crate::scene::Value::{value}, constant: {} }},",
            p.name, p.constant
        );
    }
    let _ = writeln!(s, "        ],");
    let (a, b, h) = spec.default_experiment;
    let _ = writeln!(s, "        default_experiment: ({a:?}, {b:?}, {h:?}),");
    let _ = writeln!(s, "    }};");
    let _ = writeln!(s, "}}");
    s
}

/// The model type of a scene, as Rust text (for the export of a binary).
pub fn model_type(type_name: &str, spec: &SceneSpec) -> String {
    match spec.variant {
        Variant::OneD => format!("crate::fmus::hill1d::Hill1DModel<{type_name}>"),
        Variant::Fe => format!("crate::fmus::hillfe::HillFEModel<{type_name}>"),
    }
}

/// Apply every parameter setting of `spec` (start values and constants)
/// through `set`, the model's own setter (which checks the range), with the
/// variable of `all` (the variant's complete table) of the setting's name.
/// A model calls it when it is created; the scene was checked by
/// [`Draft::resolve`], so an error here means a scene type not made by it.
pub fn apply_settings<V: Copy>(
    spec: &SceneSpec,
    all: &[ScalarVariable<V>],
    mut set: impl FnMut(V, Value) -> Result<(), String>,
) -> Result<(), String> {
    for s in spec.parameters {
        let v = all
            .iter()
            .find(|v| v.name == s.name && v.causality == Causality::Parameter)
            .ok_or_else(|| format!("scene {}: no parameter '{}'", spec.model_identifier, s.name))?;
        set(v.id, s.value).map_err(|e| {
            format!(
                "scene {}: {} = {}: {e}",
                spec.model_identifier, s.name, s.value
            )
        })?;
    }
    Ok(())
}
