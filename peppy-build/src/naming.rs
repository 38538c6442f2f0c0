//! Rust names for document names: field identifiers, module names and
//! generated type names. The registries that report two things claiming
//! one name are peppy-schema's ([`Names`]), shared with the layout.

pub(crate) use peppy_schema::layout::{NameKind, Names, short_location};
use peppy_schema::names::{NOT_RAW, is_rust_keyword};
pub(crate) use peppy_schema::names::{module, nested_type, type_prefix};
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
