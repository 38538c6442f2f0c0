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

/// Generated tokens with machine paths replaced in their string literals,
/// before pretty-printing: the printer wraps a macro call's body by its
/// length, so a path redacted only afterwards would make the layout depend
/// on where the checkout lives.
pub(crate) fn redact_tokens(tokens: &proc_macro2::TokenStream) -> proc_macro2::TokenStream {
    use proc_macro2::{Group, Literal, TokenTree};
    let fixtures = fixtures().display().to_string();
    tokens
        .clone()
        .into_iter()
        .map(|tree| match tree {
            TokenTree::Group(group) => {
                let mut redacted = Group::new(group.delimiter(), redact_tokens(&group.stream()));
                redacted.set_span(group.span());
                TokenTree::Group(redacted)
            }
            TokenTree::Literal(literal) if literal.to_string().contains(&fixtures) => {
                let text = literal.to_string().replace(&fixtures, "[fixtures]");
                let mut redacted: Literal = text.parse().expect("a literal stays a literal");
                redacted.set_span(literal.span());
                TokenTree::Literal(redacted)
            }
            other => other,
        })
        .collect()
}
