//! The slashed spelling of a node (`peppy_schema: "node/v1"`), read
//! into the same model as `node_v1`: `manifest.implements`
//! becomes conformance (with the slot's link_id), `depends_on.contracts`
//! interface slots, `cardinality` the slot's [`Cardinality`], and every
//! contract member is listed explicitly as `{ link_id, name }` (checked
//! against the contract when it is read, see `resolve`).

use super::refine::parse_refine;
use super::slots::{read_identity_part, read_link_id};
use super::*;
use crate::model::Cardinality;

/// A member a node provides through a slot: a contract member under an
/// `implements` slot, or a pairing topic under a participant slot.
#[derive(Debug, Clone)]
pub struct MemberRef {
    /// Topic, service or action.
    pub kind: EntryKind,
    /// The `implements` (or pairing) slot.
    pub link_id: String,
    /// The member's name in the contract.
    pub name: String,
    /// Pinned lengths, if any.
    pub refine: Option<Refine>,
    /// Where the entry is.
    pub loc: Loc,
}

/// What `node/v1`'s `manifest` adds to `node_v1`'s.
#[derive(Default)]
pub(super) struct ImplementsManifest {
    pub implements: Vec<InterfaceRef>,
    pub dependencies: Vec<Dependency>,
    pub pairings: Vec<PairingSlot>,
}

/// `manifest.implements` and `manifest.depends_on` of a `node/v1` document.
pub(super) fn parse_implements_manifest(
    r: &mut Reader<'_>,
    mobj: &Obj<'_>,
    ok: &mut bool,
) -> ImplementsManifest {
    let mut out = ImplementsManifest::default();
    if let Some(n) = mobj.get("implements") {
        out.implements = parse_implements(r, n, ok);
    }
    if let Some(d) = mobj.get("depends_on")
        && let Some(obj) = r.object(
            d,
            "manifest.depends_on",
            &["nodes", "contracts", "pairings", "pairing_observers"],
        )
    {
        for (key, kind) in [
            ("nodes", SlotKind::Node),
            ("contracts", SlotKind::Interface),
        ] {
            for (item, path) in items(r, &obj, key, ok) {
                match parse_slot(r, item, &path, kind) {
                    Some(dep) => out.dependencies.push(dep),
                    None => *ok = false,
                }
            }
        }
        for (key, observer) in [("pairings", false), ("pairing_observers", true)] {
            for (item, path) in items(r, &obj, key, ok) {
                match parse_pairing_slot(r, item, &path, observer) {
                    Some(p) => out.pairings.push(p),
                    None => *ok = false,
                }
            }
        }
    } else if mobj.get("depends_on").is_some() {
        *ok = false;
    }
    *ok &= check_link_namespace(r, &out);
    out
}

fn items<'n>(
    r: &mut Reader<'_>,
    obj: &Obj<'n>,
    key: &str,
    ok: &mut bool,
) -> Vec<(&'n Node, String)> {
    let Some(list) = obj.get(key) else {
        return Vec::new();
    };
    let path = obj.path_of(key);
    match r.array(list, &path) {
        Some(items) => items
            .iter()
            .enumerate()
            .map(|(i, n)| (n, index(&path, i)))
            .collect(),
        None => {
            *ok = false;
            Vec::new()
        }
    }
}

fn read_pin(r: &mut Reader<'_>, obj: &Obj<'_>, ok: &mut bool) -> Option<String> {
    let s = obj.get("sha256")?;
    let v = read_sha256(r, s, &obj.path_of("sha256"));
    *ok &= v.is_some();
    v
}

