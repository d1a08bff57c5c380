//! Tests of scene files' text: invalid scenes are rejected naming the
//! problem, every parse-level problem of a file in one report; the key lists
//! the parse-level check uses are the fields serde fills.

use super::*;

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

/// PASSIVE with seven parse-level problems: an unknown key at the top level
/// and one in [components] and one in [default_experiment], a missing
/// required field (description), an unknown variant, a value of the wrong
/// type at the top level and one in [components]; and an unknown output, a
/// problem of resolution, which is not reported while the file does not
/// parse into a scene.
const MANY_PROBLEMS: &str = r#"
model_identifier = "P"
varaint = "1d"
variant = "2d"
inputs = "length"
outputs = ["forse"]
[components]
contractile_element = false
series_element = false
matrx = false
matrix = 1
[default_experiment]
stop = 1.0
step = 1e-3
stpe = 1e-3
"#;

#[test]
fn every_parse_level_problem_is_named_in_one_report() {
    let e = match load_scene(MANY_PROBLEMS) {
        Ok(s) => panic!("accepted: {s:?}"),
        Err(e) => e,
    };
    let expected = [
        "missing field `description` at the top level: a string",
        "line 3: unknown field `varaint` at the top level; allowed: model_identifier, \
         description, variant, inputs, outputs, components, parameters, constants, fe, \
         default_experiment",
        "line 4: unknown variant `2d`; allowed: 1d, fe, musculotendon_1d, musculotendon_fe",
        "line 5: inputs = \"length\": must be an array of strings",
        "line 10: unknown field `matrx` in [components]; allowed: activation_dynamics, \
         contractile_element, fv_shortening, fv_lengthening, series_element, \
         parallel_element, matrix, volumetric",
        "line 11: components.matrix = 1: must be true or false",
        "line 15: unknown field `stpe` in [default_experiment]; allowed: start, stop, step",
    ];
    assert_eq!(e, expected, "the report:\n{}", e.join("\n"));
}

