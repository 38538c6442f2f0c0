//! Pairing documents (`peppy_schema: "pairing/v1"`): the whole
//! conversation between two node instances that pair one to one, as a flat
//! list of topics, each emitted by one of two named roles and consumed by
//! the other.
//!
//! peppy reads and checks pairings (so a repository can hold them and a
//! node's pairing slots can later resolve against them); it does not run
//! them yet.

use std::sync::Arc;

use crate::diag::{Code, Diagnostics, did_you_mean, list};
use crate::entries::{EntryKind, TOPIC_KEYS, TopicDecl, check_unique, topic_fields};
use crate::interface::parse_manifest;
use crate::json::{Node, Value};
use crate::names::check_name;
use crate::node::Identity;
use crate::read::{Loc, Obj, Reader, index};
use crate::source::SourceFile;

/// A parsed, validated `pairing/v1` document.
#[derive(Debug, Clone)]
pub struct PairingDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// sha256 of the file's exact bytes (lowercase hex): its revision, what
    /// a `sha256` pin on a pairing slot names.
    pub sha256: String,
    /// `manifest.name` / `manifest.tag`.
    pub identity: Identity,
    /// Where `manifest.name` is.
    pub name_loc: Loc,
    /// `manifest.labels`.
    pub labels: Vec<String>,
    /// The two roles, in the order written; distinct, neither `_`.
    pub roles: [PairingRole; 2],
    /// The topics, in the order written; at least one, names unique across
    /// the list whichever role emits them.
    pub topics: Vec<PairingTopic>,
}

/// One of a pairing's two roles.
#[derive(Debug, Clone)]
pub struct PairingRole {
    /// The role's name (the name rule).
    pub name: String,
    /// Where it is written in `roles`.
    pub loc: Loc,
}

/// One topic of a pairing: emitted by the role `emitted_by`, consumed by the
/// other one.
#[derive(Debug, Clone)]
pub struct PairingTopic {
    /// The emitting role, one of [`PairingDoc::roles`].
    pub emitted_by: String,
    /// Name, QoS profile (default `standard`) and message format, read as a
    /// contract's topic is (`decl.loc` is where the name is).
    pub decl: TopicDecl,
    /// Where `emitted_by` is written.
    pub emitted_by_loc: Loc,
}

impl PairingDoc {
    /// The role names, in the order written.
    pub fn role_names(&self) -> [&str; 2] {
        [&self.roles[0].name, &self.roles[1].name]
    }

    /// Whether `role` is one of the two roles.
    pub fn has_role(&self, role: &str) -> bool {
        self.roles.iter().any(|r| r.name == role)
    }

    /// The role opposite `role`, or `None` when `role` is not one of the two.
    pub fn counterpart(&self, role: &str) -> Option<&str> {
        match self.role_names() {
            [a, b] if a == role => Some(b),
            [a, b] if b == role => Some(a),
            _ => None,
        }
    }

    /// The topics `role` emits (the other role consumes them), in order.
    pub fn emitted_by<'a>(&'a self, role: &'a str) -> impl Iterator<Item = &'a PairingTopic> {
        self.topics.iter().filter(move |t| t.emitted_by == role)
    }

    /// The topic named `name`.
    pub fn topic(&self, name: &str) -> Option<&PairingTopic> {
        self.topics.iter().find(|t| t.decl.name == name)
    }
}

/// The top-level keys of a pairing.
const KEYS: &[&str] = &["peppy_schema", "manifest", "roles", "topics"];

/// Top-level keys a contract has and a pairing refuses by design: they get
/// their own error rather than an unknown-key did-you-mean.
const NOT_IN_PAIRINGS: &[&str] = &["services", "actions"];

/// The role name reserved as a link key (the `_` default link), which a
/// role would collide with.
const RESERVED_ROLE: &str = "_";

