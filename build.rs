//! Build script of hill-muscle: the scene an FMU binary exports (issue 6).
//!
//! With the Cargo feature `export-scene`, `fmu_build` writes the Rust text of
//! the scene's `Scene` type and its `export_fmi2!` line to a file and passes
//! its path in `HILL_MUSCLE_SCENE_RS`; this script copies it to
//! `$OUT_DIR/exported_scene.rs`, which `src/lib.rs` includes. The scene's
//! components are then constants of the compiled crate, so only this crate
//! is rebuilt per scene (its dependencies keep their features). Without the
//! feature the file is empty: the library exports no FMU.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=HILL_MUSCLE_SCENE_RS");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("exported_scene.rs");
    let text = if std::env::var_os("CARGO_FEATURE_EXPORT_SCENE").is_some() {
        let Ok(path) = std::env::var("HILL_MUSCLE_SCENE_RS") else {
            eprintln!(
                "hill-muscle: the feature export-scene needs HILL_MUSCLE_SCENE_RS, the scene file \
                 fmu_build generates: build FMUs with `cargo run --release -p fmu_build -- --scene \
                 fmu_build/scenes/<name>.toml`"
            );
            std::process::exit(1);
        };
        println!("cargo:rerun-if-changed={path}");
        match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("hill-muscle: HILL_MUSCLE_SCENE_RS = {path}: {e}");
                std::process::exit(1);
            }
        }
    } else {
        String::new()
    };
    if std::fs::read_to_string(&out).ok().as_deref() != Some(text.as_str()) {
        std::fs::write(&out, text).expect("write exported_scene.rs");
    }
}
