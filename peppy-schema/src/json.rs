//! A JSON5 value tree in which every value and key keeps its byte span.
//!
//! Syntax is parsed by `jsonc-parser` (all of JSON5: comments, unquoted keys,
//! single quotes, hex, `Infinity`, trailing commas); this module turns its
//! AST into an owned tree and enforces the size and depth limits, so deep
//! nesting is a located error rather than a stack overflow. It also rejects
//! what that parser accepts beyond JSON5: unquoted keys that are not
//! identifiers (`foo-bar`, `123`) and raw line breaks inside strings.

use std::sync::Arc;

use jsonc_parser::ast;
use jsonc_parser::{CollectOptions, CommentCollectionStrategy, ParseOptions};

use crate::diag::{Code, Diagnostic, Diagnostics};
use crate::source::{MAX_DOCUMENT_BYTES, SourceFile, Span};

/// Objects and arrays may nest this deep; real documents use less than 15.
pub const MAX_DEPTH: usize = 64;

/// A value with its span.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Where the value is in the text.
    pub span: Span,
    /// The value.
    pub value: Value,
}

/// A JSON5 value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `null`
    Null,
    /// `true` / `false`
    Bool(bool),
    /// Any number, kept exact when it is an integer.
    Number(Number),
    /// A string.
    String(String),
    /// An array.
    Array(Vec<Node>),
    /// An object, keys in document order.
    Object(Vec<Member>),
}

/// One `key: value` of an object.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    /// The key text.
    pub key: String,
    /// Where the key is.
    pub key_span: Span,
    /// The value.
    pub value: Node,
}

/// A number as written: exact when it is an integer, else a float.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Number {
    /// An integer literal (decimal or hex) that fits 128 bits.
    Int(i128),
    /// Anything else, including `Infinity` and `NaN`.
    Float(f64),
}

impl Number {
    /// The value as a float.
    pub fn as_f64(self) -> f64 {
        match self {
            Number::Int(i) => i as f64,
            Number::Float(f) => f,
        }
    }

    fn parse(raw: &str) -> Option<Number> {
        let (negative, body) = match raw.as_bytes().first() {
            Some(b'-') => (true, &raw[1..]),
            Some(b'+') => (false, &raw[1..]),
            _ => (false, raw),
        };
        let sign = if negative { -1.0 } else { 1.0 };
        if let Some(hex) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
            let v = i128::from_str_radix(hex, 16).ok()?;
            return Some(Number::Int(if negative { -v } else { v }));
        }
        match body {
            "Infinity" => return Some(Number::Float(sign * f64::INFINITY)),
            "NaN" => return Some(Number::Float(f64::NAN)),
            _ => {}
        }
        if body.bytes().all(|b| b.is_ascii_digit())
            && !body.is_empty()
            && let Ok(v) = body.parse::<i128>()
        {
            return Some(Number::Int(if negative { -v } else { v }));
        }
        let mut text = body.to_string();
        if text.starts_with('.') {
            text.insert(0, '0');
        }
        if text.ends_with('.') {
            text.push('0');
        }
        text.parse::<f64>().ok().map(|f| Number::Float(sign * f))
    }
}

impl Value {
    /// `object`, `array`, `string`, ... for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Null => "null",
            Value::Bool(_) => "a boolean",
            Value::Number(_) => "a number",
            Value::String(_) => "a string",
            Value::Array(_) => "an array",
            Value::Object(_) => "an object",
        }
    }
}

