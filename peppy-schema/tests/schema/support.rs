//! Helpers shared by the test modules.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use peppy_schema::{
    Code, Diagnostic, Diagnostics, LauncherDoc, NodeDoc, RepoOptions, StackCheck, check_launcher,
};

/// Parses a node document named `peppy.json5`.
pub(crate) fn parse_node(text: &str) -> Result<(NodeDoc, Diagnostics), Diagnostics> {
    NodeDoc::parse("peppy.json5", text)
}

/// A node document that must be valid.
pub(crate) fn node_ok(text: &str) -> (NodeDoc, Diagnostics) {
    match parse_node(text) {
        Ok(v) => v,
        Err(e) => panic!("expected a valid node document, got:\n{e}"),
    }
}

/// A node document that must be invalid: all its findings.
pub(crate) fn node_err(text: &str) -> Diagnostics {
    match parse_node(text) {
        Ok(_) => panic!("expected errors, the document was accepted:\n{text}"),
        Err(e) => e,
    }
}

/// Codes of all findings, sorted by position.
pub(crate) fn codes(d: &Diagnostics) -> Vec<Code> {
    d.sorted().iter().map(|d| d.code).collect()
}

/// Codes of the errors only, sorted by position.
pub(crate) fn error_codes(d: &Diagnostics) -> Vec<Code> {
    d.sorted()
        .iter()
        .filter(|d| d.is_error())
        .map(|d| d.code)
        .collect()
}

/// Every finding with `code`, sorted by position.
pub(crate) fn all(d: &Diagnostics, code: Code) -> Vec<&Diagnostic> {
    d.sorted().into_iter().filter(|x| x.code == code).collect()
}

/// The one finding with `code`.
pub(crate) fn one(d: &Diagnostics, code: Code) -> &Diagnostic {
    let found = all(d, code);
    assert_eq!(
        found.len(),
        1,
        "expected exactly one {code}, found {}:\n{d}",
        found.len()
    );
    found[0]
}

/// 1-based line and column (in characters) of the first occurrence of `needle`.
pub(crate) fn pos(text: &str, needle: &str) -> (usize, usize) {
    pos_nth(text, needle, 0)
}

/// 1-based line and column of the `n`th (0-based) occurrence of `needle`.
pub(crate) fn pos_nth(text: &str, needle: &str, n: usize) -> (usize, usize) {
    let (offset, _) = text
        .match_indices(needle)
        .nth(n)
        .unwrap_or_else(|| panic!("`{needle}` occurs fewer than {} times", n + 1));
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, text[line_start..offset].chars().count() + 1)
}

/// Line and column of a located diagnostic.
pub(crate) fn lc(d: &Diagnostic) -> (usize, usize) {
    let at = d
        .line_col()
        .unwrap_or_else(|| panic!("diagnostic is not located: {d}"));
    (at.line, at.column)
}

/// The key path, which every located diagnostic here has.
pub(crate) fn key(d: &Diagnostic) -> &str {
    d.key_path
        .as_deref()
        .unwrap_or_else(|| panic!("no key path: {d}"))
}

/// The help text, which the diagnostic must have.
pub(crate) fn help(d: &Diagnostic) -> &str {
    d.help.as_deref().unwrap_or_else(|| panic!("no help: {d}"))
}

/// Asserts code, key path and position (the first occurrence of `needle` in `text`).
#[track_caller]
pub(crate) fn assert_at(d: &Diagnostic, code: Code, key_path: &str, text: &str, needle: &str) {
    assert_eq!(d.code, code, "{d}");
    assert_eq!(key(d), key_path, "{d}");
    assert_eq!(lc(d), pos(text, needle), "{d} should point at `{needle}`");
}

/// A temporary directory tree of documents.
pub(crate) struct Tree {
    dir: tempfile::TempDir,
}

impl Tree {
    pub(crate) fn new() -> Tree {
        Tree {
            dir: tempfile::tempdir().expect("temp dir"),
        }
    }

    /// The root, canonical (so it compares equal to paths the crate canonicalises).
    pub(crate) fn root(&self) -> PathBuf {
        std::fs::canonicalize(self.dir.path()).expect("canonical temp dir")
    }

    /// `root/rel`.
    pub(crate) fn path(&self, rel: &str) -> PathBuf {
        self.root().join(rel)
    }

    /// Writes `text` to `root/rel`, creating directories.
    pub(crate) fn write(&self, rel: &str, text: &str) -> PathBuf {
        let p = self.path(rel);
        std::fs::create_dir_all(p.parent().expect("parent")).expect("mkdir");
        std::fs::write(&p, text).expect("write");
        p
    }

    /// Creates `root/rel` as a directory.
    pub(crate) fn mkdir(&self, rel: &str) -> PathBuf {
        let p = self.path(rel);
        std::fs::create_dir_all(&p).expect("mkdir");
        p
    }
}

/// Repository options that ignore the process environment.
pub(crate) fn options(explicit: Vec<PathBuf>) -> RepoOptions {
    RepoOptions {
        explicit,
        env: Some(OsString::new()),
        last: Vec::new(),
    }
}

/// A node document: `depends_on`, `interfaces` and extra `execution` keys are spliced in.
pub(crate) fn node_text(
    name: &str,
    depends_on: &str,
    interfaces: &str,
    execution_extra: &str,
) -> String {
    format!(
        r#"{{
  peppy_schema: "node_v1",
  manifest: {{
    name: "{name}",
    tag: "v1",
    depends_on: {{ {depends_on} }},
  }},
  interfaces: {{ {interfaces} }},
  execution: {{ language: "rust", run_cmd: ["./{name}"], {execution_extra} }},
}}
"#
    )
}

/// An interface document with the given `interfaces` body.
pub(crate) fn interface_text(name: &str, tag: &str, body: &str) -> String {
    format!(
        r#"{{
  peppy_schema: "interface_v1",
  manifest: {{ name: "{name}", tag: "{tag}" }},
  interfaces: {{ {body} }},
}}
"#
    )
}

/// `/work/main/examples`.
pub(crate) fn examples_dir() -> PathBuf {
    std::fs::canonicalize(Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples"))
        .expect("examples directory")
}

/// Checks a launcher that must be valid.
pub(crate) fn stack_ok(path: &Path) -> StackCheck {
    match check_launcher(path, &options(Vec::new())) {
        Ok(s) => s,
        Err(e) => panic!("expected `{}` to check, got:\n{e}", path.display()),
    }
}

/// Checks a launcher that must be invalid.
pub(crate) fn stack_err(path: &Path) -> Diagnostics {
    match check_launcher(path, &options(Vec::new())) {
        Ok(_) => panic!("expected `{}` to fail", path.display()),
        Err(e) => e,
    }
}

/// Every finding of a launcher that must be refused.
pub(crate) fn launcher_err(text: &str) -> Diagnostics {
    match LauncherDoc::parse("stack.json5", text) {
        Ok(_) => panic!("expected errors:\n{text}"),
        Err(e) => e,
    }
}

/// A launcher that must be valid, without warnings.
pub(crate) fn launcher_ok(text: &str) -> LauncherDoc {
    match LauncherDoc::parse("stack.json5", text) {
        Ok((l, w)) => {
            assert!(w.is_empty(), "{w}");
            l
        }
        Err(e) => panic!("expected a valid launcher, got:\n{e}"),
    }
}
