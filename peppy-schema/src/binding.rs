//! The binding engine: which slot each binding fills, and the routing
//! filter every slot applies (SPEC 5 and 6.1).
//!
//! This is the one implementation of those rules. The launcher's plan
//! (`check`, `up`, `graph`) feeds it bindings whose producers it knows from
//! the launcher file; a node started on its own (`run --bind`, a plain
//! `cargo run`, a Python node through `peppy-launch plan`) feeds it `--bind`
//! flags whose producers it may not know. The rules and the wording of
//! every error are the same in both; only the help text differs, because
//! the fix is spelled differently in a launcher file and on a command line.
//! A node started by the launcher takes the slots it is handed as they are
//! ([`fit_plan`] only checks they are its slots): nothing binds twice.

use std::collections::BTreeSet;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::diag::{Code, list};
use crate::model::{Cardinality, Dependency, Identity, SlotKind, Spelling};

/// What fills one slot.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum SlotBinding {
    /// A pinned slot bound to one producer.
    Pinned {
        /// The producer instance.
        producer: String,
    },
    /// A `from_any` slot with explicit producers: only these flow in.
    FromAnyBound {
        /// Producer instances, in binding order.
        producers: Vec<String>,
    },
    /// A `from_any` slot without bindings: any unclaimed producer of its kind.
    FromAnyUnbound,
    /// A slot of `node/v1`'s cardinality (`zero_or_one`, `one_or_more`,
    /// `zero_or_more`): exactly these producers, in link order, fixed for
    /// the instance's life. Empty: nothing flows in (an empty
    /// `zero_or_more` slot, or a vacated `zero_or_one` one).
    Set {
        /// Producer instances, in link order.
        producers: Vec<String>,
        /// Why a `zero_or_one` slot is vacant (`{ vacant: "why" }`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vacant: Option<String>,
    },
}

/// Which producers' messages a consumer keeps for one slot (SPEC 5).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(
    rename_all = "snake_case",
    tag = "kind",
    content = "producers",
    deny_unknown_fields
)]
pub enum RouteFilter {
    /// Only this producer.
    Pin(String),
    /// Only these producers.
    OnlyFrom(BTreeSet<String>),
    /// Any producer of the slot's kind except these.
    AnyExcept(BTreeSet<String>),
    /// Any producer of the slot's kind.
    Any,
}

impl RouteFilter {
    /// Whether a message from `producer` (already of the slot's kind) passes.
    pub fn accepts(&self, producer: &str) -> bool {
        match self {
            RouteFilter::Pin(p) => p == producer,
            RouteFilter::OnlyFrom(set) => set.contains(producer),
            RouteFilter::AnyExcept(set) => !set.contains(producer),
            RouteFilter::Any => true,
        }
    }
}

/// One slot of one consumer instance, filled. The launcher hands each
/// instance its slots in its runtime config; the node applies them as
/// they are ([`fit_plan`]), it never binds again.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlotPlan {
    /// The slot's link_id.
    pub link_id: String,
    /// Node or interface slot.
    pub kind: SlotKind,
    /// The node or interface it wants.
    pub target: Identity,
    /// What fills it.
    pub binding: SlotBinding,
    /// The consumer-side filter.
    pub filter: RouteFilter,
}

impl SlotPlan {
    /// The server a request through this slot goes to without asking
    /// anyone: the pinned producer, or the one producer a `from_any` slot's
    /// filter lets through. `None`: requests probe every server of the
    /// slot's kind and take the first the filter accepts.
    pub fn named_server(&self) -> Option<&str> {
        match (&self.binding, &self.filter) {
            (SlotBinding::Pinned { producer }, _) => Some(producer),
            (_, RouteFilter::OnlyFrom(set)) if set.len() == 1 => {
                set.iter().next().map(String::as_str)
            }
            _ => None,
        }
    }
}

/// What the engine knows of a producer instance: the node it runs and the
/// interfaces that node conforms to.
#[derive(Debug, Clone, Copy)]
pub struct Producer<'a> {
    /// The node the instance runs.
    pub node: &'a Identity,
    /// The interfaces that node declares in `conforms_to`.
    pub conforms_to: &'a [Identity],
}

impl Producer<'_> {
    /// Whether an instance of this node can fill a slot of `kind` wanting
    /// `target`: a node slot takes exactly that node, an interface slot any
    /// node that declares conformance (a matching name does not count).
    pub fn fits(&self, kind: SlotKind, target: &Identity) -> bool {
        match kind {
            SlotKind::Node => self.node == target,
            SlotKind::Interface => self.conforms_to.contains(target),
        }
    }
}

/// The identities of a node's `conforms_to` entries, for [`Producer`].
#[cfg(feature = "documents")]
pub fn conformances(node: &crate::node::NodeDoc) -> Vec<Identity> {
    node.conforms_to.iter().map(|c| c.target.clone()).collect()
}

/// One binding handed to the engine: a key (a slot's link_id or a
/// free-form label) and the producer instance it names, written in one of
/// the [`BindForm`]s.
#[derive(Debug, Clone, Copy)]
pub struct BindRequest<'a> {
    /// The binding key.
    pub key: &'a str,
    /// The producer instance id (empty for [`BindForm::EmptyList`] and
    /// [`BindForm::Vacant`]).
    pub instance: &'a str,
    /// The producer's node, when it is known (it always is in a launcher;
    /// on a command line it is not).
    pub producer: Option<Producer<'a>>,
    /// How the binding is written.
    pub form: BindForm<'a>,
}

