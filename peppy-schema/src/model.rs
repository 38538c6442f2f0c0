//! What a node is at run time: its identity, its slots and its parameter
//! schema. This part of the model needs no document parser: the build
//! embeds it in the node binary ([`NodeModel::to_json`]) and the runtime
//! reads it back, so a robot binary neither parses JSON5 nor links the
//! parser and the diagnostics renderer.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::loc::Loc;
use crate::params::ParameterSchema;

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
    /// Accepts any number of producers (else exactly one, pinned).
    pub from_any: bool,
    /// Interface revision pin (interface slots only).
    pub sha256: Option<String>,
    /// Where the entry is (not carried into a compiled [`NodeModel`]).
    #[serde(skip)]
    pub loc: Loc,
}

/// A node as the runtime needs it: identity, slots (`depends_on`, in
/// order) and parameter schema.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NodeModel {
    /// `name:tag`.
    pub identity: Identity,
    /// The slots.
    pub dependencies: Vec<Dependency>,
    /// `execution.parameters`.
    pub parameters: ParameterSchema,
}

impl NodeModel {
    /// The slot named `link_id`.
    pub fn dependency(&self, link_id: &str) -> Option<&Dependency> {
        self.dependencies.iter().find(|d| d.link_id == link_id)
    }

    /// The model as compact JSON, for embedding in a node binary.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a node model serializes")
    }

    /// Reads a model embedded by [`NodeModel::to_json`].
    pub fn from_json(text: &str) -> Result<NodeModel, serde_json::Error> {
        serde_json::from_str(text)
    }
}

#[cfg(feature = "documents")]
impl NodeModel {
    /// The run-time part of a node document.
    pub fn of(doc: &crate::node::NodeDoc) -> NodeModel {
        NodeModel {
            identity: doc.identity(),
            dependencies: doc.dependencies.clone(),
            parameters: doc.execution.parameters.clone(),
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
            json.starts_with(r#"{"identity":{"name":"pinger","tag":"v1"},"dependencies":[{"kind":"node","target":{"name":"ponger","tag":"v1"},"link_id":"ponger","from_any":false,"sha256":null}],"#),
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
