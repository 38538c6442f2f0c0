//! `refine` (`node/v1`): pinning lengths a contract or pairing
//! leaves open. A refinement mirrors the member's structure down to the
//! array: a field maps to `{ $length: N }`, `{ $items: { ... } }` (into an
//! array of objects) or a map of nested refinements (into an object).
//! Parsing checks the shape; [`check_refine`] checks, once the document the
//! member comes from is read, that every pin lands on an open array of
//! scalar items.

use super::*;
use crate::entries::FeedbackDecl;
use crate::format::{Field, FieldType};

/// A member's `refine` block: one format refinement per message the
/// member carries.
#[derive(Debug, Clone)]
pub struct Refine {
    /// The refined messages, in document order.
    pub formats: Vec<(RefinedMessage, FormatRefine)>,
    /// Where the block is.
    pub loc: Loc,
}

/// Which message of a member a refinement is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefinedMessage {
    /// A topic's `message_format`.
    Topic,
    /// A service's `request_message_format`.
    Request,
    /// A service's `response_message_format`.
    Response,
    /// An action's `goal_service.request_message_format`.
    GoalRequest,
    /// An action's `goal_service.response_message_format`.
    GoalResponse,
    /// An action's `feedback_topic.message_format`.
    Feedback,
    /// An action's `result_service.response_message_format`.
    Result,
}

impl RefinedMessage {
    /// The key path inside `refine`.
    pub fn as_str(self) -> &'static str {
        match self {
            RefinedMessage::Topic => "message_format",
            RefinedMessage::Request => "request_message_format",
            RefinedMessage::Response => "response_message_format",
            RefinedMessage::GoalRequest => "goal_service.request_message_format",
            RefinedMessage::GoalResponse => "goal_service.response_message_format",
            RefinedMessage::Feedback => "feedback_topic.message_format",
            RefinedMessage::Result => "result_service.response_message_format",
        }
    }
}

/// Refinements of the fields of one object.
#[derive(Debug, Clone)]
pub struct FormatRefine {
    /// The refined fields, in document order.
    pub fields: Vec<FieldRefine>,
}

/// One refined field.
#[derive(Debug, Clone)]
pub struct FieldRefine {
    /// The field's name.
    pub field: String,
    /// What is pinned.
    pub pin: Pin,
    /// Where the field's key is.
    pub loc: Loc,
}

/// What a refinement does to one field.
#[derive(Debug, Clone)]
pub enum Pin {
    /// `{ $length: N }`: the open array gets N items.
    Length(u32),
    /// `{ $items: { ... } }`: refinements inside an array of objects.
    Items(FormatRefine),
    /// `{ field: ... }`: refinements inside an object.
    Nested(FormatRefine),
}

/// Reads a `refine` block of a member of `kind`.
pub(super) fn parse_refine(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    kind: EntryKind,
) -> Option<Refine> {
    let keys: &[&str] = match kind {
        EntryKind::Topic => &["message_format"],
        EntryKind::Service => &["request_message_format", "response_message_format"],
        EntryKind::Action => &["goal_service", "feedback_topic", "result_service"],
    };
    let obj = r.object(node, path, keys)?;
    let mut ok = true;
    // Every message refined, with where: read once the shape is known.
    let mut targets: Vec<(RefinedMessage, &Node, String)> = Vec::new();
    for m in obj.members {
        let p = obj.path_of(&m.key);
        let nested: &[(&str, RefinedMessage)] = match (kind, m.key.as_str()) {
            (EntryKind::Topic, "message_format") => {
                targets.push((RefinedMessage::Topic, &m.value, p));
                continue;
            }
            (EntryKind::Service, "request_message_format") => {
                targets.push((RefinedMessage::Request, &m.value, p));
                continue;
            }
            (EntryKind::Service, "response_message_format") => {
                targets.push((RefinedMessage::Response, &m.value, p));
                continue;
            }
            (EntryKind::Action, "goal_service") => &[
                ("request_message_format", RefinedMessage::GoalRequest),
                ("response_message_format", RefinedMessage::GoalResponse),
            ],
            (EntryKind::Action, "feedback_topic") => {
                &[("message_format", RefinedMessage::Feedback)]
            }
            (EntryKind::Action, "result_service") => {
                &[("response_message_format", RefinedMessage::Result)]
            }
            // Unknown keys were reported by `object`.
            _ => {
                ok = false;
                continue;
            }
        };
        let keys: Vec<&str> = nested.iter().map(|(k, _)| *k).collect();
        let Some(inner) = r.object(&m.value, &p, &keys) else {
            ok = false;
            continue;
        };
        if inner.members.is_empty() {
            empty_block(r, &m.value, &p);
            ok = false;
        }
        for (key, which) in nested {
            if let Some(n) = inner.get(key) {
                targets.push((*which, n, inner.path_of(key)));
            }
        }
    }
    let mut formats = Vec::new();
    for (which, n, p) in targets {
        match parse_format_refine(r, n, &p) {
            Some(f) => formats.push((which, f)),
            None => ok = false,
        }
    }
    if obj.members.is_empty() {
        empty_block(r, node, path);
        return None;
    }
    ok.then(|| Refine {
        formats,
        loc: r.loc(node.span, path),
    })
}

