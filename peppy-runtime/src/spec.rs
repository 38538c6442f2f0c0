//! What generated code tells the runtime about a node: static descriptions
//! of its entries. Generated code builds these as `static`s; the runtime
//! never needs the schema at run time beyond them and the node's compiled model.

use peppy_schema::QosProfile;

use crate::wire::keys::Owner;

/// A message format as compiled into the node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FormatSpec {
    /// The format's fingerprint (`peppy_schema::MessageFormat::fingerprint`).
    pub fingerprint: u64,
    /// Its canonical text, for mismatch warnings.
    pub canonical: &'static str,
}

impl FormatSpec {
    /// No payload.
    pub const EMPTY: FormatSpec = FormatSpec {
        fingerprint: 0,
        canonical: "(no payload)",
    };
}

/// Whose contract an entry belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OwnerSpec {
    /// This node's own declaration (its name and tag come from the node).
    Own,
    /// Another node's declaration (a node slot's producer).
    Node {
        /// Node name.
        name: &'static str,
        /// Node tag.
        tag: &'static str,
    },
    /// An interface's entry.
    Interface {
        /// Interface name.
        name: &'static str,
        /// Interface tag.
        tag: &'static str,
    },
    /// Anyone (external consumed topics).
    Any,
}

impl OwnerSpec {
    pub(crate) fn resolve<'a>(&'a self, own_name: &'a str, own_tag: &'a str) -> Option<Owner<'a>> {
        match self {
            OwnerSpec::Own => Some(Owner::Node {
                name: own_name,
                tag: own_tag,
            }),
            OwnerSpec::Node { name, tag } => Some(Owner::Node { name, tag }),
            OwnerSpec::Interface { name, tag } => Some(Owner::Interface { name, tag }),
            OwnerSpec::Any => None,
        }
    }
}

/// A topic this node emits.
#[derive(Debug)]
pub struct TopicSpec {
    /// Own or conformed.
    pub owner: OwnerSpec,
    /// Topic name.
    pub name: &'static str,
    /// QoS profile.
    pub qos: QosProfile,
    /// Payload format.
    pub format: FormatSpec,
}

/// A topic this node consumes.
#[derive(Debug)]
pub struct ConsumedTopicSpec {
    /// The slot (`None`: external).
    pub link_id: Option<&'static str>,
    /// The producer side's owner (`Any` for external topics).
    pub owner: OwnerSpec,
    /// Topic name.
    pub name: &'static str,
    /// The producer's QoS profile (sets the queue policy).
    pub qos: QosProfile,
    /// Payload format.
    pub format: FormatSpec,
}

/// A pairing topic this node's role emits, through one pairing slot.
#[derive(Debug)]
pub struct PairedTopicSpec {
    /// The pairing slot.
    pub link_id: &'static str,
    /// The topic (its owner is unused: a pairing's key names the pairing,
    /// found from the slot).
    pub topic: TopicSpec,
}

/// A pairing topic this node receives through one pairing slot: the
/// counterpart's (a participant) or the watched role's (an observer).
#[derive(Debug)]
pub struct ConsumedPairedTopicSpec {
    /// The pairing slot.
    pub link_id: &'static str,
    /// The topic (`link_id` and owner unused, as above).
    pub topic: ConsumedTopicSpec,
}

/// A service this node exposes.
#[derive(Debug)]
pub struct ServiceSpec {
    /// Own or conformed.
    pub owner: OwnerSpec,
    /// Service name.
    pub name: &'static str,
    /// Request format.
    pub request: FormatSpec,
    /// Response format.
    pub response: FormatSpec,
}

/// A service this node calls.
#[derive(Debug)]
pub struct ConsumedServiceSpec {
    /// The slot.
    pub link_id: &'static str,
    /// The producer side's owner.
    pub owner: OwnerSpec,
    /// Service name.
    pub name: &'static str,
    /// Request format.
    pub request: FormatSpec,
    /// Response format.
    pub response: FormatSpec,
}

/// An action this node exposes.
#[derive(Debug)]
pub struct ActionSpec {
    /// Own or conformed.
    pub owner: OwnerSpec,
    /// Action name.
    pub name: &'static str,
    /// Goal request format.
    pub goal: FormatSpec,
    /// Feedback format ([`FormatSpec::EMPTY`] when the action has no feedback).
    pub feedback: FormatSpec,
    /// Result format.
    pub result: FormatSpec,
}

/// An action this node calls.
#[derive(Debug)]
pub struct ConsumedActionSpec {
    /// The slot.
    pub link_id: &'static str,
    /// The producer side's owner.
    pub owner: OwnerSpec,
    /// Action name.
    pub name: &'static str,
    /// Goal request format.
    pub goal: FormatSpec,
    /// Feedback format.
    pub feedback: FormatSpec,
    /// Result format.
    pub result: FormatSpec,
}

/// Everything the runtime must set up before the node's code runs.
#[derive(Debug)]
pub struct NodeDescriptor {
    /// The node's run-time model ([`peppy_schema::NodeModel::to_json`]):
    /// identity, slots and parameter schema, compiled in by the build so
    /// the node never parses its document.
    pub model: &'static str,
    /// Where the document was read from, for messages.
    pub document_path: &'static str,
    /// Topics it emits (publishers are declared up front).
    pub emitted_topics: &'static [&'static TopicSpec],
    /// Topics it consumes (subscriptions live as long as the node).
    pub consumed_topics: &'static [&'static ConsumedTopicSpec],
    /// Services it exposes (queryables live as long as the node).
    pub exposed_services: &'static [&'static ServiceSpec],
    /// Actions it exposes (their goal, cancel and result queryables live as
    /// long as the node).
    pub exposed_actions: &'static [&'static ActionSpec],
}

/// Implemented by a node's generated `Parameters` type: ties the parameter
/// struct to the node it belongs to, so `NodeBuilder::<Parameters>` knows
/// what to set up.
pub trait NodeParameters: serde::de::DeserializeOwned + Send + 'static {
    /// The node's descriptor.
    fn descriptor() -> &'static NodeDescriptor;
}
