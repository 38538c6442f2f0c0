//! Node documents (`peppy_schema: "node_v1"`, and the legacy
//! `schema_version: 1` form mapped onto the same model). This module holds
//! the document's model and its top-level reading; `slots` reads
//! `depends_on` and `conforms_to`, `consumes` the consumed entries and
//! `execution` the `execution` (or legacy `process`) section.

mod consumes;
mod execution;
mod refine;
mod slash_ids;
mod slots;

pub(crate) use crate::model::PairingSlot;
pub use execution::{Container, Execution, Launch};
pub use refine::{FieldRefine, FormatRefine, Pin, Refine, RefinedMessage};
pub(crate) use refine::{action_message, check_refine};
pub use slash_ids::MemberRef;
pub(crate) use slots::read_sha256;

use std::sync::Arc;

use serde::Serialize;

use crate::diag::{Code, Diagnostics, list};
use crate::document::Spelling;
use crate::entries::{
    ActionDecl, EntryKind, ServiceDecl, TopicDecl, action_name, parse_action,
    parse_contract_action, parse_entry_name, parse_list, parse_service, parse_topic, service_name,
    topic_name,
};
use crate::format::{MessageFormat, parse_format};
use crate::json::{Node, Value};
pub(crate) use crate::model::{Dependency, Identity, SlotKind};
use crate::names::{check_link_id, check_name, check_tag, consumed_module, module_name};
use crate::params::{ParameterSchema, parse_parameters};
use crate::read::{Loc, Obj, Reader, index};
use crate::source::SourceFile;

use consumes::{parse_consumed_refs, parse_consumed_topics};
use execution::{parse_execution, parse_legacy_process};
use slash_ids::{
    check_member_links, parse_consumed_by_link, parse_implements_manifest, parse_produced,
};
use slots::{parse_conforms_to, parse_depends_on, read_identity_part};

/// A parsed, validated node document.
#[derive(Debug, Clone)]
pub struct NodeDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// Written in the legacy `schema_version: 1` form.
    pub legacy: bool,
    /// `node_v1` (and the legacy `schema_version: 1`), or `node/v1`.
    pub spelling: Spelling,
    /// The generated API its code uses (decided by the spelling).
    pub api: crate::NodeApi,
    /// `manifest.name`.
    pub name: String,
    /// `manifest.tag`.
    pub tag: String,
    /// Where `manifest.name` is.
    pub name_loc: Loc,
    /// `manifest.labels`.
    pub labels: Vec<String>,
    /// `manifest.depends_on.nodes` then `.interfaces`: the slots.
    pub dependencies: Vec<Dependency>,
    /// `execution`.
    pub execution: Execution,
    /// `interfaces.conforms_to` (`node_v1`) or `manifest.implements`
    /// (`node/v1`).
    pub conforms_to: Vec<InterfaceRef>,
    /// `node/v1`'s members provided through a slot (`{ link_id, name }` in
    /// `emits` / `exposes`); empty in `node_v1`, where conforming
    /// provides every member of the interface implicitly.
    pub members: Vec<MemberRef>,
    /// `node/v1`'s `depends_on.pairings` and `.pairing_observers`.
    pub pairings: Vec<PairingSlot>,
    /// `interfaces.topics.emits`.
    pub emits: Vec<TopicDecl>,
    /// `interfaces.topics.consumes`.
    pub consumed_topics: Vec<ConsumedTopic>,
    /// `interfaces.services.exposes`.
    pub exposed_services: Vec<ServiceDecl>,
    /// `interfaces.services.consumes`.
    pub consumed_services: Vec<ConsumedRef>,
    /// `interfaces.actions.exposes`.
    pub exposed_actions: Vec<ActionDecl>,
    /// `interfaces.actions.consumes`.
    pub consumed_actions: Vec<ConsumedRef>,
}

