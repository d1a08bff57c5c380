//! Scene files: the TOML text of a scene, read into a resolved [`SceneSpec`].
//!
//! Entry point: [`read_scene`] (a file; [`load_scene`] reads its text). The
//! text is read in three steps, each reporting every problem it finds,
//! naming it, before anything is built: the TOML is parsed to a table (a
//! syntax error stops there, at its line); the table is checked against the
//! scene file's keys ([`SCENE_KEYS`]: unknown keys, missing required ones,
//! values of the wrong type, an unknown variant, each with its line); then,
//! `serde` having turned it into a [`Draft`], [`Draft::resolve`] checks that
//! against the variant's variable table. Invariant: [`SCENE_KEYS`] are the
//! fields of [`SceneFile`] and the structs under it (a test keeps them so).

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

use hill_muscle::scene::{SceneSpec, Value};
use serde::Deserialize;
use toml::de::{DeArray, DeTable, DeValue};
use toml::Spanned;

use crate::resolve::{variant_name, ComponentChoice, Draft, VARIANTS};

/// What the value of a scene file's key must be.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Str,
    /// A string naming one of [`VARIANTS`].
    Variant,
    Bool,
    /// An integer or a float.
    Number,
    /// An array of strings.
    StrList,
    /// A table of `name = value`, the values checked when the scene
    /// resolves (`[parameters]`, `[constants]`).
    Values,
    /// A table with these keys.
    Table(&'static [Key]),
}

/// A key of a table of a scene file.
#[derive(Clone, Copy, Debug)]
struct Key {
    name: &'static str,
    kind: Kind,
    required: bool,
}

const fn optional(name: &'static str, kind: Kind) -> Key {
    Key {
        name,
        kind,
        required: false,
    }
}

const fn required(name: &'static str, kind: Kind) -> Key {
    Key {
        name,
        kind,
        required: true,
    }
}

/// The keys of a scene file, by table: what [`check_scene_table`] accepts
/// and names in its messages. They are the fields of [`SceneFile`] and the
/// structs under it, which serde fills once the table passes (a test keeps
/// the two the same, names and required-ness).
const SCENE_KEYS: &[Key] = &[
    required("model_identifier", Kind::Str),
    required("description", Kind::Str),
    required("variant", Kind::Variant),
    required("inputs", Kind::StrList),
    required("outputs", Kind::StrList),
    optional("components", Kind::Table(COMPONENTS_KEYS)),
    optional("parameters", Kind::Values),
    optional("constants", Kind::Values),
    optional("fe", Kind::Table(FE_KEYS)),
    required("default_experiment", Kind::Table(EXPERIMENT_KEYS)),
];

/// `[components]`: all optional, present unless set to false.
const COMPONENTS_KEYS: &[Key] = &[
    optional("activation_dynamics", Kind::Bool),
    optional("contractile_element", Kind::Bool),
    optional("fv_shortening", Kind::Bool),
    optional("fv_lengthening", Kind::Bool),
    optional("series_element", Kind::Bool),
    optional("parallel_element", Kind::Bool),
    optional("matrix", Kind::Bool),
    optional("volumetric", Kind::Bool),
];

/// `[fe]` (the library refuses it in a 1d scene).
const FE_KEYS: &[Key] = &[
    optional("mesh", Kind::Str),
    optional("mesh_constant", Kind::Bool),
];

/// `[default_experiment]` (start defaults to 0).
const EXPERIMENT_KEYS: &[Key] = &[
    optional("start", Kind::Number),
    required("stop", Kind::Number),
    required("step", Kind::Number),
];

fn variant_names() -> Vec<&'static str> {
    VARIANTS.map(variant_name).to_vec()
}

impl Kind {
    /// What a value of this kind is, for messages.
    fn describe(self) -> String {
        let names = |keys: &[Key]| keys.iter().map(|k| k.name).collect::<Vec<_>>().join(", ");
        match self {
            Kind::Str => "a string".into(),
            Kind::Variant => format!("one of {}", quoted(&variant_names())),
            Kind::Bool => "true or false".into(),
            Kind::Number => "a number".into(),
            Kind::StrList => "an array of strings".into(),
            Kind::Values => "a table of name = value".into(),
            Kind::Table(keys) => {
                let needed: Vec<&str> =
                    keys.iter().filter(|k| k.required).map(|k| k.name).collect();
                if needed.is_empty() {
                    format!("a table of {}", names(keys))
                } else {
                    format!(
                        "a table of {} ({} required)",
                        names(keys),
                        needed.join(", ")
                    )
                }
            }
        }
    }

