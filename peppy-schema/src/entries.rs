//! Topic, service and action declarations: the shapes shared by a node's
//! emits / exposes and an interface document's contract.

use std::fmt;

use serde::Serialize;

use crate::diag::{Code, did_you_mean, list};
use crate::document::Spelling;
use crate::format::{MessageFormat, parse_optional_format};
use crate::json::Node;
use crate::names::check_entry_name;
use crate::read::{Loc, Reader, index};

/// Service names the runtime keeps for itself.
pub const RESERVED_SERVICE_NAMES: &[&str] = &["node_ready", "node_health", "shutdown"];

pub(crate) use crate::qos::{QOS_NAMES, QosProfile};

/// An emitted topic (or an interface's topic).
#[derive(Debug, Clone)]
pub struct TopicDecl {
    /// Topic name.
    pub name: String,
    /// QoS profile.
    pub qos: QosProfile,
    /// Payload format; `None` for a message with no payload.
    pub format: Option<MessageFormat>,
    /// Where it is declared.
    pub loc: Loc,
}

/// An exposed service (or an interface's service).
#[derive(Debug, Clone)]
pub struct ServiceDecl {
    /// Service name.
    pub name: String,
    /// Request format; `None` for no request payload.
    pub request: Option<MessageFormat>,
    /// Response format; `None` for no response payload.
    pub response: Option<MessageFormat>,
    /// Where it is declared.
    pub loc: Loc,
}

/// An exposed action (or an interface's action).
#[derive(Debug, Clone)]
pub struct ActionDecl {
    /// Action name.
    pub name: String,
    /// Goal request format.
    pub goal: Option<MessageFormat>,
    /// The declared goal response (`goal_service.response_message_format`,
    /// the current `node/v1` and `contract/v1` spelling): data the server
    /// sends with its decision, beside the framework's accepted flag and
    /// reason. `node_v1` and `interface_v1` have none.
    pub goal_response: Option<MessageFormat>,
    /// Feedback topic, if the action publishes feedback.
    pub feedback: Option<FeedbackDecl>,
    /// Result format.
    pub result: Option<MessageFormat>,
    /// Where it is declared.
    pub loc: Loc,
}

/// An action's feedback stream.
#[derive(Debug, Clone)]
pub struct FeedbackDecl {
    /// QoS profile of the stream.
    pub qos: QosProfile,
    /// Feedback payload.
    pub format: MessageFormat,
}

/// What kind of entry, for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EntryKind {
    /// A topic.
    Topic,
    /// A service.
    Service,
    /// An action.
    Action,
}

/// A topic, service or action declaration: its name and where it is
/// written, for what lays out or describes any of the three alike.
pub trait Declared {
    /// The entry's name.
    fn name(&self) -> &str;
    /// Where the declaration is.
    fn decl_loc(&self) -> &Loc;
}

macro_rules! declared {
    ($($decl:ty),*) => {$(
        impl Declared for $decl {
            fn name(&self) -> &str {
                &self.name
            }
            fn decl_loc(&self) -> &Loc {
                &self.loc
            }
        }
    )*};
}

declared!(TopicDecl, ServiceDecl, ActionDecl);

impl EntryKind {
    /// `topic`, `service`, `action`.
    pub fn as_str(self) -> &'static str {
        match self {
            EntryKind::Topic => "topic",
            EntryKind::Service => "service",
            EntryKind::Action => "action",
        }
    }
}

impl fmt::Display for EntryKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

pub(crate) fn parse_qos(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    ok: &mut bool,
) -> QosProfile {
    let Some(node) = node else {
        return QosProfile::default();
    };
    let Some(s) = r.string(node, path) else {
        *ok = false;
        return QosProfile::default();
    };
    match QosProfile::parse(&s) {
        Some(q) => q,
        None => {
            let help = match did_you_mean(&s, QOS_NAMES.iter().copied()) {
                Some(c) => format!(
                    "did you mean `{c}`? profiles: {}",
                    list(QOS_NAMES.iter().copied())
                ),
                None => format!("profiles: {}", list(QOS_NAMES.iter().copied())),
            };
            r.error_help(
                Code::InvalidValue,
                node.span,
                path,
                format!("unknown qos_profile `{s}`"),
                help,
            );
            *ok = false;
            QosProfile::default()
        }
    }
}

