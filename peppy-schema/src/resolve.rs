//! Resolution: everything code generation and the launcher need about one
//! node, with its conformed interfaces and dependency slots looked up in
//! the repositories and sha256 pins checked.

use std::path::PathBuf;
use std::sync::Arc;

use serde::Serialize;

use crate::diag::{Code, Diagnostic, Diagnostics, list};
use crate::document::{DocumentKind, Spelling};
use crate::entries::{ActionDecl, EntryKind, QosProfile, ServiceDecl, TopicDecl};
use crate::format::MessageFormat;
use crate::interface::InterfaceDoc;
use crate::node::RefinedMessage;
use crate::node::{ConsumedRef, Dependency, Identity, NodeDoc, SlotKind, TopicSource};
use crate::pairing_slots::ResolvedPairing;
use crate::read::Loc;
use crate::repos::{Entry, RepoIndex};

/// Where a topic, service or action lives on the wire: a node's own
/// declaration, or one inherited from an interface it conforms to. The two
/// never cross, even with equal names.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "identity")]
pub enum Origin {
    /// Declared by the node itself (`node/<name>/<tag>`).
    Node(Identity),
    /// Inherited from a conformed interface (`interface/<name>/<tag>`).
    Interface(Identity),
}

/// An entry a node provides, with where it comes from.
#[derive(Debug, Clone)]
pub struct Provided<T> {
    /// The declaration (from the node or the interface document).
    pub decl: T,
    /// Its wire identity.
    pub origin: Origin,
}

/// The slot a linked entry is consumed through.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SlotRef {
    /// The slot's link_id.
    pub link_id: String,
    /// Node or interface slot.
    pub kind: SlotKind,
    /// The producer node or interface of the slot.
    pub target: Identity,
    /// Whether the slot takes any number of producers.
    pub from_any: bool,
}

/// A consumed topic, resolved.
#[derive(Debug, Clone)]
pub struct ResolvedTopic {
    /// Topic name.
    pub name: String,
    /// The slot, or `None` for an external topic.
    pub slot: Option<SlotRef>,
    /// The producer-side wire identity (`None` for external topics, which
    /// accept any emitter).
    pub origin: Option<Origin>,
    /// Payload format (`None`: no payload).
    pub format: Option<MessageFormat>,
    /// The producer's QoS profile (external topics: `standard`).
    pub qos: QosProfile,
    /// Where the consumer declares it.
    pub loc: Loc,
}

/// A consumed service or action, resolved through its slot.
#[derive(Debug, Clone)]
pub struct ResolvedCall<T> {
    /// The slot.
    pub slot: SlotRef,
    /// The producer-side declaration.
    pub decl: T,
    /// The producer-side wire identity.
    pub origin: Origin,
    /// Where the consumer declares it.
    pub loc: Loc,
}

/// An interface document a node depends on or conforms to.
#[derive(Debug, Clone)]
pub struct UsedInterface {
    /// The document.
    pub doc: Arc<InterfaceDoc>,
    /// Its file.
    pub path: PathBuf,
}

/// One node with everything it provides and consumes resolved.
#[derive(Debug, Clone)]
pub struct ResolvedNode {
    /// The node's own document.
    pub node: Arc<NodeDoc>,
    /// Conformed interfaces, in `conforms_to` order.
    pub conformed: Vec<UsedInterface>,
    /// Own emitted topics, then those of each conformed interface.
    pub emitted_topics: Vec<Provided<TopicDecl>>,
    /// Own exposed services, then conformed ones.
    pub exposed_services: Vec<Provided<ServiceDecl>>,
    /// Own exposed actions, then conformed ones.
    pub exposed_actions: Vec<Provided<ActionDecl>>,
    /// Consumed topics, in declaration order.
    pub consumed_topics: Vec<ResolvedTopic>,
    /// Consumed services, in declaration order.
    pub consumed_services: Vec<ResolvedCall<ServiceDecl>>,
    /// Consumed actions, in declaration order.
    pub consumed_actions: Vec<ResolvedCall<ActionDecl>>,
    /// Pairing slots, participants and observers, in declaration order.
    pub pairings: Vec<ResolvedPairing>,
    /// Every file read to resolve the node (for rebuild tracking).
    pub files: Vec<PathBuf>,
}