impl Node {
    /// The member named `key`, if this is an object that has it.
    pub fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Object(members) => members.iter().find(|m| m.key == key).map(|m| &m.value),
            _ => None,
        }
    }

    /// The member (key, spans and value) named `key`, if this is an
    /// object that has it.
    pub fn get_member(&self, key: &str) -> Option<&Member> {
        match &self.value {
            Value::Object(members) => members.iter().find(|m| m.key == key),
            _ => None,
        }
    }

    /// The string value, if this is a string.
    pub fn as_str(&self) -> Option<&str> {
        match &self.value {
            Value::String(s) => Some(s),
            _ => None,
        }
    }

    /// Follows a dot-path (`video.fps`) through objects.
    pub fn find_path(&self, dot_path: &str) -> Option<&Node> {
        dot_path
            .split('.')
            .filter(|s| !s.is_empty())
            .try_fold(self, |node, key| node.get(key))
    }

    /// Converts to a `serde_json::Value` (non-finite floats become `null`).
    pub fn to_json(&self) -> serde_json::Value {
        match &self.value {
            Value::Null => serde_json::Value::Null,
            Value::Bool(b) => serde_json::Value::Bool(*b),
            Value::Number(Number::Int(i)) => {
                if let Ok(v) = i64::try_from(*i) {
                    v.into()
                } else if let Ok(v) = u64::try_from(*i) {
                    v.into()
                } else {
                    serde_json::Number::from_f64(*i as f64)
                        .map_or(serde_json::Value::Null, serde_json::Value::Number)
                }
            }
            Value::Number(Number::Float(f)) => serde_json::Number::from_f64(*f)
                .map_or(serde_json::Value::Null, serde_json::Value::Number),
            Value::String(s) => serde_json::Value::String(s.clone()),
            Value::Array(items) => items.iter().map(Node::to_json).collect(),
            Value::Object(members) => serde_json::Value::Object(
                members
                    .iter()
                    .map(|m| (m.key.clone(), m.value.to_json()))
                    .collect(),
            ),
        }
    }
}

/// Parses one JSON5 document. On success the tree is returned together with
/// any non-fatal findings (duplicate keys); syntax errors, over-deep nesting
/// and oversize input return `Err`.
pub fn parse(file: &Arc<SourceFile>) -> Result<(Node, Diagnostics), Diagnostics> {
    let text = file.text();
    if text.len() > MAX_DOCUMENT_BYTES {
        return Err(Diagnostic::error(
            Code::DocumentTooLarge,
            format!(
                "document is {} bytes; peppy documents may be at most {MAX_DOCUMENT_BYTES} bytes",
                text.len()
            ),
        )
        .at(file, Span::new(0, 0))
        .into());
    }
    let options = ParseOptions {
        allow_missing_commas: false,
        ..ParseOptions::default()
    };
    let collect = CollectOptions {
        comments: CommentCollectionStrategy::Off,
        tokens: false,
    };
    let parsed = jsonc_parser::parse_to_ast(text, &collect, &options).map_err(|e| {
        use jsonc_parser::errors::ParseErrorKind;
        let range = e.range();
        // The parser stops inside such a key with a generic message.
        if !matches!(e.kind(), ParseErrorKind::NestingDepthExceeded)
            && let Some(key) = bad_key_at(text, range.start)
        {
            return Diagnostics::from(unquoted_key_error(file, key));
        }
        let (code, message) = match e.kind() {
            ParseErrorKind::NestingDepthExceeded => (
                Code::NestingTooDeep,
                format!("objects and arrays nest deeper than {MAX_DEPTH} levels"),
            ),
            kind => (Code::Syntax, lowercase_first(&kind.to_string())),
        };
        Diagnostics::from(
            Diagnostic::error(code, format!("invalid JSON5: {message}"))
                .at(file, Span::new(range.start, range.end)),
        )
    })?;
    let Some(root) = parsed.value else {
        return Err(Diagnostic::error(
            Code::Syntax,
            "invalid JSON5: the document is empty; expected an object",
        )
        .at(file, Span::new(0, 0))
        .into());
    };
    let mut diags = Diagnostics::new();
    let node = convert(&root, file, 1, &mut diags).ok_or_else(|| diags.clone())?;
    Ok((node, diags))
}

fn lowercase_first(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_lowercase().chain(c).collect(),
        None => String::new(),
    }
}

fn span_of(range: jsonc_parser::common::Range) -> Span {
    Span::new(range.start, range.end)
}

/// Whether `key` may be written unquoted: a JSON5 identifier (ECMAScript
/// IdentifierName), with Unicode letters and digits as `char` classes them.
fn is_identifier(key: &str) -> bool {
    let mut chars = key.chars();
    chars
        .next()
        .is_some_and(|c| c == '$' || c == '_' || c.is_alphabetic())
        && chars.all(|c| c == '$' || c == '_' || c.is_alphanumeric())
}