fn read_cardinality(r: &mut Reader<'_>, obj: &Obj<'_>, ok: &mut bool) -> Cardinality {
    let Some(n) = obj.get("cardinality") else {
        return Cardinality::One;
    };
    let path = obj.path_of("cardinality");
    let Some(s) = r.string(n, &path) else {
        *ok = false;
        return Cardinality::One;
    };
    Cardinality::parse(&s).unwrap_or_else(|| {
        let names = Cardinality::NAMES.iter().copied();
        let help = match crate::diag::did_you_mean(&s, names.clone()) {
            Some(c) => format!("did you mean `{c}`? cardinalities: {}", list(names)),
            None => format!("cardinalities: {}", list(names)),
        };
        r.error_help(
            Code::InvalidValue,
            n.span,
            &path,
            format!("unknown cardinality `{s}`"),
            help,
        );
        *ok = false;
        Cardinality::One
    })
}

fn parse_slot(r: &mut Reader<'_>, node: &Node, path: &str, kind: SlotKind) -> Option<Dependency> {
    let keys: &[&str] = match kind {
        SlotKind::Node => &["name", "tag", "link_id", "cardinality"],
        SlotKind::Interface => &["name", "tag", "link_id", "sha256", "cardinality"],
    };
    if let Some(m) = node.get_member("from_any") {
        r.error_help(
            Code::UnknownKey,
            m.key_span,
            &crate::read::join(path, "from_any"),
            "`from_any` is `node_v1`'s spelling; `node/v1` writes `cardinality`",
            "write `cardinality: \"zero_or_more\"` (any number, bound explicitly in the launcher's `links`)",
        );
        return None;
    }
    let obj = r.object(node, path, keys)?;
    let mut ok = true;
    let name = read_identity_part(r, &obj, "name", check_name, Code::InvalidName);
    let tag = read_identity_part(r, &obj, "tag", |s| check_tag(s, false), Code::InvalidTag);
    let link_id = read_link_id(r, &obj, "link_id");
    let sha256 = read_pin(r, &obj, &mut ok);
    let cardinality = read_cardinality(r, &obj, &mut ok);
    let ((name, _), (tag, _), link_id) = (name?, tag?, link_id?);
    ok.then(|| Dependency {
        kind,
        target: Identity::new(name, tag),
        link_id,
        from_any: false,
        cardinality,
        sha256,
        loc: r.loc(node.span, path),
    })
}

fn parse_pairing_slot(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    observer: bool,
) -> Option<PairingSlot> {
    let (wrong, code, why) = if observer {
        (
            "optional",
            Code::OptionalOnObserverSlot,
            "an observer slot says how many sources it takes with `cardinality` (`zero_or_one` may stay empty)",
        )
    } else {
        (
            "cardinality",
            Code::CardinalityOnPairingSlot,
            "a participant slot holds one peer; write `optional: true` if it may stay vacant",
        )
    };
    if let Some(m) = node.get_member(wrong) {
        r.error_help(
            code,
            m.key_span,
            &crate::read::join(path, wrong),
            format!(
                "`{wrong}` is not a key of a {} slot",
                if observer {
                    "pairing observer"
                } else {
                    "pairing"
                }
            ),
            why,
        );
        return None;
    }
    let keys: &[&str] = if observer {
        &["name", "tag", "role", "link_id", "sha256", "cardinality"]
    } else {
        &["name", "tag", "role", "link_id", "sha256", "optional"]
    };
    let obj = r.object(node, path, keys)?;
    let mut ok = true;
    let name = read_identity_part(r, &obj, "name", check_name, Code::InvalidName);
    let tag = read_identity_part(r, &obj, "tag", |s| check_tag(s, false), Code::InvalidTag);
    let role = match obj.get("role") {
        Some(n) => {
            let p = obj.path_of("role");
            r.string(n, &p).and_then(|s| match check_name(&s) {
                Ok(()) => Some(s),
                Err(why) => {
                    r.error(
                        Code::InvalidName,
                        n.span,
                        &p,
                        format!("invalid role `{s}`: {why}"),
                    );
                    None
                }
            })
        }
        None => {
            r.error_help(
                Code::PairingSlotMissingRole,
                node.span,
                path,
                format!("`{path}` names no `role`"),
                if observer {
                    "an observer names the role it watches: `role: \"<role>\"`"
                } else {
                    "a participant names the role it plays: `role: \"<role>\"`"
                },
            );
            None
        }
    };
    // The sentinel check reads the raw string first: the general link_id
    // rule refuses these characters too, and would hide the specific code.
    let link_id = match obj.get("link_id").map(|n| (n, &n.value)) {
        Some((n, Value::String(id)))
            if id.contains(['/', '@']) || ["*", "**", "_"].contains(&id.as_str()) =>
        {
            r.error(
                Code::PairingSentinelLinkId,
                n.span,
                &obj.path_of("link_id"),
                format!("link_id `{id}` is reserved in link targets (`/`, `@`, `*`, `**`, `_`)"),
            );
            ok = false;
            None
        }
        _ => read_link_id(r, &obj, "link_id"),
    };
    let sha256 = read_pin(r, &obj, &mut ok);
    let optional = match obj.get("optional") {
        Some(n) => r.bool(n, &obj.path_of("optional")).unwrap_or_else(|| {
            ok = false;
            false
        }),
        None => false,
    };
    let cardinality = read_cardinality(r, &obj, &mut ok);
    let ((name, _), (tag, _), role, link_id) = (name?, tag?, role?, link_id?);
    ok.then(|| PairingSlot {
        link_id,
        pairing: Identity::new(name, tag),
        role,
        counterpart: String::new(),
        observer,
        sha256,
        optional,
        cardinality,
        loc: r.loc(node.span, path),
    })
}