/// Reads an entry's `name` and checks it; `None` with an error when absent or invalid.
pub(crate) fn parse_entry_name(
    r: &mut Reader<'_>,
    obj: &crate::read::Obj<'_>,
    kind: EntryKind,
) -> Option<(String, Loc)> {
    let node = r.required(obj, "name")?;
    let path = obj.path_of("name");
    let name = r.string(node, &path)?;
    if let Err(why) = check_entry_name(&name) {
        r.error(
            Code::InvalidEntryName,
            node.span,
            &path,
            format!("invalid {kind} name `{name}`: {why}"),
        );
        return None;
    }
    Some((name, r.loc(node.span, &path)))
}

/// Reports names that appear twice in one list.
pub(crate) fn check_unique<'a>(
    r: &mut Reader<'_>,
    kind: EntryKind,
    entries: impl IntoIterator<Item = (&'a str, &'a Loc)>,
) {
    let mut seen: Vec<(&str, &Loc)> = Vec::new();
    for (name, loc) in entries {
        if let Some((_, first)) = seen.iter().find(|(n, _)| *n == name) {
            let lc = first.file.line_col(first.span.start);
            let d = loc
                .error(
                    Code::DuplicateEntryName,
                    format!("duplicate {kind} name `{name}`"),
                )
                .with_help(format!(
                    "`{name}` is already declared at line {}, column {}",
                    lc.line, lc.column
                ));
            r.diags.push(d);
        } else {
            seen.push((name, loc));
        }
    }
}

/// The keys of a topic declaration.
pub(crate) const TOPIC_KEYS: &[&str] = &["name", "qos_profile", "message_format"];