/// What a node offers: own entries and those inherited through `conforms_to`.
struct Offer {
    topics: Vec<Provided<TopicDecl>>,
    services: Vec<Provided<ServiceDecl>>,
    actions: Vec<Provided<ActionDecl>>,
    /// What a producer provides only through a contract, hidden from a
    /// node slot of a `node/v1` node: `(kind, name, implements link_id)`.
    contract_backed: Vec<(EntryKind, String, String)>,
}

impl Offer {
    fn names(&self, kind: EntryKind) -> Vec<&str> {
        match kind {
            EntryKind::Topic => self.topics.iter().map(|t| t.decl.name.as_str()).collect(),
            EntryKind::Service => self.services.iter().map(|t| t.decl.name.as_str()).collect(),
            EntryKind::Action => self.actions.iter().map(|t| t.decl.name.as_str()).collect(),
        }
    }
}

/// Resolves `node` (whose file is `node_path`) against `index`.
pub fn resolve_node(
    node: Arc<NodeDoc>,
    node_path: PathBuf,
    index: &RepoIndex,
) -> Result<(ResolvedNode, Diagnostics), Diagnostics> {
    let mut diags = Diagnostics::new();
    let mut files = vec![node_path];

    // What this node provides: its own entries, then its interfaces'.
    let mut provides = node_offer(&node);
    let mut conformed = Vec::new();
    for c in &node.conforms_to {
        let Some(entry) = find_interface(
            index,
            &c.target,
            c.sha256.as_deref(),
            &c.loc,
            "conforms to",
            &mut diags,
        ) else {
            continue;
        };
        files.push(entry.path.clone());
        let mut offer = interface_offer(&entry.doc, &c.target);
        if let Some(link_id) = &c.link_id {
            check_coverage(&node, link_id, c, &entry.doc, &mut diags);
            offer.refine_members(&node, link_id);
        }
        provides.extend(offer);
        conformed.push(UsedInterface {
            doc: entry.doc.clone(),
            path: entry.path.clone(),
        });
    }

    let pairings = crate::pairing_slots::resolve_pairings(&node, index, &mut files, &mut diags);
    let node = with_counterparts(node, &pairings);

    // What each slot offers.
    let mut offers: Vec<(&Dependency, Offer)> = Vec::new();
    for dep in &node.dependencies {
        let offer = match dep.kind {
            SlotKind::Interface => {
                let Some(entry) = find_interface(
                    index,
                    &dep.target,
                    dep.sha256.as_deref(),
                    &dep.loc,
                    "depends on",
                    &mut diags,
                ) else {
                    continue;
                };
                files.push(entry.path.clone());
                interface_offer(&entry.doc, &dep.target)
            }
            SlotKind::Node => {
                // A node that hears peers of its own kind (a swarm, a
                // scaffold greeting its neighbours) is its own producer:
                // its document answers for its `name:tag` before any
                // repository, so it resolves where no repository lists it.
                let producer: &NodeDoc = if is_itself(&node, &dep.target) {
                    &node
                } else {
                    let Some(entry) = find_node(index, &dep.target, &dep.loc, &mut diags) else {
                        continue;
                    };
                    files.push(entry.path.clone());
                    &entry.doc
                };
                let natives_only = node.spelling == Spelling::SlashIds;
                match producer_offer(producer, index, dep, natives_only, &mut files, &mut diags) {
                    Some(o) => o,
                    None => continue,
                }
            }
        };
        offers.push((dep, offer));
    }

    let consumed_topics = resolve_topics(&node, &offers, &mut diags);
    let consumed_services = resolve_calls(
        &node.consumed_services,
        &offers,
        |o| &o.services,
        EntryKind::Service,
        &mut diags,
    );
    let consumed_actions = resolve_calls(
        &node.consumed_actions,
        &offers,
        |o| &o.actions,
        EntryKind::Action,
        &mut diags,
    );

    files.sort();
    files.dedup();
    let resolved = ResolvedNode {
        node,
        conformed,
        emitted_topics: provides.topics,
        exposed_services: provides.services,
        exposed_actions: provides.actions,
        consumed_topics,
        consumed_services,
        consumed_actions,
        pairings,
        files,
    };
    diags.into_result(resolved)
}

/// The node with each pairing slot's counterpart role filled in from its
/// pairing, so the model a binary embeds carries it.
fn with_counterparts(node: Arc<NodeDoc>, pairings: &[ResolvedPairing]) -> Arc<NodeDoc> {
    if pairings.is_empty() {
        return node;
    }
    let mut doc = (*node).clone();
    for slot in &mut doc.pairings {
        if let Some(r) = pairings.iter().find(|r| r.slot.link_id == slot.link_id) {
            slot.counterpart = r.slot.counterpart.clone();
        }
    }
    Arc::new(doc)
}

