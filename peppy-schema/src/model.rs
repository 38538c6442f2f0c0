//! What a node is at run time: its identity, its slots and its parameter
//! schema. This part of the model needs no document parser: the build
//! embeds it in the node binary ([`NodeModel::to_json`]) and the runtime
//! reads it back, so a robot binary neither parses JSON5 nor links the
//! parser and the diagnostics renderer.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::loc::Loc;
use crate::params::ParameterSchema;

/// Which spelling a document is written in, named by its `peppy_schema`
/// ids: underscored (`node_v1`, `interface_v1`, `launcher_v1`: PeppyOS up
/// to v0.12) or slashed (`node/v1`, `contract/v1`, `launcher/v1`, ...:
/// PeppyOS v0.13 on, read as of v0.25.7). Both are read into one model;
/// the spelling decides only what each document may say and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Spelling {
    /// `<kind>_v1` ids (`node_v1`, `interface_v1`, `launcher_v1`).
    // Models embedded by earlier builds name it `seeds`.
    #[default]
    #[serde(alias = "seeds")]
    UnderscoreIds,
    /// `<kind>/v1` ids (`node/v1`, `contract/v1`, `pairing/v1`, ...).
    // Models embedded by earlier builds name it `today`.
    #[serde(alias = "today")]
    SlashIds,
}

impl Spelling {
    /// The generated API a node document of this spelling is written
    /// against: the reader's one decision, stored in the model.
    pub fn node_api(self) -> NodeApi {
        match self {
            Spelling::UnderscoreIds => NodeApi::Emit,
            Spelling::SlashIds => NodeApi::Peppylib,
        }
    }

    /// What this spelling calls a shared contract (`interface_v1`
    /// documents or `contract/v1` ones), for messages and listings.
    pub fn contract_word(self) -> &'static str {
        match self {
            Spelling::UnderscoreIds => "interface",
            Spelling::SlashIds => "contract",
        }
    }
}

/// Which generated API a node's code is written against. The reader
/// decides it (from the document's spelling) and the model carries it, so
/// the code generators and the launcher ask this and never the spelling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeApi {
    /// Positional `emit`, `on_next_message_received`,
    /// `ActionHandle::expose`; a conformed interface's entries live under
    /// `<interface>::<tag>::<name>` (and by name when unambiguous).
    #[default]
    Emit,
    /// PeppyOS's `peppylib` API (`declare_publisher`, `subscribe`,
    /// `GoalDecision`, calls aimed at a bound producer); entries reached
    /// through a slot or an `implements` link live under its link_id.
    Peppylib,
}

/// How many producers a slot takes (`node/v1`'s `cardinality`). A
/// `node_v1` pinned slot is `one`; its `from_any` slot is `zero_or_more`
/// that also takes free-form binding keys and, left unbound, any producer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Cardinality {
    /// Exactly one producer (the default).
    #[default]
    One,
    /// None or one; an empty slot is written `{ vacant: "why" }`.
    ZeroOrOne,
    /// At least one.
    OneOrMore,
    /// Any number, none included.
    ZeroOrMore,
}

impl Cardinality {
    /// The names, as written in a document.
    pub const NAMES: &'static [&'static str] =
        &["one", "zero_or_one", "one_or_more", "zero_or_more"];

    /// Reads a name as written in a document.
    pub fn parse(s: &str) -> Option<Cardinality> {
        match s {
            "one" => Some(Cardinality::One),
            "zero_or_one" => Some(Cardinality::ZeroOrOne),
            "one_or_more" => Some(Cardinality::OneOrMore),
            "zero_or_more" => Some(Cardinality::ZeroOrMore),
            _ => None,
        }
    }

    /// As written in a document.
    pub fn as_str(self) -> &'static str {
        match self {
            Cardinality::One => "one",
            Cardinality::ZeroOrOne => "zero_or_one",
            Cardinality::OneOrMore => "one_or_more",
            Cardinality::ZeroOrMore => "zero_or_more",
        }
    }

    /// Whether the slot is bound to a single value (`one`, `zero_or_one`),
    /// as opposed to a list.
    pub fn is_scalar(self) -> bool {
        matches!(self, Cardinality::One | Cardinality::ZeroOrOne)
    }

    /// Whether the slot may stay empty.
    pub fn admits_empty(self) -> bool {
        matches!(self, Cardinality::ZeroOrOne | Cardinality::ZeroOrMore)
    }
}

