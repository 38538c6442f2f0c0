//! Walking a spanned tree with typed getters that report located errors.
//!
//! Every document parser is written against [`Reader`]: it asks for the
//! shape it expects and gets `None` plus a diagnostic when the document has
//! another shape, so one pass collects every error of a document.

use std::sync::Arc;

use crate::diag::{Code, Diagnostics, did_you_mean, list};
use crate::json::{Member, Node, Number, Value};
use crate::source::{SourceFile, Span};

/// Spellings of the legacy `schema_version: 1` form, so that a current
/// document using one gets pointed at its replacement.
const LEGACY_KEYS: &[(&str, &str)] = &[
    ("local_id", "link_id"),
    ("local_node_id", "link_id"),
    ("schema_version", "peppy_schema"),
    ("process", "execution"),
    ("add_cmd", "build_cmd"),
    ("start_cmd", "run_cmd"),
];

/// `parent.key`, or `key` at the root.
pub(crate) fn join(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

/// `parent[i]`.
pub(crate) fn index(parent: &str, i: usize) -> String {
    format!("{parent}[{i}]")
}

pub(crate) use crate::loc::Loc;

/// An object being read, with its key path.
pub(crate) struct Obj<'n> {
    pub(crate) node: &'n Node,
    pub(crate) members: &'n [Member],
    pub(crate) path: String,
}

impl<'n> Obj<'n> {
    pub(crate) fn get(&self, key: &str) -> Option<&'n Node> {
        self.members.iter().find(|m| m.key == key).map(|m| &m.value)
    }

    pub(crate) fn member(&self, key: &str) -> Option<&'n Member> {
        self.members.iter().find(|m| m.key == key)
    }

    pub(crate) fn path_of(&self, key: &str) -> String {
        join(&self.path, key)
    }
}

