//! What a launch answers as its nodes' core node (`peppylib::info`,
//! `peppylib::stack::list`): its own facts and its stack, built from the
//! instances it started and kept current by their supervisors and their
//! liveliness tokens.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Mutex;
use std::time::Instant;

use peppy_runtime::ProducerRef;
use peppy_runtime::core_functions::CoreView;
use peppy_runtime::info::{ContainerInfo, InfoResponse};
use peppy_runtime::stack::{
    InstanceState, NodeStage, SerializedEdge, SerializedInstance, SerializedNode,
    SerializedNodeGraph, SerializedPairingSlot,
};
use peppy_schema::{PairEnd, PairingSlot, SlotBinding, SlotKind};

use crate::up::Planned;

/// One launch (or `run`'s hub) as its nodes' core node.
pub(crate) struct LaunchView {
    core_node: String,
    /// This run of the core node: the launcher's pid and start time.
    run_id: String,
    host_name: String,
    started: Instant,
    port: u16,
    nodes: Vec<SerializedNode>,
    /// `(consumer node, producer node, contract)` by index in `nodes`.
    edges: Vec<(usize, usize, Option<String>)>,
    /// Instances whose supervisor has returned: exited for good.
    ended: Mutex<HashMap<String, InstanceState>>,
}

impl LaunchView {
    /// The view of core node `core_node` starting `planned` (the instances
    /// that failed to plan are left out: they never start). `slots` gives
    /// a node's pairing slots (by its `name:tag`).
    pub(crate) fn new(
        core_node: &str,
        port: u16,
        planned: &[&Planned],
        slots: &dyn Fn(&str) -> Vec<PairingSlot>,
    ) -> LaunchView {
        let mut nodes: Vec<SerializedNode> = Vec::new();
        let mut node_of: HashMap<&str, usize> = HashMap::new();
        for p in planned {
            let (name, tag) = p.node.split_once(':').unwrap_or((&p.node, ""));
            let index = match nodes.iter().position(|n| n.name == name && n.tag == tag) {
                Some(i) => i,
                None => {
                    nodes.push(SerializedNode {
                        name: name.to_string(),
                        tag: tag.to_string(),
                        core_node: core_node.to_string(),
                        config_path: p.dir.join("peppy.json5").display().to_string(),
                        artifact_path: p.argv.first().cloned(),
                        stage: Some(NodeStage::Ready),
                        instances: Vec::new(),
                    });
                    nodes.len() - 1
                }
            };
            node_of.insert(&p.config.instance_id, index);
            nodes[index].instances.push(SerializedInstance {
                instance_id: p.config.instance_id.clone(),
                state: InstanceState::Starting,
                healthy: true,
                slot_bindings: slot_bindings(p, planned),
                pairing_slots: pairing_slots(p, &slots(&p.node)),
            });
        }
        let mut edges = Vec::new();
        for p in planned {
            let from = node_of[p.config.instance_id.as_str()];
            for slot in &p.config.slots {
                let via = (slot.kind == SlotKind::Interface).then(|| slot.target.to_string());
                for producer in producers(&slot.binding) {
                    if let Some(&to) = node_of.get(producer.as_str()) {
                        let edge = (from, to, via.clone());
                        if !edges.contains(&edge) {
                            edges.push(edge);
                        }
                    }
                }
            }
        }
        LaunchView {
            core_node: core_node.to_string(),
            run_id: format!("{}-{}", std::process::id(), crate::runs::now_ms()),
            host_name: host_name(),
            started: Instant::now(),
            port,
            nodes,
            edges,
            ended: Mutex::new(HashMap::new()),
        }
    }

    /// Records that instance `id`'s supervisor returned: it will not run
    /// again (`failed`: it crashed, or kept crashing).
    pub(crate) fn ended(&self, id: &str, failed: bool) {
        let state = if failed {
            InstanceState::Failed
        } else {
            InstanceState::Finished
        };
        self.ended
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id.to_string(), state);
    }
}

/// The producers a slot's binding names.
pub(crate) fn producers(binding: &SlotBinding) -> Vec<&String> {
    match binding {
        SlotBinding::Pinned { producer } => vec![producer],
        SlotBinding::FromAnyBound { producers } | SlotBinding::Set { producers, .. } => {
            producers.iter().collect()
        }
        _ => Vec::new(),
    }
}

/// Each producer slot's producers, with the core node that runs each
/// (this one's, for a producer it does not start).
fn slot_bindings(p: &Planned, planned: &[&Planned]) -> BTreeMap<String, Vec<ProducerRef>> {
    p.config
        .slots
        .iter()
        .map(|slot| {
            let refs = producers(&slot.binding)
                .into_iter()
                .map(|id| {
                    let core = planned
                        .iter()
                        .find(|o| &o.config.instance_id == id)
                        .map_or(p.config.core_node.as_str(), |o| o.config.core_node.as_str());
                    ProducerRef::new(core, id.as_str())
                })
                .collect();
            (slot.link_id.clone(), refs)
        })
        .collect()
}

/// Each pairing slot as planned: the pairing, the role, the peer or the
/// sources.
fn pairing_slots(p: &Planned, slots: &[PairingSlot]) -> BTreeMap<String, SerializedPairingSlot> {
    slots
        .iter()
        .map(|slot| {
            let end = |e: &PairEnd| match &e.link_id {
                Some(l) => format!("{}/{l}", e.instance),
                None => e.instance.clone(),
            };
            let planned = p
                .config
                .pairs
                .iter()
                .find(|pair| pair.link_id == slot.link_id);
            (
                slot.link_id.clone(),
                SerializedPairingSlot {
                    pairing_name: slot.pairing.name.clone(),
                    pairing_tag: slot.pairing.tag.clone(),
                    role: slot.role.clone(),
                    binding: planned
                        .map_or_else(Vec::new, |pair| pair.peers.iter().map(end).collect()),
                },
            )
        })
        .collect()
}

/// The port of the first TCP endpoint among `endpoints` (0 for none).
pub(crate) fn port_of(endpoints: &[String]) -> u16 {
    endpoints
        .iter()
        .filter_map(|e| e.strip_prefix("tcp/"))
        .find_map(|addr| addr.rsplit_once(':')?.1.parse().ok())
        .unwrap_or(0)
}

fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its whole length, and gethostname
    // writes at most that many bytes.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return String::new();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

impl CoreView for LaunchView {
    fn info(&self) -> InfoResponse {
        InfoResponse {
            uptime_secs: self.started.elapsed().as_secs(),
            core_node_name: self.core_node.clone(),
            core_node_instance_id: self.run_id.clone(),
            host_name: self.host_name.clone(),
            node_count: self.nodes.len() as u32,
            git_version: format!("peppy-launch {}", env!("CARGO_PKG_VERSION")),
            container_info: ContainerInfo::default(),
            messaging_port: self.port,
        }
    }

    fn graph(&self, live: &HashSet<String>) -> SerializedNodeGraph {
        let ended = self.ended.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let mut nodes = self.nodes.clone();
        for node in &mut nodes {
            for i in &mut node.instances {
                let up = live.contains(&i.instance_id);
                i.state = match ended.get(&i.instance_id) {
                    Some(state) => *state,
                    None if up => InstanceState::Running,
                    None => InstanceState::Starting,
                };
                i.healthy = up;
            }
        }
        let edges = self
            .edges
            .iter()
            .map(|(from, to, via)| SerializedEdge {
                from: nodes[*from].clone(),
                to: nodes[*to].clone(),
                via_contract: via.clone(),
            })
            .collect();
        SerializedNodeGraph { nodes, edges }
    }
}