/// How a binding is written: the grammar decides which slots it may fill.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum BindForm<'a> {
    /// `launcher_v1`'s `bindings: { key: "inst" }` or `--bind key@inst`: one
    /// producer, possibly under a free-form key; repeating a key adds
    /// producers to a slot that takes several.
    #[default]
    Key,
    /// `launcher/v1`'s `links: { slot: "inst" }`: for a slot that takes one.
    Scalar,
    /// One item of `launcher/v1`'s `links: { slot: ["a", "b"] }`: for a
    /// slot that takes a list.
    Item,
    /// `--link slot@inst` (the `links` grammar), which may repeat for a
    /// list slot.
    Flag,
    /// `launcher/v1`'s `links: { slot: [] }`.
    EmptyList,
    /// `launcher/v1`'s `links: { slot: { vacant: "why" } }` or
    /// `--vacant-link slot=why`.
    Vacant(&'a str),
}

impl<'a> BindRequest<'a> {
    /// A binding in the `bindings` grammar ([`BindForm::Key`]).
    pub fn key(key: &'a str, instance: &'a str, producer: Option<Producer<'a>>) -> Self {
        BindRequest {
            key,
            instance,
            producer,
            form: BindForm::Key,
        }
    }

    /// Whether it names a producer (not an empty list or a vacancy).
    fn names_producer(&self) -> bool {
        !matches!(self.form, BindForm::EmptyList | BindForm::Vacant(_))
    }
}

/// Why a binding, or the lack of one, was refused. `Display` is the message
/// shared by every front end; [`BindError::code`] its stable name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BindError {
    /// A key names a node slot, and the producer runs another node.
    TargetMismatch {
        /// The consumer's spelling (words the message).
        spelling: Spelling,
        /// The consumer instance.
        consumer: String,
        /// The binding key (the slot's link_id).
        key: String,
        /// The producer instance.
        instance: String,
        /// The node the producer runs.
        producer_node: Identity,
        /// The node the slot wants.
        wanted: Identity,
    },
    /// A key names an interface slot, and the producer's node does not
    /// conform to the interface (`node/v1`: does not implement the
    /// contract).
    NotConformed {
        /// The consumer's spelling (names the error).
        spelling: Spelling,
        /// The consumer instance.
        consumer: String,
        /// The binding key (the slot's link_id).
        key: String,
        /// The producer instance.
        instance: String,
        /// The node the producer runs.
        producer_node: Identity,
        /// The interface the slot wants.
        wanted: Identity,
    },
    /// A key names no slot, and no `from_any` slot takes the producer.
    DeadKey {
        /// The consumer instance.
        consumer: String,
        /// The consumer's node.
        node: Identity,
        /// The binding key.
        key: String,
        /// The producer instance.
        instance: String,
        /// The producer's node, when known.
        producer_node: Option<Identity>,
        /// Every slot: `(link_id, kind, target, from_any)`.
        slots: Vec<(String, SlotKind, Identity, bool)>,
    },
    /// A free-form key whose producer's node is unknown, and the consumer
    /// has `from_any` slots of different kinds: which one it fills cannot
    /// be decided without guessing.
    AmbiguousKey {
        /// The consumer instance.
        consumer: String,
        /// The binding key.
        key: String,
        /// The producer instance.
        instance: String,
        /// The candidate `from_any` slots: `(link_id, kind, target)`.
        candidates: Vec<(String, SlotKind, Identity)>,
    },
    /// A pinned slot (`node/v1`: a slot of cardinality `one`) has no
    /// binding.
    PinnedUnbound {
        /// The consumer's spelling (names the error).
        spelling: Spelling,
        /// The consumer instance.
        consumer: String,
        /// The slot's link_id.
        link_id: String,
        /// Node or interface slot.
        kind: SlotKind,
        /// What it wants.
        target: Identity,
    },
    /// A pinned slot (`node/v1`: one of cardinality `one` or
    /// `zero_or_one`) is bound twice.
    PinnedTwice {
        /// The consumer's spelling (names the error).
        spelling: Spelling,
        /// The consumer instance.
        consumer: String,
        /// The slot's link_id.
        link_id: String,
        /// The producer bound first.
        first: String,
        /// The producer bound again.
        second: String,
    },
    /// The `links` grammar: a link key that names no slot (free-form keys
    /// are `node_v1`'s `from_any`).
    UnknownSlot {
        /// The consumer instance.
        consumer: String,
        /// The consumer's node.
        node: Identity,
        /// The link key.
        key: String,
        /// Every slot's link_id, sorted.
        declared: Vec<String>,
    },
    /// A slot of `node/v1`'s cardinality linked in a shape it does not
    /// take.
    Shape {
        /// The consumer instance.
        consumer: String,
        /// The slot.
        link_id: String,
        /// Its cardinality.
        cardinality: Cardinality,
        /// What was wrong.
        problem: ShapeProblem,
    },
    /// A slot that may not stay empty as written: unlinked `one` /
    /// `one_or_more`, a `zero_or_one` left out instead of vacated, or
    /// `[]` on `one_or_more`.
    Unfulfilled {
        /// The consumer instance.
        consumer: String,
        /// The slot.
        link_id: String,
        /// Node or interface slot.
        kind: SlotKind,
        /// What it wants.
        target: Identity,
        /// Its cardinality.
        cardinality: Cardinality,
        /// Written as an empty list (else left out).
        empty_list: bool,
    },
    /// The same producer twice in one slot.
    DuplicateProducer {
        /// The consumer instance.
        consumer: String,
        /// The slot.
        link_id: String,
        /// The producer.
        instance: String,
    },
}