pub(crate) struct Reader<'a> {
    pub(crate) file: &'a Arc<SourceFile>,
    pub(crate) diags: &'a mut Diagnostics,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(file: &'a Arc<SourceFile>, diags: &'a mut Diagnostics) -> Self {
        Reader { file, diags }
    }

    pub(crate) fn loc(&self, span: Span, path: &str) -> Loc {
        Loc {
            file: self.file.clone(),
            span,
            key_path: path.to_string(),
        }
    }

    pub(crate) fn error(&mut self, code: Code, span: Span, path: &str, message: impl Into<String>) {
        let d = self.loc(span, path).error(code, message);
        self.diags.push(d);
    }

    /// Checks a key of `links` (or, `binding`, of `launcher_v1`'s
    /// `bindings`) by the one link-key rule
    /// ([`check_link_key`](crate::names::check_link_key)), reporting why
    /// not; true when it is one.
    pub(crate) fn link_key(&mut self, key: &str, span: Span, path: &str, binding: bool) -> bool {
        let word = if binding { "binding key" } else { "link key" };
        match crate::names::check_link_key(key) {
            Ok(()) => true,
            Err(crate::names::LinkKeyError::Reserved) => {
                let (code, help) = if binding {
                    (
                        Code::ReservedBindingKey,
                        "use a slot's link_id to pin it, or any other label to feed a from_any slot",
                    )
                } else {
                    (
                        Code::LinkSentinelKey,
                        "a link key is the link_id of one of the node's slots",
                    )
                };
                self.error_help(code, span, path, format!("{word} `_` is reserved"), help);
                false
            }
            Err(crate::names::LinkKeyError::Invalid(why)) => {
                self.error(
                    Code::InvalidName,
                    span,
                    path,
                    format!("invalid {word} `{key}`: {why}"),
                );
                false
            }
        }
    }

    pub(crate) fn error_help(
        &mut self,
        code: Code,
        span: Span,
        path: &str,
        message: impl Into<String>,
        help: impl Into<String>,
    ) {
        let d = self.loc(span, path).error(code, message).with_help(help);
        self.diags.push(d);
    }

    pub(crate) fn warn_help(
        &mut self,
        code: Code,
        span: Span,
        path: &str,
        message: impl Into<String>,
        help: impl Into<String>,
    ) {
        let d = self.loc(span, path).warning(code, message).with_help(help);
        self.diags.push(d);
    }

    fn wrong_type(&mut self, node: &Node, path: &str, expected: &str) {
        self.error(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected {expected} for `{}`, found {}",
                display_path(path),
                node.value.kind()
            ),
        );
    }

    /// An object whose keys must all be in `allowed`; unknown keys are
    /// reported (with a did-you-mean) and otherwise ignored.
    pub(crate) fn object<'n>(
        &mut self,
        node: &'n Node,
        path: &str,
        allowed: &[&str],
    ) -> Option<Obj<'n>> {
        let Value::Object(members) = &node.value else {
            self.wrong_type(node, path, "an object");
            return None;
        };
        for m in members {
            if !allowed.contains(&m.key.as_str()) {
                self.unknown_key(m, path, allowed);
            }
        }
        Some(Obj {
            node,
            members,
            path: path.to_string(),
        })
    }

    pub(crate) fn unknown_key(&mut self, m: &Member, parent: &str, allowed: &[&str]) {
        let legacy = LEGACY_KEYS
            .iter()
            .find(|(old, new)| *old == m.key && allowed.contains(new));
        let help = match legacy
            .map(|(_, new)| *new)
            .or_else(|| did_you_mean(&m.key, allowed.iter().copied()))
        {
            Some(s) => format!(
                "did you mean `{s}`? accepted keys here: {}",
                list(allowed.iter().copied())
            ),
            None => format!("accepted keys here: {}", list(allowed.iter().copied())),
        };
        let where_ = if parent.is_empty() {
            "at the top level".to_string()
        } else {
            format!("in `{}`", display_path(parent))
        };
        self.error_help(
            Code::UnknownKey,
            m.key_span,
            &join(parent, &m.key),
            format!("unknown key `{}` {where_}", m.key),
            help,
        );
    }

    /// The value of a required key, or a `MissingKey` error at the object.
    pub(crate) fn required<'n>(&mut self, obj: &Obj<'n>, key: &str) -> Option<&'n Node> {
        let found = obj.get(key);
        if found.is_none() {
            let where_ = if obj.path.is_empty() {
                "at the top level".to_string()
            } else {
                format!("in `{}`", display_path(&obj.path))
            };
            self.error(
                Code::MissingKey,
                Span::new(obj.node.span.start, obj.node.span.start + 1),
                &obj.path,
                format!("missing required key `{key}` {where_}"),
            );
        }
        found
    }

    pub(crate) fn string(&mut self, node: &Node, path: &str) -> Option<String> {
        match &node.value {
            Value::String(s) => Some(s.clone()),
            _ => {
                self.wrong_type(node, path, "a string");
                None
            }
        }
    }

    pub(crate) fn bool(&mut self, node: &Node, path: &str) -> Option<bool> {
        match &node.value {
            Value::Bool(b) => Some(*b),
            _ => {
                self.wrong_type(node, path, "`true` or `false`");
                None
            }
        }
    }

    pub(crate) fn array<'n>(&mut self, node: &'n Node, path: &str) -> Option<&'n [Node]> {
        match &node.value {
            Value::Array(items) => Some(items),
            _ => {
                self.wrong_type(node, path, "an array");
                None
            }
        }
    }

    pub(crate) fn string_list(&mut self, node: &Node, path: &str) -> Option<Vec<String>> {
        let items = self.array(node, path)?;
        let mut out = Vec::with_capacity(items.len());
        let mut ok = true;
        for (i, item) in items.iter().enumerate() {
            match self.string(item, &index(path, i)) {
                Some(s) => out.push(s),
                None => ok = false,
            }
        }
        ok.then_some(out)
    }

    /// A non-negative integer no larger than `max`.
    pub(crate) fn uint(&mut self, node: &Node, path: &str, max: u64) -> Option<u64> {
        match &node.value {
            Value::Number(Number::Int(i)) if *i >= 0 && *i <= max as i128 => Some(*i as u64),
            Value::Number(_) => {
                self.error(
                    Code::InvalidValue,
                    node.span,
                    path,
                    format!(
                        "`{}` must be an integer from 0 to {max}",
                        display_path(path)
                    ),
                );
                None
            }
            _ => {
                self.wrong_type(node, path, "an integer");
                None
            }
        }
    }
}

/// Key paths as shown to users (the root is `the document`).
pub(crate) fn display_path(path: &str) -> &str {
    if path.is_empty() { "(document)" } else { path }
}