fn parse_implements(r: &mut Reader<'_>, node: &Node, ok: &mut bool) -> Vec<InterfaceRef> {
    let path = "manifest.implements";
    let Some(list) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out: Vec<InterfaceRef> = Vec::new();
    for (i, item) in list.iter().enumerate() {
        let ipath = index(path, i);
        let Some(obj) = r.object(item, &ipath, &["name", "tag", "link_id", "sha256"]) else {
            *ok = false;
            continue;
        };
        let name = read_identity_part(r, &obj, "name", check_name, Code::InvalidName);
        let tag = read_identity_part(r, &obj, "tag", |s| check_tag(s, false), Code::InvalidTag);
        let link_id = read_link_id(r, &obj, "link_id");
        let sha256 = read_pin(r, &obj, ok);
        let (Some((name, _)), Some((tag, _)), Some(link_id)) = (name, tag, link_id) else {
            *ok = false;
            continue;
        };
        let entry = InterfaceRef {
            target: Identity::new(name, tag),
            sha256,
            link_id: Some(link_id),
            loc: r.loc(item.span, &ipath),
        };
        let clash = out.iter().find(|e| {
            e.target == entry.target
                || (e.target.name == entry.target.name
                    && e.target.tag.replace('-', "_") == entry.target.tag.replace('-', "_"))
        });
        if let Some(first) = clash {
            let (code, what) = if first.target == entry.target {
                (
                    Code::DuplicateImplementsContract,
                    format!("`{}` is implemented twice", entry.target),
                )
            } else {
                (
                    Code::ImplementsTagSanitizationCollision,
                    format!(
                        "`{}` and `{}` collide once `-` is read as `_`",
                        first.target, entry.target
                    ),
                )
            };
            r.diags.push(
                entry
                    .loc
                    .error(code, what)
                    .with_help("a node implements a contract once; list it under one link_id"),
            );
            *ok = false;
            continue;
        }
        out.push(entry);
    }
    out
}

/// One link_id namespace across `implements`, `nodes`, `contracts`,
/// `pairings` and `pairing_observers`.
fn check_link_namespace(r: &mut Reader<'_>, m: &ImplementsManifest) -> bool {
    let all: Vec<(&str, &Loc)> = m
        .implements
        .iter()
        .filter_map(|i| i.link_id.as_deref().map(|l| (l, &i.loc)))
        .chain(m.dependencies.iter().map(|d| (d.link_id.as_str(), &d.loc)))
        .chain(m.pairings.iter().map(|p| (p.link_id.as_str(), &p.loc)))
        .collect();
    let mut ok = true;
    for (i, (id, loc)) in all.iter().enumerate() {
        if let Some((_, first)) = all[..i].iter().find(|(o, _)| o == id) {
            let lc = first.file.line_col(first.span.start);
            r.diags.push(
                loc.error(Code::DuplicateLinkId, format!("duplicate link_id `{id}` in `manifest`"))
                    .with_help(format!(
                        "link_ids are one namespace across `implements` and every `depends_on` list; `{id}` is already used at line {}, column {}",
                        lc.line, lc.column
                    )),
            );
            ok = false;
        }
    }
    ok
}

