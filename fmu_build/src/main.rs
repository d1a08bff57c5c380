//! Builds the muscle FMUs, one per scene (issue 6).
//!
//! ```text
//! cargo run --release -p fmu_build                          # every shipped scene into dist/
//! cargo run --release -p fmu_build -- --scene fmu_build/scenes/passive_1d.toml
//! cargo run --release -p fmu_build -- --fmu HillMuscle1D    # one shipped scene by its identifier
//! cargo run --release -p fmu_build -- --check FILE.toml     # check a scene, build nothing
//! cargo run --release -p fmu_build -- --update-model-descriptions
//! ```
//!
//! A scene file (TOML, see README "Scenes" and `fmu_build/scenes/`) is read
//! in three steps, each reporting every problem it finds, naming it, before
//! anything is built: the TOML is parsed to a table (a syntax error stops
//! there, at its line); the table is checked against the scene file's keys
//! ([`SCENE_KEYS`]: unknown keys, missing required ones, values of the wrong
//! type, an unknown variant, each with its line); then, `serde` having
//! turned it into a [`hill_muscle::scene::Draft`], the library checks that
//! against the variant's variable table
//! ([`hill_muscle::scene::Draft::resolve`]).
//!
//! For each scene: the model description and documentation are generated
//! from the scene's variable table (the same table the binary dispatches
//! on); the scene's `Scene` type is written as Rust to
//! `target/fmu_build/<id>.rs` and handed to the crate's build script in
//! `HILL_MUSCLE_SCENE_RS`; the cdylib is compiled with
//! `--no-default-features --features export-scene` (plus `fe` for FE
//! scenes), so only hill-muscle recompiles per scene and a 1D binary carries
//! no FE code; `dist/<id>.fmu` is zipped with `modelDescription.xml`,
//! `binaries/<platform>/<id>.<ext>` and `documentation/index.html`.
//!
//! `--update-model-descriptions` writes `modelDescription/<id>.xml` for
//! every shipped scene and `src/scene/shipped.rs` (the shipped scenes as
//! Rust types, used by the library and its tests); tests keep both equal to
//! this generator's output.

use std::collections::BTreeMap;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use hill_muscle::fmi2::model_description::{documentation_html_for, model_description_for};
use hill_muscle::fmi2::{ModelInfo, ScalarVariable};
use hill_muscle::fmus;
use hill_muscle::scene::{
    model_type, rust_source, ComponentChoice, Draft, SceneSpec, Value, Variant,
};
use serde::Deserialize;
use toml::de::{DeArray, DeTable, DeValue};
use toml::Spanned;

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

/// The variants a scene can name, by [`Variant::name`].
const VARIANTS: [Variant; 2] = [Variant::OneD, Variant::Fe];

fn variant_names() -> Vec<&'static str> {
    VARIANTS.map(Variant::name).to_vec()
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
        variant: VARIANTS.into_iter().find(|v| v.name() == file.variant),
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

fn read_scene(path: &Path) -> Result<SceneSpec, String> {
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

/// modelDescription.xml and documentation/index.html of a table.
fn describe_table<V: Copy>(
    info: &ModelInfo,
    vars: &[ScalarVariable<V>],
    law_html: &str,
) -> (String, String) {
    (
        model_description_for(info, vars),
        documentation_html_for(info, vars, law_html),
    )
}

/// modelDescription.xml and documentation/index.html of a scene.
fn describe(spec: &SceneSpec) -> (String, String) {
    match spec.variant {
        Variant::OneD => describe_table(
            &fmus::hill1d::info_for(spec),
            &spec.variables(fmus::hill1d::all_variables()),
            fmus::hill1d::LAW_HTML,
        ),
        Variant::Fe => describe_table(
            &fmus::hillfe::info_for(spec),
            &spec.variables(fmus::hillfe::all_variables()),
            &format!("{}{}", fmus::hillfe::FE_HTML, fmus::hill1d::LAW_HTML),
        ),
    }
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("fmu_build sits in the workspace")
        .to_path_buf()
}

fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"))
}