/// One `conforms_to` (or `node/v1`'s `implements`) entry.
#[derive(Debug, Clone)]
pub struct InterfaceRef {
    /// The interface.
    pub target: Identity,
    /// Revision pin.
    pub sha256: Option<String>,
    /// `node/v1`'s `implements` slot name (`None` in `node_v1`).
    pub link_id: Option<String>,
    /// Where the entry is.
    pub loc: Loc,
}

/// A consumed topic: through a slot, or external with its own format.
#[derive(Debug, Clone)]
pub struct ConsumedTopic {
    /// Topic name.
    pub name: String,
    /// Linked or external.
    pub source: TopicSource,
    /// `node/v1`'s pinned lengths (`refine`).
    pub refine: Option<Refine>,
    /// Where the entry is.
    pub loc: Loc,
}

/// Where a consumed topic comes from.
#[derive(Debug, Clone)]
pub enum TopicSource {
    /// From the producers of a `depends_on` slot.
    Linked {
        /// The slot.
        link_id: String,
    },
    /// From any emitter of that topic name, with this format.
    External(MessageFormat),
}

/// A consumed service or action: always through a slot.
#[derive(Debug, Clone)]
pub struct ConsumedRef {
    /// The slot.
    pub link_id: String,
    /// Service or action name on the producer.
    pub name: String,
    /// `node/v1`'s pinned lengths (`refine`).
    pub refine: Option<Refine>,
    /// Where the entry is.
    pub loc: Loc,
}

impl NodeDoc {
    /// `name:tag`.
    pub fn identity(&self) -> Identity {
        Identity::new(&self.name, &self.tag)
    }

    /// The slot named `link_id`.
    pub fn dependency(&self, link_id: &str) -> Option<&Dependency> {
        self.dependencies.iter().find(|d| d.link_id == link_id)
    }

    /// Whether the node claims conformance to `interface`.
    pub fn conforms_to(&self, interface: &Identity) -> bool {
        self.conforms_to.iter().any(|c| &c.target == interface)
    }

    /// Every consumed entry's `refine`: `(link_id, name, where)`.
    pub(crate) fn consumed_refines(&self) -> impl Iterator<Item = (&str, &str, &Loc)> {
        let topics = self
            .consumed_topics
            .iter()
            .filter_map(|t| match (&t.source, &t.refine) {
                (TopicSource::Linked { link_id }, Some(r)) => {
                    Some((link_id.as_str(), t.name.as_str(), &r.loc))
                }
                _ => None,
            });
        let calls = self
            .consumed_services
            .iter()
            .chain(&self.consumed_actions)
            .filter_map(|c| {
                c.refine
                    .as_ref()
                    .map(|r| (c.link_id.as_str(), c.name.as_str(), &r.loc))
            });
        topics.chain(calls)
    }
}

const LEGACY_HELP: &str = "legacy `schema_version: 1` spelling";