/// How a link's shape disagrees with its slot's cardinality.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeProblem {
    /// A list on a slot that takes one producer.
    ArrayOnScalar,
    /// A single value on a slot that takes a list.
    ScalarOnMulti,
    /// `{ vacant }` on a slot whose cardinality has no vacancy.
    VacantInvalid,
}

fn describe(kind: SlotKind, target: &Identity) -> String {
    format!("{} `{target}`", kind.as_str())
}

impl BindError {
    /// The error's stable name.
    pub fn code(&self) -> Code {
        match self {
            BindError::TargetMismatch { .. } => Code::BindingTargetMismatch,
            BindError::NotConformed {
                spelling: Spelling::UnderscoreIds,
                ..
            } => Code::BindingInterfaceNotConformed,
            BindError::NotConformed { .. } => Code::BindingContractNotImplemented,
            BindError::DeadKey { .. } | BindError::AmbiguousKey { .. } => Code::DeadBindingKey,
            BindError::PinnedUnbound {
                spelling: Spelling::UnderscoreIds,
                ..
            } => Code::PinnedSlotUnbound,
            BindError::PinnedUnbound { .. }
            | BindError::Unfulfilled {
                empty_list: false, ..
            } => Code::BindingSlotUnfulfilled,
            BindError::Unfulfilled { .. } => Code::BindingCardinalityUnmet,
            BindError::PinnedTwice {
                spelling: Spelling::UnderscoreIds,
                ..
            } => Code::DuplicateBindingKey,
            BindError::PinnedTwice { .. } => Code::BindingSingleSlotMultipleTargets,
            BindError::UnknownSlot { .. } => Code::LinkUnknownSlot,
            BindError::Shape { problem, .. } => match problem {
                ShapeProblem::ArrayOnScalar => Code::BindingArrayOnScalarSlot,
                ShapeProblem::ScalarOnMulti => Code::BindingScalarOnMultiSlot,
                ShapeProblem::VacantInvalid => Code::LinkVacantInvalid,
            },
            BindError::DuplicateProducer { .. } => Code::DuplicateBoundProducer,
        }
    }

    /// What would fix it, in the words of a launcher file. `fit` lists the
    /// launcher's instances that could fill an unbound pinned slot.
    pub fn launcher_help(&self, fit: &[String]) -> String {
        match self {
            BindError::PinnedUnbound {
                spelling,
                link_id,
                kind,
                target,
                ..
            } => {
                let key = match spelling {
                    Spelling::UnderscoreIds => "bindings",
                    Spelling::SlashIds => "links",
                };
                match fit.first() {
                    None => format!(
                        "add `{key}: {{ {link_id}: \"<instance_id>\" }}`; no instance in this launcher fills {} yet",
                        describe(*kind, target)
                    ),
                    Some(first) => format!(
                        "add `{key}: {{ {link_id}: \"{first}\" }}`; instances that fit: {}",
                        list(fit.iter().map(String::as_str))
                    ),
                }
            }
            BindError::Unfulfilled {
                link_id,
                cardinality,
                empty_list,
                ..
            } => {
                let first = fit.first().map_or("<instance_id>", String::as_str);
                let fits = if fit.is_empty() {
                    String::new()
                } else {
                    format!(
                        "; instances that fit: {}",
                        list(fit.iter().map(String::as_str))
                    )
                };
                match (cardinality, empty_list) {
                    (Cardinality::ZeroOrOne, _) => format!(
                        "link it (`links: {{ {link_id}: \"{first}\" }}`), or leave it empty on purpose: `links: {{ {link_id}: {{ vacant: \"<why>\" }} }}`{fits}"
                    ),
                    _ => format!(
                        "link at least one producer: `links: {{ {link_id}: [\"{first}\"] }}`{fits}"
                    ),
                }
            }
            BindError::Shape {
                link_id,
                cardinality,
                problem,
                ..
            } => match problem {
                ShapeProblem::ArrayOnScalar => format!(
                    "a `{cardinality}` slot takes one producer: write `{link_id}: \"<instance_id>\"`"
                ),
                ShapeProblem::ScalarOnMulti => format!(
                    "a `{cardinality}` slot takes a list: write `{link_id}: [\"<instance_id>\"]`"
                ),
                ShapeProblem::VacantInvalid => {
                    vacancy_help(*cardinality, "`[]` or leave the slot out")
                }
            },
            BindError::UnknownSlot { .. } | BindError::DuplicateProducer { .. } => {
                self.common_help()
            }
            BindError::AmbiguousKey { candidates, .. } => format!(
                "use one of the slots' link_ids as the key: {}",
                list(candidates.iter().map(|(l, _, _)| l.as_str()))
            ),
            BindError::PinnedTwice { link_id, .. } => {
                format!("a pinned slot takes one producer; keep one binding for `{link_id}`")
            }
            other => other.common_help(),
        }
    }

