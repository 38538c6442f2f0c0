//! Rust names for document names: field identifiers, module names and
//! generated type names, plus the registries that report two things
//! claiming one name.

use std::collections::HashMap;

use peppy_schema::names::{NOT_RAW, is_rust_keyword};
pub(crate) use peppy_schema::names::{consumed_module, module, nested_type, type_prefix};
use peppy_schema::{Code, Diagnostic, Diagnostics, Loc};
use proc_macro2::{Ident, Span};

/// An identifier from text the schema already validated. Anything that
/// still is not an identifier becomes `__invalid` (and cannot compile)
/// rather than a panic.
pub(crate) fn ident(s: &str) -> Ident {
    let valid = s
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && s != "_";
    if !valid {
        return Ident::new("__invalid", Span::call_site());
    }
    if NOT_RAW.contains(&s) {
        return Ident::new(&format!("{s}_"), Span::call_site());
    }
    if is_rust_keyword(s) {
        Ident::new_raw(s, Span::call_site())
    } else {
        Ident::new(s, Span::call_site())
    }
}

/// The identifier of a message or parameter field (`type` -> `r#type`).
pub(crate) fn field_ident(name: &str) -> Ident {
    ident(name)
}

/// Whether rustc's `non_snake_case` lint accepts `s` (a copy of its rule).
pub(crate) fn is_snake_case(s: &str) -> bool {
    let s = s.trim_matches('_');
    let mut allow_underscore = true;
    s.chars().all(|c| match c {
        '_' if !allow_underscore => false,
        '_' => {
            allow_underscore = false;
            true
        }
        c if c.is_uppercase() => false,
        _ => {
            allow_underscore = true;
            true
        }
    })
}

/// Where a name was claimed: what claimed it and where it is declared.
#[derive(Clone)]
struct Claim {
    what: String,
    loc: Option<Loc>,
}

/// Names claimed within one scope (a module's types, or its child
/// modules); a second claim of a name is a located error.
#[derive(Default)]
pub(crate) struct Names {
    claims: HashMap<String, Claim>,
}

impl Names {
    /// A scope whose `fixed` names belong to the generator.
    pub(crate) fn with_fixed(fixed: &[&str]) -> Self {
        let mut names = Names::default();
        for f in fixed {
            names.claims.insert(
                (*f).to_string(),
                Claim {
                    what: format!("the generated `{f}`"),
                    loc: None,
                },
            );
        }
        names
    }

    /// Claims `name` for `what` declared at `loc`. On a clash, pushes a
    /// located error (`kind` says what kind of name: "type", "module") and
    /// returns `false`.
    pub(crate) fn claim(
        &mut self,
        kind: NameKind,
        name: &str,
        what: &str,
        loc: &Loc,
        diags: &mut Diagnostics,
    ) -> bool {
        if let Some(first) = self.claims.get(name) {
            diags.push(clash(kind, name, what, loc, first));
            return false;
        }
        self.claims.insert(
            name.to_string(),
            Claim {
                what: what.to_string(),
                loc: Some(loc.clone()),
            },
        );
        true
    }
}

/// What kind of generated name clashed.
#[derive(Clone, Copy)]
pub(crate) enum NameKind {
    /// A generated struct.
    Type,
    /// A generated module.
    Module,
    /// A generated module of a node on PeppyOS's `peppylib` API, where
    /// PeppyOS names the clash `ModuleNameCollision`.
    PeppylibModule,
}

impl NameKind {
    /// The module kind for a node on `api`.
    pub(crate) fn module_of(api: peppy_schema::NodeApi) -> NameKind {
        match api {
            peppy_schema::NodeApi::Peppylib => NameKind::PeppylibModule,
            peppy_schema::NodeApi::Emit => NameKind::Module,
        }
    }
}

fn clash(kind: NameKind, name: &str, what: &str, loc: &Loc, first: &Claim) -> Diagnostic {
    let where_first = first
        .loc
        .as_ref()
        .map(|l| format!(" (declared at {})", short_location(l)))
        .unwrap_or_default();
    match kind {
        NameKind::Type => loc
            .error(
                Code::InvalidFieldName,
                format!(
                    "generated type name `{name}` of {what} collides with {}{where_first}",
                    first.what
                ),
            )
            .with_help(
                "nested structs are named after their parent and field (`header` -> `MessageHeader`, parameter group `video.encoder` -> `VideoEncoder`, array items `...Item`); rename one of the two",
            ),
        NameKind::Module | NameKind::PeppylibModule => loc
            .error(
                match kind {
                    NameKind::PeppylibModule => Code::ModuleNameCollision,
                    _ => Code::ConflictingDefinition,
                },
                format!(
                    "module name clash: {what} would be generated as module `{name}`, which {} already uses{where_first}",
                    first.what
                ),
            )
            .with_help(
                "module names are the names lowercased with every other character as `_`; rename one of the two",
            ),
    }
}

/// `file.json5:line:col` with the file name only (stable across machines).
pub(crate) fn short_location(loc: &Loc) -> String {
    let path = loc.file.path();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    let lc = loc.file.line_col(loc.span.start);
    format!("{name}:{}:{}", lc.line, lc.column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers() {
        assert_eq!(field_ident("type").to_string(), "r#type");
        assert_eq!(field_ident("header").to_string(), "header");
        assert_eq!(ident("9x").to_string(), "__invalid");
        assert_eq!(module("Video-Stream"), "video_stream");
        assert_eq!(module("self"), "self_");
        assert_eq!(module("1cam"), "_1cam");
        assert_eq!(type_prefix("video_stream_info"), "VideoStreamInfo");
        assert_eq!(type_prefix("2d"), "_2d");
        assert_eq!(nested_type("Message", "frame_id"), "MessageFrameId");
    }

    #[test]
    fn snake_case_like_rustc() {
        for ok in ["a", "frame_id", "_private", "x1", "a_b_c", "__x"] {
            assert!(is_snake_case(ok), "{ok}");
        }
        for bad in ["Frame", "frameId", "SPEC", "a__b"] {
            assert!(!is_snake_case(bad), "{bad}");
        }
    }
}