/// Parses a node document from its root value.
pub(crate) fn parse_node(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<NodeDoc> {
    let mut r = Reader::new(file, diags);
    let spelling = Spelling::of(root);
    let slash_ids = spelling == Spelling::SlashIds;
    let legacy = root.get("schema_version").is_some() && root.get("peppy_schema").is_none();
    let top_keys: &[&str] = if legacy {
        &["schema_version", "manifest", "process", "interfaces"]
    } else {
        &["peppy_schema", "manifest", "interfaces", "execution"]
    };
    let root_obj = r.object(root, "", top_keys)?;
    let mut ok = true;
    if legacy && let Some(v) = root_obj.member("schema_version") {
        r.warn_help(
            Code::LegacySpelling,
            v.key_span,
            "schema_version",
            format!("{LEGACY_HELP}: `schema_version: 1`"),
            "write `peppy_schema: \"node_v1\"`",
        );
    }
    let manifest = parse_manifest(&mut r, &root_obj, legacy, slash_ids, &mut ok);
    if manifest.name.is_none() || manifest.tag.is_none() {
        ok = false;
    }
    let execution = if legacy {
        parse_legacy_process(&mut r, &root_obj, manifest.legacy_language)
    } else {
        r.required(&root_obj, "execution")
            .and_then(|e| parse_execution(&mut r, e))
    };
    if execution.is_none() {
        ok = false;
    }
    let mut i = if slash_ids {
        parse_link_interfaces(&mut r, &root_obj, &mut ok)
    } else {
        parse_interfaces(&mut r, &root_obj, legacy, &mut ok)
    };
    if !slash_ids {
        ok &= check_consumed_links(&mut r, root, legacy, &i);
    }
    // two consumed entries generating the same module
    check_consumed_modules(
        &mut r,
        spelling,
        &i.consumed_topics,
        &i.consumed_services,
        &i.consumed_actions,
    );
    if slash_ids {
        i.conforms_to = manifest.implements;
    }

    if !ok || r.diags.has_errors() {
        return None;
    }
    let (name, name_loc) = manifest.name?;
    let (tag, _) = manifest.tag?;
    let doc = NodeDoc {
        file: file.clone(),
        legacy,
        spelling,
        api: spelling.node_api(),
        name,
        tag,
        name_loc,
        labels: manifest.labels,
        dependencies: manifest.dependencies,
        execution: execution?,
        conforms_to: i.conforms_to,
        members: i.members,
        pairings: manifest.pairings,
        emits: i.emits,
        consumed_topics: i.consumed_topics,
        exposed_services: i.exposed_services,
        consumed_services: i.consumed_services,
        exposed_actions: i.exposed_actions,
        consumed_actions: i.consumed_actions,
    };
    if slash_ids {
        check_member_links(r.diags, &doc);
        if r.diags.has_errors() {
            return None;
        }
    }
    Some(doc)
}

/// What `manifest` holds.
struct Manifest {
    name: Option<(String, Loc)>,
    tag: Option<(String, Loc)>,
    labels: Vec<String>,
    dependencies: Vec<Dependency>,
    /// `node/v1`'s `manifest.implements`.
    implements: Vec<InterfaceRef>,
    /// `node/v1`'s pairing slots.
    pairings: Vec<PairingSlot>,
    /// The legacy form's `manifest.language`.
    legacy_language: Option<String>,
}

/// `manifest`: identity, labels, `depends_on` (and the legacy `language`).
fn parse_manifest(
    r: &mut Reader<'_>,
    root_obj: &Obj<'_>,
    legacy: bool,
    slash_ids: bool,
    ok: &mut bool,
) -> Manifest {
    let mut name = None;
    let mut tag = None;
    let mut labels = Vec::new();
    let mut dependencies = Vec::new();
    let mut implements = Vec::new();
    let mut pairings = Vec::new();
    let mut legacy_language = None;
    if let Some(m) = r.required(root_obj, "manifest") {
        let keys: &[&str] = if legacy {
            &["name", "tag", "labels", "depends_on", "language"]
        } else if slash_ids {
            &["name", "tag", "labels", "implements", "depends_on"]
        } else {
            &["name", "tag", "labels", "depends_on"]
        };
        if let Some(mobj) = r.object(m, "manifest", keys) {
            name = read_identity_part(r, &mobj, "name", check_name, Code::InvalidName);
            tag = read_identity_part(r, &mobj, "tag", |s| check_tag(s, legacy), Code::InvalidTag);
            if let Some(l) = mobj.get("labels") {
                labels = r.string_list(l, "manifest.labels").unwrap_or_default();
            }
            if slash_ids {
                let t = parse_implements_manifest(r, &mobj, ok);
                dependencies = t.dependencies;
                implements = t.implements;
                pairings = t.pairings;
            } else if let Some(d) = mobj.get("depends_on") {
                match parse_depends_on(r, d, legacy) {
                    Some(deps) => dependencies = deps,
                    None => *ok = false,
                }
            }
            if legacy && let Some(lang) = mobj.member("language") {
                r.warn_help(
                    Code::LegacySpelling,
                    lang.key_span,
                    "manifest.language",
                    format!("{LEGACY_HELP}: `manifest.language`"),
                    "write `execution.language`",
                );
                legacy_language = r.string(&lang.value, "manifest.language");
            }
        }
    }
    Manifest {
        name,
        tag,
        labels,
        dependencies,
        implements,
        pairings,
        legacy_language,
    }
}

/// What `interfaces` holds.
#[derive(Default)]
struct Interfaces {
    conforms_to: Vec<InterfaceRef>,
    members: Vec<MemberRef>,
    emits: Vec<TopicDecl>,
    consumed_topics: Vec<ConsumedTopic>,
    exposed_services: Vec<ServiceDecl>,
    consumed_services: Vec<ConsumedRef>,
    exposed_actions: Vec<ActionDecl>,
    consumed_actions: Vec<ConsumedRef>,
}

/// `interfaces`: conformance, topics, services and actions.
fn parse_interfaces(
    r: &mut Reader<'_>,
    root_obj: &Obj<'_>,
    legacy: bool,
    ok: &mut bool,
) -> Interfaces {
    let mut conforms_to = Vec::new();
    let mut emits = Vec::new();
    let mut consumed_topics = Vec::new();
    let mut exposed_services = Vec::new();
    let mut consumed_services = Vec::new();
    let mut exposed_actions = Vec::new();
    let mut consumed_actions = Vec::new();
    if let Some(i) = root_obj.get("interfaces") {
        if let Some(iobj) = r.object(
            i,
            "interfaces",
            &["topics", "services", "actions", "conforms_to"],
        ) {
            conforms_to = parse_conforms_to(r, iobj.get("conforms_to"), ok);
            if let Some(t) = iobj.get("topics") {
                if let Some(tobj) = r.object(t, "interfaces.topics", &["emits", "consumes"]) {
                    emits = parse_list(
                        r,
                        tobj.get("emits"),
                        "interfaces.topics.emits",
                        EntryKind::Topic,
                        ok,
                        parse_topic,
                        topic_name,
                    );
                    consumed_topics = parse_consumed_topics(r, tobj.get("consumes"), legacy, ok);
                } else {
                    *ok = false;
                }
            }
            if let Some(s) = iobj.get("services") {
                if let Some(sobj) = r.object(s, "interfaces.services", &["exposes", "consumes"]) {
                    exposed_services = parse_list(
                        r,
                        sobj.get("exposes"),
                        "interfaces.services.exposes",
                        EntryKind::Service,
                        ok,
                        parse_service,
                        service_name,
                    );
                    consumed_services = parse_consumed_refs(
                        r,
                        sobj.get("consumes"),
                        "interfaces.services.consumes",
                        EntryKind::Service,
                        legacy,
                        ok,
                    );
                } else {
                    *ok = false;
                }
            }
            if let Some(a) = iobj.get("actions") {
                if let Some(aobj) = r.object(a, "interfaces.actions", &["exposes", "consumes"]) {
                    exposed_actions = parse_list(
                        r,
                        aobj.get("exposes"),
                        "interfaces.actions.exposes",
                        EntryKind::Action,
                        ok,
                        parse_action,
                        action_name,
                    );
                    consumed_actions = parse_consumed_refs(
                        r,
                        aobj.get("consumes"),
                        "interfaces.actions.consumes",
                        EntryKind::Action,
                        legacy,
                        ok,
                    );
                } else {
                    *ok = false;
                }
            }
        } else {
            *ok = false;
        }
    }

    Interfaces {
        conforms_to,
        members: Vec::new(),
        emits,
        consumed_topics,
        exposed_services,
        consumed_services,
        exposed_actions,
        consumed_actions,
    }
}

/// `node/v1`'s `interfaces`: natives and slot members in `emits` / `exposes`,
/// `{ link_id, name, refine? }` in `consumes`.
fn parse_link_interfaces(r: &mut Reader<'_>, root_obj: &Obj<'_>, ok: &mut bool) -> Interfaces {
    let mut out = Interfaces::default();
    let Some(i) = root_obj.get("interfaces") else {
        return out;
    };
    let Some(iobj) = r.object(i, "interfaces", &["topics", "services", "actions"]) else {
        *ok = false;
        return out;
    };
    let mut section =
        |r: &mut Reader<'_>, key: &str, produced: &str| -> Option<(Option<&Node>, Option<&Node>)> {
            let n = iobj.get(key)?;
            match r.object(n, &format!("interfaces.{key}"), &[produced, "consumes"]) {
                Some(o) => Some((o.get(produced), o.get("consumes"))),
                None => {
                    *ok = false;
                    None
                }
            }
        };
    let topics = section(r, "topics", "emits");
    let services = section(r, "services", "exposes");
    let actions = section(r, "actions", "exposes");
    if let Some((emits, consumes)) = topics {
        let path = "interfaces.topics.emits";
        let (natives, members) = parse_produced(
            r,
            emits,
            path,
            EntryKind::Topic,
            parse_topic,
            topic_name,
            ok,
        );
        out.emits = natives;
        out.members.extend(members);
        let consumed = parse_consumed_by_link(
            r,
            consumes,
            "interfaces.topics.consumes",
            EntryKind::Topic,
            ok,
        );
        out.consumed_topics = consumed
            .into_iter()
            .map(|(c, refine)| ConsumedTopic {
                name: c.name,
                source: TopicSource::Linked { link_id: c.link_id },
                refine,
                loc: c.loc,
            })
            .collect();
    }
    if let Some(section) = services {
        let (natives, members, consumed) = calls_section(
            r,
            section,
            "services",
            EntryKind::Service,
            parse_service,
            service_name,
            ok,
        );
        out.exposed_services = natives;
        out.members.extend(members);
        out.consumed_services = consumed;
    }
    if let Some(section) = actions {
        let (natives, members, consumed) = calls_section(
            r,
            section,
            "actions",
            EntryKind::Action,
            parse_contract_action,
            action_name,
            ok,
        );
        out.exposed_actions = natives;
        out.members.extend(members);
        out.consumed_actions = consumed;
    }
    out
}

