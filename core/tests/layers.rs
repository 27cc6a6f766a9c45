//! The library's modules form layers read as the pipeline (see docs/ARCHITECTURE.md): a module
//! may use only the modules listed before it. This test reads the sources, so a new import that
//! points down the pipeline (and would make a cycle possible) fails here, naming the file.

use std::path::{Path, PathBuf};

/// Foundation first, then the pipeline.
const LAYERS: &[&str] = &[
    "problem", "assets", "io", "image", "color", "geometry", // foundation
    "codebook", "family", "builtin", "render", "synth", "pose", "detect", "train", "eval",
];

fn sources(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for entry in std::fs::read_dir(path).unwrap() {
            sources(&entry.unwrap().path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

fn is_test_file(path: &Path) -> bool {
    let name = path.file_stem().unwrap().to_string_lossy();
    name == "tests"
        || name.ends_with("_tests")
        || path.components().any(|c| c.as_os_str() == "tests")
}

/// The `crate::module` paths a file's non-test code names (comments and test modules skipped).
fn uses(text: &str) -> Vec<String> {
    let code = text
        .find("#[cfg(test)]")
        .or_else(|| text.find("#[cfg(all(test"))
        .map_or(text, |end| &text[..end]);
    let mut found = Vec::new();
    for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
        for (at, _) in line.match_indices("crate::") {
            let before = line[..at].chars().last();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                continue; // e.g. `tagsmith_crate::`
            }
            let name: String = line[at + 7..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            found.push(name);
        }
    }
    found
}

#[test]
fn modules_import_only_the_layers_before_them() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut violations = Vec::new();
    for (rank, module) in LAYERS.iter().enumerate() {
        let dir = src.join(module);
        let mut files = Vec::new();
        if dir.is_dir() {
            sources(&dir, &mut files);
        } else {
            files.push(src.join(format!("{module}.rs")));
        }
        assert!(
            files.iter().all(|f| f.exists()),
            "module {module} not found"
        );
        for file in files.iter().filter(|f| !is_test_file(f)) {
            let text = std::fs::read_to_string(file).unwrap();
            for used in uses(&text) {
                let Some(used_rank) = LAYERS.iter().position(|l| *l == used) else {
                    continue; // a re-export at the crate root, e.g. `crate::Family`
                };
                if used_rank > rank {
                    violations.push(format!(
                        "{}: {module} uses crate::{used}, a later layer",
                        file.strip_prefix(&src).unwrap().display()
                    ));
                }
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

#[test]
fn every_module_of_the_crate_is_in_a_layer() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    for line in lib.lines() {
        if let Some(name) = line.trim().strip_prefix("pub mod ") {
            let name = name.trim_end_matches(';');
            assert!(
                LAYERS.contains(&name),
                "lib.rs declares {name}, which has no layer"
            );
        }
    }
}

#[test]
fn the_checker_sees_a_downward_import() {
    let text =
        "use crate::family::Family;\n// crate::eval in a comment\n#[cfg(test)]\nuse crate::eval;";
    assert_eq!(uses(text), ["family"]);
}
