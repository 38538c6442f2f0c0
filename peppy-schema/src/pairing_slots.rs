//! Resolving a node's pairing slots against their `pairing/v1` documents:
//! the role exists, the slot lists exactly the topics its role emits and
//! only the counterpart's (or, for an observer, the watched role's) topics
//! it consumes, and pins hold (docs/PAIRINGS.md §1).

use std::path::PathBuf;
use std::sync::Arc;

use crate::diag::{Code, Diagnostic, Diagnostics, list};
use crate::entries::EntryKind;
use crate::node::{NodeDoc, PairingSlot, Refine, RefinedMessage, TopicSource};
use crate::pairing::{PairingDoc, PairingTopic};
use crate::read::Loc;
use crate::repos::{Entry, RepoIndex};

/// One topic of a pairing as a slot uses it.
#[derive(Debug, Clone)]
pub struct PairingTopicUse {
    /// The pairing's topic (name, QoS, format, emitting role).
    pub topic: PairingTopic,
    /// Where the node lists it.
    pub loc: Loc,
}

/// A pairing slot with its document and the topics it sends and receives.
#[derive(Debug, Clone)]
pub struct ResolvedPairing {
    /// The slot, its `counterpart` filled in.
    pub slot: PairingSlot,
    /// The pairing document.
    pub doc: Arc<PairingDoc>,
    /// Its file.
    pub path: PathBuf,
    /// A participant's topics, every one its role emits, in the node's
    /// `emits` order; empty for an observer.
    pub emitted: Vec<PairingTopicUse>,
    /// A participant's: the counterpart's topics it consumes; an
    /// observer's: the watched role's topics it consumes. In the node's
    /// `consumes` order.
    pub consumed: Vec<PairingTopicUse>,
}

/// Resolves every pairing slot of `node`; the documents read are added to
/// `files`.
pub(crate) fn resolve_pairings(
    node: &NodeDoc,
    index: &RepoIndex,
    files: &mut Vec<PathBuf>,
    diags: &mut Diagnostics,
) -> Vec<ResolvedPairing> {
    let mut out = Vec::new();
    for slot in &node.pairings {
        let Some(entry) = find_pairing(index, slot, diags) else {
            continue;
        };
        files.push(entry.path.clone());
        let doc = &entry.doc;
        let Some(counterpart) = doc.counterpart(&slot.role) else {
            diags.push(
                slot.loc
                    .error(
                        Code::PairingRoleUnknown,
                        format!(
                            "slot `{}` {} role `{}`, which pairing `{}` does not have",
                            slot.link_id,
                            if slot.observer { "watches" } else { "plays" },
                            slot.role,
                            slot.pairing
                        ),
                    )
                    .with_help(format!("its roles are {}", list(doc.role_names()))),
            );
            continue;
        };
        let mut slot = slot.clone();
        slot.counterpart = counterpart.to_string();
        let emitted = if slot.observer {
            Vec::new()
        } else {
            emitted_topics(node, &slot, doc, diags)
        };
        let consumed = consumed_topics(node, &slot, doc, diags);
        out.push(ResolvedPairing {
            slot,
            doc: doc.clone(),
            path: entry.path.clone(),
            emitted,
            consumed,
        });
    }
    out
}

/// The pairing document a slot names, its pin checked.
fn find_pairing<'i>(
    index: &'i RepoIndex,
    slot: &PairingSlot,
    diags: &mut Diagnostics,
) -> Option<&'i Entry<PairingDoc>> {
    let candidates = index.pairings(&slot.pairing);
    if candidates.is_empty() {
        diags.push(not_found(index, slot));
        return None;
    }
    let Some(pin) = &slot.sha256 else {
        return candidates.first();
    };
    if let Some(e) = candidates.iter().find(|e| &e.doc.sha256 == pin) {
        return Some(e);
    }
    let actual: Vec<String> = candidates
        .iter()
        .map(|e| format!("`{}` in `{}`", e.doc.sha256, e.path.display()))
        .collect();
    diags.push(
        slot.loc
            .error(
                Code::PairingShaMismatch,
                format!(
                    "slot `{}` pins pairing `{}` to sha256 `{pin}`, but the pairing document has sha256 {}",
                    slot.link_id,
                    slot.pairing,
                    actual.join(", ")
                ),
            )
            .with_help(format!(
                "the pairing changed since it was pinned: review the change, then set `sha256: \"{}\"`",
                candidates[0].doc.sha256
            )),
    );
    None
}

fn not_found(index: &RepoIndex, slot: &PairingSlot) -> Diagnostic {
    let id = &slot.pairing;
    if let Some(b) = index.broken(crate::document::DocumentKind::Pairing, id) {
        return slot
            .loc
            .error(
                Code::DependencyInvalid,
                format!(
                    "pairing `{id}` is defined in `{}`, but that document is invalid",
                    b.path.display()
                ),
            )
            .with_help(format!("run `peppy-launch validate {}`", b.path.display()));
    }
    let known: Vec<String> = index.pairing_ids().map(ToString::to_string).collect();
    let mut help = index.searched();
    if let Some(s) = crate::diag::did_you_mean(&id.to_string(), known.iter().map(String::as_str)) {
        help = format!("did you mean `{s}`? {help}");
    }
    slot.loc
        .error(
            Code::DependencyNotFound,
            format!("no repository provides pairing `{id}`"),
        )
        .with_help(help)
}