/// `node/v1`'s `services` or `actions` section: what it `exposes`
/// (natives and slot members) and what it `consumes`.
fn calls_section<T>(
    r: &mut Reader<'_>,
    (exposes, consumes): (Option<&Node>, Option<&Node>),
    key: &str,
    kind: EntryKind,
    native: fn(&mut Reader<'_>, &Node, &str) -> Option<T>,
    name_of: fn(&T) -> (&str, &Loc),
    ok: &mut bool,
) -> (Vec<T>, Vec<MemberRef>, Vec<ConsumedRef>) {
    let path = format!("interfaces.{key}.exposes");
    let (natives, members) = parse_produced(r, exposes, &path, kind, native, name_of, ok);
    let consumed =
        parse_consumed_by_link(r, consumes, &format!("interfaces.{key}.consumes"), kind, ok)
            .into_iter()
            .map(|(c, refine)| ConsumedRef { refine, ..c })
            .collect();
    (natives, members, consumed)
}

/// Every link_id a consumed entry uses must be declared; `false` if one is not.
fn check_consumed_links(r: &mut Reader<'_>, root: &Node, legacy: bool, i: &Interfaces) -> bool {
    // Judged against every link_id written in `depends_on`, so that an error
    // in one of its entries does not also make every consumer of it "undeclared".
    let written = written_link_ids(root, legacy);
    let declared: Vec<&str> = written.iter().map(String::as_str).collect();
    let mut ok = true;
    for (kind, link_id, loc) in consumed_links(
        &i.consumed_topics,
        &i.consumed_services,
        &i.consumed_actions,
    ) {
        if !declared.contains(&link_id) {
            r.diags.push(undeclared_link(kind, link_id, loc, &declared));
            ok = false;
        }
    }
    ok
}

/// The slot link_id of every consumed entry, with its kind and place.
fn consumed_links<'a>(
    topics: &'a [ConsumedTopic],
    services: &'a [ConsumedRef],
    actions: &'a [ConsumedRef],
) -> impl Iterator<Item = (EntryKind, &'a str, &'a Loc)> {
    topics
        .iter()
        .filter_map(|t| match &t.source {
            TopicSource::Linked { link_id } => Some((EntryKind::Topic, link_id.as_str(), &t.loc)),
            TopicSource::External(_) => None,
        })
        .chain(
            services
                .iter()
                .map(|c| (EntryKind::Service, c.link_id.as_str(), &c.loc)),
        )
        .chain(
            actions
                .iter()
                .map(|c| (EntryKind::Action, c.link_id.as_str(), &c.loc)),
        )
}

