//! The generated code of every fixture, pretty-printed.

use crate::support::{config, fixture_dirs, redact, redact_tokens};

#[test]
fn generated_code_of_every_fixture() {
    let dirs = fixture_dirs();
    assert!(dirs.len() >= 5, "{dirs:?}");
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let generated = match config(&dir).generate() {
            Ok(g) => g,
            Err(peppy_build::Error::Schema { diagnostics, .. }) => {
                panic!("fixture {name}:\n{diagnostics}")
            }
            Err(e) => panic!("fixture {name}: {e}"),
        };
        let text = peppy_build::pretty(&redact_tokens(&generated.tokens)).expect("a Rust file");
        insta::assert_snapshot!(name, redact(&text));
    }
}

/// The Python package of every fixture: each file under its path, in
/// order. The same document gives the same module tree in both languages.
#[test]
fn python_package_of_every_fixture() {
    for dir in fixture_dirs() {
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let generated = config(&dir).generate().expect("the fixture resolves");
        let files = peppy_build::python_package(&generated.check.resolved)
            .unwrap_or_else(|d| panic!("fixture {name}:\n{d}"));
        let mut text = String::new();
        for (path, body) in files {
            text.push_str(&format!("=== {} ===\n{body}\n", path.display()));
        }
        insta::assert_snapshot!(format!("python_{name}"), redact(&text));
    }
}
