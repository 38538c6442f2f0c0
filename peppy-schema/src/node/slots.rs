//! `manifest.depends_on` (slots, link ids, sha256 pins) and `conforms_to`.

use super::*;

pub(super) fn read_identity_part(
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

pub(super) fn parse_depends_on(
    r: &mut Reader<'_>,
    node: &Node,
    legacy: bool,
) -> Option<Vec<Dependency>> {
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
        // `node_v1`'s `from_any` slot takes any number; a pinned one, one.
        cardinality: if from_any {
            crate::model::Cardinality::ZeroOrMore
        } else {
            crate::model::Cardinality::One
        },
        sha256,
        loc: r.loc(node.span, path),
    })
}

pub(super) fn read_link_id(r: &mut Reader<'_>, obj: &Obj<'_>, key: &str) -> Option<String> {
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

pub(super) fn parse_conforms_to(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    ok: &mut bool,
) -> Vec<InterfaceRef> {
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
            link_id: None,
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
