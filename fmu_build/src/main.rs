//! Builds the muscle FMUs.
//!
//! ```text
//! cargo run --release -p fmu_build                       # every FMU into dist/
//! cargo run --release -p fmu_build -- --fmu HillMuscle1D # one FMU
//! cargo run --release -p fmu_build -- --update-model-descriptions
//! ```
//!
//! For each FMU: the model description and documentation are generated from
//! the model's variable table (the same table the binary dispatches on), the
//! cdylib is compiled with `--no-default-features` and exactly that FMU's
//! export feature (so it carries no other model's code: HillMuscle1D is built
//! without the `fe` feature, hence without `hill_muscle::fe` and faer;
//! `export-hfe` turns `fe` on), and `dist/<id>.fmu` is zipped with
//! `modelDescription.xml`, `binaries/<platform>/<id>.<ext>` and
//! `documentation/index.html`.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use hill_muscle::fmi2::model_description::{documentation_html, model_description};
use hill_muscle::fmus;

/// One FMU the project ships.
struct FmuSpec {
    id: &'static str,
    /// Cargo feature of the hill-muscle crate that exports this FMU's C API;
    /// the binary is built with only this feature (and what it implies).
    feature: &'static str,
    model_description: fn() -> String,
    documentation: fn() -> String,
}

fn fmus() -> Vec<FmuSpec> {
    vec![
        FmuSpec {
            id: "HillMuscle1D",
            feature: "export-hill1d",
            model_description: model_description::<fmus::hill1d::Hill1D>,
            documentation: || documentation_html::<fmus::hill1d::Hill1D>(fmus::hill1d::LAW_HTML),
        },
        FmuSpec {
            id: "HillMuscleFE",
            feature: "export-hfe",
            model_description: model_description::<fmus::hillfe::HillFE>,
            documentation: || {
                documentation_html::<fmus::hillfe::HillFE>(&format!(
                    "{}{}",
                    fmus::hillfe::FE_HTML,
                    fmus::hill1d::LAW_HTML
                ))
            },
        },
    ]
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("fmu_build sits in the workspace")
        .to_path_buf()
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

fn build_library(spec: &FmuSpec, root: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "-p",
            "hill-muscle",
            "--lib",
            "--no-default-features",
            "--features",
            spec.feature,
        ])
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!("cargo build of {} failed", spec.id));
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
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

fn write_fmu(spec: &FmuSpec, lib: &Path, out_dir: &Path) -> Result<PathBuf, String> {
    use zip::write::SimpleFileOptions;
    fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let path = out_dir.join(format!("{}.fmu", spec.id));
    let tmp = out_dir.join(format!(".{}.fmu.tmp", spec.id));
    let file = fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    let (plat, _, ext) = platform();
    let binary = fs::read(lib).map_err(|e| format!("{}: {e}", lib.display()))?;
    let entries: [(String, Vec<u8>); 3] = [
        (
            "modelDescription.xml".into(),
            (spec.model_description)().into_bytes(),
        ),
        (format!("binaries/{plat}/{}.{ext}", spec.id), binary),
        (
            "documentation/index.html".into(),
            (spec.documentation)().into_bytes(),
        ),
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

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut only: Option<String> = None;
    let mut out_dir: Option<PathBuf> = None;
    let mut update_md = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--fmu" => only = Some(args.next().ok_or("--fmu needs a model identifier")?),
            "--out" => out_dir = Some(args.next().ok_or("--out needs a directory")?.into()),
            "--update-model-descriptions" => update_md = true,
            "-h" | "--help" => {
                println!("usage: fmu_build [--fmu ID] [--out DIR] [--update-model-descriptions]");
                return Ok(());
            }
            other => return Err(format!("unknown argument {other:?} (see --help)")),
        }
    }
    let root = workspace_root();
    let specs: Vec<FmuSpec> = fmus()
        .into_iter()
        .filter(|s| only.as_deref().is_none_or(|id| id == s.id))
        .collect();
    if specs.is_empty() {
        let known: Vec<&str> = fmus().iter().map(|s| s.id).collect();
        return Err(format!(
            "unknown FMU {:?}; known: {}",
            only.unwrap_or_default(),
            known.join(", ")
        ));
    }
    if update_md {
        for spec in &specs {
            let path = root
                .join("modelDescription")
                .join(format!("{}.xml", spec.id));
            fs::write(&path, (spec.model_description)())
                .map_err(|e| format!("{}: {e}", path.display()))?;
            println!("wrote {}", path.display());
        }
        return Ok(());
    }
    let out_dir = out_dir.unwrap_or_else(|| root.join("dist"));
    for spec in &specs {
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
