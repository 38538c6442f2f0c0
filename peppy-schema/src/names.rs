//! What names, tags, identifiers and key segments may look like, and the
//! Rust names generated from them (the one naming rule the schema's clash
//! checks and the generator share).

/// Rust keywords (all editions, including reserved ones): a field named like
/// one is generated as a raw identifier (`type` -> `r#type`).
const RUST_KEYWORDS: &[&str] = &[
    "as", "break", "const", "continue", "crate", "else", "enum", "extern", "false", "fn", "for",
    "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return",
    "self", "Self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where",
    "while", "async", "await", "dyn", "abstract", "become", "box", "do", "final", "macro",
    "override", "priv", "typeof", "unsized", "virtual", "yield", "try", "gen",
];

/// Keywords that cannot be raw identifiers either: a module or identifier
/// named like one gets a trailing `_`.
pub const NOT_RAW: &[&str] = &["self", "Self", "super", "crate", "_"];

fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '-'
}

/// What a node, interface or instance name may contain, for messages.
pub const NAME_CHARS: &str = "ASCII letters, digits, `_` and `-`";

/// Checks a node / interface / instance name: non-empty, [`NAME_CHARS`] only.
pub fn check_name(s: &str) -> Result<(), String> {
    if s.is_empty() {
        return Err("must not be empty".into());
    }
    if let Some(c) = s.chars().find(|c| !is_name_char(*c)) {
        return Err(format!("contains {c:?}; allowed: {NAME_CHARS}"));
    }
    Ok(())
}

/// Checks a tag: a letter first, then letters, digits, `_`, `-` (no dots:
/// tags are contract labels, not versions). Legacy documents also accept
/// dotted versions such as `0.1.0`.
pub fn check_tag(s: &str, legacy: bool) -> Result<(), String> {
    if legacy {
        if s.is_empty() {
            return Err("must not be empty".into());
        }
        if let Some(c) = s.chars().find(|c| !is_name_char(*c) && *c != '.') {
            return Err(format!("contains {c:?}; allowed: {NAME_CHARS} and `.`"));
        }
        return Ok(());
    }
    let mut chars = s.chars();
    match chars.next() {
        None => return Err("must not be empty".into()),
        Some(c) if !c.is_ascii_alphabetic() => {
            return Err(format!(
                "must start with an ASCII letter (tags are contract labels like `v1`, not versions), found {c:?}"
            ));
        }
        Some(_) => {}
    }
    if let Some(c) = chars.find(|c| !is_name_char(*c)) {
        return Err(format!(
            "contains {c:?}; allowed after the first letter: {NAME_CHARS}"
        ));
    }
    Ok(())
}

/// Checks a `link_id` or binding key: [`NAME_CHARS`], at least one letter or
/// digit (it becomes part of a Rust module name).
pub fn check_link_id(s: &str) -> Result<(), String> {
    check_name(s)?;
    if !s.chars().any(|c| c.is_ascii_alphanumeric()) {
        return Err("must contain at least one ASCII letter or digit".into());
    }
    Ok(())
}

/// Why a key of a launcher's `links`, a composition's `set_links` /
/// `add_links`, or a `--link` / `--vacant-link` flag is refused: the one
/// rule for all of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkKeyError {
    /// `_`, which stands for "every slot" in PeppyOS's selectors.
    Reserved,
    /// Not a link_id ([`check_link_id`]).
    Invalid(String),
}

impl std::fmt::Display for LinkKeyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkKeyError::Reserved => {
                f.write_str("`_` is reserved; a link key is the link_id of one of the node's slots")
            }
            LinkKeyError::Invalid(why) => f.write_str(why),
        }
    }
}

/// Checks a link key: a slot's link_id ([`check_link_id`]), not `_`.
pub fn check_link_key(s: &str) -> Result<(), LinkKeyError> {
    if s == "_" {
        return Err(LinkKeyError::Reserved);
    }
    check_link_id(s).map_err(LinkKeyError::Invalid)
}

/// The longest core node name: a machine's name.
pub const MAX_CORE_NODE_NAME: usize = 63;

/// The name `--place LINK@self` gives the machine a command runs on, so no
/// core node may take it.
pub const SELF_CORE_NODE: &str = "self";

/// Checks a core node name, in a launcher's `core_nodes` or given on the
/// command line (`--place`, `--core-node`): a name ([`check_name`]) of at
/// most [`MAX_CORE_NODE_NAME`] characters that is not `self`.
pub fn check_core_node_name(s: &str) -> Result<(), String> {
    check_name(s)?;
    if s.chars().count() > MAX_CORE_NODE_NAME {
        return Err(format!("longer than {MAX_CORE_NODE_NAME} characters"));
    }
    if s == SELF_CORE_NODE {
        return Err("`self` stands for the machine a command runs on (`--place link@self`)".into());
    }
    Ok(())
}

/// Checks a topic, service or action name: it is a key segment on the wire
/// and a Rust module name, so [`NAME_CHARS`] with at least one letter or digit.
pub fn check_entry_name(s: &str) -> Result<(), String> {
    check_link_id(s)
}

/// Checks a message or parameter field name: an ASCII Rust identifier
/// (keywords are fine, they are escaped), not `_`, `self`, `Self`, `super` or
/// `crate`.
pub fn check_field_name(s: &str) -> Result<(), String> {
    let mut chars = s.chars();
    let first_ok = chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
    if !first_ok || !s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(
            "must be an ASCII identifier: a letter or `_` first, then letters, digits or `_`"
                .into(),
        );
    }
    if NOT_RAW.contains(&s) {
        return Err(format!("`{s}` cannot be a Rust identifier, even escaped"));
    }
    Ok(())
}

