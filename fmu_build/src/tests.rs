//! Tests of scene files: the shipped ones resolve and their generated
//! artefacts are committed; invalid scenes are rejected naming the problem.

use super::*;

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

const PASSIVE: &str = r#"
model_identifier = "P"
description = "test"
variant = "1d"
inputs = ["length"]
outputs = ["force"]
[components]
contractile_element = false
series_element = false
[default_experiment]
stop = 1.0
step = 1e-3
"#;

/// The errors of `text` joined (panics if it resolves).
fn errors(text: &str) -> String {
    match load_scene(text) {
        Ok(s) => panic!("accepted: {s:?}"),
        Err(e) => e.join("\n"),
    }
}

#[test]
fn a_minimal_scene_resolves_with_defaults() {
    let s = load_scene(PASSIVE).unwrap();
    assert!(!s.components.contractile && !s.components.activation_dynamics);
    assert!(!s.components.fv_shortening && !s.components.fv_lengthening);
    assert!(s.components.matrix && s.components.parallel);
    assert_eq!(s.outputs, ["force"]);
    assert!(s.setting("S").is_none() && s.setting("alpha").is_none());
    assert_eq!(s.setting("D").unwrap().value, Value::Real(1e-9));
    assert_eq!(s.default_experiment, (0.0, 1.0, 1e-3));
}

#[test]
fn invalid_scenes_are_rejected_naming_the_problem() {
    let with = |from: &str, to: &str| {
        assert!(PASSIVE.contains(from), "{from}");
        PASSIVE.replacen(from, to, 1)
    };
    let cases: Vec<(String, &str)> = vec![
        // An output that needs an absent component.
        (
            with(
                r#"outputs = ["force"]"#,
                r#"outputs = ["force", "active_stress"]"#,
            ),
            "output 'active_stress' needs the contractile element",
        ),
        // Unknown names: output, input, parameter, key.
        (
            with(r#"outputs = ["force"]"#, r#"outputs = ["forse"]"#),
            "unknown output 'forse'",
        ),
        (
            with(
                r#"inputs = ["length"]"#,
                r#"inputs = ["length", "velocity"]"#,
            ),
            "unknown input 'velocity'",
        ),
        (
            with(
                "[default_experiment]",
                "[parameters]\nsigmaO = 1e5\n[default_experiment]",
            ),
            "unknown parameter 'sigmaO'",
        ),
        (
            with("[components]", "[components]\nmatrx = false"),
            "unknown field `matrx`",
        ),
        (
            with(r#"variant = "1d""#, r#"variant = "2d""#),
            "unknown variant `2d`",
        ),
        // A variant without that option.
        (
            with(
                r#"outputs = ["force"]"#,
                r#"outputs = ["force", "volume_ratio_min"]"#,
            ),
            "output 'volume_ratio_min' is not available in the 1d variant",
        ),
        (
            with(
                "[default_experiment]",
                "[fe]\nmesh = \"lumped\"\n[default_experiment]",
            ),
            "the 1d variant has no mesh",
        ),
        (
            with(r#"variant = "1d""#, r#"variant = "fe""#).replace(
                "series_element = false",
                "series_element = false\nmatrix = false",
            ),
            "components.matrix = false is not available in the fe variant",
        ),
        (
            with(r#"variant = "1d""#, r#"variant = "fe""#).replace(
                r#"outputs = ["force"]"#,
                r#"outputs = ["force", "stiffness"]"#,
            ),
            "output 'stiffness' is not available in the fe variant",
        ),
        // Parameters: unused by the scene, out of range, wrong type, twice.
        (
            with(
                "[default_experiment]",
                "[parameters]\nS = 40.0\n[default_experiment]",
            ),
            "parameter 'S' is not used by this scene: it belongs to the activation dynamics",
        ),
        (
            with(
                "[default_experiment]",
                "[constants]\nD = 1.0\n[default_experiment]",
            ),
            "parameter 'D' = 1.0 is out of range",
        ),
        (
            with(
                "[default_experiment]",
                "[constants]\nL0 = true\n[default_experiment]",
            ),
            "parameter 'L0' = true: must be a number",
        ),
        (
            with(
                "[default_experiment]",
                "[parameters]\nD = 1e-9\n[constants]\nD = 1e-9\n[default_experiment]",
            ),
            "parameter 'D' is given twice",
        ),
        // Component rules.
        (
            with("series_element = false", "series_element = true"),
            "contractile_element = false but series_element = true",
        ),
        (
            with(
                "series_element = false",
                "series_element = false\nvolumetric = false",
            ),
            "components.volumetric = false is not available",
        ),
        (
            with(
                r#"inputs = ["length"]"#,
                r#"inputs = ["length", "activation"]"#,
            ),
            "input 'activation' needs the contractile element",
        ),
        (
            with(
                r#"outputs = ["force"]"#,
                r#"outputs = ["force", "stiffness"]"#,
            )
            .replace(r#"inputs = ["length"]"#, "inputs = []"),
            "output 'stiffness' (d force / d length) needs the input 'length'",
        ),
        (
            with(
                "contractile_element = false\nseries_element = false",
                "fv_shortening = false\nfv_lengthening = false",
            ),
            "needs at least one f_v branch",
        ),
        (
            with(
                "contractile_element = false\nseries_element = false",
                "fv_lengthening = false",
            ),
            "the contractile element needs the input 'activation'",
        ),
        // Identifier and experiment.
        (
            with(r#"model_identifier = "P""#, r#"model_identifier = "1 bad""#),
            "model_identifier = \"1 bad\"",
        ),
        (
            with("stop = 1.0", "stop = -1.0"),
            "[default_experiment]: start = 0, stop = -1, step = 0.001",
        ),
    ];
    for (text, expect) in &cases {
        let e = errors(text);
        assert!(
            e.contains(expect),
            "expected {expect:?} in:\n{e}\n--- scene:\n{text}"
        );
    }
}