/// A participant's `emits` under its slot: exactly the topics its role
/// emits, each once.
fn emitted_topics(
    node: &NodeDoc,
    slot: &PairingSlot,
    doc: &PairingDoc,
    diags: &mut Diagnostics,
) -> Vec<PairingTopicUse> {
    let listed: Vec<_> = node
        .members
        .iter()
        .filter(|m| m.kind == EntryKind::Topic && m.link_id == slot.link_id)
        .collect();
    let mut problems = Vec::new();
    let missing: Vec<&str> = doc
        .emitted_by(&slot.role)
        .map(|t| t.decl.name.as_str())
        .filter(|n| !listed.iter().any(|m| m.name == *n))
        .collect();
    if !missing.is_empty() {
        problems.push(format!("missing: {}", list(missing)));
    }
    let mut out = Vec::new();
    for (i, m) in listed.iter().enumerate() {
        if listed[..i].iter().any(|o| o.name == m.name) {
            problems.push(format!("`{}` is listed twice", m.name));
            continue;
        }
        match doc.topic(&m.name) {
            None => problems.push(format!("unknown topic `{}`", m.name)),
            Some(t) if t.emitted_by != slot.role => problems.push(format!(
                "`{}` is emitted by role `{}`, not `{}`",
                m.name, t.emitted_by, slot.role
            )),
            Some(t) => {
                check_refine(m.refine.as_ref(), t, diags);
                out.push(PairingTopicUse {
                    topic: t.refined(m.refine.as_ref()),
                    loc: m.loc.clone(),
                });
            }
        }
    }
    if !problems.is_empty() {
        let expected: Vec<&str> = doc
            .emitted_by(&slot.role)
            .map(|t| t.decl.name.as_str())
            .collect();
        diags.push(
            slot.loc
                .error(
                    Code::PairingCoverageMismatch,
                    format!(
                        "pairing slot `{}` does not list the topics role `{}` of `{}` emits: {}",
                        slot.link_id,
                        slot.role,
                        slot.pairing,
                        problems.join("; ")
                    ),
                )
                .with_help(if expected.is_empty() {
                    format!(
                        "role `{}` emits nothing: list no `emits` under `{}`",
                        slot.role, slot.link_id
                    )
                } else {
                    format!(
                        "list each of {} once under `interfaces.topics.emits` as `{{ link_id: \"{}\", name: ... }}`",
                        list(expected),
                        slot.link_id
                    )
                }),
        );
    }
    out
}

/// The topics a slot consumes: a participant the counterpart's, an
/// observer the watched role's.
fn consumed_topics(
    node: &NodeDoc,
    slot: &PairingSlot,
    doc: &PairingDoc,
    diags: &mut Diagnostics,
) -> Vec<PairingTopicUse> {
    let from_role = if slot.observer {
        &slot.role
    } else {
        &slot.counterpart
    };
    let mut out = Vec::new();
    for t in &node.consumed_topics {
        if !matches!(&t.source, TopicSource::Linked { link_id } if *link_id == slot.link_id) {
            continue;
        }
        let offered: Vec<&str> = doc
            .emitted_by(from_role)
            .map(|t| t.decl.name.as_str())
            .collect();
        let problem = match doc.topic(&t.name) {
            Some(p) if &p.emitted_by == from_role => {
                check_refine(t.refine.as_ref(), p, diags);
                out.push(PairingTopicUse {
                    topic: p.refined(t.refine.as_ref()),
                    loc: t.loc.clone(),
                });
                continue;
            }
            Some(p) if slot.observer => format!(
                "observer slot `{}` watches role `{}`, and `{}` is emitted by `{}`",
                slot.link_id, slot.role, t.name, p.emitted_by
            ),
            Some(_) => format!(
                "slot `{}` plays role `{}`, which emits `{}` itself",
                slot.link_id, slot.role, t.name
            ),
            None => format!("pairing `{}` has no topic `{}`", slot.pairing, t.name),
        };
        let help = match crate::diag::did_you_mean(&t.name, offered.iter().copied()) {
            Some(s) => format!(
                "did you mean `{s}`? role `{from_role}` emits {}",
                list(offered)
            ),
            None if offered.is_empty() => format!("role `{from_role}` emits nothing"),
            None => format!("role `{from_role}` emits {}", list(offered)),
        };
        diags.push(
            t.loc
                .error(Code::PairingCoverageMismatch, problem)
                .with_help(help),
        );
    }
    out
}

/// A `refine` on a pairing topic lands on an open array of scalars.
fn check_refine(refine: Option<&Refine>, topic: &PairingTopic, diags: &mut Diagnostics) {
    let Some(refine) = refine else { return };
    let problems = crate::node::check_refine(refine, |which| {
        (which == RefinedMessage::Topic).then(|| topic.decl.format.clone())
    });
    for (loc, what) in problems {
        diags.push(
            loc.error(
                Code::RefinementMismatch,
                format!("`refine` of `{}`: {what}", topic.decl.name),
            )
            .with_help("a pin lands on an array the document leaves open (no `$length`) whose items are scalars"),
        );
    }
}

impl PairingTopic {
    /// This topic as a node that refines it with `refine` sees it.
    fn refined(&self, refine: Option<&Refine>) -> PairingTopic {
        PairingTopic {
            decl: self.decl.refined(refine),
            ..self.clone()
        }
    }
}
