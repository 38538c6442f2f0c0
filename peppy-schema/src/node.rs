//! Node documents (`peppy_schema: "node_v1"`, and the legacy
//! `schema_version: 1` form mapped onto the same model).

use std::sync::Arc;

use serde::Serialize;

use crate::diag::{Code, Diagnostics};
use crate::entries::{
    ActionDecl, EntryKind, ServiceDecl, TopicDecl, action_name, parse_action, parse_entry_name,
    parse_list, parse_service, parse_topic, service_name, topic_name,
};
use crate::format::{MessageFormat, parse_format};
use crate::json::{Node, Value};
pub(crate) use crate::model::{Dependency, Identity, SlotKind};
use crate::names::{check_link_id, check_name, check_tag, consumed_module, module_name};
use crate::params::{ParameterSchema, parse_parameters};
use crate::read::{Loc, Obj, Reader, index};
use crate::source::SourceFile;

/// A parsed, validated node document.
#[derive(Debug, Clone)]
pub struct NodeDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// Written in the legacy `schema_version: 1` form.
    pub legacy: bool,
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
    /// `interfaces.conforms_to`.
    pub conforms_to: Vec<InterfaceRef>,
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

/// One `conforms_to` entry.
#[derive(Debug, Clone)]
pub struct InterfaceRef {
    /// The interface.
    pub target: Identity,
    /// Revision pin.
    pub sha256: Option<String>,
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
    /// Where the entry is.
    pub loc: Loc,
}

/// `execution`.
#[derive(Debug, Clone)]
pub struct Execution {
    /// `rust`, `python`, ...
    pub language: String,
    /// Build argv, run in the node's directory.
    pub build_cmd: Option<Vec<String>>,
    /// Run argv, run in the node's directory.
    pub run_cmd: Option<Vec<String>>,
    /// Container settings (carried; running containers is out of scope).
    pub container: Option<Container>,
    /// Parameter schema.
    pub parameters: ParameterSchema,
}

/// How a launcher starts a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Launch<'a> {
    /// `run_cmd`, run in the node's directory.
    Command(&'a [String]),
    /// A Rust node without `run_cmd`: the executable `cargo build` reports
    /// for the package in the node's directory.
    CargoBinary,
    /// `execution.container` (not started by peppy-launch yet).
    Container(&'a Container),
}

impl Execution {
    /// How a launcher starts the node.
    pub fn launch(&self) -> Launch<'_> {
        match (&self.run_cmd, &self.container) {
            (Some(argv), _) => Launch::Command(argv),
            (None, Some(c)) => Launch::Container(c),
            (None, None) => Launch::CargoBinary,
        }
    }

    /// The build to run before starting: `build_cmd`, or `cargo build` for
    /// a cargo-located Rust node that gives none.
    pub fn build_command(&self) -> Option<Vec<String>> {
        match (&self.build_cmd, self.launch()) {
            (Some(cmd), _) => Some(cmd.clone()),
            (None, Launch::CargoBinary) => Some(vec!["cargo".into(), "build".into()]),
            (None, _) => None,
        }
    }
}

/// `execution.container` (accepted and carried).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Container {
    /// Definition file.
    pub def_file: String,
    /// Host paths to mount.
    pub mount_paths: Vec<String>,
    /// Extra `apptainer build` arguments.
    pub apptainer_build_extra_args: Vec<String>,
    /// Extra `apptainer run` arguments.
    pub apptainer_run_extra_args: Vec<String>,
    /// Extra `lima shell` arguments.
    pub lima_shell_extra_args: Vec<String>,
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
}

const LEGACY_HELP: &str = "legacy `schema_version: 1` spelling";