/// The span of the word around `offset` when it is followed by `:` and is
/// not an identifier: an unquoted key the parser could not read.
fn bad_key_at(text: &str, offset: usize) -> Option<Span> {
    let in_word = |c: char| !c.is_whitespace() && !"{}[],:\"'".contains(c);
    let offset = offset.min(text.len());
    if !text.is_char_boundary(offset) {
        return None;
    }
    let start = text[..offset]
        .char_indices()
        .rev()
        .take_while(|&(_, c)| in_word(c))
        .last()
        .map_or(offset, |(i, _)| i);
    let end = text[offset..]
        .find(|c: char| !in_word(c))
        .map_or(text.len(), |i| offset + i);
    let followed_by_colon = text[end..].trim_start_matches([' ', '\t']).starts_with(':');
    (start < end && followed_by_colon && !is_identifier(&text[start..end]))
        .then(|| Span::new(start, end))
}

fn unquoted_key_error(file: &Arc<SourceFile>, key: Span) -> Diagnostic {
    let name = &file.text()[key.start..key.end];
    Diagnostic::error(
        Code::Syntax,
        format!("invalid JSON5: `{name}` is not a valid unquoted key"),
    )
    .at(file, key)
    .with_help(format!(
        "unquoted keys hold only letters, digits (not first), `_` and `$`; quote the key: `\"{name}\"`"
    ))
}

/// The offset of the first line break in a string literal's raw text that
/// is not a line continuation (a backslash right before it).
fn raw_line_break(raw: &str) -> Option<usize> {
    let bytes = raw.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            // Skips the escaped character; `\` CR LF is one continuation.
            b'\\' => {
                i += if bytes[i + 1..].starts_with(b"\r\n") {
                    3
                } else {
                    2
                }
            }
            b'\n' | b'\r' => return Some(i),
            _ => i += 1,
        }
    }
    None
}

/// Reports a string literal at `span` that holds a raw line break.
fn check_string(file: &Arc<SourceFile>, span: Span, diags: &mut Diagnostics) {
    let raw = &file.text()[span.start..span.end];
    if let Some(at) = raw_line_break(raw) {
        diags.push(
            Diagnostic::error(
                Code::Syntax,
                "invalid JSON5: a line break inside a string",
            )
            .at(file, Span::new(span.start, span.start + at))
            .with_help(
                "JSON5 strings end on the line they start: write `\\n` for a line break, or end the line with `\\` to continue the string on the next",
            ),
        );
    }
}

