//! The committed `modelDescription/*.xml` files are exactly what the variable
//! tables generate, so every interface change shows in review. Update them with
//! `cargo run -p fmu_build -- --update-model-descriptions`.

use hill_muscle::fmi2::model_description::{guid, model_description, validate_table};
use hill_muscle::fmus::hill1d::Hill1D;

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