/// Parses a node document from its root value.
pub(crate) fn parse_node(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<NodeDoc> {
    let mut r = Reader::new(file, diags);
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

    // manifest
    let mut name = None;
    let mut tag = None;
    let mut labels = Vec::new();
    let mut dependencies = Vec::new();
    let mut legacy_language = None;
    if let Some(m) = r.required(&root_obj, "manifest") {
        let keys: &[&str] = if legacy {
            &["name", "tag", "labels", "depends_on", "language"]
        } else {
            &["name", "tag", "labels", "depends_on"]
        };
        if let Some(mobj) = r.object(m, "manifest", keys) {
            name = read_identity_part(&mut r, &mobj, "name", check_name, Code::InvalidName);
            tag = read_identity_part(
                &mut r,
                &mobj,
                "tag",
                |s| check_tag(s, legacy),
                Code::InvalidTag,
            );
            if let Some(l) = mobj.get("labels") {
                labels = r.string_list(l, "manifest.labels").unwrap_or_default();
            }
            if let Some(d) = mobj.get("depends_on") {
                match parse_depends_on(&mut r, d, legacy) {
                    Some(deps) => dependencies = deps,
                    None => ok = false,
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
    if name.is_none() || tag.is_none() {
        ok = false;
    }

    // execution
    let execution = if legacy {
        parse_legacy_process(&mut r, &root_obj, legacy_language)
    } else {
        r.required(&root_obj, "execution")
            .and_then(|e| parse_execution(&mut r, e))
    };
    if execution.is_none() {
        ok = false;
    }

    // interfaces
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
            conforms_to = parse_conforms_to(&mut r, iobj.get("conforms_to"), &mut ok);
            if let Some(t) = iobj.get("topics") {
                if let Some(tobj) = r.object(t, "interfaces.topics", &["emits", "consumes"]) {
                    emits = parse_list(
                        &mut r,
                        tobj.get("emits"),
                        "interfaces.topics.emits",
                        EntryKind::Topic,
                        &mut ok,
                        parse_topic,
                        topic_name,
                    );
                    consumed_topics =
                        parse_consumed_topics(&mut r, tobj.get("consumes"), legacy, &mut ok);
                } else {
                    ok = false;
                }
            }
            if let Some(s) = iobj.get("services") {
                if let Some(sobj) = r.object(s, "interfaces.services", &["exposes", "consumes"]) {
                    exposed_services = parse_list(
                        &mut r,
                        sobj.get("exposes"),
                        "interfaces.services.exposes",
                        EntryKind::Service,
                        &mut ok,
                        parse_service,
                        service_name,
                    );
                    consumed_services = parse_consumed_refs(
                        &mut r,
                        sobj.get("consumes"),
                        "interfaces.services.consumes",
                        EntryKind::Service,
                        legacy,
                        &mut ok,
                    );
                } else {
                    ok = false;
                }
            }
            if let Some(a) = iobj.get("actions") {
                if let Some(aobj) = r.object(a, "interfaces.actions", &["exposes", "consumes"]) {
                    exposed_actions = parse_list(
                        &mut r,
                        aobj.get("exposes"),
                        "interfaces.actions.exposes",
                        EntryKind::Action,
                        &mut ok,
                        parse_action,
                        action_name,
                    );
                    consumed_actions = parse_consumed_refs(
                        &mut r,
                        aobj.get("consumes"),
                        "interfaces.actions.consumes",
                        EntryKind::Action,
                        legacy,
                        &mut ok,
                    );
                } else {
                    ok = false;
                }
            }
        } else {
            ok = false;
        }
    }

    // link ids used by consumed entries must be declared
    let consumed_links = consumed_topics
        .iter()
        .filter_map(|t| match &t.source {
            TopicSource::Linked { link_id } => Some((link_id.as_str(), &t.loc, EntryKind::Topic)),
            TopicSource::External(_) => None,
        })
        .chain(
            consumed_services
                .iter()
                .map(|s| (s.link_id.as_str(), &s.loc, EntryKind::Service)),
        )
        .chain(
            consumed_actions
                .iter()
                .map(|a| (a.link_id.as_str(), &a.loc, EntryKind::Action)),
        );
    // Judged against every link_id written in `depends_on`, so that an error
    // in one of its entries does not also make every consumer of it "undeclared".
    let written = written_link_ids(root, legacy);
    for (link_id, loc, kind) in consumed_links {
        if !written.iter().any(|w| w == link_id) {
            let declared: Vec<&str> = written.iter().map(String::as_str).collect();
            r.diags.push(
                loc.error(
                    Code::UndeclaredLinkId,
                    format!("consumed {kind} uses link_id `{link_id}`, which `manifest.depends_on` does not declare"),
                )
                .with_help(format!(
                    "declare it under `manifest.depends_on.nodes` or `.interfaces`; declared link_ids: {}",
                    crate::diag::list(declared)
                )),
            );
            ok = false;
        }
    }

    // two consumed entries generating the same module
    check_consumed_modules(
        &mut r,
        &consumed_topics,
        &consumed_services,
        &consumed_actions,
    );

    if !ok || r.diags.has_errors() {
        return None;
    }
    let (name, name_loc) = name?;
    let (tag, _) = tag?;
    Some(NodeDoc {
        file: file.clone(),
        legacy,
        name,
        tag,
        name_loc,
        labels,
        dependencies,
        execution: execution?,
        conforms_to,
        emits,
        consumed_topics,
        exposed_services,
        consumed_services,
        exposed_actions,
        consumed_actions,
    })
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
    topics: &[ConsumedTopic],
    services: &[ConsumedRef],
    actions: &[ConsumedRef],
) {
    let topic_modules = topics.iter().map(|t| {
        let module = match &t.source {
            TopicSource::Linked { link_id } => consumed_module(Some(link_id), &t.name),
            TopicSource::External(_) => consumed_module(None, &t.name),
        };
        (module, &t.loc)
    });
    check_modules(r, "consumed_topics", topic_modules);
    check_modules(
        r,
        "consumed_services",
        services.iter().map(consumed_ref_module),
    );
    check_modules(
        r,
        "consumed_actions",
        actions.iter().map(consumed_ref_module),
    );
}

fn consumed_ref_module(c: &ConsumedRef) -> (String, &Loc) {
    (consumed_module(Some(&c.link_id), &c.name), &c.loc)
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

fn read_identity_part(
    r: &mut Reader<'_>,
    obj: &Obj<'_>,
    key: &str,
    check: impl Fn(&str) -> Result<(), String>,
    code: Code,
) -> Option<(String, Loc)> {
    let node = r.required(obj, key)?;
    let path = obj.path_of(key);
    let value = r.string(node, &path)?;
    if let Err(why) = check(&value) {
        r.error(
            code,
            node.span,
            &path,
            format!("invalid `{path}` `{value}`: {why}"),
        );
        return None;
    }
    Some((value, r.loc(node.span, &path)))
}

/// Checks a sha256 pin's spelling: 64 lowercase hex characters.
pub(crate) fn read_sha256(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<String> {
    let s = r.string(node, path)?;
    if s.len() != 64
        || !s
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
    {
        r.error_help(
            Code::InvalidValue,
            node.span,
            path,
            format!("`{path}` must be 64 lowercase hex characters, found `{s}`"),
            "a pin is the sha256 of the interface document's bytes, e.g. from `sha256sum file.json5`",
        );
        return None;
    }
    Some(s)
}

fn parse_depends_on(r: &mut Reader<'_>, node: &Node, legacy: bool) -> Option<Vec<Dependency>> {
    let obj = r.object(node, "manifest.depends_on", &["nodes", "interfaces"])?;
    let mut ok = true;
    let mut deps = Vec::new();
    for (key, kind) in [
        ("nodes", SlotKind::Node),
        ("interfaces", SlotKind::Interface),
    ] {
        let Some(list) = obj.get(key) else { continue };
        let path = obj.path_of(key);
        let Some(items) = r.array(list, &path) else {
            ok = false;
            continue;
        };
        for (i, item) in items.iter().enumerate() {
            match parse_dependency(r, item, &index(&path, i), kind, legacy) {
                Some(d) => deps.push(d),
                None => ok = false,
            }
        }
    }
    for (i, d) in deps.iter().enumerate() {
        if let Some(first) = deps[..i].iter().find(|e| e.link_id == d.link_id) {
            let lc = first.loc.file.line_col(first.loc.span.start);
            r.diags.push(
                d.loc
                    .error(Code::DuplicateLinkId, format!("duplicate link_id `{}` in `manifest.depends_on`", d.link_id))
                    .with_help(format!(
                        "link_ids are unique across `nodes` and `interfaces`; `{}` is already used at line {}, column {}",
                        d.link_id, lc.line, lc.column
                    )),
            );
            ok = false;
        }
        if d.from_any
            && let Some(first) = deps[..i]
                .iter()
                .find(|e| e.from_any && e.target == d.target)
        {
            r.diags.push(
                    d.loc
                        .error(
                            Code::ConflictingFromAny,
                            format!("a second `from_any` slot for `{}` (`{}` is one already)", d.target, first.link_id),
                        )
                        .with_help("at most one entry per name:tag may be `from_any`; one from_any slot takes every producer of that kind"),
                );
            ok = false;
        }
    }
    ok.then_some(deps)
}

fn parse_dependency(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    kind: SlotKind,
    legacy: bool,
) -> Option<Dependency> {
    let keys: &[&str] = match (kind, legacy) {
        (SlotKind::Node, false) => &["name", "tag", "link_id", "from_any"],
        (SlotKind::Node, true) => &["name", "tag", "link_id", "local_id", "from_any"],
        (SlotKind::Interface, _) => &["name", "tag", "link_id", "from_any", "sha256"],
    };
    let obj = r.object(node, path, keys)?;
    let mut ok = true;
    let name = read_identity_part(r, &obj, "name", check_name, Code::InvalidName);
    let tag = read_identity_part(r, &obj, "tag", |s| check_tag(s, legacy), Code::InvalidTag);
    let link_key = if legacy && obj.get("link_id").is_none() && obj.get("local_id").is_some() {
        if let Some(m) = obj.member("local_id") {
            r.warn_help(
                Code::LegacySpelling,
                m.key_span,
                &obj.path_of("local_id"),
                format!("{LEGACY_HELP}: `local_id`"),
                "write `link_id`",
            );
        }
        "local_id"
    } else {
        "link_id"
    };
    let link_id = read_link_id(r, &obj, link_key);
    let from_any = match obj.get("from_any") {
        Some(f) => r.bool(f, &obj.path_of("from_any")).unwrap_or_else(|| {
            ok = false;
            false
        }),
        None => false,
    };
    let sha256 = match obj.get("sha256") {
        Some(s) => {
            let v = read_sha256(r, s, &obj.path_of("sha256"));
            ok &= v.is_some();
            v
        }
        None => None,
    };
    let (name, _) = name?;
    let (tag, _) = tag?;
    let link_id = link_id?;
    ok.then(|| Dependency {
        kind,
        target: Identity::new(name, tag),
        link_id,
        from_any,
        sha256,
        loc: r.loc(node.span, path),
    })
}

fn read_link_id(r: &mut Reader<'_>, obj: &Obj<'_>, key: &str) -> Option<String> {
    let node = r.required(obj, key)?;
    let path = obj.path_of(key);
    let s = r.string(node, &path)?;
    if let Err(why) = check_link_id(&s) {
        r.error(
            Code::InvalidName,
            node.span,
            &path,
            format!("invalid link_id `{s}`: {why}"),
        );
        return None;
    }
    Some(s)
}

fn parse_conforms_to(r: &mut Reader<'_>, node: Option<&Node>, ok: &mut bool) -> Vec<InterfaceRef> {
    let Some(node) = node else { return Vec::new() };
    let path = "interfaces.conforms_to";
    let Some(items) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out: Vec<InterfaceRef> = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index(path, i);
        let Some(obj) = r.object(item, &ipath, &["name", "tag", "sha256"]) else {
            *ok = false;
            continue;
        };
        let name = read_identity_part(r, &obj, "name", check_name, Code::InvalidName);
        let tag = read_identity_part(r, &obj, "tag", |s| check_tag(s, false), Code::InvalidTag);
        let sha256 = match obj.get("sha256") {
            Some(s) => match read_sha256(r, s, &obj.path_of("sha256")) {
                Some(v) => Some(v),
                None => {
                    *ok = false;
                    None
                }
            },
            None => None,
        };
        let (Some((name, _)), Some((tag, _))) = (name, tag) else {
            *ok = false;
            continue;
        };
        let entry = InterfaceRef {
            target: Identity::new(name, tag),
            sha256,
            loc: r.loc(item.span, &ipath),
        };
        let clash = out.iter().find(|e| {
            e.target == entry.target
                || (e.target.name == entry.target.name
                    && module_name(&e.target.tag) == module_name(&entry.target.tag))
        });
        if let Some(first) = clash {
            let what = if first.target == entry.target {
                format!("duplicate `conforms_to` entry `{}`", entry.target)
            } else {
                format!(
                    "`conforms_to` entries `{}` and `{}` collide: both generate module `{}::{}`",
                    first.target,
                    entry.target,
                    module_name(&entry.target.name),
                    module_name(&entry.target.tag)
                )
            };
            r.diags.push(
                entry
                    .loc
                    .error(Code::DuplicateConformance, what)
                    .with_help("list each interface once"),
            );
            *ok = false;
            continue;
        }
        out.push(entry);
    }
    out
}

fn parse_consumed_topics(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    legacy: bool,
    ok: &mut bool,
) -> Vec<ConsumedTopic> {
    let Some(node) = node else { return Vec::new() };
    let path = "interfaces.topics.consumes";
    let Some(items) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index(path, i);
        let keys: &[&str] = if legacy {
            &["name", "link_id", "local_node_id", "message_format"]
        } else {
            &["name", "link_id", "message_format"]
        };
        let Some(obj) = r.object(item, &ipath, keys) else {
            *ok = false;
            continue;
        };
        let name = parse_entry_name(r, &obj, EntryKind::Topic);
        let link_key = link_key(r, &obj, legacy);
        let source = match (link_key, obj.member("message_format")) {
            (Some(key), Some(mf)) => {
                r.error_help(
                    Code::LinkedFormatGiven,
                    mf.key_span,
                    &obj.path_of("message_format"),
                    "a linked consumed topic takes its format from the producer; it cannot state a `message_format`",
                    format!("remove `message_format`, or remove `{key}` to consume the topic externally (from any emitter)"),
                );
                None
            }
            (Some(key), None) => {
                read_link_id(r, &obj, key).map(|link_id| TopicSource::Linked { link_id })
            }
            (None, Some(mf)) => parse_format(r, &mf.value, &obj.path_of("message_format"))
                .map(TopicSource::External),
            (None, None) => {
                r.error_help(
                    Code::ExternalFormatMissing,
                    item.span,
                    &ipath,
                    "a consumed topic needs a `link_id` or a `message_format`",
                    "add `link_id` to receive it from a `depends_on` slot, or an inline `message_format` to receive it from any emitter (external)",
                );
                None
            }
        };
        match (name, source) {
            (Some((name, _)), Some(source)) => out.push(ConsumedTopic {
                name,
                source,
                loc: r.loc(item.span, &ipath),
            }),
            _ => *ok = false,
        }
    }
    out
}

/// `link_id`, or in legacy documents `local_node_id` (with a warning).
fn link_key(r: &mut Reader<'_>, obj: &Obj<'_>, legacy: bool) -> Option<&'static str> {
    if obj.get("link_id").is_some() {
        return Some("link_id");
    }
    if legacy && let Some(m) = obj.member("local_node_id") {
        r.warn_help(
            Code::LegacySpelling,
            m.key_span,
            &obj.path_of("local_node_id"),
            format!("{LEGACY_HELP}: `local_node_id`"),
            "write `link_id`",
        );
        return Some("local_node_id");
    }
    None
}

fn parse_consumed_refs(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    kind: EntryKind,
    legacy: bool,
    ok: &mut bool,
) -> Vec<ConsumedRef> {
    let Some(node) = node else { return Vec::new() };
    let Some(items) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index(path, i);
        let keys: &[&str] = if legacy {
            &["name", "link_id", "local_node_id"]
        } else {
            &["name", "link_id"]
        };
        let Some(obj) = r.object(item, &ipath, keys) else {
            *ok = false;
            continue;
        };
        let name = parse_entry_name(r, &obj, kind);
        let link = match link_key(r, &obj, legacy) {
            Some(key) => read_link_id(r, &obj, key),
            None => {
                r.error_help(
                    Code::MissingLinkId,
                    item.span,
                    &ipath,
                    format!("a consumed {kind} needs a `link_id`"),
                    format!(
                        "{kind}s are caller-driven and always need a target: declare the producer in `manifest.depends_on` and name its link_id here; only topics can be consumed externally"
                    ),
                );
                None
            }
        };
        match (name, link) {
            (Some((name, _)), Some(link_id)) => out.push(ConsumedRef {
                link_id,
                name,
                loc: r.loc(item.span, &ipath),
            }),
            _ => *ok = false,
        }
    }
    out
}

fn parse_command(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<Vec<String>> {
    let argv = r.string_list(node, path)?;
    if argv.is_empty() || argv[0].trim().is_empty() {
        r.error(
            Code::EmptyCommand,
            node.span,
            path,
            format!("`{path}` must name a program: an argv like [\"cargo\", \"run\"]"),
        );
        return None;
    }
    Some(argv)
}

/// `cargo build ...` (what a cargo-located node's build must be).
fn is_cargo_build(argv: &[String]) -> bool {
    argv.first().is_some_and(|p| p == "cargo") && argv.get(1).is_some_and(|c| c == "build")
}

fn parse_execution(r: &mut Reader<'_>, node: &Node) -> Option<Execution> {
    let obj = r.object(
        node,
        "execution",
        &[
            "language",
            "build_cmd",
            "run_cmd",
            "parameters",
            "container",
        ],
    )?;
    let mut ok = true;
    let language = r
        .required(&obj, "language")
        .and_then(|l| r.string(l, "execution.language"));
    if let Some(l) = &language
        && l.trim().is_empty()
    {
        r.error(
            Code::InvalidValue,
            obj.get("language").expect("present").span,
            "execution.language",
            "`execution.language` must not be empty",
        );
        ok = false;
    }
    let build_cmd = obj
        .get("build_cmd")
        .map(|b| parse_command(r, b, "execution.build_cmd"));
    let run_cmd = obj
        .get("run_cmd")
        .map(|b| parse_command(r, b, "execution.run_cmd"));
    let container = obj.get("container").map(|c| parse_container(r, c));
    let parameters = obj
        .get("parameters")
        .map(|p| parse_parameters(r, p, "execution.parameters"));
    match (&run_cmd, &container) {
        (Some(_), Some(_)) => {
            r.error_help(
                Code::ExecutionConflict,
                obj.member("container").expect("present").key_span,
                "execution.container",
                "`execution` has both `run_cmd` and `container`",
                "give exactly one: `run_cmd` for a process, `container` for a container",
            );
            ok = false;
        }
        // A Rust node built with cargo: the launcher learns its executable
        // from cargo's build messages.
        (None, None) if language.as_deref() == Some("rust") => {
            if let Some(Some(cmd)) = &build_cmd
                && !is_cargo_build(cmd)
            {
                r.error_help(
                    Code::ExecutionConflict,
                    obj.get("build_cmd").expect("present").span,
                    "execution.build_cmd",
                    "`execution` has no `run_cmd`, and `build_cmd` is not a `cargo build`",
                    "the executable of a Rust node without `run_cmd` is learned from `cargo build`: use `build_cmd: [\"cargo\", \"build\", ...]`, or give a `run_cmd`",
                );
                ok = false;
            }
        }
        (None, None) => {
            r.error_help(
                Code::ExecutionConflict,
                node.span,
                "execution",
                "`execution` has neither `run_cmd` nor `container`",
                "add `run_cmd: [\"./my_node\"]` (or a `container`); only `language: \"rust\"` nodes built with cargo may omit it",
            );
            ok = false;
        }
        _ => {}
    }
    let build_cmd = match build_cmd {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let run_cmd = match run_cmd {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let container = match container {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let parameters = match parameters {
        Some(None) => {
            ok = false;
            ParameterSchema::default()
        }
        Some(Some(p)) => p,
        None => ParameterSchema::default(),
    };
    let language = language?;
    ok.then_some(Execution {
        language,
        build_cmd,
        run_cmd,
        container,
        parameters,
    })
}

fn parse_container(r: &mut Reader<'_>, node: &Node) -> Option<Container> {
    let path = "execution.container";
    let obj = r.object(
        node,
        path,
        &[
            "def_file",
            "mount_paths",
            "apptainer_build_extra_args",
            "apptainer_run_extra_args",
            "lima_shell_extra_args",
        ],
    )?;
    let def_file = r
        .required(&obj, "def_file")
        .and_then(|d| r.string(d, &obj.path_of("def_file")));
    let mut list = |key: &str| -> Option<Vec<String>> {
        match obj.get(key) {
            Some(n) => r.string_list(n, &obj.path_of(key)),
            None => Some(Vec::new()),
        }
    };
    let mount_paths = list("mount_paths");
    let build = list("apptainer_build_extra_args");
    let run = list("apptainer_run_extra_args");
    let lima = list("lima_shell_extra_args");
    Some(Container {
        def_file: def_file?,
        mount_paths: mount_paths?,
        apptainer_build_extra_args: build?,
        apptainer_run_extra_args: run?,
        lima_shell_extra_args: lima?,
    })
}

fn parse_legacy_process(
    r: &mut Reader<'_>,
    root: &Obj<'_>,
    language: Option<String>,
) -> Option<Execution> {
    let language = match language {
        Some(l) => Some(l),
        None => {
            if let Some(m) = root.get("manifest")
                && m.get("language").is_none()
            {
                r.error(
                    Code::MissingKey,
                    m.span,
                    "manifest",
                    "missing required key `language` in `manifest` (legacy form)",
                );
            }
            None
        }
    };
    let process = r.required(root, "process")?;
    let obj = r.object(process, "process", &["add_cmd", "start_cmd"])?;
    let mut ok = true;
    let build_cmd = match obj.member("add_cmd") {
        Some(m) => {
            r.warn_help(
                Code::LegacySpelling,
                m.key_span,
                "process.add_cmd",
                format!("{LEGACY_HELP}: `process.add_cmd`"),
                "write `execution.build_cmd`",
            );
            let v = parse_command(r, &m.value, "process.add_cmd");
            ok &= v.is_some();
            v
        }
        None => None,
    };
    let run_cmd = match r.required(&obj, "start_cmd") {
        Some(n) => {
            let m = obj.member("start_cmd").expect("present");
            r.warn_help(
                Code::LegacySpelling,
                m.key_span,
                "process.start_cmd",
                format!("{LEGACY_HELP}: `process.start_cmd`"),
                "write `execution.run_cmd`",
            );
            parse_command(r, n, "process.start_cmd")
        }
        None => None,
    };
    if let Some(m) = root.member("process") {
        r.warn_help(
            Code::LegacySpelling,
            m.key_span,
            "process",
            format!("{LEGACY_HELP}: `process`"),
            "write `execution`",
        );
    }
    let language = language?;
    let run_cmd = run_cmd?;
    ok.then_some(Execution {
        language,
        build_cmd,
        run_cmd: Some(run_cmd),
        container: None,
        parameters: ParameterSchema::default(),
    })
}