    fn accepts(self, v: &DeValue) -> bool {
        match self {
            Kind::Str | Kind::Variant => matches!(v, DeValue::String(_)),
            Kind::Bool => matches!(v, DeValue::Boolean(_)),
            Kind::Number => matches!(v, DeValue::Integer(_) | DeValue::Float(_)),
            Kind::StrList => match v {
                DeValue::Array(a) => a.iter().all(|x| matches!(x.get_ref(), DeValue::String(_))),
                _ => false,
            },
            Kind::Values | Kind::Table(_) => matches!(v, DeValue::Table(_)),
        }
    }
}

fn quoted(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("{n:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The problems of a scene file that parse-level checking finds, each with
/// where it is in the text (`None`: the file as a whole).
struct Problems<'t> {
    text: &'t str,
    found: Vec<(Option<usize>, String)>,
}

impl Problems<'_> {
    fn push(&mut self, at: Option<usize>, msg: String) {
        self.found.push((at, msg));
    }

    /// The messages in the order of the text, each prefixed by its line.
    fn into_messages(mut self) -> Vec<String> {
        self.found.sort_by_key(|(at, _)| *at);
        let text = self.text;
        self.found
            .into_iter()
            .map(|(at, msg)| match at {
                None => msg,
                Some(i) => format!("line {}: {msg}", text[..i].matches('\n').count() + 1),
            })
            .collect()
    }

    /// Check `table`, the top level (`section` None) or the table
    /// `[section]` whose header (or first key) is at `header`.
    fn check(
        &mut self,
        table: &DeTable,
        section: Option<&str>,
        header: Option<usize>,
        keys: &[Key],
    ) {
        let place = match section {
            None => "at the top level".to_string(),
            Some(s) => format!("in [{s}]"),
        };
        for (k, v) in table.iter() {
            let name: &str = k.get_ref();
            let Some(key) = keys.iter().find(|key| key.name == name) else {
                let allowed: Vec<&str> = keys.iter().map(|k| k.name).collect();
                self.push(
                    Some(k.span().start),
                    format!(
                        "unknown field `{name}` {place}; allowed: {}",
                        allowed.join(", ")
                    ),
                );
                continue;
            };
            let path = match section {
                None => name.to_string(),
                Some(s) => format!("{s}.{name}"),
            };
            if !key.kind.accepts(v.get_ref()) {
                let msg = wrong_type(self.text, &path, v, key.kind);
                self.push(Some(v.span().start), msg);
                continue;
            }
            match (key.kind, v.get_ref()) {
                (Kind::Variant, DeValue::String(s)) if !variant_names().contains(&s.as_ref()) => {
                    self.push(
                        Some(v.span().start),
                        format!(
                            "unknown variant `{s}`; allowed: {}",
                            variant_names().join(", ")
                        ),
                    );
                }
                (Kind::Table(sub), DeValue::Table(t)) => {
                    self.check(t, Some(&path), Some(k.span().start), sub);
                }
                _ => {}
            }
        }
        for key in keys.iter().filter(|k| k.required) {
            if !table.iter().any(|(k, _)| k.get_ref() == key.name) {
                self.push(
                    header,
                    format!(
                        "missing field `{}` {place}: {}",
                        key.name,
                        key.kind.describe()
                    ),
                );
            }
        }
    }
}

/// `path = value: must be …`, the value as written if it is written after
/// `=` on one line (the span of a `[table]` or `[[array]]` is its header),
/// else `path: must be …, not a table`.
fn wrong_type(text: &str, path: &str, v: &Spanned<DeValue>, kind: Kind) -> String {
    let src = text.get(v.span()).unwrap_or("").trim();
    let tables =
        |a: &DeArray| !a.is_empty() && a.iter().all(|x| matches!(x.get_ref(), DeValue::Table(_)));
    // What was found, with its article.
    let (inline, found) = match v.get_ref() {
        DeValue::Table(_) => (src.starts_with('{'), "a table".to_string()),
        DeValue::Array(a) if tables(a) => (!src.starts_with("[["), "an array of tables".into()),
        DeValue::Array(_) => (true, "an array".into()),
        DeValue::Integer(_) => (true, "an integer".into()),
        other => (true, format!("a {}", other.type_str())),
    };
    if inline && !src.is_empty() && !src.contains('\n') && src.len() <= 60 {
        format!("{path} = {src}: must be {}", kind.describe())
    } else {
        format!("{path}: must be {}, not {found}", kind.describe())
    }
}

/// Every parse-level problem of a scene file's table: unknown keys, missing
/// required keys, values of the wrong type, an unknown variant (none: serde
/// can fill [`SceneFile`] from it).
fn check_scene_table(text: &str, table: &DeTable) -> Vec<String> {
    let mut p = Problems {
        text,
        found: Vec::new(),
    };
    p.check(table, None, None, SCENE_KEYS);
    p.into_messages()
}

