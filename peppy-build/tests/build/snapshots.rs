//! The generated code of every fixture, pretty-printed.

use crate::support::{config, fixture_dirs, redact};

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
        let text = peppy_build::pretty(&generated.tokens).expect("a Rust file");
        insta::assert_snapshot!(name, redact(&text));
    }
}