fn empty_block(r: &mut Reader<'_>, node: &Node, path: &str) {
    r.error_help(
        Code::InvalidRefine,
        node.span,
        path,
        format!("`{path}` is empty"),
        "a refinement pins at least one length; remove the empty block",
    );
}

/// A map of field refinements.
fn parse_format_refine(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<FormatRefine> {
    let Value::Object(members) = &node.value else {
        r.error(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected an object of field refinements for `{path}`, found {}",
                node.value.kind()
            ),
        );
        return None;
    };
    if members.is_empty() {
        empty_block(r, node, path);
        return None;
    }
    let mut ok = true;
    let mut fields = Vec::new();
    for m in members {
        let p = crate::read::join(path, &m.key);
        if m.key.starts_with('$') {
            r.error_help(
                Code::InvalidRefine,
                m.key_span,
                &p,
                format!("`{}` cannot stand at the level of `{path}`", m.key),
                "a refinement names fields; `$length` and `$items` go inside a field: `{ field: { $length: 7 } }`",
            );
            ok = false;
            continue;
        }
        match parse_field_refine(r, &m.value, &p) {
            Some(pin) => fields.push(FieldRefine {
                field: m.key.clone(),
                pin,
                loc: r.loc(m.key_span, &p),
            }),
            None => ok = false,
        }
    }
    ok.then_some(FormatRefine { fields })
}

/// `{ $length: N }`, `{ $items: {...} }`, or nested field refinements.
fn parse_field_refine(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<Pin> {
    let Value::Object(members) = &node.value else {
        r.error_help(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected an object for `{path}`, found {}",
                node.value.kind()
            ),
            "write `{ $length: N }`, `{ $items: { ... } }` or refinements of the object's fields",
        );
        return None;
    };
    if members.is_empty() {
        empty_block(r, node, path);
        return None;
    }
    let dollar: Vec<&crate::json::Member> =
        members.iter().filter(|m| m.key.starts_with('$')).collect();
    if dollar.is_empty() {
        return parse_format_refine(r, node, path).map(Pin::Nested);
    }
    if dollar.len() != members.len() || dollar.len() > 1 {
        r.error_help(
            Code::InvalidRefine,
            node.span,
            path,
            format!("`{path}` mixes refinement forms"),
            "a field takes exactly one of `{ $length: N }`, `{ $items: { ... } }` or refinements of its fields",
        );
        return None;
    }
    let m = dollar[0];
    let p = crate::read::join(path, &m.key);
    match m.key.as_str() {
        "$length" => r
            .uint(&m.value, &p, crate::MAX_FIXED_LENGTH)
            .map(|n| Pin::Length(n as u32)),
        "$items" => parse_format_refine(r, &m.value, &p).map(Pin::Items),
        other => {
            r.error_help(
                Code::InvalidRefine,
                m.key_span,
                &p,
                format!("unknown refinement `{other}`"),
                "a refinement is `$length` or `$items`",
            );
            None
        }
    }
}

/// Why a pin does not land (PeppyOS's `RefinementProblem` kinds).
fn problem(kind: &str, field: &FieldRefine, what: String) -> (Loc, String) {
    (field.loc.clone(), format!("{kind}: {what}"))
}

/// Checks every pin of `refine` against the member's formats; returns each
/// problem with where it is written.
pub(crate) fn check_refine(
    refine: &Refine,
    message: impl Fn(RefinedMessage) -> Option<Option<MessageFormat>>,
) -> Vec<(Loc, String)> {
    let mut out = Vec::new();
    for (which, f) in &refine.formats {
        match message(*which) {
            Some(Some(format)) => check_fields(&format.fields, f, which.as_str(), &mut out),
            _ => out.push((
                refine.loc.clone(),
                format!(
                    "FormatAbsent: the member has no `{}` to refine",
                    which.as_str()
                ),
            )),
        }
    }
    out
}