/// The error of a consumed entry whose link_id no slot declares: one rule
/// for both spellings.
fn undeclared_link(
    kind: EntryKind,
    link_id: &str,
    loc: &Loc,
    declared: &[&str],
) -> crate::Diagnostic {
    let help = match crate::diag::did_you_mean(link_id, declared.iter().copied()) {
        Some(s) => format!(
            "did you mean `{s}`? declared link_ids: {}",
            crate::diag::list(declared.iter().copied())
        ),
        None => format!(
            "declare it under `manifest.depends_on`; declared link_ids: {}",
            crate::diag::list(declared.iter().copied())
        ),
    };
    loc.error(
        Code::UndeclaredLinkId,
        format!(
            "consumed {kind} uses link_id `{link_id}`, which `manifest.depends_on` does not declare"
        ),
    )
    .with_help(help)
}

/// Every `link_id` written in `manifest.depends_on` (and legacy `local_id`),
/// whether or not its entry is otherwise valid: in order, once each.
fn written_link_ids(root: &Node, legacy: bool) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let Some(deps) = root.get("manifest").and_then(|m| m.get("depends_on")) else {
        return out;
    };
    for list in ["nodes", "interfaces"] {
        let Some(Value::Array(items)) = deps.get(list).map(|n| &n.value) else {
            continue;
        };
        for item in items {
            let id = item
                .get("link_id")
                .or_else(|| if legacy { item.get("local_id") } else { None })
                .and_then(Node::as_str);
            if let Some(id) = id
                && !out.iter().any(|o| o == id)
            {
                out.push(id.to_string());
            }
        }
    }
    out
}