    /// What would fix it, in the words of a command line (`--bind`, or
    /// `--link` and `--vacant-link`).
    pub fn command_line_help(&self) -> String {
        match self {
            BindError::PinnedUnbound {
                spelling: Spelling::UnderscoreIds,
                link_id,
                ..
            } => {
                format!("pass --bind {link_id}@<producer instance id>")
            }
            BindError::PinnedUnbound { link_id, .. } => {
                format!("pass --link {link_id}@<producer instance id>")
            }
            BindError::Unfulfilled {
                link_id,
                cardinality: Cardinality::ZeroOrOne,
                ..
            } => format!(
                "pass --link {link_id}@<producer instance id>, or --vacant-link '{link_id}=<why>' to leave it empty on purpose"
            ),
            BindError::Unfulfilled { link_id, .. } => {
                format!(
                    "pass --link {link_id}@<producer instance id> (repeat it for more producers)"
                )
            }
            BindError::Shape {
                cardinality,
                problem: ShapeProblem::VacantInvalid,
                ..
            } => vacancy_help(*cardinality, "leave the flag out"),
            BindError::Shape { link_id, .. } => {
                format!("pass --link {link_id}@<producer instance id> once per producer")
            }
            BindError::UnknownSlot { .. } | BindError::DuplicateProducer { .. } => {
                self.common_help()
            }
            BindError::AmbiguousKey {
                instance,
                candidates,
                ..
            } => format!(
                "name the slot: {}",
                candidates
                    .iter()
                    .map(|(l, _, _)| format!("--bind {l}@{instance}"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ),
            BindError::PinnedTwice {
                spelling: Spelling::UnderscoreIds,
                link_id,
                ..
            } => {
                format!("a pinned slot takes one producer; pass --bind {link_id}@... once")
            }
            BindError::PinnedTwice { link_id, .. } => {
                format!("the slot takes one producer; pass --link {link_id}@... once")
            }
            other => other.common_help(),
        }
    }

    fn common_help(&self) -> String {
        match self {
            BindError::TargetMismatch {
                spelling: Spelling::UnderscoreIds,
                wanted,
                ..
            } => format!("bind an instance of `{wanted}`"),
            BindError::TargetMismatch { wanted, .. } => format!("link an instance of `{wanted}`"),
            BindError::NotConformed {
                spelling: Spelling::SlashIds,
                producer_node,
                wanted,
                ..
            } => format!(
                "link an instance of a node that implements it, or add `implements: [{{ name: \"{}\", tag: \"{}\", link_id: \"...\" }}]` (and its members) to `{producer_node}`",
                wanted.name, wanted.tag
            ),
            BindError::NotConformed {
                producer_node,
                wanted,
                ..
            } => format!(
                "bind an instance of a node that declares it, or add `conforms_to: [{{ name: \"{}\", tag: \"{}\" }}]` to `{producer_node}` (a matching name or matching topics do not count)",
                wanted.name, wanted.tag
            ),
            BindError::DeadKey {
                node,
                instance,
                producer_node,
                slots,
                ..
            } => {
                let declared: Vec<&str> = slots.iter().map(|(l, _, _, _)| l.as_str()).collect();
                let from_any: Vec<String> = slots
                    .iter()
                    .filter(|(_, _, _, any)| *any)
                    .map(|(l, k, t, _)| format!("`{l}` ({})", describe(*k, t)))
                    .collect();
                if declared.is_empty() {
                    format!(
                        "node `{node}` declares no slots (`manifest.depends_on` is empty); remove the binding"
                    )
                } else if from_any.is_empty() {
                    format!(
                        "declared link_ids: {}; a free-form key needs a from_any slot, and `{node}` has none",
                        list(declared.iter().copied())
                    )
                } else {
                    let deploys = producer_node
                        .as_ref()
                        .map(|p| format!("; `{instance}` deploys `{p}`"))
                        .unwrap_or_default();
                    format!(
                        "declared link_ids: {}; from_any slots: {}{deploys}",
                        list(declared.iter().copied()),
                        from_any.join(", ")
                    )
                }
            }
            BindError::UnknownSlot { key, declared, .. } => {
                let names = declared.iter().map(String::as_str);
                match crate::diag::did_you_mean(key, names.clone()) {
                    Some(s) => format!("did you mean `{s}`? declared slots: {}", list(names)),
                    None if declared.is_empty() => {
                        "the node declares no slots (`manifest.depends_on` is empty); remove the link".to_string()
                    }
                    None => format!("declared slots: {}", list(names)),
                }
            }
            BindError::DuplicateProducer { instance, .. } => {
                format!("list `{instance}` once")
            }
            // Covered by the front-end specific helps.
            BindError::AmbiguousKey { .. }
            | BindError::PinnedUnbound { .. }
            | BindError::PinnedTwice { .. }
            | BindError::Unfulfilled { .. }
            | BindError::Shape { .. } => String::new(),
        }
    }
}

/// Why a vacancy is refused, by cardinality; `instead` says how an empty
/// `zero_or_more` slot is written in this front end.
fn vacancy_help(cardinality: Cardinality, instead: &str) -> String {
    match cardinality {
        Cardinality::ZeroOrMore => {
            format!("a `zero_or_more` slot can simply stay empty: {instead}")
        }
        _ => format!(
            "a `{cardinality}` slot is required; only a `zero_or_one` slot may be vacant (change the node's cardinality if it may run without a producer)"
        ),
    }
}

impl fmt::Display for BindError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BindError::TargetMismatch {
                spelling,
                consumer,
                key,
                instance,
                producer_node,
                wanted,
            } => write!(
                f,
                "{} `{key}` on instance `{consumer}`: `{instance}` deploys node `{producer_node}`, but slot `{key}` expects node `{wanted}`",
                match spelling {
                    Spelling::UnderscoreIds => "binding",
                    Spelling::SlashIds => "link",
                }
            ),
            BindError::NotConformed {
                spelling: Spelling::UnderscoreIds,
                consumer,
                key,
                instance,
                producer_node,
                wanted,
            } => write!(
                f,
                "binding `{key}` on instance `{consumer}`: `{instance}` deploys `{producer_node}`, which does not conform to interface `{wanted}` required by slot `{key}`"
            ),
            BindError::NotConformed {
                consumer,
                key,
                instance,
                producer_node,
                wanted,
                ..
            } => write!(
                f,
                "link `{key}` on instance `{consumer}`: `{instance}` deploys `{producer_node}`, which does not implement contract `{wanted}` required by slot `{key}`"
            ),
            BindError::DeadKey {
                consumer,
                node,
                key,
                instance,
                ..
            } => write!(
                f,
                "binding `{key}` on instance `{consumer}` matches no slot of `{node}`, and no from_any slot accepts `{instance}`"
            ),
            BindError::AmbiguousKey {
                consumer,
                key,
                instance,
                candidates,
            } => write!(
                f,
                "binding `{key}` on instance `{consumer}` matches no slot, and `{instance}` could fill any of the from_any slots {}; its node is not known here",
                candidates
                    .iter()
                    .map(|(l, k, t)| format!("`{l}` ({})", describe(*k, t)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            BindError::PinnedUnbound {
                spelling: Spelling::UnderscoreIds,
                consumer,
                link_id,
                kind,
                target,
            } => write!(
                f,
                "instance `{consumer}`: pinned slot `{link_id}` ({}) is unbound",
                describe(*kind, target)
            ),
            BindError::PinnedUnbound {
                consumer,
                link_id,
                kind,
                target,
                ..
            } => write!(
                f,
                "instance `{consumer}`: slot `{link_id}` ({}, cardinality one) is not linked",
                describe(*kind, target)
            ),
            BindError::PinnedTwice {
                spelling: Spelling::UnderscoreIds,
                consumer,
                link_id,
                first,
                second,
            } => write!(
                f,
                "instance `{consumer}`: pinned slot `{link_id}` is bound to `{first}` and again to `{second}`"
            ),
            BindError::PinnedTwice {
                consumer,
                link_id,
                first,
                second,
                ..
            } => write!(
                f,
                "instance `{consumer}`: slot `{link_id}` takes one producer and is linked to `{first}` and again to `{second}`"
            ),
            BindError::UnknownSlot {
                consumer,
                node,
                key,
                ..
            } => write!(
                f,
                "link `{key}` on instance `{consumer}` names no slot of `{node}`"
            ),
            BindError::Shape {
                consumer,
                link_id,
                cardinality,
                problem,
            } => match problem {
                ShapeProblem::ArrayOnScalar => write!(
                    f,
                    "instance `{consumer}`: slot `{link_id}` (cardinality {cardinality}) takes one producer, and is linked to a list"
                ),
                ShapeProblem::ScalarOnMulti => write!(
                    f,
                    "instance `{consumer}`: slot `{link_id}` (cardinality {cardinality}) takes a list, and is linked to a single instance"
                ),
                ShapeProblem::VacantInvalid => write!(
                    f,
                    "instance `{consumer}`: slot `{link_id}` (cardinality {cardinality}) cannot be vacant"
                ),
            },
            BindError::Unfulfilled {
                consumer,
                link_id,
                kind,
                target,
                cardinality,
                empty_list,
            } => {
                let what = describe(*kind, target);
                if *empty_list {
                    write!(
                        f,
                        "instance `{consumer}`: slot `{link_id}` ({what}, cardinality {cardinality}) is linked to an empty list"
                    )
                } else {
                    write!(
                        f,
                        "instance `{consumer}`: slot `{link_id}` ({what}, cardinality {cardinality}) is not linked"
                    )
                }
            }
            BindError::DuplicateProducer {
                consumer,
                link_id,
                instance,
            } => write!(
                f,
                "instance `{consumer}`: slot `{link_id}` lists `{instance}` twice"
            ),
        }
    }
}

impl std::error::Error for BindError {}

/// The outcome of [`assign`]: the slots that could be filled, and every
/// error, each with the index of the [`BindRequest`] it is about (`None`
/// for a pinned slot nobody bound).
#[derive(Debug, Clone, Default)]
pub struct Assignment {
    /// Filled slots in `depends_on` order (an unbound pinned slot is left out).
    pub slots: Vec<SlotPlan>,
    /// What was refused.
    pub errors: Vec<(Option<usize>, BindError)>,
}

/// Fills the slots of `consumer` (an instance of `node`, written in
/// `spelling`, whose slots are `dependencies`) from `binds`, in order
/// (SPEC 6.1 rules 2-4, and `launcher/v1`'s link rules):
///
/// - a key equal to a slot's link_id binds that slot, in a shape its
///   cardinality takes ([`BindForm`]), and the producer must fit it when
///   its node is known;
/// - any other key is free-form in the `bindings` grammar and joins the first
///   `from_any` slot, in link_id order, that the producer fits; when the
///   producer's node is not known, that is the first `from_any` slot if all
///   of them want the same thing, and an [`BindError::AmbiguousKey`]
///   otherwise. In the `links` grammar (or for a `node/v1` node)
///   every key must name a slot ([`BindError::UnknownSlot`]);
/// - every slot ends within its cardinality: a pinned (`one`) slot bound,
///   a `one_or_more` slot given a producer, a `zero_or_one` slot linked or
///   vacated on purpose.
///
/// Then each slot gets its routing filter ([`compute_filters`]).
pub fn assign(
    consumer: &str,
    node: &Identity,
    spelling: Spelling,
    dependencies: &[Dependency],
    binds: &[BindRequest<'_>],
) -> Assignment {
    let n = dependencies.len();
    let mut pinned: Vec<Option<&str>> = vec![None; n];
    let mut producers: Vec<Vec<String>> = vec![Vec::new(); n];
    let mut empty_list = vec![false; n];
    let mut vacant: Vec<Option<&str>> = vec![None; n];
    let mut from_any: Vec<usize> = (0..n).filter(|&i| dependencies[i].from_any).collect();
    from_any.sort_by(|&a, &b| dependencies[a].link_id.cmp(&dependencies[b].link_id));
    // A slot whose own binding was refused is not also reported unbound.
    let mut refused_slots: Vec<usize> = Vec::new();
    let mut errors = Vec::new();

    for (index, b) in binds.iter().enumerate() {
        let mut refuse = |e: BindError| errors.push((Some(index), e));
        if let Some(slot) = dependencies.iter().position(|d| d.link_id == b.key) {
            let dep = &dependencies[slot];
            // `node_v1`'s `from_any` slot takes any number: a list, `[]` or
            // a flag, and no vacancy (it may simply stay empty).
            let shape = if dep.from_any {
                matches!(b.form, BindForm::Vacant(_)).then_some(ShapeProblem::VacantInvalid)
            } else {
                shape_problem(dep.cardinality, b.form)
            };
            if let Some(problem) = shape {
                refuse(BindError::Shape {
                    consumer: consumer.to_string(),
                    link_id: dep.link_id.clone(),
                    cardinality: if dep.from_any {
                        Cardinality::ZeroOrMore
                    } else {
                        dep.cardinality
                    },
                    problem,
                });
                refused_slots.push(slot);
                continue;
            }
            match b.form {
                BindForm::EmptyList => {
                    empty_list[slot] = true;
                    continue;
                }
                BindForm::Vacant(why) => {
                    vacant[slot] = Some(why);
                    continue;
                }
                _ => {}
            }
            if let Some(p) = b.producer
                && !p.fits(dep.kind, &dep.target)
            {
                refuse(mismatch(spelling, consumer, b, p, dep));
                refused_slots.push(slot);
                continue;
            }
            if dep.from_any {
                producers[slot].push(b.instance.to_string());
            } else if !dep.cardinality.is_scalar() {
                if producers[slot].iter().any(|p| p == b.instance) {
                    refuse(BindError::DuplicateProducer {
                        consumer: consumer.to_string(),
                        link_id: dep.link_id.clone(),
                        instance: b.instance.to_string(),
                    });
                } else {
                    producers[slot].push(b.instance.to_string());
                }
            } else if let Some(first) = pinned[slot] {
                refuse(BindError::PinnedTwice {
                    spelling,
                    consumer: consumer.to_string(),
                    link_id: dep.link_id.clone(),
                    first: first.to_string(),
                    second: b.instance.to_string(),
                });
            } else {
                pinned[slot] = Some(b.instance);
            }
            continue;
        }
        if b.form != BindForm::Key || spelling == Spelling::SlashIds || !b.names_producer() {
            let mut declared: Vec<String> =
                dependencies.iter().map(|d| d.link_id.clone()).collect();
            declared.sort();
            refuse(BindError::UnknownSlot {
                consumer: consumer.to_string(),
                node: node.clone(),
                key: b.key.to_string(),
                declared,
            });
            continue;
        }
        let chosen = match free_form_slot(consumer, dependencies, &from_any, b) {
            Ok(chosen) => chosen,
            Err(e) => {
                refuse(*e);
                continue;
            }
        };
        match chosen {
            Some(slot) => producers[slot].push(b.instance.to_string()),
            None => refuse(BindError::DeadKey {
                consumer: consumer.to_string(),
                node: node.clone(),
                key: b.key.to_string(),
                instance: b.instance.to_string(),
                producer_node: b.producer.map(|p| p.node.clone()),
                slots: dependencies
                    .iter()
                    .map(|d| (d.link_id.clone(), d.kind, d.target.clone(), d.from_any))
                    .collect(),
            }),
        }
    }

    // As PeppyOS plans links: keys that name no slot and illegal vacancies
    // first, and nothing else until they are fixed (a misspelt key would
    // otherwise also leave its slot "unlinked").
    if errors.iter().any(|(_, e)| {
        matches!(
            e,
            BindError::UnknownSlot { .. }
                | BindError::Shape {
                    problem: ShapeProblem::VacantInvalid,
                    ..
                }
        )
    }) {
        return Assignment {
            slots: Vec::new(),
            errors,
        };
    }

    let mut slots = Vec::new();
    for (i, dep) in dependencies.iter().enumerate() {
        let refused = refused_slots.contains(&i);
        let unfulfilled = |empty_list: bool| BindError::Unfulfilled {
            consumer: consumer.to_string(),
            link_id: dep.link_id.clone(),
            kind: dep.kind,
            target: dep.target.clone(),
            cardinality: dep.cardinality,
            empty_list,
        };
        let binding = if dep.from_any {
            // Left out, a from_any slot takes any producer; linked to `[]`,
            // exactly none, as written.
            if producers[i].is_empty() && !empty_list[i] {
                SlotBinding::FromAnyUnbound
            } else {
                SlotBinding::FromAnyBound {
                    producers: std::mem::take(&mut producers[i]),
                }
            }
        } else if dep.cardinality == Cardinality::One {
            match pinned[i] {
                Some(p) => SlotBinding::Pinned {
                    producer: p.to_string(),
                },
                None => {
                    if !refused {
                        errors.push((
                            None,
                            BindError::PinnedUnbound {
                                spelling,
                                consumer: consumer.to_string(),
                                link_id: dep.link_id.clone(),
                                kind: dep.kind,
                                target: dep.target.clone(),
                            },
                        ));
                    }
                    continue;
                }
            }
        } else {
            let mut set: Vec<String> = pinned[i].map(str::to_string).into_iter().collect();
            set.append(&mut producers[i]);
            if vacant[i].is_some() && !set.is_empty() {
                errors.push((
                    None,
                    BindError::Shape {
                        consumer: consumer.to_string(),
                        link_id: dep.link_id.clone(),
                        cardinality: dep.cardinality,
                        problem: ShapeProblem::VacantInvalid,
                    },
                ));
                continue;
            }
            let missing = match dep.cardinality {
                Cardinality::ZeroOrOne => set.is_empty() && vacant[i].is_none(),
                Cardinality::OneOrMore => set.is_empty(),
                _ => false,
            };
            if missing {
                if !refused {
                    errors.push((None, unfulfilled(empty_list[i])));
                }
                continue;
            }
            SlotBinding::Set {
                producers: set,
                vacant: vacant[i].map(str::to_string),
            }
        };
        slots.push(SlotPlan {
            link_id: dep.link_id.clone(),
            kind: dep.kind,
            target: dep.target.clone(),
            binding,
            filter: RouteFilter::Any,
        });
    }
    compute_filters(&mut slots);
    Assignment { slots, errors }
}

/// Whether a binding written as `form` fits a slot of `cardinality`.
fn shape_problem(cardinality: Cardinality, form: BindForm<'_>) -> Option<ShapeProblem> {
    match (cardinality.is_scalar(), form) {
        (_, BindForm::Vacant(_)) if cardinality != Cardinality::ZeroOrOne => {
            Some(ShapeProblem::VacantInvalid)
        }
        (true, BindForm::Item | BindForm::EmptyList) => Some(ShapeProblem::ArrayOnScalar),
        (false, BindForm::Scalar) => Some(ShapeProblem::ScalarOnMulti),
        _ => None,
    }
}

/// The `from_any` slot (index into `dependencies`, `from_any` in link_id
/// order) a free-form key joins: the first its producer fits; with the
/// producer's node unknown, the first when every `from_any` slot wants the
/// same producers, else [`BindError::AmbiguousKey`]. `Ok(None)`: none takes it.
fn free_form_slot(
    consumer: &str,
    dependencies: &[Dependency],
    from_any: &[usize],
    b: &BindRequest<'_>,
) -> Result<Option<usize>, Box<BindError>> {
    if let Some(p) = b.producer {
        return Ok(from_any
            .iter()
            .copied()
            .find(|&i| p.fits(dependencies[i].kind, &dependencies[i].target)));
    }
    let mut wants = from_any
        .iter()
        .map(|&i| (dependencies[i].kind, &dependencies[i].target));
    let first = wants.next();
    if first.is_some() && wants.any(|w| Some(w) != first) {
        return Err(Box::new(BindError::AmbiguousKey {
            consumer: consumer.to_string(),
            key: b.key.to_string(),
            instance: b.instance.to_string(),
            candidates: from_any
                .iter()
                .map(|&i| {
                    let d = &dependencies[i];
                    (d.link_id.clone(), d.kind, d.target.clone())
                })
                .collect(),
        }));
    }
    Ok(from_any.first().copied())
}

/// Why a plan handed to a node does not fit the node's own slots. The
/// launcher decided the plan from the documents it read; a mismatch means
/// the node's program was generated from other documents.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlanMismatch {
    /// The plan fills a slot the node does not declare.
    #[error("the plan fills slot `{0}`, which this node does not declare")]
    UnknownSlot(String),
    /// The plan fills one slot twice.
    #[error("the plan fills slot `{0}` twice")]
    Twice(String),
    /// The plan leaves a slot of the node out.
    #[error("the plan leaves slot `{0}` out")]
    Missing(String),
    /// The plan's slot wants another node or interface than the node's.
    #[error("the plan's slot `{link_id}` wants {planned}, this node's wants {declared}")]
    Target {
        /// The slot.
        link_id: String,
        /// What the plan says it wants (`node x:v1`).
        planned: String,
        /// What the node declares (`interface y:v1`).
        declared: String,
    },
    /// A binding its slot's declaration does not allow: pinned for a
    /// `from_any` slot or the other way round, or a set of producers its
    /// cardinality does not take.
    #[error("the plan binds slot `{0}` as {1}, which its declaration does not allow")]
    Binding(String, &'static str),
}

/// Checks that `slots`, a plan the launcher decided, is a plan for exactly
/// the slots in `dependencies` (same link_ids, kinds and targets; a pinned
/// slot pinned, a `from_any` slot not), and returns it in `depends_on`
/// order. Bindings and filters are taken as they are: deciding them is
/// [`assign`]'s, once, in the launcher (or in a standalone run's flag
/// parser), never again in the node.
pub fn fit_plan(
    dependencies: &[Dependency],
    mut slots: Vec<SlotPlan>,
) -> Result<Vec<SlotPlan>, PlanMismatch> {
    if let Some(extra) = slots
        .iter()
        .find(|s| !dependencies.iter().any(|d| d.link_id == s.link_id))
    {
        return Err(PlanMismatch::UnknownSlot(extra.link_id.clone()));
    }
    let mut ordered = Vec::with_capacity(dependencies.len());
    for dep in dependencies {
        let mut found = slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.link_id == dep.link_id)
            .map(|(i, _)| i);
        let at = match (found.next(), found.next()) {
            (Some(at), None) => at,
            (Some(_), Some(_)) => return Err(PlanMismatch::Twice(dep.link_id.clone())),
            (None, _) => return Err(PlanMismatch::Missing(dep.link_id.clone())),
        };
        let slot = slots.swap_remove(at);
        if slot.kind != dep.kind || slot.target != dep.target {
            return Err(PlanMismatch::Target {
                link_id: slot.link_id,
                planned: describe(slot.kind, &slot.target),
                declared: describe(dep.kind, &dep.target),
            });
        }
        let fits = match &slot.binding {
            SlotBinding::Pinned { .. } => !dep.from_any && dep.cardinality == Cardinality::One,
            SlotBinding::FromAnyBound { .. } | SlotBinding::FromAnyUnbound => dep.from_any,
            SlotBinding::Set { producers, vacant } => {
                !dep.from_any
                    && dep.cardinality != Cardinality::One
                    && (!dep.cardinality.is_scalar() || producers.len() <= 1)
                    && (dep.cardinality != Cardinality::OneOrMore || !producers.is_empty())
                    && (vacant.is_none() || dep.cardinality == Cardinality::ZeroOrOne)
            }
        };
        if !fits {
            let what = match &slot.binding {
                SlotBinding::Pinned { .. } => "pinned",
                SlotBinding::Set { .. } => "a set of producers",
                _ => "from_any",
            };
            return Err(PlanMismatch::Binding(slot.link_id, what));
        }
        ordered.push(slot);
    }
    Ok(ordered)
}

fn mismatch(
    spelling: Spelling,
    consumer: &str,
    b: &BindRequest<'_>,
    p: Producer<'_>,
    dep: &Dependency,
) -> BindError {
    let (consumer, key, instance) = (
        consumer.to_string(),
        b.key.to_string(),
        b.instance.to_string(),
    );
    match dep.kind {
        SlotKind::Node => BindError::TargetMismatch {
            spelling,
            consumer,
            key,
            instance,
            producer_node: p.node.clone(),
            wanted: dep.target.clone(),
        },
        SlotKind::Interface => BindError::NotConformed {
            spelling,
            consumer,
            key,
            instance,
            producer_node: p.node.clone(),
            wanted: dep.target.clone(),
        },
    }
}

/// Per slot, SPEC 5: pinned -> that producer; from_any bound -> the listed
/// producers minus those pinned by a sibling; from_any unbound -> any except
/// producers claimed by siblings. Siblings are slots of the same kind and
/// `name:tag`.
pub fn compute_filters(slots: &mut [SlotPlan]) {
    let snapshot: Vec<(SlotKind, Identity, String, SlotBinding)> = slots
        .iter()
        .map(|s| {
            (
                s.kind,
                s.target.clone(),
                s.link_id.clone(),
                s.binding.clone(),
            )
        })
        .collect();
    for slot in slots.iter_mut() {
        let siblings = snapshot
            .iter()
            .filter(|(k, t, l, _)| *k == slot.kind && *t == slot.target && *l != slot.link_id);
        slot.filter = match &slot.binding {
            SlotBinding::Pinned { producer } => RouteFilter::Pin(producer.clone()),
            SlotBinding::FromAnyBound { producers } => {
                let pinned_elsewhere: BTreeSet<&str> = siblings
                    .filter_map(|(_, _, _, b)| match b {
                        SlotBinding::Pinned { producer } => Some(producer.as_str()),
                        _ => None,
                    })
                    .collect();
                RouteFilter::OnlyFrom(
                    producers
                        .iter()
                        .filter(|p| !pinned_elsewhere.contains(p.as_str()))
                        .cloned()
                        .collect(),
                )
            }
            // `node/v1`'s slots take exactly their set: siblings do not
            // matter.
            SlotBinding::Set { producers, .. } => {
                RouteFilter::OnlyFrom(producers.iter().cloned().collect())
            }
            SlotBinding::FromAnyUnbound => {
                let claimed: BTreeSet<String> = siblings
                    .flat_map(|(_, _, _, b)| match b {
                        SlotBinding::Pinned { producer } => vec![producer.clone()],
                        SlotBinding::FromAnyBound { producers }
                        | SlotBinding::Set { producers, .. } => producers.clone(),
                        SlotBinding::FromAnyUnbound => Vec::new(),
                    })
                    .collect();
                if claimed.is_empty() {
                    RouteFilter::Any
                } else {
                    RouteFilter::AnyExcept(claimed)
                }
            }
        };
    }
}