/// A declaration's name, for matching consumers to producers.
trait Named: Sized {
    fn name(&self) -> &str;
    /// The format `refine` names (`None`: the entry has no such message).
    fn message(&self, which: RefinedMessage) -> Option<Option<MessageFormat>>;
    /// The declaration as a node refining it with `refine` sees it.
    fn refined(&self, refine: Option<&crate::node::Refine>) -> Self;
}

impl Named for TopicDecl {
    fn name(&self) -> &str {
        &self.name
    }
    fn refined(&self, refine: Option<&crate::node::Refine>) -> Self {
        TopicDecl::refined(self, refine)
    }
    fn message(&self, which: RefinedMessage) -> Option<Option<MessageFormat>> {
        (which == RefinedMessage::Topic).then(|| self.format.clone())
    }
}

impl Named for ServiceDecl {
    fn name(&self) -> &str {
        &self.name
    }
    fn refined(&self, refine: Option<&crate::node::Refine>) -> Self {
        ServiceDecl::refined(self, refine)
    }
    fn message(&self, which: RefinedMessage) -> Option<Option<MessageFormat>> {
        match which {
            RefinedMessage::Request => Some(self.request.clone()),
            RefinedMessage::Response => Some(self.response.clone()),
            _ => None,
        }
    }
}

impl Named for ActionDecl {
    fn name(&self) -> &str {
        &self.name
    }
    fn refined(&self, refine: Option<&crate::node::Refine>) -> Self {
        ActionDecl::refined(self, refine)
    }
    fn message(&self, which: RefinedMessage) -> Option<Option<MessageFormat>> {
        crate::node::action_message(self, which)
    }
}

/// Checks a consumed entry's `refine` against what its producer declares.
fn check_consumed_refine<T: Named>(
    refine: Option<&crate::node::Refine>,
    decl: &T,
    diags: &mut Diagnostics,
) {
    if let Some(refine) = refine {
        let problems = crate::node::check_refine(refine, |which| decl.message(which));
        refinement_problems(decl.name(), problems, diags);
    }
}

/// `items`, each with the wire identity `origin`.
fn provided<T: Clone>(items: &[T], origin: &Origin) -> Vec<Provided<T>> {
    items
        .iter()
        .map(|d| Provided {
            decl: d.clone(),
            origin: origin.clone(),
        })
        .collect()
}

/// A node's own entries.
fn node_offer(node: &NodeDoc) -> Offer {
    let own = Origin::Node(node.identity());
    Offer {
        topics: provided(&node.emits, &own),
        services: provided(&node.exposed_services, &own),
        actions: provided(&node.exposed_actions, &own),
        contract_backed: Vec::new(),
    }
}

/// The entries of interface `identity`.
fn interface_offer(doc: &InterfaceDoc, identity: &Identity) -> Offer {
    let origin = Origin::Interface(identity.clone());
    Offer {
        topics: provided(&doc.topics, &origin),
        services: provided(&doc.services, &origin),
        actions: provided(&doc.actions, &origin),
        contract_backed: Vec::new(),
    }
}

impl Offer {
    /// The members a node implements under `link_id`, as its `refine`s
    /// pin them.
    fn refine_members(&mut self, node: &NodeDoc, link_id: &str) {
        let refine = |kind: EntryKind, name: &str| {
            node.members
                .iter()
                .find(|m| m.kind == kind && m.link_id == link_id && m.name == name)
                .and_then(|m| m.refine.as_ref())
        };
        for p in &mut self.topics {
            p.decl = p.decl.refined(refine(EntryKind::Topic, &p.decl.name));
        }
        for p in &mut self.services {
            p.decl = p.decl.refined(refine(EntryKind::Service, &p.decl.name));
        }
        for p in &mut self.actions {
            p.decl = p.decl.refined(refine(EntryKind::Action, &p.decl.name));
        }
    }

    fn extend(&mut self, other: Offer) {
        self.topics.extend(other.topics);
        self.services.extend(other.services);
        self.actions.extend(other.actions);
    }
}

fn slot_of(dep: &Dependency) -> SlotRef {
    SlotRef {
        link_id: dep.link_id.clone(),
        kind: dep.kind,
        target: dep.target.clone(),
        from_any: dep.from_any,
    }
}