fn check_fields(fields: &[Field], refine: &FormatRefine, at: &str, out: &mut Vec<(Loc, String)>) {
    for fr in &refine.fields {
        let Some(field) = fields.iter().find(|f| f.name == fr.field) else {
            let names: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
            out.push(problem(
                "UnknownField",
                fr,
                format!(
                    "`{at}` has no field `{}` (fields: {})",
                    fr.field,
                    crate::diag::list(names)
                ),
            ));
            continue;
        };
        let path = format!("{at}.{}", fr.field);
        match (&fr.pin, &field.ty) {
            (
                Pin::Length(_),
                FieldType::Array {
                    length: Some(n), ..
                },
            ) => out.push(problem(
                "AlreadyFixed",
                fr,
                format!("`{path}` already has `$length: {n}`"),
            )),
            (Pin::Length(_), FieldType::Array { items, .. }) => {
                if !matches!(**items, FieldType::Primitive(_)) {
                    out.push(problem(
                        "UnsupportedItems",
                        fr,
                        format!("`{path}` holds objects; only arrays of scalars take a length"),
                    ));
                }
            }
            (Pin::Items(inner), FieldType::Array { items, .. }) => match &**items {
                FieldType::Object(sub) => check_fields(sub, inner, &format!("{path}[]"), out),
                _ => out.push(problem(
                    "ItemsNotObjects",
                    fr,
                    format!("`{path}` is not an array of objects; `$items` steps into objects"),
                )),
            },
            (Pin::Nested(inner), FieldType::Object(sub)) => check_fields(sub, inner, &path, out),
            (Pin::Nested(_), _) => out.push(problem(
                "NotAnObject",
                fr,
                format!("`{path}` is not an object"),
            )),
            (_, _) => out.push(problem(
                "NotAnArray",
                fr,
                format!("`{path}` is not an array"),
            )),
        }
    }
}

/// `format` (message `which` of a member) as the refining node sees it:
/// every pin of `refine` on that message applied. Pins that do not land
/// are left out ([`check_refine`] reports them).
fn pinned(
    refine: Option<&Refine>,
    which: RefinedMessage,
    format: &Option<MessageFormat>,
) -> Option<MessageFormat> {
    let mut format = format.clone()?;
    for (w, f) in refine.map(|r| r.formats.as_slice()).unwrap_or_default() {
        if *w == which {
            pin_fields(&mut format.fields, f);
        }
    }
    Some(format)
}

fn pin_fields(fields: &mut [Field], refine: &FormatRefine) {
    for fr in &refine.fields {
        let Some(field) = fields.iter_mut().find(|f| f.name == fr.field) else {
            continue;
        };
        match (&fr.pin, &mut field.ty) {
            (
                Pin::Length(n),
                FieldType::Array {
                    items,
                    length: None,
                    pinned,
                },
            ) if matches!(**items, FieldType::Primitive(_)) => *pinned = Some(*n),
            (Pin::Items(inner), FieldType::Array { items, .. }) => {
                if let FieldType::Object(sub) = &mut **items {
                    pin_fields(sub, inner);
                }
            }
            (Pin::Nested(inner), FieldType::Object(sub)) => pin_fields(sub, inner),
            _ => {}
        }
    }
}

impl TopicDecl {
    /// This topic as a node that refines it with `refine` sees it.
    pub(crate) fn refined(&self, refine: Option<&Refine>) -> TopicDecl {
        TopicDecl {
            format: pinned(refine, RefinedMessage::Topic, &self.format),
            ..self.clone()
        }
    }
}

impl ServiceDecl {
    /// This service as a node that refines it with `refine` sees it.
    pub(crate) fn refined(&self, refine: Option<&Refine>) -> ServiceDecl {
        ServiceDecl {
            request: pinned(refine, RefinedMessage::Request, &self.request),
            response: pinned(refine, RefinedMessage::Response, &self.response),
            ..self.clone()
        }
    }
}

impl ActionDecl {
    /// This action as a node that refines it with `refine` sees it.
    pub(crate) fn refined(&self, refine: Option<&Refine>) -> ActionDecl {
        let feedback = self.feedback.as_ref().map(|f| FeedbackDecl {
            qos: f.qos,
            format: pinned(refine, RefinedMessage::Feedback, &Some(f.format.clone()))
                .unwrap_or_else(|| f.format.clone()),
        });
        ActionDecl {
            goal: pinned(refine, RefinedMessage::GoalRequest, &self.goal),
            goal_response: pinned(refine, RefinedMessage::GoalResponse, &self.goal_response),
            feedback,
            result: pinned(refine, RefinedMessage::Result, &self.result),
            ..self.clone()
        }
    }
}

/// The formats of an action or service member, by refined message.
pub(crate) fn action_message(
    a: &ActionDecl,
    which: RefinedMessage,
) -> Option<Option<MessageFormat>> {
    match which {
        RefinedMessage::GoalRequest => Some(a.goal.clone()),
        RefinedMessage::GoalResponse => Some(a.goal_response.clone()),
        RefinedMessage::Feedback => {
            Some(a.feedback.as_ref().map(|f: &FeedbackDecl| f.format.clone()))
        }
        RefinedMessage::Result => Some(a.result.clone()),
        _ => None,
    }
}