/// `node/v1`'s produced entries of one section: natives (the node owns the
/// shape) and members (`{ link_id, name, refine? }`, shaped by a contract
/// or a pairing).
pub(super) fn parse_produced<T>(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    kind: EntryKind,
    native: fn(&mut Reader<'_>, &Node, &str) -> Option<T>,
    name_of: fn(&T) -> (&str, &Loc),
    ok: &mut bool,
) -> (Vec<T>, Vec<MemberRef>) {
    let mut natives = Vec::new();
    let mut members: Vec<MemberRef> = Vec::new();
    let Some(node) = node else {
        return (natives, members);
    };
    let Some(list) = r.array(node, path) else {
        *ok = false;
        return (natives, members);
    };
    for (i, item) in list.iter().enumerate() {
        let ipath = index(path, i);
        if item.get("link_id").is_none() {
            if let Some(m) = item.get_member("refine") {
                r.error_help(
                    Code::RefineWithoutLinkId,
                    m.key_span,
                    &crate::read::join(&ipath, "refine"),
                    format!("`refine` on a native entry of `{path}`"),
                    "a native entry states its own lengths (`$length` in its `message_format`); `refine` is for entries with a `link_id`",
                );
                *ok = false;
                continue;
            }
            match native(r, item, &ipath) {
                Some(v) => natives.push(v),
                None => *ok = false,
            }
            continue;
        }
        match parse_member(r, item, &ipath, kind, path) {
            Some(m) => members.push(m),
            None => *ok = false,
        }
    }
    crate::entries::check_unique(r, kind, natives.iter().map(name_of));
    for (i, m) in members.iter().enumerate() {
        if let Some(first) = members[..i]
            .iter()
            .find(|o| o.link_id == m.link_id && o.name == m.name)
        {
            let lc = first.loc.file.line_col(first.loc.span.start);
            r.diags.push(
                m.loc
                    .error(
                        Code::DuplicateInterfaceEntry,
                        format!(
                            "`{}` of `{}` is listed twice in `{path}`",
                            m.name, m.link_id
                        ),
                    )
                    .with_help(format!(
                        "list each member once; it is already listed at line {}, column {}",
                        lc.line, lc.column
                    )),
            );
            *ok = false;
        }
    }
    (natives, members)
}

fn parse_member(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    kind: EntryKind,
    section: &str,
) -> Option<MemberRef> {
    let shape_keys: &[&str] = match kind {
        EntryKind::Topic => &["qos_profile", "message_format"],
        EntryKind::Service => &["request_message_format", "response_message_format"],
        EntryKind::Action => &["goal_service", "feedback_topic", "result_service"],
    };
    let mut ok = true;
    if let Value::Object(members) = &node.value {
        for m in members
            .iter()
            .filter(|m| shape_keys.contains(&m.key.as_str()))
        {
            r.error_help(
                Code::LinkedEntryWithInlineShape,
                m.key_span,
                &crate::read::join(path, &m.key),
                format!("`{}` on an entry with a `link_id` in `{section}`", m.key),
                "an entry with a `link_id` takes its shape from the contract or pairing of that slot; remove the key, or remove `link_id` to declare the entry natively",
            );
            ok = false;
        }
    }
    let mut allowed = vec!["link_id", "name", "refine"];
    allowed.extend_from_slice(shape_keys);
    let obj = r.object(node, path, &allowed)?;
    let link_id = read_link_id(r, &obj, "link_id");
    let name = parse_entry_name(r, &obj, kind);
    let refine = match obj.get("refine") {
        Some(n) => {
            let v = parse_refine(r, n, &obj.path_of("refine"), kind);
            ok &= v.is_some();
            v
        }
        None => None,
    };
    let (link_id, (name, _)) = (link_id?, name?);
    ok.then(|| MemberRef {
        kind,
        link_id,
        name,
        refine,
        loc: r.loc(node.span, path),
    })
}

/// `node/v1`'s consumed entries: `{ link_id, name, refine? }` only (no
/// external topics).
pub(super) fn parse_consumed_by_link(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    kind: EntryKind,
    ok: &mut bool,
) -> Vec<(ConsumedRef, Option<Refine>)> {
    let Some(node) = node else { return Vec::new() };
    let Some(list) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, item) in list.iter().enumerate() {
        let ipath = index(path, i);
        if kind == EntryKind::Topic
            && item.get("link_id").is_none()
            && let Some(m) = item.get_member("message_format")
        {
            r.error_help(
                Code::UnknownKey,
                m.key_span,
                &crate::read::join(&ipath, "message_format"),
                "external consumed topics are `node_v1`'s spelling; `node/v1` consumes through a slot",
                "declare the producer (`depends_on.nodes` or `.contracts`) and write `{ link_id, name }`",
            );
            *ok = false;
            continue;
        }
        let Some(obj) = r.object(item, &ipath, &["link_id", "name", "refine"]) else {
            *ok = false;
            continue;
        };
        let link_id = read_link_id(r, &obj, "link_id");
        let name = parse_entry_name(r, &obj, kind);
        let refine = match obj.get("refine") {
            Some(n) => match parse_refine(r, n, &obj.path_of("refine"), kind) {
                Some(v) => Some(v),
                None => {
                    *ok = false;
                    None
                }
            },
            None => None,
        };
        match (link_id, name) {
            (Some(link_id), Some((name, _))) => out.push((
                ConsumedRef {
                    link_id,
                    name,
                    refine: None,
                    loc: r.loc(item.span, &ipath),
                },
                refine,
            )),
            _ => *ok = false,
        }
    }
    out
}