/// Consumed topics: external ones with their own format, linked ones with
/// the format and QoS their slot's producer declares.
fn resolve_topics(
    node: &NodeDoc,
    offers: &[(&Dependency, Offer)],
    diags: &mut Diagnostics,
) -> Vec<ResolvedTopic> {
    let mut out = Vec::new();
    for t in &node.consumed_topics {
        match &t.source {
            TopicSource::External(format) => out.push(ResolvedTopic {
                name: t.name.clone(),
                slot: None,
                origin: None,
                format: Some(format.clone()),
                qos: QosProfile::Standard,
                loc: t.loc.clone(),
            }),
            TopicSource::Linked { link_id } => {
                let Some((dep, offer)) = offers.iter().find(|(d, _)| &d.link_id == link_id) else {
                    continue;
                };
                match offer.topics.iter().find(|p| p.decl.name == t.name) {
                    Some(p) => {
                        check_consumed_refine(t.refine.as_ref(), &p.decl, diags);
                        out.push(ResolvedTopic {
                            name: t.name.clone(),
                            slot: Some(slot_of(dep)),
                            origin: Some(p.origin.clone()),
                            format: p.decl.refined(t.refine.as_ref()).format,
                            qos: p.decl.qos,
                            loc: t.loc.clone(),
                        })
                    }
                    None => diags.push(missing_on_producer(
                        &t.loc,
                        EntryKind::Topic,
                        &t.name,
                        dep,
                        offer,
                    )),
                }
            }
        }
    }
    out
}

/// Consumed services or actions, each matched to its slot producer's
/// declaration (`pick` chooses which of the offer's lists).
fn resolve_calls<T: Clone + Named>(
    refs: &[ConsumedRef],
    offers: &[(&Dependency, Offer)],
    pick: fn(&Offer) -> &Vec<Provided<T>>,
    kind: EntryKind,
    diags: &mut Diagnostics,
) -> Vec<ResolvedCall<T>> {
    let mut out = Vec::new();
    for c in refs {
        let Some((dep, offer)) = offers.iter().find(|(d, _)| d.link_id == c.link_id) else {
            continue;
        };
        match pick(offer).iter().find(|p| p.decl.name() == c.name) {
            Some(p) => {
                check_consumed_refine(c.refine.as_ref(), &p.decl, diags);
                out.push(ResolvedCall {
                    slot: slot_of(dep),
                    decl: p.decl.refined(c.refine.as_ref()),
                    origin: p.origin.clone(),
                    loc: c.loc.clone(),
                })
            }
            None => diags.push(missing_on_producer(&c.loc, kind, &c.name, dep, offer)),
        }
    }
    out
}

/// A producer node's offer: own entries win a name clash with conformed
/// ones. A `node/v1` consumer sees only the producer's own
/// entries through a node slot (`natives_only`): what a contract shapes is
/// consumed through a contract slot.
fn producer_offer(
    producer: &NodeDoc,
    index: &RepoIndex,
    dep: &Dependency,
    natives_only: bool,
    files: &mut Vec<PathBuf>,
    diags: &mut Diagnostics,
) -> Option<Offer> {
    let mut offer = node_offer(producer);
    if natives_only {
        offer.contract_backed = producer
            .members
            .iter()
            .map(|m| (m.kind, m.name.clone(), m.link_id.clone()))
            .collect();
        return Some(offer);
    }
    for c in &producer.conforms_to {
        // The producer's own pins are checked when the producer is built; here
        // we only need the contract it inherits.
        let Some(entry) = index.interface(&c.target) else {
            diags.push(
                dep.loc
                    .error(
                        Code::DependencyNotFound,
                        format!("dependency `{}` conforms to interface `{}`, which no repository provides", dep.target, c.target),
                    )
                    .with_help(index.searched()),
            );
            return None;
        };
        files.push(entry.path.clone());
        let origin = Origin::Interface(c.target.clone());
        for t in &entry.doc.topics {
            if !offer.topics.iter().any(|p| p.decl.name == t.name) {
                offer.topics.push(Provided {
                    decl: t.clone(),
                    origin: origin.clone(),
                });
            }
        }
        for s in &entry.doc.services {
            if !offer.services.iter().any(|p| p.decl.name == s.name) {
                offer.services.push(Provided {
                    decl: s.clone(),
                    origin: origin.clone(),
                });
            }
        }
        for a in &entry.doc.actions {
            if !offer.actions.iter().any(|p| p.decl.name == a.name) {
                offer.actions.push(Provided {
                    decl: a.clone(),
                    origin: origin.clone(),
                });
            }
        }
    }
    Some(offer)
}