/// Whether `s` is a Rust keyword (so it needs `r#`).
pub fn is_rust_keyword(s: &str) -> bool {
    RUST_KEYWORDS.contains(&s)
}

/// Python's hard keywords: no identifier, module or package can be one.
const PYTHON_KEYWORDS: &[&str] = &[
    "False", "None", "True", "and", "as", "assert", "async", "await", "break", "class", "continue",
    "def", "del", "elif", "else", "except", "finally", "for", "from", "global", "if", "import",
    "in", "is", "lambda", "nonlocal", "not", "or", "pass", "raise", "return", "try", "while",
    "with", "yield",
];

/// Whether `s` is a Python keyword (the Python generator gives such a
/// name a trailing `_`; no package can be named like one).
pub fn is_python_keyword(s: &str) -> bool {
    PYTHON_KEYWORDS.contains(&s)
}

/// The Rust module name for a topic, service, action, link id or tag:
/// lowercase, every run of other characters as one `_`, a leading digit
/// prefixed with `_`. Keywords are left to the caller to escape.
pub fn module_name(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut pending_sep = false;
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            if pending_sep && !out.is_empty() {
                out.push('_');
            }
            pending_sep = false;
            out.push(c.to_ascii_lowercase());
        } else {
            pending_sep = true;
        }
    }
    if out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, '_');
    }
    out
}

/// The Rust module of a topic, service, action, link id, interface or tag:
/// [`module_name`], never empty, and `self`/`super`/`crate` with a trailing
/// `_` (other keywords become raw identifiers).
pub fn module(name: &str) -> String {
    let mut m = module_name(name);
    if m.is_empty() {
        m.push('_');
    }
    if NOT_RAW.contains(&m.as_str()) {
        m.push('_');
    }
    m
}

/// The module of an entry consumed through slot `link_id`:
/// `<link_id>_<name>`; an external topic (no slot) is its name's module.
pub fn consumed_module(link_id: Option<&str>, name: &str) -> String {
    match link_id {
        Some(link) => module(&format!("{}_{}", module_name(link), module_name(name))),
        None => module(name),
    }
}

/// The prefix of generated type names derived from an entry name
/// (`video_stream_info` -> `VideoStreamInfo`, `2d` -> `_2d`).
pub fn type_prefix(name: &str) -> String {
    let camel = upper_camel(name);
    if camel.is_empty() || camel.starts_with(|c: char| c.is_ascii_digit()) {
        format!("_{camel}")
    } else {
        camel
    }
}

/// The nested type name of field `field` under `prefix`.
pub fn nested_type(prefix: &str, field: &str) -> String {
    format!("{prefix}{}", upper_camel(field))
}

/// `UpperCamelCase` of an identifier-like name (`frame_id` -> `FrameId`).
pub fn upper_camel(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut upper = true;
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            if upper {
                out.push(c.to_ascii_uppercase());
            } else {
                out.push(c);
            }
            upper = false;
        } else {
            upper = true;
        }
    }
    out
}

/// The instance id of a test harness's mock filling slot `link_id`
/// (`mock-<link_id>`; `index` numbers the mocks of a slot of several,
/// `mock-<link_id>-<n>`). Both generators and the harness name mocks so.
pub fn mock_instance_id(link_id: &str, index: Option<usize>) -> String {
    match index {
        None => format!("mock-{link_id}"),
        Some(n) => format!("mock-{link_id}-{n}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_keys_and_core_node_names_have_one_rule_each() {
        assert_eq!(check_link_key("left_cam"), Ok(()));
        assert_eq!(check_link_key("_"), Err(LinkKeyError::Reserved));
        for bad in ["", "a/b", "a@b", "*", "--"] {
            assert!(
                matches!(check_link_key(bad), Err(LinkKeyError::Invalid(_))),
                "{bad}"
            );
        }
        assert_eq!(check_core_node_name("robot-1"), Ok(()));
        for bad in ["self", "a.b", "", &"m".repeat(64)] {
            assert!(check_core_node_name(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn tags_are_labels_not_versions() {
        for ok in ["v1", "donut", "v1-beta", "V_2"] {
            assert!(check_tag(ok, false).is_ok(), "{ok}");
        }
        for bad in ["", "0.1.0", "v1.2", "1", "-v", "v 1"] {
            assert!(check_tag(bad, false).is_err(), "{bad}");
        }
        assert!(check_tag("0.1.0", true).is_ok());
        assert!(check_tag("0.1/0", true).is_err());
    }

    #[test]
    fn names_and_fields() {
        assert!(check_name("realsense_d405").is_ok());
        assert!(check_name("zed-2i").is_ok());
        assert!(check_name("a.b").is_err());
        assert!(check_name("").is_err());
        assert!(check_link_id("__").is_err());
        assert!(check_field_name("type").is_ok());
        assert!(check_field_name("_private").is_ok());
        for bad in ["self", "_", "9lives", "foo-bar", "héllo", ""] {
            assert!(check_field_name(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn module_and_type_names() {
        assert_eq!(module_name("video-stream"), "video_stream");
        assert_eq!(module_name("Video--Stream_"), "video_stream");
        assert_eq!(module_name("1cam"), "_1cam");
        assert_eq!(module_name("v1-beta"), "v1_beta");
        assert_eq!(upper_camel("frame_id"), "FrameId");
        assert_eq!(upper_camel("header"), "Header");
        assert!(is_rust_keyword("type"));
        assert!(!is_rust_keyword("header"));
    }
}
