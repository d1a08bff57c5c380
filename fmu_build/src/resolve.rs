//! Resolution of a scene as written ([`Draft`]) into the [`SceneSpec`] the
//! library's models are built on.
//!
//! Entry point: [`Draft::resolve`], which checks the draft against the
//! variant's complete variable table (`all_variables` of
//! `hill_muscle::fmus::hill1d` and `hill_muscle::fmus::hillfe`) and the law's
//! parameter rules (`hill_muscle::law::Params::validate`), and returns the
//! spec or every problem found, each naming what is wrong. Invariant: a spec it returns
//! uses exactly the parameters its components need, each within its
//! declared range, and exposes only the inputs and outputs its components
//! can compute.

use hill_muscle::fe::mesh::{Grading, Resolution, LEVELS, LUMPED, LUMPED_GRADING};
use hill_muscle::fmi2::{Causality, ScalarVariable, VarType};
use hill_muscle::fmus::{hill1d, hillfe, musculotendon1d, musculotendonfe};
use hill_muscle::law::params::Bound;
use hill_muscle::scene::{Components, Inputs, SceneSpec, Setting, Value, Variant};

/// The variants a scene can name, with their names in scene files.
pub const VARIANTS: [Variant; 4] = [
    Variant::OneD,
    Variant::Fe,
    Variant::Musculotendon1D,
    Variant::MusculotendonFe,
];

/// The name of `variant` in scene files.
pub fn variant_name(variant: Variant) -> &'static str {
    match variant {
        Variant::OneD => "1d",
        Variant::Fe => "fe",
        Variant::Musculotendon1D => "musculotendon_1d",
        Variant::MusculotendonFe => "musculotendon_fe",
    }
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

/// An FE mesh level a scene can name ([`MESH_LEVELS`]): the mesh it sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MeshLevel {
    pub name: &'static str,
    pub resolution: Resolution,
    pub grading: Grading,
}

/// The FE mesh levels a scene can name: `lumped` (the default mesh,
/// `fe::mesh::LUMPED` with its grading) and the refinement levels `level0`
/// … `level4` (`fe::mesh::LEVELS`, ungraded).
pub(crate) const MESH_LEVELS: [MeshLevel; 6] = [
    MeshLevel {
        name: "lumped",
        resolution: LUMPED,
        grading: LUMPED_GRADING,
    },
    refinement("level0", 0),
    refinement("level1", 1),
    refinement("level2", 2),
    refinement("level3", 3),
    refinement("level4", 4),
];

/// The refinement level `name`: `fe::mesh::LEVELS[i]`, ungraded.
const fn refinement(name: &'static str, i: usize) -> MeshLevel {
    MeshLevel {
        name,
        resolution: LEVELS[i],
        grading: Grading::UNIFORM,
    }
}

/// The parameters a mesh level sets.
const MESH_PARAMETERS: [&str; 4] = ["n_axial", "n_radial", "axial_grading", "radial_grading"];

/// The value `level` gives mesh parameter `name` (one of [`MESH_PARAMETERS`]).
fn mesh_value(level: &MeshLevel, name: &str) -> Value {
    // The mesh sizes are at most the table's declared maxima (96, 16).
    let count = |n: usize| Value::Integer(i32::try_from(n).expect("a mesh size fits in i32"));
    match name {
        "n_axial" => count(level.resolution.n_axial),
        "n_radial" => count(level.resolution.n_radial),
        "axial_grading" => Value::Real(level.grading.axial),
        _ => Value::Real(level.grading.radial),
    }
}

/// The complete variable table of a variant (every parameter, input and
/// output it can expose), as (name, causality, type).
fn catalogue(variant: Variant) -> Vec<(&'static str, Causality, VarType)> {
    fn rows<V>(t: Vec<ScalarVariable<V>>) -> Vec<(&'static str, Causality, VarType)> {
        t.into_iter().map(|v| (v.name, v.causality, v.ty)).collect()
    }
    match variant {
        Variant::OneD => rows(hill1d::all_variables()),
        Variant::Fe => rows(hillfe::all_variables()),
        Variant::Musculotendon1D => rows(musculotendon1d::all_variables()),
        Variant::MusculotendonFe => rows(musculotendonfe::all_variables()),
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
    /// are leaked (`'static`, as the library's `SceneSpec` holds them): a
    /// build resolves a few scenes per process.
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
        let table = catalogue(variant);
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
                    let elsewhere = VARIANTS.iter().filter(|v| **v != variant).any(|v| {
                        catalogue(*v)
                            .iter()
                            .any(|(n, cau, _)| n == name && *cau == Causality::Output)
                    });
                    if elsewhere {
                        errors.push(format!(
                            "output '{name}' is not available in the {} variant",
                            variant_name(variant)
                        ));
                    } else {
                        errors.push(format!(
                            "outputs: unknown output '{name}' (the {} variant has: {})",
                            variant_name(variant),
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
                        variant_name(variant),
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
            (Variant::OneD | Variant::Musculotendon1D, _) if self.mesh_constant.is_some() => {
                errors.push(format!(
                    "[fe] mesh_constant: the {} variant has no mesh",
                    variant_name(variant)
                ));
            }
            (Variant::OneD | Variant::Musculotendon1D, Some(m)) => {
                errors.push(format!(
                    "[fe] mesh = {m:?}: the {} variant has no mesh",
                    variant_name(variant)
                ));
            }
            (Variant::OneD | Variant::Musculotendon1D, None) => {}
            (Variant::Fe | Variant::MusculotendonFe, m) => {
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
                (
                    mesh_value(&level, name),
                    self.mesh_constant.unwrap_or(false),
                )
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
        if matches!(variant, Variant::Fe | Variant::MusculotendonFe) {
            for (name, on) in [
                ("parallel_element", c.parallel),
                ("matrix", c.matrix),
                ("fv_shortening", c.fv_shortening || !c.contractile),
                ("fv_lengthening", c.fv_lengthening || !c.contractile),
            ] {
                if !on {
                    errors.push(format!(
                        "components.{name} = false is not available in the {} variant: its solver \
                         (src/fe) evaluates the complete law (leave out the contractile element, \
                         the activation dynamics, inputs and outputs instead)",
                        variant_name(variant)
                    ));
                }
            }
        }
        c
    }

    /// The law's parameters as a whole (`hill_muscle::law::Params::validate`).
    fn check_law_parameters(&self, settings: &[Setting], errors: &mut Vec<String>) {
        let mut p = hill_muscle::law::Params::default();
        for s in settings {
            if let (Some(info), Value::Real(x)) = (
                hill_muscle::law::PARAMETERS
                    .iter()
                    .find(|i| i.name == s.name),
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