pub(crate) fn parse_pairing(
    file: &Arc<SourceFile>,
    sha256: String,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<PairingDoc> {
    let mut r = Reader::new(file, diags);
    let Value::Object(members) = &root.value else {
        // Not an object: let the common reader say so.
        r.object(root, "", KEYS);
        return None;
    };
    for m in members {
        if NOT_IN_PAIRINGS.contains(&m.key.as_str()) {
            r.error_help(
                Code::PairingTopicsOnly,
                m.key_span,
                &m.key,
                format!("`{}` in a pairing: pairings are topics-only", m.key),
                "each of a pairing's topics is `emitted_by` one role and consumed by the other; \
                 offer services and actions through a contract (`contract/v1`) instead",
            );
        } else if !KEYS.contains(&m.key.as_str()) {
            r.unknown_key(m, "", KEYS);
        }
    }
    let obj = Obj {
        node: root,
        members,
        path: String::new(),
    };
    let (identity, labels) = match r.required(&obj, "manifest") {
        Some(m) => parse_manifest(&mut r, m),
        None => (None, Vec::new()),
    };
    let roles = parse_roles(&mut r, &obj);
    let topics = parse_topics(&mut r, &obj, roles.as_ref());
    if r.diags.has_errors() {
        return None;
    }
    let (identity, name_loc) = identity?;
    Some(PairingDoc {
        file: file.clone(),
        sha256,
        identity,
        name_loc,
        labels,
        roles: roles?,
        topics: topics?,
    })
}

/// `roles`: exactly two names, distinct, neither `_`. `None` unless all of
/// that holds (topics then go unchecked against the roles, rather than
/// reporting an error per topic for one mistake in `roles`).
fn parse_roles(r: &mut Reader<'_>, obj: &Obj<'_>) -> Option<[PairingRole; 2]> {
    let node = r.required(obj, "roles")?;
    let items = r.array(node, "roles")?;
    let mut roles: Vec<PairingRole> = Vec::with_capacity(2);
    let mut ok = true;
    for (i, item) in items.iter().enumerate() {
        let path = index("roles", i);
        let Some(name) = r.string(item, &path) else {
            ok = false;
            continue;
        };
        if let Err(why) = check_name(&name) {
            r.error(
                Code::InvalidName,
                item.span,
                &path,
                format!("invalid role `{name}`: {why}"),
            );
            ok = false;
        } else if name == RESERVED_ROLE {
            r.error_help(
                Code::ReservedRole,
                item.span,
                &path,
                "the role `_` is reserved",
                "`_` is the reserved default link key; name the role after its side of the conversation",
            );
            ok = false;
        } else if let Some(first) = roles.iter().find(|p| p.name == name) {
            let at = first.loc.file.line_col(first.loc.span.start);
            r.error_help(
                Code::DuplicateRole,
                item.span,
                &path,
                format!("duplicate role `{name}`"),
                format!(
                    "`{name}` is already the role at line {}, column {}; a pairing's two roles are distinct",
                    at.line, at.column
                ),
            );
            ok = false;
        } else {
            let loc = r.loc(item.span, &path);
            roles.push(PairingRole { name, loc });
        }
    }
    if items.len() != 2 {
        r.error_help(
            Code::PairingRoleCount,
            node.span,
            "roles",
            format!(
                "a pairing declares exactly two roles, found {}",
                items.len()
            ),
            "name the two sides of the conversation, e.g. `roles: [\"leader\", \"follower\"]`",
        );
        return None;
    }
    if !ok {
        return None;
    }
    <[PairingRole; 2]>::try_from(roles).ok()
}

/// `topics`: a non-empty list of `{ emitted_by, name, qos_profile?,
/// message_format? }`, names unique across the list.
fn parse_topics(
    r: &mut Reader<'_>,
    obj: &Obj<'_>,
    roles: Option<&[PairingRole; 2]>,
) -> Option<Vec<PairingTopic>> {
    let node = r.required(obj, "topics")?;
    let items = r.array(node, "topics")?;
    if items.is_empty() {
        r.error_help(
            Code::EmptyPairing,
            node.span,
            "topics",
            "a pairing declares no topics",
            "declare at least one topic; a role may emit none (a one-directional pair)",
        );
        return None;
    }
    let mut topics = Vec::with_capacity(items.len());
    let mut ok = true;
    for (i, item) in items.iter().enumerate() {
        match parse_topic(r, item, &index("topics", i), roles) {
            Some(t) => topics.push(t),
            None => ok = false,
        }
    }
    // One namespace whichever role emits: a node's generated module per
    // pairing topic is named by the topic alone.
    check_unique(
        r,
        EntryKind::Topic,
        topics.iter().map(|t| (t.decl.name.as_str(), &t.decl.loc)),
    );
    ok.then_some(topics)
}

fn parse_topic(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    roles: Option<&[PairingRole; 2]>,
) -> Option<PairingTopic> {
    let keys: Vec<&str> = std::iter::once("emitted_by")
        .chain(TOPIC_KEYS.iter().copied())
        .collect();
    let obj = r.object(node, path, &keys)?;
    let emitted_by = r.required(&obj, "emitted_by").and_then(|n| {
        let epath = obj.path_of("emitted_by");
        let role = r.string(n, &epath)?;
        if let Some(roles) = roles
            && !roles.iter().any(|p| p.name == role)
        {
            let names = roles.iter().map(|p| p.name.as_str());
            let help = match did_you_mean(&role, names.clone()) {
                Some(s) => format!("did you mean `{s}`? roles: {}", list(names)),
                None => format!("roles: {}", list(names)),
            };
            r.error_help(
                Code::UnknownRole,
                n.span,
                &epath,
                format!("`emitted_by` names `{role}`, which is not one of the pairing's roles"),
                help,
            );
            return None;
        }
        Some((role, r.loc(n.span, &epath)))
    });
    let decl = topic_fields(r, &obj);
    let (emitted_by, emitted_by_loc) = emitted_by?;
    Some(PairingTopic {
        emitted_by,
        decl: decl?,
        emitted_by_loc,
    })
}
