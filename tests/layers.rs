//! The library's layers import only downward (docs/ARCHITECTURE.md): the law
//! and the muscles know nothing of FMI, the FMI layer nothing of muscles,
//! and no two layers import each other. Read from the sources: every
//! `crate::<module>` outside a comment counts as an import.

use std::fs;
use std::path::Path;

/// Each top-level module of `src/` and the modules it may import.
const ALLOWED: &[(&str, &[&str])] = &[
    ("law", &[]),
    ("step_control", &[]),
    ("specimen", &[]),
    ("outputs", &[]),
    ("muscle1d", &["law", "step_control", "specimen", "outputs"]),
    ("fe", &["law", "step_control", "specimen", "outputs"]),
    ("fmi2", &[]),
    ("scene", &["fmi2", "law"]),
    (
        "fmus",
        &[
            "fmi2",
            "scene",
            "muscle1d",
            "fe",
            "law",
            "step_control",
            "specimen",
        ],
    ),
];

/// Every `.rs` file under `path` (or `path` itself).
fn sources(path: &Path, out: &mut Vec<std::path::PathBuf>) {
    if path.is_dir() {
        for entry in fs::read_dir(path).unwrap() {
            sources(&entry.unwrap().path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The `crate::<module>` names a source file uses outside comments.
fn imports(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            let after = &rest[at + "crate::".len()..];
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            // `$crate::` in a macro is the crate seen from outside.
            if !rest[..at].ends_with('$') {
                found.push(name);
            }
            rest = after;
        }
    }
    found
}

#[test]
fn layers_import_only_downward() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut problems = Vec::new();
    for (layer, allowed) in ALLOWED {
        let dir = src.join(layer);
        let root = if dir.is_dir() {
            dir
        } else {
            src.join(format!("{layer}.rs"))
        };
        assert!(root.exists(), "no module {layer} in src/");
        let mut files = Vec::new();
        sources(&root, &mut files);
        for file in files {
            let text = fs::read_to_string(&file).unwrap();
            for name in imports(&text) {
                if name != *layer && !allowed.contains(&name.as_str()) {
                    problems.push(format!("{} imports crate::{name}", file.display()));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

/// Every top-level module is in [`ALLOWED`], so a new one gets a place.
#[test]
fn every_module_has_a_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    for entry in fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if name == "lib" {
            continue;
        }
        assert!(
            ALLOWED.iter().any(|(l, _)| *l == name),
            "src/{name} has no layer in tests/layers.rs"
        );
    }
}
