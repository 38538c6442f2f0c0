//! `stack::list`: the nodes of this node's core node's stack, their
//! instances and the links between them, as PeppyOS's `peppylib::stack`
//! answers it (a router or a dashboard node reads which instances run).

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::node::NodeRunner;
use crate::wire::keys::CoreFunction;

/// How long [`list`] waits for its core node by default.
pub use crate::core_functions::DEFAULT_RESPONSE_TIMEOUT;

/// Where an instance is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InstanceState {
    /// Started, not yet reachable.
    Starting,
    /// Up and reachable.
    Running,
    /// Exited with status 0, for good.
    Finished,
    /// Exited otherwise (a crash), for good.
    Failed,
}

impl InstanceState {
    /// `starting`, `running`, `finished` or `failed`.
    pub fn as_str(self) -> &'static str {
        match self {
            InstanceState::Starting => "starting",
            InstanceState::Running => "running",
            InstanceState::Finished => "finished",
            InstanceState::Failed => "failed",
        }
    }

    /// Whether the instance has exited for good.
    pub fn is_terminal(self) -> bool {
        matches!(self, InstanceState::Finished | InstanceState::Failed)
    }
}

impl fmt::Display for InstanceState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where a node is in the stack's life (peppy's are `Ready` once built).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NodeStage {
    /// Known, not built.
    Added,
    /// Being built.
    Building,
    /// Built, its instances may run.
    Ready,
    /// The stack's root.
    Root,
}

impl NodeStage {
    /// The stage's name.
    pub fn as_str(self) -> &'static str {
        match self {
            NodeStage::Added => "Added",
            NodeStage::Building => "Building",
            NodeStage::Ready => "Ready",
            NodeStage::Root => "Root",
        }
    }
}

impl fmt::Display for NodeStage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One instance of a node.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SerializedInstance {
    /// Its instance id.
    pub instance_id: String,
    /// Where it is in its life.
    pub state: InstanceState,
    /// Whether it answered when last asked (a running instance that
    /// stopped answering is not).
    #[serde(default = "healthy")]
    pub healthy: bool,
    /// Each producer slot's bound producers, `(core_node, instance_id)`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub slot_bindings: BTreeMap<String, Vec<crate::ProducerRef>>,
    /// Each pairing slot's peer (or observed sources), as planned.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub pairing_slots: BTreeMap<String, SerializedPairingSlot>,
}

fn healthy() -> bool {
    true
}

/// One pairing slot of an instance.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SerializedPairingSlot {
    /// The pairing's name.
    pub pairing_name: String,
    /// The pairing's tag.
    pub pairing_tag: String,
    /// The role the instance plays (or watches, for an observer).
    pub role: String,
    /// The planned peer or sources (`instance` or `instance/slot`), empty
    /// while unpaired.
    pub binding: Vec<String>,
}

/// A node of the stack.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SerializedNode {
    /// Its name.
    pub name: String,
    /// Its tag.
    pub tag: String,
    /// The core node whose stack holds it.
    pub core_node: String,
    /// Its `peppy.json5`.
    pub config_path: String,
    /// Its program, when known.
    pub artifact_path: Option<String>,
    /// Where it is in the stack's life.
    #[serde(default)]
    pub stage: Option<NodeStage>,
    /// Its instances, in every state.
    #[serde(default)]
    pub instances: Vec<SerializedInstance>,
}

impl SerializedNode {
    /// `name:tag`.
    pub fn label(&self) -> String {
        format!("{}:{}", self.name, self.tag)
    }

    /// The ids of its running instances (those still starting are left
    /// out: not reachable yet).
    pub fn running_instance_ids(&self) -> Vec<&str> {
        self.instances
            .iter()
            .filter(|i| i.state == InstanceState::Running)
            .map(|i| i.instance_id.as_str())
            .collect()
    }

    /// How many of its instances run.
    pub fn instance_count(&self) -> usize {
        self.running_instance_ids().len()
    }

    /// The stage's name, `Unknown` when not given.
    pub fn stage_label(&self) -> &'static str {
        self.stage.map_or("Unknown", NodeStage::as_str)
    }
}

/// A dependency between two nodes: `from` consumes from `to`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SerializedEdge {
    /// The consumer.
    pub from: SerializedNode,
    /// The producer.
    pub to: SerializedNode,
    /// `name:tag` of the contract the dependency goes through, `None` for
    /// a node dependency.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub via_contract: Option<String>,
}

/// The stack: its nodes and their dependencies.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SerializedNodeGraph {
    /// Every node.
    pub nodes: Vec<SerializedNode>,
    /// Every dependency between two of them.
    pub edges: Vec<SerializedEdge>,
}

/// No node of the stack has that name and tag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeNotFound {
    label: String,
}

impl NodeNotFound {
    /// The missing `name:tag`.
    pub fn label(&self) -> &str {
        &self.label
    }
}

impl fmt::Display for NodeNotFound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "no node matches `{}`", self.label)
    }
}

impl std::error::Error for NodeNotFound {}

impl SerializedNodeGraph {
    /// The node `name:tag`.
    pub fn find_node(&self, name: &str, tag: &str) -> Option<&SerializedNode> {
        self.nodes.iter().find(|n| n.name == name && n.tag == tag)
    }

    /// The running instances of node `name:tag` (empty while every one is
    /// still starting); [`NodeNotFound`] when the stack has no such node.
    pub fn running_instance_ids_by_node(
        &self,
        name: &str,
        tag: &str,
    ) -> std::result::Result<Vec<&str>, NodeNotFound> {
        self.find_node(name, tag)
            .map(SerializedNode::running_instance_ids)
            .ok_or_else(|| NodeNotFound {
                label: format!("{name}:{tag}"),
            })
    }
}

/// [`list`]'s answer: the stack and who served it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StackList {
    /// The stack.
    pub graph: SerializedNodeGraph,
    /// The core node that answered.
    pub core_node: String,
    /// Its run (`core_node_instance_id` of `info`).
    pub instance_id: String,
    /// Its machine.
    pub host_name: String,
}

/// The stack of this node's core node. `response_timeout` is `None` for
/// 10 s.
pub async fn list(
    node_runner: &NodeRunner,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<StackList> {
    crate::core_functions::ask_json(
        node_runner,
        CoreFunction::List,
        response_timeout.into(),
        "stack list",
    )
    .await
}