fn check_consumed_modules(
    r: &mut Reader<'_>,
    spelling: Spelling,
    topics: &[ConsumedTopic],
    services: &[ConsumedRef],
    actions: &[ConsumedRef],
) {
    let topic_modules = topics.iter().map(|t| {
        let module = match &t.source {
            TopicSource::Linked { link_id } => linked_module(spelling, link_id, &t.name),
            TopicSource::External(_) => consumed_module(None, &t.name),
        };
        (module, &t.loc)
    });
    check_modules(r, "consumed_topics", topic_modules);
    for (category, list) in [
        ("consumed_services", services),
        ("consumed_actions", actions),
    ] {
        let modules = list
            .iter()
            .map(|c| (linked_module(spelling, &c.link_id, &c.name), &c.loc));
        check_modules(r, category, modules);
    }
}

/// The module a consumed entry generates: `<link>_<name>` in `node_v1`,
/// `<link>::<name>` in `node/v1`.
fn linked_module(spelling: Spelling, link_id: &str, name: &str) -> String {
    match spelling {
        Spelling::UnderscoreIds => consumed_module(Some(link_id), name),
        Spelling::SlashIds => format!("{}::{}", module_name(link_id), module_name(name)),
    }
}

fn check_modules<'a>(
    r: &mut Reader<'_>,
    category: &str,
    modules: impl Iterator<Item = (String, &'a Loc)>,
) {
    let mut seen: Vec<(String, &Loc)> = Vec::new();
    for (module, loc) in modules {
        if let Some((_, first)) = seen.iter().find(|(m, _)| *m == module) {
            let lc = first.file.line_col(first.span.start);
            r.diags.push(
                loc.error(
                    Code::DuplicateEntryName,
                    format!("this entry would generate `{category}::{module}`, like the entry at line {}, column {}", lc.line, lc.column),
                )
                .with_help("consume each topic, service or action once per link_id"),
            );
        } else {
            seen.push((module, loc));
        }
    }
}