/// Returns `None` only when the depth limit is hit (reported in `diags`).
fn convert(
    value: &ast::Value<'_>,
    file: &Arc<SourceFile>,
    depth: usize,
    diags: &mut Diagnostics,
) -> Option<Node> {
    use jsonc_parser::common::Ranged;
    let span = span_of(value.range());
    let value = match value {
        ast::Value::NullKeyword(_) => Value::Null,
        ast::Value::BooleanLit(b) => Value::Bool(b.value),
        ast::Value::StringLit(s) => {
            check_string(file, span, diags);
            Value::String(s.value.to_string())
        }
        ast::Value::NumberLit(n) => match Number::parse(n.value) {
            Some(num) => Value::Number(num),
            None => {
                diags.push(
                    Diagnostic::error(
                        Code::Syntax,
                        format!("invalid JSON5: number `{}` is out of range", n.value),
                    )
                    .at(file, span),
                );
                Value::Null
            }
        },
        ast::Value::Array(_) | ast::Value::Object(_) if depth > MAX_DEPTH => {
            diags.push(
                Diagnostic::error(
                    Code::NestingTooDeep,
                    format!("objects and arrays nest deeper than {MAX_DEPTH} levels"),
                )
                .at(file, Span::new(span.start, span.start + 1)),
            );
            return None;
        }
        ast::Value::Array(a) => Value::Array(
            a.elements
                .iter()
                .map(|e| convert(e, file, depth + 1, diags))
                .collect::<Option<_>>()?,
        ),
        ast::Value::Object(o) => {
            let mut members: Vec<Member> = Vec::with_capacity(o.properties.len());
            for prop in &o.properties {
                let (key, key_span) = match &prop.name {
                    ast::ObjectPropName::String(s) => {
                        check_string(file, span_of(s.range), diags);
                        (s.value.to_string(), span_of(s.range))
                    }
                    ast::ObjectPropName::Word(w) => {
                        if !is_identifier(w.value) {
                            diags.push(unquoted_key_error(file, span_of(w.range)));
                        }
                        (w.value.to_string(), span_of(w.range))
                    }
                };
                let value = convert(&prop.value, file, depth + 1, diags)?;
                if let Some(first) = members.iter().find(|m| m.key == key) {
                    let first_at = file.line_col(first.key_span.start);
                    diags.push(
                        Diagnostic::error(Code::DuplicateKey, format!("duplicate key `{key}`"))
                            .at(file, key_span)
                            .with_help(format!(
                                "`{key}` is already set at line {}, column {}; keep one",
                                first_at.line, first_at.column
                            )),
                    );
                    continue;
                }
                members.push(Member {
                    key,
                    key_span,
                    value,
                });
            }
            Value::Object(members)
        }
    };
    Some(Node { span, value })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(text: &str) -> Result<(Node, Diagnostics), Diagnostics> {
        parse(&SourceFile::new("t.json5", text))
    }

    #[test]
    fn parses_all_of_json5() {
        let (node, diags) = parse_str(
            "// comment\n{ unquoted: 'single', \"q\": 0x1F, neg: -.5, inf: -Infinity, plus: +3, \
             trailing: [1, 2,], /* block */ s: 'a\\\nb', }",
        )
        .unwrap();
        assert!(diags.is_empty());
        assert_eq!(node.get("unquoted").unwrap().as_str(), Some("single"));
        assert_eq!(node.get("q").unwrap().value, Value::Number(Number::Int(31)));
        assert_eq!(
            node.get("neg").unwrap().value,
            Value::Number(Number::Float(-0.5))
        );
        assert_eq!(
            node.get("inf").unwrap().value,
            Value::Number(Number::Float(f64::NEG_INFINITY))
        );
        assert_eq!(
            node.get("plus").unwrap().value,
            Value::Number(Number::Int(3))
        );
        assert_eq!(node.get("s").unwrap().as_str(), Some("ab"));
    }

    #[test]
    fn keeps_key_order_and_spans() {
        let text = "{ b: 1, a: 2 }";
        let (node, _) = parse_str(text).unwrap();
        let Value::Object(members) = &node.value else {
            panic!("object expected")
        };
        assert_eq!(members[0].key, "b");
        assert_eq!(members[1].key, "a");
        assert_eq!(
            &text[members[1].key_span.start..members[1].key_span.end],
            "a"
        );
    }

    #[test]
    fn syntax_errors_are_located() {
        let err = parse_str("{\n  a: 1,\n  b: ,\n}").unwrap_err();
        let d = err.sorted()[0];
        assert_eq!(d.code, Code::Syntax);
        assert_eq!(d.line_col().unwrap().line, 3);
    }

    #[test]
    fn duplicate_keys_are_reported_with_first_position() {
        let (_, diags) = parse_str("{ a: 1,\n a: 2 }").unwrap();
        let d = diags.sorted()[0];
        assert_eq!(d.code, Code::DuplicateKey);
        assert!(d.help.as_deref().unwrap().contains("line 1"));
    }

    #[test]
    fn deep_nesting_is_an_error_not_a_crash() {
        for open in ["[", "{a:"] {
            let close = if open == "[" { "]" } else { "}" };
            let text = format!("{}1{}", open.repeat(100_000), close.repeat(100_000));
            let err = parse_str(&text).unwrap_err();
            assert!(err.contains(Code::NestingTooDeep), "{err}");
        }
        // Just past our own limit, but well within the parser's.
        let text = format!(
            "{}1{}",
            "[".repeat(MAX_DEPTH + 1),
            "]".repeat(MAX_DEPTH + 1)
        );
        let err = parse_str(&text).unwrap_err();
        assert!(err.contains(Code::NestingTooDeep));
        let text = format!("{}1{}", "[".repeat(MAX_DEPTH), "]".repeat(MAX_DEPTH));
        assert!(parse_str(&text).is_ok());
    }

    #[test]
    fn oversize_and_empty_documents_are_errors() {
        let big = format!("{{a: \"{}\"}}", "x".repeat(MAX_DOCUMENT_BYTES));
        assert!(
            parse_str(&big)
                .unwrap_err()
                .contains(Code::DocumentTooLarge)
        );
        assert!(
            parse_str("  // nothing\n")
                .unwrap_err()
                .contains(Code::Syntax)
        );
    }
}