/// A scene file as written (TOML), once [`check_scene_table`] has passed it;
/// the fields are [`SCENE_KEYS`] (unknown keys are refused here too).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    model_identifier: String,
    description: String,
    variant: String,
    inputs: Vec<String>,
    outputs: Vec<String>,
    #[serde(default)]
    components: ComponentsFile,
    #[serde(default)]
    parameters: BTreeMap<String, toml::Value>,
    #[serde(default)]
    constants: BTreeMap<String, toml::Value>,
    fe: Option<FeFile>,
    default_experiment: ExperimentFile,
}

/// `[components]`: [`COMPONENTS_KEYS`].
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentsFile {
    activation_dynamics: Option<bool>,
    contractile_element: Option<bool>,
    fv_shortening: Option<bool>,
    fv_lengthening: Option<bool>,
    series_element: Option<bool>,
    parallel_element: Option<bool>,
    matrix: Option<bool>,
    volumetric: Option<bool>,
}

/// `[fe]`: [`FE_KEYS`].
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FeFile {
    mesh: Option<String>,
    mesh_constant: Option<bool>,
}

/// `[default_experiment]`: [`EXPERIMENT_KEYS`].
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ExperimentFile {
    #[serde(default)]
    start: f64,
    stop: f64,
    step: f64,
}

/// A TOML value as a parameter value (integers stay integers: the library
/// accepts them for Real parameters too).
fn value_of(table: &str, name: &str, v: &toml::Value) -> Result<Value, String> {
    match v {
        toml::Value::Float(x) => Ok(Value::Real(*x)),
        toml::Value::Integer(i) => Ok(i32::try_from(*i)
            .map(Value::Integer)
            .unwrap_or(Value::Real(*i as f64))),
        toml::Value::Boolean(b) => Ok(Value::Boolean(*b)),
        other => Err(format!(
            "[{table}] {name} = {other}: must be a number or true/false"
        )),
    }
}

/// Parse and check a scene file's text: the resolved scene, or every
/// problem, each naming what is wrong.
///
/// A TOML syntax error is reported alone (the parser stops there). Every
/// parse-level problem ([`check_scene_table`]) is reported together; the
/// scene is not resolved then, since what is left of it is not what the
/// user meant (a misspelt `contractile_elemnt = false` would be resolved as
/// a scene with the contractile element, and named for problems it does not
/// have). Otherwise every problem of the scene is reported together.
fn load_scene(text: &str) -> Result<SceneSpec, Vec<String>> {
    let table = DeTable::parse(text).map_err(|e| vec![e.to_string()])?;
    let problems = check_scene_table(text, table.get_ref());
    if !problems.is_empty() {
        return Err(problems);
    }
    // The table passed the keys serde is given, so this fails only if the
    // two disagree (a test keeps them the same).
    let file: SceneFile = toml::from_str(text).map_err(|e| vec![e.to_string()])?;
    let mut errors = Vec::new();
    let mut values = |table: &str, m: &BTreeMap<String, toml::Value>| -> Vec<(String, Value)> {
        m.iter()
            .filter_map(|(k, v)| match value_of(table, k, v) {
                Ok(v) => Some((k.clone(), v)),
                Err(e) => {
                    errors.push(e);
                    None
                }
            })
            .collect()
    };
    let parameters = values("parameters", &file.parameters);
    let constants = values("constants", &file.constants);
    let c = &file.components;
    let draft = Draft {
        model_identifier: file.model_identifier,
        description: file.description,
        variant: VARIANTS
            .into_iter()
            .find(|v| variant_name(*v) == file.variant),
        components: ComponentChoice {
            activation_dynamics: c.activation_dynamics,
            contractile: c.contractile_element,
            fv_shortening: c.fv_shortening,
            fv_lengthening: c.fv_lengthening,
            series: c.series_element,
            parallel: c.parallel_element,
            matrix: c.matrix,
            volumetric: c.volumetric,
        },
        inputs: file.inputs,
        outputs: file.outputs,
        parameters,
        constants,
        mesh: file.fe.as_ref().and_then(|f| f.mesh.clone()),
        mesh_constant: file.fe.as_ref().and_then(|f| f.mesh_constant),
        default_experiment: Some((
            file.default_experiment.start,
            file.default_experiment.stop,
            file.default_experiment.step,
        )),
    };
    match draft.resolve() {
        Ok(spec) if errors.is_empty() => Ok(spec),
        Ok(_) => Err(errors),
        Err(mut more) => {
            errors.append(&mut more);
            Err(errors)
        }
    }
}

/// Read and check the scene file at `path` ([`load_scene`]): the resolved
/// scene, or one message listing every problem.
pub fn read_scene(path: &Path) -> Result<SceneSpec, String> {
    let text = fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    load_scene(&text).map_err(|errors| {
        let mut msg = format!("scene {} is invalid:", path.display());
        for e in errors {
            msg.push_str("\n  - ");
            msg.push_str(&e.replace('\n', "\n    "));
        }
        msg
    })
}

#[cfg(test)]
mod tests;