/// The slot a link_id names, for `node/v1`'s cross-reference rules.
enum SlotOf {
    Implements,
    Node,
    Contract,
    Participant,
    Observer,
    None,
}

fn slot_of(doc: &NodeDoc, link_id: &str) -> SlotOf {
    if doc
        .conforms_to
        .iter()
        .any(|c| c.link_id.as_deref() == Some(link_id))
    {
        return SlotOf::Implements;
    }
    if let Some(d) = doc.dependency(link_id) {
        return match d.kind {
            SlotKind::Node => SlotOf::Node,
            SlotKind::Interface => SlotOf::Contract,
        };
    }
    match doc.pairings.iter().find(|p| p.link_id == link_id) {
        Some(p) if p.observer => SlotOf::Observer,
        Some(_) => SlotOf::Participant,
        None => SlotOf::None,
    }
}

fn declared(doc: &NodeDoc) -> Vec<&str> {
    doc.conforms_to
        .iter()
        .filter_map(|c| c.link_id.as_deref())
        .chain(doc.dependencies.iter().map(|d| d.link_id.as_str()))
        .chain(doc.pairings.iter().map(|p| p.link_id.as_str()))
        .collect()
}

/// The cross-references of a `node/v1` document (PeppyOS's
/// `validate_interfaces`): produced members name an `implements` slot (or,
/// for topics, a participant pairing slot), consumed entries a `depends_on`
/// slot, `refine` only where a contract or pairing shapes the entry, and
/// every observer slot is consumed.
pub(super) fn check_member_links(diags: &mut Diagnostics, doc: &NodeDoc) {
    for m in &doc.members {
        let section = produced_section(m.kind);
        let found = match slot_of(doc, &m.link_id) {
            SlotOf::Implements => continue,
            SlotOf::Participant if m.kind == EntryKind::Topic => continue,
            SlotOf::Observer if m.kind == EntryKind::Topic => {
                diags.push(
                    m.loc
                        .error(
                            Code::EmitsOnObserverSlot,
                            format!("`{section}` names observer slot `{}`", m.link_id),
                        )
                        .with_help("an observer only watches: list the watched role's topics under `topics.consumes`"),
                );
                continue;
            }
            SlotOf::None => {
                let ids = declared(doc);
                let help = match crate::diag::did_you_mean(&m.link_id, ids.iter().copied()) {
                    Some(s) => format!("did you mean `{s}`? declare the contract in `manifest.implements`"),
                    None => "declare the contract it comes from in `manifest.implements: [{ name, tag, link_id }]`".to_string(),
                };
                diags.push(
                    m.loc
                        .error(
                            Code::UndeclaredEmitsLinkId,
                            format!("`{section}` entry `{}` names link_id `{}`, which `manifest` does not declare", m.name, m.link_id),
                        )
                        .with_help(help),
                );
                continue;
            }
            SlotOf::Node => "depends_on.nodes",
            SlotOf::Contract => "depends_on.contracts",
            SlotOf::Participant => "depends_on.pairings",
            SlotOf::Observer => "depends_on.pairing_observers",
        };
        diags.push(
            m.loc
                .error(
                    Code::EmitsLinkIdNotImplements,
                    format!("`{section}` entry `{}` names `{}`, a `{found}` slot", m.name, m.link_id),
                )
                .with_help(if m.kind == EntryKind::Topic {
                    "a produced entry names an `implements` slot or a pairing slot this node takes part in"
                } else {
                    "services and actions are provided through an `implements` slot (pairings are topics-only)"
                }),
        );
    }
    let consumed = consumed_links(
        &doc.consumed_topics,
        &doc.consumed_services,
        &doc.consumed_actions,
    );
    for (kind, link_id, loc) in consumed {
        match slot_of(doc, link_id) {
            SlotOf::Implements => diags.push(
                loc.error(
                    Code::ConsumedItemReferencesImplementsLinkId,
                    format!("consumed {kind} names `{link_id}`, an `implements` slot"),
                )
                .with_help("a node does not consume what it implements; to relay a contract, also declare it under `depends_on.contracts` with another link_id"),
            ),
            SlotOf::Participant | SlotOf::Observer if kind != EntryKind::Topic => diags.push(
                loc.error(
                    Code::ConsumedItemReferencesPairingLinkId,
                    format!("consumed {kind} names pairing slot `{link_id}`"),
                )
                .with_help("pairings are topics-only"),
            ),
            SlotOf::None => diags.push(undeclared_link(kind, link_id, loc, &declared(doc))),
            _ => {}
        }
    }
    for (link_id, name, refine_loc) in doc.consumed_refines() {
        if matches!(slot_of(doc, link_id), SlotOf::Node) {
            diags.push(
                refine_loc
                    .error(
                        Code::RefineOnNodeSlot,
                        format!("`refine` on `{name}`, consumed through node slot `{link_id}`"),
                    )
                    .with_help("a node slot takes the producer's own shape; `refine` pins lengths a contract or pairing leaves open"),
            );
        }
    }
    for p in doc.pairings.iter().filter(|p| p.observer) {
        let consumed = doc
            .consumed_topics
            .iter()
            .any(|t| matches!(&t.source, TopicSource::Linked { link_id } if *link_id == p.link_id));
        if !consumed {
            diags.push(
                p.loc
                    .error(
                        Code::ObserverLinkNeverConsumed,
                        format!("observer slot `{}` is never consumed", p.link_id),
                    )
                    .with_help(format!(
                        "list the watched role's topics under `interfaces.topics.consumes` as `{{ link_id: \"{}\", name: ... }}`, or remove the slot",
                        p.link_id
                    )),
            );
        }
    }
}

fn produced_section(kind: EntryKind) -> &'static str {
    match kind {
        EntryKind::Topic => "interfaces.topics.emits",
        EntryKind::Service => "interfaces.services.exposes",
        EntryKind::Action => "interfaces.actions.exposes",
    }
}