#[test]
fn each_parse_level_problem_is_named_with_its_line() {
    let with = |from: &str, to: &str| {
        assert!(PASSIVE.contains(from), "{from}");
        PASSIVE.replacen(from, to, 1)
    };
    let cases: Vec<(String, &str)> = vec![
        // Missing required fields, at the top level and in a table.
        (
            with("description = \"test\"\n", ""),
            "missing field `description` at the top level: a string",
        ),
        (
            with("variant = \"1d\"\n", ""),
            "missing field `variant` at the top level: one of \"1d\", \"fe\", \"musculotendon_1d\", \"musculotendon_fe\"",
        ),
        (
            with("outputs = [\"force\"]\n", ""),
            "missing field `outputs` at the top level: an array of strings",
        ),
        (
            with("step = 1e-3\n", ""),
            "line 10: missing field `step` in [default_experiment]: a number",
        ),
        (
            with("[default_experiment]\nstop = 1.0\nstep = 1e-3\n", ""),
            "missing field `default_experiment` at the top level: a table of start, stop, \
             step (stop, step required)",
        ),
        // Unknown keys, with the allowed ones.
        (
            with(
                "[default_experiment]",
                "[fe]\nmesh_level = 1\n[default_experiment]",
            ),
            "line 11: unknown field `mesh_level` in [fe]; allowed: mesh, mesh_constant",
        ),
        (
            with(
                "[default_experiment]",
                "[parameter]\nD = 1e-9\n[default_experiment]",
            ),
            "line 10: unknown field `parameter` at the top level; allowed:",
        ),
        // Values of the wrong type.
        (
            with(r#"inputs = ["length"]"#, r#"inputs = "length""#),
            "line 5: inputs = \"length\": must be an array of strings",
        ),
        (
            with(r#"outputs = ["force"]"#, r#"outputs = ["force", 2]"#),
            "line 6: outputs = [\"force\", 2]: must be an array of strings",
        ),
        (
            with(r#"variant = "1d""#, "variant = 1"),
            "line 4: variant = 1: must be one of \"1d\", \"fe\", \"musculotendon_1d\", \"musculotendon_fe\"",
        ),
        (
            with("series_element = false", "series_element = \"no\""),
            "line 9: components.series_element = \"no\": must be true or false",
        ),
        (
            with("stop = 1.0", "stop = \"1\""),
            "line 11: default_experiment.stop = \"1\": must be a number",
        ),
        (
            with("[components]", "fe = \"lumped\"\n[components]"),
            "line 7: fe = \"lumped\": must be a table of mesh, mesh_constant",
        ),
        (
            with(
                "[default_experiment]",
                "[[fe]]\nmesh = \"lumped\"\n[default_experiment]",
            ),
            "line 10: fe: must be a table of mesh, mesh_constant, not an array of tables",
        ),
        (
            with("[components]", "parameters = 1\n[components]"),
            "line 7: parameters = 1: must be a table of name = value",
        ),
    ];
    for (text, expect) in &cases {
        let e = errors(text);
        assert!(
            e.contains(expect),
            "expected {expect:?} in:\n{e}\n--- scene:\n{text}"
        );
    }
    // A TOML syntax error stops the parse: it is reported alone, at its line
    // (the unknown key before it is not reached).
    let text = with("[components]", "colour = 1\n[components]\nmatrix = = false");
    match load_scene(&text) {
        Ok(s) => panic!("accepted: {s:?}"),
        Err(e) => assert!(
            e.len() == 1 && e[0].contains("TOML parse error at line 9"),
            "{e:?}"
        ),
    }
}

/// The field names serde's derive gives `T` (it passes them to
/// `deserialize_struct`).
fn serde_fields<T: for<'de> Deserialize<'de>>() -> Vec<&'static str> {
    use serde::de::{Error, Visitor};
    struct Probe(Vec<&'static str>);
    impl<'de> serde::Deserializer<'de> for &mut Probe {
        type Error = serde::de::value::Error;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Self::Error> {
            Err(Error::custom("not a struct"))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Self::Error> {
            self.0 = fields.to_vec();
            Err(Error::custom("probed"))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
            byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map
            enum identifier ignored_any
        }
    }
    let mut probe = Probe(Vec::new());
    let _ = T::deserialize(&mut probe);
    probe.0
}

/// A TOML text with every key of `keys` but `without` (a dotted path), each
/// with a value of its kind.
fn sample(keys: &[Key], prefix: &str, without: &str) -> Vec<String> {
    keys.iter()
        .filter_map(|k| {
            let path = format!("{prefix}{}", k.name);
            let value = match k.kind {
                Kind::Str => "\"x\"".to_string(),
                Kind::Variant => "\"fe\"".into(),
                Kind::Bool => "true".into(),
                Kind::Number => "1.5".into(),
                Kind::StrList => "[\"x\"]".into(),
                Kind::Values => "{ x = 1 }".into(),
                Kind::Table(sub) => format!(
                    "{{ {} }}",
                    sample(sub, &format!("{path}."), without).join(", ")
                ),
            };
            (path != without).then(|| format!("{} = {value}", k.name))
        })
        .collect()
}

#[test]
fn the_key_lists_are_the_serde_fields() {
    let names = |keys: &[Key]| {
        let mut n: Vec<&str> = keys.iter().map(|k| k.name).collect();
        n.sort();
        n
    };
    let sorted = |mut v: Vec<&'static str>| {
        v.sort();
        v
    };
    assert_eq!(names(SCENE_KEYS), sorted(serde_fields::<SceneFile>()));
    assert_eq!(
        names(COMPONENTS_KEYS),
        sorted(serde_fields::<ComponentsFile>())
    );
    assert_eq!(names(FE_KEYS), sorted(serde_fields::<FeFile>()));
    assert_eq!(
        names(EXPERIMENT_KEYS),
        sorted(serde_fields::<ExperimentFile>())
    );
    // Required: the check and serde refuse the file without the key; not
    // required: both accept it (and both accept the file with every key).
    fn paths(keys: &[Key], prefix: &str, out: &mut Vec<(String, bool)>) {
        for k in keys {
            let path = format!("{prefix}{}", k.name);
            out.push((path.clone(), k.required));
            if let Kind::Table(sub) = k.kind {
                paths(sub, &format!("{path}."), out);
            }
        }
    }
    let mut all = vec![(String::new(), false)];
    paths(SCENE_KEYS, "", &mut all);
    for (path, required) in &all {
        let text = sample(SCENE_KEYS, "", path).join("\n");
        let checked = check_scene_table(&text, DeTable::parse(&text).unwrap().get_ref());
        let parsed = toml::from_str::<SceneFile>(&text);
        if *required {
            assert!(
                checked.len() == 1 && checked[0].contains("missing field"),
                "without {path}: {checked:?}"
            );
            assert!(parsed.is_err(), "serde accepts the file without {path}");
        } else {
            assert!(checked.is_empty(), "without {path:?}: {checked:?}");
            if let Err(e) = parsed {
                panic!("without {path:?}: {e}");
            }
        }
    }
}