pub(crate) fn parse_topic(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<TopicDecl> {
    let obj = r.object(node, path, TOPIC_KEYS)?;
    topic_fields(r, &obj)
}

/// A topic's [`TOPIC_KEYS`] read from an object whose keys the caller has
/// checked: a pairing's topic is a topic declaration plus `emitted_by`, read
/// by this one grammar so names, QoS and formats follow the same rules.
pub(crate) fn topic_fields(r: &mut Reader<'_>, obj: &crate::read::Obj<'_>) -> Option<TopicDecl> {
    let mut ok = true;
    let name = parse_entry_name(r, obj, EntryKind::Topic);
    let qos = parse_qos(
        r,
        obj.get("qos_profile"),
        &obj.path_of("qos_profile"),
        &mut ok,
    );
    let format = parse_optional_format(
        r,
        obj.get("message_format"),
        &obj.path_of("message_format"),
        &mut ok,
    );
    let (name, loc) = name?;
    ok.then_some(TopicDecl {
        name,
        qos,
        format,
        loc,
    })
}

pub(crate) fn parse_service(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<ServiceDecl> {
    let obj = r.object(
        node,
        path,
        &["name", "request_message_format", "response_message_format"],
    )?;
    let mut ok = true;
    let name = parse_entry_name(r, &obj, EntryKind::Service);
    if let Some((n, loc)) = &name
        && RESERVED_SERVICE_NAMES.contains(&n.as_str())
    {
        r.diags.push(
            loc.error(
                Code::ReservedServiceName,
                format!("service name `{n}` is reserved by the runtime"),
            )
            .with_help(format!(
                "reserved: {}; pick another name",
                list(RESERVED_SERVICE_NAMES.iter().copied())
            )),
        );
        ok = false;
    }
    let request = parse_optional_format(
        r,
        obj.get("request_message_format"),
        &obj.path_of("request_message_format"),
        &mut ok,
    );
    let response = parse_optional_format(
        r,
        obj.get("response_message_format"),
        &obj.path_of("response_message_format"),
        &mut ok,
    );
    let (name, loc) = name?;
    ok.then_some(ServiceDecl {
        name,
        request,
        response,
        loc,
    })
}

/// An action as `node_v1` and `interface_v1` spell it.
pub(crate) fn parse_action(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<ActionDecl> {
    parse_action_in(r, node, path, Spelling::UnderscoreIds)
}

/// An action as `contract/v1` and `node/v1` spell it: a result request
/// takes no format (an unknown key, not an ignored one), and the feedback
/// topic may carry a `type` and a `name`, which peppy does not use.
pub(crate) fn parse_contract_action(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
) -> Option<ActionDecl> {
    parse_action_in(r, node, path, Spelling::SlashIds)
}

fn parse_action_in(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    spelling: Spelling,
) -> Option<ActionDecl> {
    let slashed = spelling == Spelling::SlashIds;
    let obj = r.object(
        node,
        path,
        &["name", "goal_service", "feedback_topic", "result_service"],
    )?;
    let mut ok = true;
    let name = parse_entry_name(r, &obj, EntryKind::Action);
    let mut goal = None;
    let mut goal_response = None;
    if let Some(g) = obj.get("goal_service") {
        let gpath = obj.path_of("goal_service");
        if let Some(gobj) = r.object(
            g,
            &gpath,
            &["request_message_format", "response_message_format"],
        ) {
            goal = parse_optional_format(
                r,
                gobj.get("request_message_format"),
                &gobj.path_of("request_message_format"),
                &mut ok,
            );
            if slashed {
                goal_response = parse_optional_format(
                    r,
                    gobj.get("response_message_format"),
                    &gobj.path_of("response_message_format"),
                    &mut ok,
                );
            } else if let Some(m) = gobj.member("response_message_format") {
                r.warn_help(
                    Code::IgnoredKey,
                    m.key_span,
                    &gobj.path_of("response_message_format"),
                    "`goal_service.response_message_format` is ignored",
                    "a goal response is always `{ accepted: bool, error_message: optional string }` in the `node_v1` spelling; declare the node in `node/v1` to send data with the decision",
                );
            }
        } else {
            ok = false;
        }
    }
    let mut feedback = None;
    if let Some(f) = obj.get("feedback_topic") {
        let fpath = obj.path_of("feedback_topic");
        let keys: &[&str] = if slashed {
            &["qos_profile", "message_format", "type", "name"]
        } else {
            &["qos_profile", "message_format"]
        };
        if let Some(fobj) = r.object(f, &fpath, keys) {
            for key in ["type", "name"] {
                if let Some(m) = fobj.member(key) {
                    r.warn_help(
                        Code::IgnoredKey,
                        m.key_span,
                        &fobj.path_of(key),
                        format!("`feedback_topic.{key}` is not used by peppy"),
                        "a feedback stream is named by its action; the key can stay",
                    );
                }
            }
            let qos = parse_qos(
                r,
                fobj.get("qos_profile"),
                &fobj.path_of("qos_profile"),
                &mut ok,
            );
            match r.required(&fobj, "message_format") {
                Some(mf) => {
                    match crate::format::parse_format(r, mf, &fobj.path_of("message_format")) {
                        Some(format) => feedback = Some(FeedbackDecl { qos, format }),
                        None => ok = false,
                    }
                }
                None => ok = false,
            }
        } else {
            ok = false;
        }
    }
    let mut result = None;
    if let Some(s) = obj.get("result_service") {
        let spath = obj.path_of("result_service");
        let keys: &[&str] = if slashed {
            &["response_message_format"]
        } else {
            &["request_message_format", "response_message_format"]
        };
        if let Some(sobj) = r.object(s, &spath, keys) {
            result = parse_optional_format(
                r,
                sobj.get("response_message_format"),
                &sobj.path_of("response_message_format"),
                &mut ok,
            );
            if let Some(m) = sobj.member("request_message_format") {
                r.warn_help(
                    Code::IgnoredKey,
                    m.key_span,
                    &sobj.path_of("request_message_format"),
                    "`result_service.request_message_format` is ignored",
                    "a result request only names the goal; remove the key",
                );
            }
        } else {
            ok = false;
        }
    }
    let (name, loc) = name?;
    ok.then_some(ActionDecl {
        name,
        goal,
        goal_response,
        feedback,
        result,
        loc,
    })
}

/// Parses a list with `item` and checks names are unique.
pub(crate) fn parse_list<T>(
    r: &mut Reader<'_>,
    node: Option<&Node>,
    path: &str,
    kind: EntryKind,
    ok: &mut bool,
    item: fn(&mut Reader<'_>, &Node, &str) -> Option<T>,
    name_of: fn(&T) -> (&str, &Loc),
) -> Vec<T> {
    let Some(node) = node else { return Vec::new() };
    let Some(items) = r.array(node, path) else {
        *ok = false;
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, n) in items.iter().enumerate() {
        match item(r, n, &index(path, i)) {
            Some(v) => out.push(v),
            None => *ok = false,
        }
    }
    check_unique(r, kind, out.iter().map(name_of));
    out
}

pub(crate) fn topic_name(t: &TopicDecl) -> (&str, &Loc) {
    (&t.name, &t.loc)
}
pub(crate) fn service_name(s: &ServiceDecl) -> (&str, &Loc) {
    (&s.name, &s.loc)
}
pub(crate) fn action_name(a: &ActionDecl) -> (&str, &Loc) {
    (&a.name, &a.loc)
}