impl fmt::Display for Cardinality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A `name:tag` identity of a node or interface.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Identity {
    /// Name.
    pub name: String,
    /// Tag.
    pub tag: String,
}

impl Identity {
    /// `name:tag`.
    pub fn new(name: impl Into<String>, tag: impl Into<String>) -> Self {
        Identity {
            name: name.into(),
            tag: tag.into(),
        }
    }

    /// Parses `name:tag`.
    pub fn parse(s: &str) -> Option<Identity> {
        let (name, tag) = s.split_once(':')?;
        (!name.is_empty() && !tag.is_empty() && !tag.contains(':'))
            .then(|| Identity::new(name, tag))
    }
}

impl fmt::Display for Identity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.name, self.tag)
    }
}

/// Whether a slot is filled by one node or by any conforming node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SlotKind {
    /// `depends_on.nodes`: instances of exactly that node.
    Node,
    /// `depends_on.interfaces`: instances of nodes that conform to it.
    Interface,
}

impl SlotKind {
    /// `node` / `interface`.
    pub fn as_str(self) -> &'static str {
        match self {
            SlotKind::Node => "node",
            SlotKind::Interface => "interface",
        }
    }
}

/// One `depends_on` entry: a slot named by its `link_id`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Dependency {
    /// Node or interface slot.
    pub kind: SlotKind,
    /// The producer node or the interface.
    pub target: Identity,
    /// The slot's name.
    pub link_id: String,
    /// `node_v1`'s `from_any`: any number of producers, free-form binding
    /// keys, and any producer of the slot's kind while unbound.
    pub from_any: bool,
    /// How many producers the slot takes (`zero_or_more` for `from_any`).
    #[serde(default)]
    pub cardinality: Cardinality,
    /// Interface revision pin (interface slots only).
    pub sha256: Option<String>,
    /// Where the entry is (not carried into a compiled [`NodeModel`]).
    #[serde(skip)]
    pub loc: Loc,
}

/// A `depends_on.pairings` (participant) or `depends_on.pairing_observers`
/// slot: one exclusive peer playing the counterpart role (participant), or
/// the sources playing `role` that the node watches (observer).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PairingSlot {
    /// The slot's link_id.
    pub link_id: String,
    /// The pairing document.
    pub pairing: Identity,
    /// The role this node plays (participant) or watches (observer).
    pub role: String,
    /// The pairing's other role, filled in when the slot is resolved
    /// against its pairing document (empty before): a participant's peer
    /// plays it, and an observer's sources are paired with instances
    /// playing it.
    #[serde(default)]
    pub counterpart: String,
    /// Whether it observes rather than takes part.
    #[serde(default)]
    pub observer: bool,
    /// Pairing revision pin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    /// A participant slot that may stay vacant.
    #[serde(default)]
    pub optional: bool,
    /// An observer slot's cardinality (`one` for participants).
    #[serde(default)]
    pub cardinality: Cardinality,
    /// Where the entry is (not carried into a compiled [`NodeModel`]).
    #[serde(skip)]
    pub loc: Loc,
}

impl PairingSlot {
    /// Whether the slot may end with nobody in it: an optional participant,
    /// or an observer whose cardinality admits none.
    pub fn admits_empty(&self) -> bool {
        if self.observer {
            self.cardinality.admits_empty()
        } else {
            self.optional
        }
    }
}

/// A node as the runtime needs it: identity, slots (`depends_on`, in
/// order) and parameter schema.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NodeModel {
    /// The spelling of the document it was read from: the names binding
    /// errors are reported under.
    #[serde(default)]
    pub spelling: Spelling,
    /// The generated API the node's code uses.
    #[serde(default)]
    pub api: NodeApi,
    /// `name:tag`.
    pub identity: Identity,
    /// The slots.
    pub dependencies: Vec<Dependency>,
    /// `execution.parameters`.
    pub parameters: ParameterSchema,
    /// `node/v1`'s pairing slots, participants and observers, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pairings: Vec<PairingSlot>,
}

impl NodeModel {
    /// The slot named `link_id`.
    pub fn dependency(&self, link_id: &str) -> Option<&Dependency> {
        self.dependencies.iter().find(|d| d.link_id == link_id)
    }