/// The shipped scenes: `fmu_build/scenes/*.toml`, sorted by file name.
fn shipped_scene_files(root: &Path) -> Result<Vec<PathBuf>, String> {
    let dir = root.join("fmu_build").join("scenes");
    let mut files: Vec<PathBuf> = fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    Ok(files)
}

/// The text of `src/scene/shipped.rs` for the shipped scenes.
fn shipped_source(scenes: &[(PathBuf, SceneSpec)], root: &Path) -> String {
    let mut s = String::from(
        "//! The shipped scenes, one `Scene` type each (named by its model identifier).\n\
         //!\n\
         //! Generated by `cargo run -p fmu_build -- --update-model-descriptions` from\n\
         //! `fmu_build/scenes/*.toml`; do not edit (a test keeps it equal to the\n\
         //! generator's output).\n",
    );
    for (path, spec) in scenes {
        let rel = path.strip_prefix(root).unwrap_or(path);
        s.push_str(&format!("\n// From {}.\n", rel.display()));
        s.push_str(&rust_source(spec.model_identifier, spec));
    }
    s
}

/// FMI platform folder and shared-library extension of this host.
fn platform() -> (&'static str, &'static str, &'static str) {
    if cfg!(target_os = "linux") {
        ("linux64", "lib", "so")
    } else if cfg!(target_os = "macos") {
        ("darwin64", "lib", "dylib")
    } else {
        ("win64", "", "dll")
    }
}

fn build_library(spec: &SceneSpec, root: &Path) -> Result<PathBuf, String> {
    let target = target_dir(root);
    let gen_dir = target.join("fmu_build");
    fs::create_dir_all(&gen_dir).map_err(|e| format!("{}: {e}", gen_dir.display()))?;
    let gen = gen_dir.join(format!("{}.rs", spec.model_identifier));
    let text = format!(
        "// Generated by fmu_build: the scene this binary exports.\n{}\ncrate::export_fmi2!({});\n",
        rust_source("ExportedScene", spec),
        model_type("ExportedScene", spec)
    );
    // Rewritten only when it changes, so an unchanged scene is not rebuilt.
    if fs::read_to_string(&gen).ok().as_deref() != Some(text.as_str()) {
        fs::write(&gen, &text).map_err(|e| format!("{}: {e}", gen.display()))?;
    }
    let features = match spec.variant {
        Variant::OneD => "export-scene",
        Variant::Fe => "export-scene,fe",
    };
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(root)
        .env("HILL_MUSCLE_SCENE_RS", &gen)
        .args([
            "build",
            "--release",
            "-p",
            "hill-muscle",
            "--lib",
            "--no-default-features",
            "--features",
            features,
        ])
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!("cargo build of {} failed", spec.model_identifier));
    }
    let (_, prefix, ext) = platform();
    let lib = target
        .join("release")
        .join(format!("{prefix}hill_muscle.{ext}"));
    if lib.exists() {
        Ok(lib)
    } else {
        Err(format!("built library not found at {}", lib.display()))
    }
}

