//! Interface documents (`peppy_schema: "interface_v1"`, and
//! `"contract/v1"`, which holds the same content): a named contract of
//! topics, services and actions that nodes conform to.

use std::sync::Arc;

use crate::diag::{Code, Diagnostics};
use crate::document::Spelling;
use crate::entries::{
    ActionDecl, EntryKind, ServiceDecl, TopicDecl, action_name, parse_action,
    parse_contract_action, parse_list, parse_service, parse_topic, service_name, topic_name,
};
use crate::json::Node;
use crate::names::{check_name, check_tag};
use crate::node::Identity;
use crate::read::{Loc, Reader};
use crate::source::SourceFile;

/// A parsed, validated interface document.
#[derive(Debug, Clone)]
pub struct InterfaceDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// sha256 of the file's exact bytes (lowercase hex): its revision.
    pub sha256: String,
    /// `interface_v1` or `contract/v1`.
    pub spelling: Spelling,
    /// `manifest.name` / `manifest.tag`.
    pub identity: Identity,
    /// Where `manifest.name` is.
    pub name_loc: Loc,
    /// `manifest.labels`.
    pub labels: Vec<String>,
    /// `interfaces.topics`.
    pub topics: Vec<TopicDecl>,
    /// `interfaces.services`.
    pub services: Vec<ServiceDecl>,
    /// `interfaces.actions`.
    pub actions: Vec<ActionDecl>,
}

pub(crate) fn parse_interface(
    file: &Arc<SourceFile>,
    sha256: String,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<InterfaceDoc> {
    let spelling = Spelling::of(root);
    let mut r = Reader::new(file, diags);
    let obj = r.object(root, "", &["peppy_schema", "manifest", "interfaces"])?;
    let mut ok = true;
    let (identity, labels) = match r.required(&obj, "manifest") {
        Some(m) => parse_manifest(&mut r, m),
        None => (None, Vec::new()),
    };
    let mut topics = Vec::new();
    let mut services = Vec::new();
    let mut actions = Vec::new();
    if let Some(i) = r.required(&obj, "interfaces")
        && let Some(iobj) = r.object(i, "interfaces", &["topics", "services", "actions"])
    {
        topics = parse_list(
            &mut r,
            iobj.get("topics"),
            "interfaces.topics",
            EntryKind::Topic,
            &mut ok,
            parse_topic,
            topic_name,
        );
        services = parse_list(
            &mut r,
            iobj.get("services"),
            "interfaces.services",
            EntryKind::Service,
            &mut ok,
            parse_service,
            service_name,
        );
        actions = parse_list(
            &mut r,
            iobj.get("actions"),
            "interfaces.actions",
            EntryKind::Action,
            &mut ok,
            match spelling {
                Spelling::UnderscoreIds => parse_action,
                Spelling::SlashIds => parse_contract_action,
            },
            action_name,
        );
    }
    if r.diags.has_errors() || !ok {
        return None;
    }
    let (identity, name_loc) = identity?;
    Some(InterfaceDoc {
        file: file.clone(),
        sha256,
        spelling,
        identity,
        name_loc,
        labels,
        topics,
        services,
        actions,
    })
}

/// A `manifest` of the documents that only describe (an interface, a
/// contract, a pairing): `name` (the name rule), `tag` (the tag rule) and
/// optional `labels`; anything else, `depends_on` and `implements` included,
/// is an unknown key. Returns the identity with where its name is, when both
/// halves are valid, and the labels.
pub(crate) fn parse_manifest(
    r: &mut Reader<'_>,
    m: &Node,
) -> (Option<(Identity, Loc)>, Vec<String>) {
    let Some(mobj) = r.object(m, "manifest", &["name", "tag", "labels"]) else {
        return (None, Vec::new());
    };
    let name = r.required(&mobj, "name").and_then(|n| {
        let s = r.string(n, "manifest.name")?;
        match check_name(&s) {
            Ok(()) => Some((s, r.loc(n.span, "manifest.name"))),
            Err(why) => {
                r.error(
                    Code::InvalidName,
                    n.span,
                    "manifest.name",
                    format!("invalid `manifest.name` `{s}`: {why}"),
                );
                None
            }
        }
    });
    let tag = r.required(&mobj, "tag").and_then(|t| {
        let s = r.string(t, "manifest.tag")?;
        match check_tag(&s, false) {
            Ok(()) => Some(s),
            Err(why) => {
                r.error(
                    Code::InvalidTag,
                    t.span,
                    "manifest.tag",
                    format!("invalid `manifest.tag` `{s}`: {why}"),
                );
                None
            }
        }
    });
    let labels = match mobj.get("labels") {
        Some(l) => r.string_list(l, "manifest.labels").unwrap_or_default(),
        None => Vec::new(),
    };
    let identity = match (name, tag) {
        (Some((n, loc)), Some(t)) => Some((Identity::new(n, t), loc)),
        _ => None,
    };
    (identity, labels)
}
