//! fmu_build as a command: an invalid scene file is rejected, naming the
//! problem, before anything is built; `--check` accepts a valid one.

use std::fs;
use std::process::Command;

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

#[test]
fn the_build_tool_rejects_an_invalid_scene_without_building() {
    let dir = std::env::temp_dir().join(format!("fmu_build_test_{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    fs::write(
        &bad,
        PASSIVE.replace(r#"outputs = ["force"]"#, r#"outputs = ["see_stretch"]"#),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_fmu_build"))
        .args([
            "--scene",
            bad.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("bad.toml is invalid")
            && stderr.contains("output 'see_stretch' needs the contractile element"),
        "{stderr}"
    );
    assert!(!dir.join("P.fmu").exists());
    let good = dir.join("good.toml");
    fs::write(&good, PASSIVE).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_fmu_build"))
        .args(["--check", good.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("scene P (1d variant) is valid: 9 variables"),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    fs::remove_dir_all(&dir).unwrap();
}