fn missing_on_producer(
    loc: &Loc,
    kind: EntryKind,
    name: &str,
    dep: &Dependency,
    offer: &Offer,
) -> Diagnostic {
    if let Some((_, _, link_id)) = offer
        .contract_backed
        .iter()
        .find(|(k, n, _)| *k == kind && n == name)
    {
        return loc
            .error(
                Code::ConsumedInterfaceOnlyContractBacked,
                format!(
                    "node `{}` provides {kind} `{name}` only through its contract slot `{link_id}`, and a node slot sees only a producer's own entries",
                    dep.target
                ),
            )
            .with_help("consume it through `depends_on.contracts` (the contract that node implements), and link that slot to the instance");
    }
    let what = match dep.kind {
        SlotKind::Node => format!("node `{}`", dep.target),
        SlotKind::Interface => format!("interface `{}`", dep.target),
    };
    let offered = offer.names(kind);
    let help = match crate::diag::did_you_mean(name, offered.iter().copied()) {
        Some(s) => format!(
            "did you mean `{s}`? {what} offers {kind}s: {}",
            list(offered.iter().copied())
        ),
        None => format!("{what} offers {kind}s: {}", list(offered.iter().copied())),
    };
    loc.error(
        Code::MissingOnProducer,
        format!("slot `{}` ({what}) has no {kind} `{name}`", dep.link_id),
    )
    .with_help(help)
}

/// `node/v1`'s explicit member list of one `implements` slot against the
/// contract: each member exactly once, in the section of its kind
/// (`ContractCoverageMismatch`); then every `refine` of those members
/// lands on an open array (`RefinementMismatch`).
fn check_coverage(
    node: &NodeDoc,
    link_id: &str,
    claim: &crate::node::InterfaceRef,
    contract: &InterfaceDoc,
    diags: &mut Diagnostics,
) {
    let listed: Vec<&crate::node::MemberRef> = node
        .members
        .iter()
        .filter(|m| m.link_id == link_id)
        .collect();
    let has = |kind: EntryKind, name: &str| match kind {
        EntryKind::Topic => contract.topics.iter().any(|t| t.name == name),
        EntryKind::Service => contract.services.iter().any(|t| t.name == name),
        EntryKind::Action => contract.actions.iter().any(|t| t.name == name),
    };
    let all = [EntryKind::Topic, EntryKind::Service, EntryKind::Action];
    let mut problems = Vec::new();
    for kind in all {
        let names: Vec<&str> = match kind {
            EntryKind::Topic => contract.topics.iter().map(|t| t.name.as_str()).collect(),
            EntryKind::Service => contract.services.iter().map(|t| t.name.as_str()).collect(),
            EntryKind::Action => contract.actions.iter().map(|t| t.name.as_str()).collect(),
        };
        let missing: Vec<&str> = names
            .into_iter()
            .filter(|n| !listed.iter().any(|m| m.kind == kind && m.name == *n))
            .collect();
        if !missing.is_empty() {
            problems.push(format!("missing {kind}s: {}", list(missing)));
        }
    }
    for m in &listed {
        if has(m.kind, &m.name) {
            continue;
        }
        let elsewhere = all.iter().find(|k| **k != m.kind && has(**k, &m.name));
        problems.push(match elsewhere {
            Some(k) => format!(
                "wrong kind: `{}` is {} {k} of the contract, listed as {} {}",
                m.name,
                article(*k),
                article(m.kind),
                m.kind
            ),
            None => format!("unknown {}: `{}`", m.kind, m.name),
        });
    }
    if !problems.is_empty() {
        diags.push(
            claim
                .loc
                .error(
                    Code::ContractCoverageMismatch,
                    format!(
                        "implements slot `{link_id}` does not list the members of contract `{}`: {}",
                        claim.target,
                        problems.join("; ")
                    ),
                )
                .with_help(format!(
                    "list every member of `{}` once, in the section of its kind, as `{{ link_id: \"{link_id}\", name: \"<member>\" }}`",
                    claim.target
                )),
        );
        return;
    }
    for m in listed {
        let Some(refine) = &m.refine else { continue };
        let problems = crate::node::check_refine(refine, |which| {
            use crate::node::RefinedMessage as R;
            match (m.kind, which) {
                (EntryKind::Topic, R::Topic) => contract
                    .topics
                    .iter()
                    .find(|t| t.name == m.name)
                    .map(|t| t.format.clone()),
                (EntryKind::Service, R::Request | R::Response) => contract
                    .services
                    .iter()
                    .find(|t| t.name == m.name)
                    .map(|s| {
                        if which == R::Request {
                            s.request.clone()
                        } else {
                            s.response.clone()
                        }
                    }),
                (EntryKind::Action, _) => contract
                    .actions
                    .iter()
                    .find(|a| a.name == m.name)
                    .and_then(|a| crate::node::action_message(a, which)),
                _ => None,
            }
        });
        refinement_problems(&m.name, problems, diags);
    }
}

