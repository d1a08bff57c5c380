//! Builds the muscle FMUs, one per scene.
//!
//! ```text
//! cargo run --release -p fmu_build                          # every shipped scene into dist/
//! cargo run --release -p fmu_build -- --scene fmu_build/scenes/passive_1d.toml
//! cargo run --release -p fmu_build -- --fmu HillMuscle1D    # one shipped scene by its identifier
//! cargo run --release -p fmu_build -- --check FILE.toml     # check a scene, build nothing
//! cargo run --release -p fmu_build -- --update-model-descriptions
//! ```
//!
//! A scene file (TOML, see README "Scenes" and `fmu_build/scenes/`) is
//! read and checked by [`scene_file`], which hands it to [`resolve`] for the
//! checks against the variant's variable table; every problem is reported,
//! named, before anything is built. [`codegen`] writes the Rust text of a
//! resolved scene.
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

mod codegen;
mod resolve;
mod scene_file;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use hill_muscle::fmi2::model_description::{documentation_html_for, model_description_for};
use hill_muscle::fmi2::{ModelInfo, ScalarVariable};
use hill_muscle::fmus;
use hill_muscle::scene::{SceneSpec, Variant};

use crate::codegen::{exported_scene_source, shipped_source};
use crate::resolve::variant_name;
use crate::scene_file::read_scene;

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
            &fmus::common::info_for(spec),
            &spec.variables(fmus::hill1d::all_variables()),
            fmus::hill1d::LAW_HTML,
        ),
        Variant::Fe => describe_table(
            &fmus::common::info_for(spec),
            &spec.variables(fmus::hillfe::all_variables()),
            &format!("{}{}", fmus::hillfe::FE_HTML, fmus::hill1d::LAW_HTML),
        ),
        Variant::Musculotendon1D => describe_table(
            &fmus::musculotendon1d::info_for(spec),
            &fmus::musculotendon1d::scene_variables(spec),
            &format!(
                "{}{}",
                fmus::musculotendon1d::MT_HTML,
                fmus::hill1d::LAW_HTML
            ),
        ),
        Variant::MusculotendonFe => describe_table(
            &fmus::musculotendon1d::info_for(spec),
            &fmus::musculotendonfe::scene_variables(spec),
            &format!(
                "{}{}{}",
                fmus::musculotendonfe::MTFE_HTML,
                fmus::hillfe::FE_HTML,
                fmus::hill1d::LAW_HTML
            ),
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
    let text = exported_scene_source(spec);
    // Rewritten only when it changes, so an unchanged scene is not rebuilt.
    if fs::read_to_string(&gen).ok().as_deref() != Some(text.as_str()) {
        fs::write(&gen, &text).map_err(|e| format!("{}: {e}", gen.display()))?;
    }
    let features = match spec.variant {
        Variant::OneD | Variant::Musculotendon1D => "export-scene",
        Variant::Fe | Variant::MusculotendonFe => "export-scene,fe",
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
                variant_name(spec.variant),
                match spec.variant {
                    Variant::OneD => spec.variables(fmus::hill1d::all_variables()).len(),
                    Variant::Fe => spec.variables(fmus::hillfe::all_variables()).len(),
                    Variant::Musculotendon1D => {
                        fmus::musculotendon1d::scene_variables(&spec).len()
                    }
                    Variant::MusculotendonFe => {
                        fmus::musculotendonfe::scene_variables(&spec).len()
                    }
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
