//! The committed `modelDescription/*.xml` files are exactly what the variable
//! tables generate, so every interface change shows in review. Update them with
//! `cargo run -p fmu_build -- --update-model-descriptions`.

use hill_muscle::fmi2::model_description::{guid, model_description, validate_table};
use hill_muscle::fmus::hill1d::Hill1D;
#[cfg(feature = "fe")]
use hill_muscle::fmus::hillfe::HillFE;

fn check_committed(id: &str, generated: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("modelDescription")
        .join(format!("{id}.xml"));
    let committed =
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .map_or(0, |i| i + 1);
        panic!(
            "{} differs from the generated model description (first difference at line {line});\n\
             if the interface change is intended, run `cargo run -p fmu_build -- --update-model-descriptions` and commit",
            path.display()
        );
    }
}

#[test]
fn hill1d_model_description_is_committed_and_valid() {
    validate_table::<Hill1D>().expect("HillMuscle1D variable table follows FMI 2.0 rules");
    let xml = model_description::<Hill1D>();
    assert!(xml.contains(&format!("guid=\"{}\"", guid::<Hill1D>())));
    for name in [
        "activation",
        "length",
        "force",
        "stress",
        "cauchy_stress",
        "activation_level",
        "fibre_stretch",
        "ce_stretch",
        "see_stretch",
        "active_stress",
        "passive_stress",
        "L0",
        "area",
        "activation_dynamics",
        "initial_activation",
        "sigma0",
        "lambda_dot_min",
    ] {
        assert!(
            xml.contains(&format!("name=\"{name}\"")),
            "missing variable {name}"
        );
    }
    check_committed("HillMuscle1D", &xml);
}

#[test]
fn hill1d_model_structure_has_the_real_dependencies() {
    use hill_muscle::fmi2::model_description::{initial_unknown_dependencies, output_dependencies};
    use hill_muscle::fmi2::Model;
    let vars = Hill1D::variables();
    let index = |name: &str| 1 + vars.iter().position(|v| v.name == name).unwrap();
    let names = |deps: &[usize]| -> Vec<&str> { deps.iter().map(|&i| vars[i - 1].name).collect() };
    // No direct feedthrough: outputs change only in fmi2DoStep.
    for (_, deps) in output_dependencies(&Hill1D::info(), &vars) {
        assert!(deps.is_empty());
    }
    let initial = initial_unknown_dependencies(&vars);
    assert_eq!(initial.len(), 9);
    let of = |name: &str| names(&initial.iter().find(|(i, _)| *i == index(name)).unwrap().1);
    let mut level = of("activation_level");
    level.sort_unstable();
    assert_eq!(
        level,
        ["activation", "activation_dynamics", "initial_activation"]
    );
    let force = of("force");
    let stress = of("stress");
    assert!(force.contains(&"area") && !stress.contains(&"area"));
    for name in ["length", "L0", "sigma0", "D", "b", "activation"] {
        assert!(stress.contains(&name), "stress at t0 depends on {name}");
    }
    // The isometric start does not involve the force-velocity relation or S.
    for name in ["S", "kc", "ke", "d", "lambda_dot_min"] {
        assert!(
            !force.contains(&name),
            "force at t0 does not depend on {name}"
        );
    }
}

#[cfg(feature = "fe")]
#[test]
fn hillfe_model_description_is_committed_and_valid() {
    validate_table::<HillFE>().expect("HillMuscleFE variable table follows FMI 2.0 rules");
    let xml = model_description::<HillFE>();
    assert!(xml.contains(&format!("guid=\"{}\"", guid::<HillFE>())));
    for name in [
        "activation",
        "length",
        "force",
        "stress",
        "volume_ratio_min",
        "volume_ratio_max",
        "max_fibre_stretch",
        "newton_iterations",
        "n_axial",
        "n_radial",
    ] {
        assert!(xml.contains(&format!("name=\"{name}\"")), "{name}");
    }
    check_committed("HillMuscleFE", &xml);
}

