//! `info`: what this node's core node is, as PeppyOS's
//! `peppylib::info` answers it.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::node::NodeRunner;
use crate::wire::keys::CoreFunction;

/// How long [`info`] waits for its core node by default.
pub use crate::core_functions::DEFAULT_RESPONSE_TIMEOUT;

/// The container runtimes a core node knows (peppy starts none: empty).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ContainerInfo {
    /// Apptainer's version, empty when absent.
    pub apptainer_version: String,
    /// Lima's version, empty when absent.
    pub lima_version: String,
}

/// A core node's facts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InfoResponse {
    /// How long the core node has been up.
    pub uptime_secs: u64,
    /// Its name (the launch's core node).
    pub core_node_name: String,
    /// This run of it (the launch's process and start).
    pub core_node_instance_id: String,
    /// The machine it runs on.
    pub host_name: String,
    /// How many nodes its stack holds.
    pub node_count: u32,
    /// The peppy it runs (`peppy-launch <version>`).
    pub git_version: String,
    /// Container runtimes.
    pub container_info: ContainerInfo,
    /// The port its router listens on (0 when it listens on none).
    pub messaging_port: u16,
}

/// Asks this node's core node what it is. `response_timeout` is `None`
/// for 10 s.
pub async fn info(
    node_runner: &NodeRunner,
    response_timeout: impl Into<Option<Duration>> + Send,
) -> Result<InfoResponse> {
    crate::core_functions::ask_json(
        node_runner,
        CoreFunction::Info,
        response_timeout.into(),
        "info",
    )
    .await
}