fn write_fmu(spec: &SceneSpec, lib: &Path, out_dir: &Path) -> Result<PathBuf, String> {
    use zip::write::SimpleFileOptions;
    let id = spec.model_identifier;
    fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let path = out_dir.join(format!("{id}.fmu"));
    let tmp = out_dir.join(format!(".{id}.fmu.tmp"));
    let file = fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    let (plat, _, ext) = platform();
    let binary = fs::read(lib).map_err(|e| format!("{}: {e}", lib.display()))?;
    let (xml, html) = describe(spec);
    let entries: [(String, Vec<u8>); 3] = [
        ("modelDescription.xml".into(), xml.into_bytes()),
        (format!("binaries/{plat}/{id}.{ext}"), binary),
        ("documentation/index.html".into(), html.into_bytes()),
    ];
    for (name, bytes) in entries {
        zip.start_file(name.as_str(), opts)
            .map_err(|e| format!("zip {name}: {e}"))?;
        zip.write_all(&bytes)
            .map_err(|e| format!("zip {name}: {e}"))?;
    }
    zip.finish().map_err(|e| format!("zip: {e}"))?;
    fs::rename(&tmp, &path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

const USAGE: &str = "usage: fmu_build [--scene FILE.toml]... [--fmu ID]... [--check FILE.toml]... \
[--out DIR] [--update-model-descriptions]\n\
  (no --scene/--fmu: every shipped scene of fmu_build/scenes/)";

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut scenes: Vec<PathBuf> = Vec::new();
    let mut ids: Vec<String> = Vec::new();
    let mut checks: Vec<PathBuf> = Vec::new();
    let mut out_dir: Option<PathBuf> = None;
    let mut update_md = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--scene" => scenes.push(args.next().ok_or("--scene needs a file")?.into()),
            "--fmu" => ids.push(args.next().ok_or("--fmu needs a model identifier")?),
            "--check" => checks.push(args.next().ok_or("--check needs a file")?.into()),
            "--out" => out_dir = Some(args.next().ok_or("--out needs a directory")?.into()),
            "--update-model-descriptions" => update_md = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => return Err(format!("unknown argument {other:?}\n{USAGE}")),
        }
    }
    let root = workspace_root();
    if !checks.is_empty() {
        for path in &checks {
            let spec = read_scene(path)?;
            println!(
                "{}: scene {} ({} variant) is valid: {} variables",
                path.display(),
                spec.model_identifier,
                spec.variant.name(),
                match spec.variant {
                    Variant::OneD => spec.variables(fmus::hill1d::all_variables()).len(),
                    Variant::Fe => spec.variables(fmus::hillfe::all_variables()).len(),
                }
            );
        }
        return Ok(());
    }
    let mut shipped = Vec::new();
    for path in shipped_scene_files(&root)? {
        let spec = read_scene(&path)?;
        shipped.push((path, spec));
    }
    for (i, (p, s)) in shipped.iter().enumerate() {
        if let Some((q, _)) = shipped[..i]
            .iter()
            .find(|(_, t)| t.model_identifier == s.model_identifier)
        {
            return Err(format!(
                "{} and {} both define model_identifier {}",
                q.display(),
                p.display(),
                s.model_identifier
            ));
        }
    }
    if update_md {
        for (_, spec) in &shipped {
            let path = root
                .join("modelDescription")
                .join(format!("{}.xml", spec.model_identifier));
            fs::write(&path, describe(spec).0).map_err(|e| format!("{}: {e}", path.display()))?;
            println!("wrote {}", path.display());
        }
        let path = root.join("src").join("scene").join("shipped.rs");
        fs::write(&path, shipped_source(&shipped, &root))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        println!("wrote {}", path.display());
        return Ok(());
    }
    let mut selected: Vec<SceneSpec> = Vec::new();
    for path in &scenes {
        selected.push(read_scene(path)?);
    }
    for id in &ids {
        match shipped.iter().find(|(_, s)| s.model_identifier == id) {
            Some((_, s)) => selected.push(*s),
            None => {
                let known: Vec<&str> = shipped.iter().map(|(_, s)| s.model_identifier).collect();
                return Err(format!(
                    "unknown FMU {id:?}; shipped scenes: {}",
                    known.join(", ")
                ));
            }
        }
    }
    if scenes.is_empty() && ids.is_empty() {
        selected = shipped.iter().map(|(_, s)| *s).collect();
    }
    let out_dir = out_dir.unwrap_or_else(|| root.join("dist"));
    for spec in &selected {
        let lib = build_library(spec, &root)?;
        let fmu = write_fmu(spec, &lib, &out_dir)?;
        println!("wrote {}", fmu.display());
    }
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("fmu_build: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests;