/// Every shipped scene (issue 6): its variable table follows the FMI 2.0
/// rules, its ModelStructure names only variables of its own table, and the
/// committed `modelDescription/<id>.xml` is the generator's output.
#[test]
fn every_shipped_scene_model_description_is_committed_and_valid() {
    use hill_muscle::fmus::hill1d::Hill1DModel;
    use hill_muscle::scene::shipped::*;
    use hill_muscle::scene::Scene;
    fn check<M: hill_muscle::fmi2::Model, S: Scene>() {
        let id = S::SPEC.model_identifier;
        validate_table::<M>().unwrap_or_else(|e| panic!("{id}: {e:?}"));
        let vars = M::variables();
        for v in &vars {
            for d in &v.depends_on {
                assert!(
                    vars.iter().any(|w| w.name == *d),
                    "{id}: {} depends on {d}, which is not in its table",
                    v.name
                );
            }
        }
        let xml = model_description::<M>();
        assert!(xml.contains(&format!("guid=\"{}\"", guid::<M>())));
        check_committed(id, &xml);
    }
    check::<Hill1DModel<HillMuscle1D>, HillMuscle1D>();
    check::<Hill1DModel<HillPassive1D>, HillPassive1D>();
    check::<Hill1DModel<HillActivated1D>, HillActivated1D>();
    check::<Hill1DModel<HillIsometric1D>, HillIsometric1D>();
    check::<Hill1DModel<HillActuator1D>, HillActuator1D>();
    #[cfg(feature = "fe")]
    {
        use hill_muscle::fmus::hillfe::HillFEModel;
        check::<HillFEModel<HillMuscleFE>, HillMuscleFE>();
        check::<HillFEModel<HillPassiveFE>, HillPassiveFE>();
        check::<HillFEModel<HillActivatedFE>, HillActivatedFE>();
    }
    // The GUIDs differ between scenes (an importer cannot mix them up).
    let mut guids = vec![
        guid::<Hill1DModel<HillMuscle1D>>(),
        guid::<Hill1DModel<HillPassive1D>>(),
        guid::<Hill1DModel<HillActivated1D>>(),
        guid::<Hill1DModel<HillIsometric1D>>(),
        guid::<Hill1DModel<HillActuator1D>>(),
    ];
    guids.sort();
    guids.dedup();
    assert_eq!(guids.len(), 5);
}

/// The actuator's `stiffness` has the force's initial dependencies and the
/// unit N/m, which the full HillMuscle1D does not declare (its interface,
/// hence its GUID, is unchanged by the scenes).
#[test]
fn the_actuator_declares_stiffness_in_newton_per_metre() {
    use hill_muscle::fmi2::Model;
    use hill_muscle::fmus::hill1d::Hill1DModel;
    use hill_muscle::scene::shipped::HillActuator1D;
    type A = Hill1DModel<HillActuator1D>;
    let vars = A::variables();
    let k = vars.iter().find(|v| v.name == "stiffness").unwrap();
    let f = vars.iter().find(|v| v.name == "force").unwrap();
    assert_eq!(k.depends_on, f.depends_on);
    assert!(A::info()
        .units
        .iter()
        .any(|u| u.name == "N/m" && u.kg == 1 && u.s == -2));
    assert!(!Hill1D::info().units.iter().any(|u| u.name == "N/m"));
    // The GUIDs of the two full FMUs since the `length` input declares its
    // own range (LENGTH_RANGE, [1e-5, 100] m, in place of L0's) and, for
    // HillMuscleFE, since the `radial_grading` parameter and its default 0.6
    // and the tunable `threads` parameter: a new interface, a new GUID.
    // Pinned so that an unintended interface change shows here.
    assert_eq!(guid::<Hill1D>(), "{7c808cb6-7bd7-8378-be77-25860ec4a448}");
    #[cfg(feature = "fe")]
    assert_eq!(guid::<HillFE>(), "{1f07a647-ef8f-8b5c-9be1-9ff36717f4cd}");
}

/// `HillMusculotendon1D`: its table follows the FMI 2.0 rules, its committed
/// modelDescription is the generator's output, the `length` input (the path)
/// starts at the rest path L_TS + L0 cos(alpha0), the angles are in rad, and
/// its GUID is pinned (an unintended interface change shows here).
#[test]
fn the_musculotendon_model_description_is_committed_and_valid() {
    use hill_muscle::fmi2::{Model, VarType};
    use hill_muscle::fmus::musculotendon1d::Musculotendon;
    validate_table::<Musculotendon>().expect("HillMusculotendon1D follows FMI 2.0 rules");
    let xml = model_description::<Musculotendon>();
    assert!(xml.contains(&format!("guid=\"{}\"", guid::<Musculotendon>())));
    check_committed("HillMusculotendon1D", &xml);
    let vars = Musculotendon::variables();
    let start = |name: &str| match vars.iter().find(|v| v.name == name).unwrap().ty {
        VarType::Real { start, .. } => start.unwrap(),
        _ => panic!("{name} is not Real"),
    };
    assert_eq!(
        start("length"),
        start("tendon_slack_length") + start("L0") * start("pennation_angle").cos()
    );
    assert!(Musculotendon::info().units.iter().any(|u| u.name == "rad"));
    for name in ["pennation", "pennation_angle"] {
        let v = vars.iter().find(|v| v.name == name).unwrap();
        assert!(
            matches!(
                v.ty,
                VarType::Real {
                    unit: Some("rad"),
                    ..
                }
            ),
            "{name}"
        );
    }
    assert_eq!(
        guid::<Musculotendon>(),
        "{a3d0017f-7000-8312-9bbe-7628b8c25047}"
    );
}