    /// The pairing slot named `link_id`.
    pub fn pairing(&self, link_id: &str) -> Option<&PairingSlot> {
        self.pairings.iter().find(|p| p.link_id == link_id)
    }

    /// The model as compact JSON, for embedding in a node binary.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a node model serializes")
    }

    /// Reads a model embedded by [`NodeModel::to_json`]. A model embedded
    /// before `api` was written gets the API its spelling decides.
    pub fn from_json(text: &str) -> Result<NodeModel, serde_json::Error> {
        let mut value: serde_json::Value = serde_json::from_str(text)?;
        if let Some(fields) = value.as_object_mut()
            && !fields.contains_key("api")
        {
            let spelling: Spelling = match fields.get("spelling") {
                Some(s) => serde_json::from_value(s.clone())?,
                None => Spelling::default(),
            };
            fields.insert("api".into(), serde_json::to_value(spelling.node_api())?);
        }
        serde_json::from_value(value)
    }
}

#[cfg(feature = "documents")]
impl NodeModel {
    /// The run-time part of a node document.
    pub fn of(doc: &crate::node::NodeDoc) -> NodeModel {
        NodeModel {
            spelling: doc.spelling,
            api: doc.api,
            identity: doc.identity(),
            dependencies: doc.dependencies.clone(),
            parameters: doc.execution.parameters.clone(),
            pairings: doc.pairings.clone(),
        }
    }
}

#[cfg(all(test, feature = "documents"))]
mod tests {
    use super::*;

    #[test]
    fn the_model_a_binary_embeds_round_trips_without_the_document() {
        let (doc, _) = crate::node::NodeDoc::parse(
            "peppy.json5",
            r#"{ peppy_schema: "node_v1",
                manifest: { name: "pinger", tag: "v1", depends_on: {
                    nodes: [{ name: "ponger", tag: "v1", link_id: "ponger" }] } },
                execution: { language: "rust", run_cmd: ["x"],
                    parameters: { rate: { $type: "f64", $default: 10 }, frame: "string" } } }"#,
        )
        .unwrap();
        let json = NodeModel::of(&doc).to_json();
        // The shape hand-written descriptors (the latency bench) rely on.
        assert!(
            json.starts_with(r#"{"spelling":"underscore_ids","api":"emit","identity":{"name":"pinger","tag":"v1"},"dependencies":[{"kind":"node","target":{"name":"ponger","tag":"v1"},"link_id":"ponger","from_any":false,"cardinality":"one","sha256":null}],"#),
            "{json}"
        );
        let back = NodeModel::from_json(&json).unwrap();
        assert_eq!(back.identity, doc.identity());
        assert_eq!(back.dependency("ponger").unwrap().kind, SlotKind::Node);
        assert_eq!(
            back.parameters
                .resolve(&serde_json::json!({ "frame": "map" })),
            Ok(serde_json::json!({ "rate": 10, "frame": "map" }))
        );
        assert!(NodeModel::from_json("{}").is_err());
    }
}

#[cfg(test)]
mod embedded_by_earlier_builds {
    use super::*;

    /// A model a binary built before the spellings were named by schema
    /// id (and before `api` was written) still reads, its API following
    /// its spelling.
    #[test]
    fn earlier_models_read_with_the_api_of_their_spelling() {
        let model = |spelling: &str| {
            NodeModel::from_json(&format!(
                r#"{{"spelling":"{spelling}","identity":{{"name":"n","tag":"v1"}},"dependencies":[],"parameters":{{"fields":[]}}}}"#
            ))
            .unwrap()
        };
        let slashed = model("today");
        assert_eq!(
            (slashed.spelling, slashed.api),
            (Spelling::SlashIds, NodeApi::Peppylib)
        );
        let underscored = model("seeds");
        assert_eq!(
            (underscored.spelling, underscored.api),
            (Spelling::UnderscoreIds, NodeApi::Emit)
        );
        let current = model("slash_ids");
        assert_eq!(current.api, NodeApi::Peppylib);
        assert!(NodeModel::from_json(r#"{"spelling":"tomorrow"}"#).is_err());
        assert!(NodeModel::from_json("[]").is_err());
    }
}
