//! Consumed topics, services and actions: linked to a slot by `link_id`
//! (legacy `local_node_id`), or external topics with their own format.

use super::slots::read_link_id;
use super::*;

pub(super) fn parse_consumed_topics(
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
                refine: None,
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

pub(super) fn parse_consumed_refs(
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
                refine: None,
                loc: r.loc(item.span, &ipath),
            }),
            _ => *ok = false,
        }
    }
    out
}
