//! Tests of the shipped scenes: they resolve, and their generated artefacts
//! (`src/scene/shipped.rs`, `modelDescription/*.xml`) are committed as the
//! generator writes them.

use super::*;
use crate::codegen::shipped_source;

fn root() -> PathBuf {
    workspace_root()
}

fn shipped() -> Vec<(PathBuf, SceneSpec)> {
    shipped_scene_files(&root())
        .unwrap()
        .into_iter()
        .map(|p| {
            let s = read_scene(&p).unwrap_or_else(|e| panic!("{e}"));
            (p, s)
        })
        .collect()
}

#[test]
fn every_shipped_scene_resolves_and_the_required_ones_are_there() {
    let ids: Vec<&str> = shipped().iter().map(|(_, s)| s.model_identifier).collect();
    for id in [
        "HillMuscle1D",
        "HillMuscleFE",
        "HillPassive1D",
        "HillPassiveFE",
        "HillActivated1D",
        "HillActivatedFE",
        "HillIsometric1D",
        "HillActuator1D",
        "HillMusculotendon1D",
        "HillMusculotendonFE",
    ] {
        assert!(ids.contains(&id), "{id} missing from {ids:?}");
    }
}

#[test]
fn shipped_rs_is_the_generator_output() {
    let committed = fs::read_to_string(root().join("src/scene/shipped.rs")).unwrap();
    assert!(
        committed == shipped_source(&shipped(), &root()),
        "src/scene/shipped.rs differs from the scene files: run \
         `cargo run -p fmu_build -- --update-model-descriptions` and commit"
    );
}

#[test]
fn committed_model_descriptions_are_the_generator_output() {
    for (path, spec) in shipped() {
        let md = root()
            .join("modelDescription")
            .join(format!("{}.xml", spec.model_identifier));
        let committed = fs::read_to_string(&md).unwrap_or_else(|e| panic!("{}: {e}", md.display()));
        assert!(
            committed == describe(&spec).0,
            "{} differs from the model description of {}",
            md.display(),
            path.display()
        );
    }
}

#[test]
fn the_shipped_types_are_the_resolved_scenes() {
    use hill_muscle::scene::{shipped as s, Scene};
    let by_id = |id: &str| {
        shipped()
            .into_iter()
            .find(|(_, x)| x.model_identifier == id)
            .unwrap()
            .1
    };
    assert_eq!(s::HillMuscle1D::SPEC, by_id("HillMuscle1D"));
    assert_eq!(s::HillPassive1D::SPEC, by_id("HillPassive1D"));
    assert_eq!(s::HillActivatedFE::SPEC, by_id("HillActivatedFE"));
}

/// The scenes' mesh levels are the FE module's: `lumped` the default mesh
/// of `HillMuscleFE` and its grading, `level0` … `level4` the refinement
/// levels, ungraded.
#[test]
fn the_scene_mesh_levels_are_the_fe_meshes() {
    use hill_muscle::fe::mesh::{Grading, LEVELS};
    let levels = crate::resolve::MESH_LEVELS;
    assert_eq!(levels[0].name, "lumped");
    assert_eq!(
        (levels[0].resolution, levels[0].grading),
        (fmus::hillfe::DEFAULT_MESH, fmus::hillfe::DEFAULT_GRADING)
    );
    for (i, (level, res)) in levels[1..].iter().zip(LEVELS).enumerate() {
        assert_eq!(level.name, format!("level{i}"));
        assert_eq!((level.resolution, level.grading), (res, Grading::UNIFORM));
    }
}