/// "a topic", "a service", "an action".
fn article(kind: EntryKind) -> &'static str {
    match kind {
        EntryKind::Action => "an",
        EntryKind::Topic | EntryKind::Service => "a",
    }
}

fn refinement_problems(name: &str, problems: Vec<(Loc, String)>, diags: &mut Diagnostics) {
    for (loc, what) in problems {
        diags.push(
            loc.error(
                Code::RefinementMismatch,
                format!("`refine` of `{name}`: {what}"),
            )
            .with_help("a pin lands on an array the document leaves open (no `$length`) whose items are scalars"),
        );
    }
}

fn is_itself(node: &NodeDoc, id: &Identity) -> bool {
    node.name == id.name && node.tag == id.tag
}

fn find_node<'i>(
    index: &'i RepoIndex,
    id: &Identity,
    loc: &Loc,
    diags: &mut Diagnostics,
) -> Option<&'i Entry<NodeDoc>> {
    if let Some(e) = index.node(id) {
        return Some(e);
    }
    diags.push(not_found(index, DocumentKind::Node, id, loc));
    None
}

fn not_found(index: &RepoIndex, kind: DocumentKind, id: &Identity, loc: &Loc) -> Diagnostic {
    if let Some(b) = index.broken(kind, id) {
        let first = b
            .diagnostics
            .sorted()
            .first()
            .map(|d| d.jump_line(None))
            .unwrap_or_default();
        return loc
            .error(
                Code::DependencyInvalid,
                format!(
                    "{} `{id}` is defined in `{}`, but that document is invalid",
                    kind.as_str(),
                    b.path.display()
                ),
            )
            .with_help(format!(
                "first problem: {first} (run `peppy-launch validate {}`)",
                b.path.display()
            ));
    }
    let known: Vec<String> = match kind {
        DocumentKind::Interface => index.interface_ids().map(ToString::to_string).collect(),
        _ => index.node_ids().map(ToString::to_string).collect(),
    };
    let mut help = index.searched();
    if let Some(s) = crate::diag::did_you_mean(&id.to_string(), known.iter().map(String::as_str)) {
        help = format!("did you mean `{s}`? {help}");
    }
    loc.error(
        Code::DependencyNotFound,
        format!("no repository provides {} `{id}`", kind.as_str()),
    )
    .with_help(help)
}

fn find_interface<'i>(
    index: &'i RepoIndex,
    id: &Identity,
    pin: Option<&str>,
    loc: &Loc,
    relation: &str,
    diags: &mut Diagnostics,
) -> Option<&'i Entry<InterfaceDoc>> {
    let candidates = index.interfaces(id);
    if candidates.is_empty() {
        diags.push(not_found(index, DocumentKind::Interface, id, loc));
        return None;
    }
    let Some(pin) = pin else {
        return candidates.first();
    };
    if let Some(e) = candidates.iter().find(|e| e.doc.sha256 == pin) {
        return Some(e);
    }
    let actual: Vec<String> = candidates
        .iter()
        .map(|e| format!("`{}` in `{}`", e.doc.sha256, e.path.display()))
        .collect();
    diags.push(
        loc.error(
            Code::InterfacePinMismatch,
            format!(
                "this node {relation} `{id}` pinned to sha256 `{pin}`, but the interface document has sha256 {}",
                actual.join(", ")
            ),
        )
        .with_help(format!(
            "the interface changed since it was pinned: review the change, then set `sha256: \"{}\"` (or restore the pinned revision)",
            candidates[0].doc.sha256
        )),
    );
    None
}
