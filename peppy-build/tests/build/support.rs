use std::path::{Path, PathBuf};

/// `peppy-build/tests/fixtures`, canonical.
pub(crate) fn fixtures() -> PathBuf {
    std::fs::canonicalize(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures"))
        .expect("fixtures directory")
}

/// Every fixture node directory, sorted.
pub(crate) fn fixture_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(fixtures())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("peppy.json5").is_file())
        .collect();
    dirs.sort();
    dirs
}

/// A config for the node in `dir`, independent of the environment.
pub(crate) fn config(dir: &Path) -> peppy_build::Config {
    let mut c = peppy_build::Config::new();
    c.manifest_dir(dir).repositories_env(None);
    c
}

/// Generated code as a stable text: machine paths replaced.
pub(crate) fn redact(text: &str) -> String {
    text.replace(&fixtures().display().to_string(), "[fixtures]")
}
