//! Which server a request through a slot goes to: the one place services
//! and actions choose it.
//!
//! A pinned slot, or a `from_any` slot bound to exactly one producer, names
//! its server. Otherwise the caller probes every server of the slot's kind
//! and takes the first that the slot's routing filter accepts and, for a
//! node slot reached on an interface's key, that runs the slot's node.

use std::borrow::Cow;
use std::time::Duration;

use peppy_schema::SlotKind;
use tokio::time::Instant;
use zenoh::query::{ConsolidationMode, QueryTarget};

use crate::error::{Error, Result};
use crate::members::live_instances;
use crate::node::NodeRunner;
use crate::spec::OwnerSpec;
use crate::wire::attachment::{QueryHeader, QueryKind};
use crate::wire::keys::{ActionPart, Channel, action_part_key, entry_selector, parse_entry_key};

/// How long discovery waits for servers to say they are there.
pub(crate) const PROBE_TIMEOUT: Duration = Duration::from_millis(500);

/// What is being reached, for keys and error messages.
pub(crate) struct Entry<'a> {
    /// The slot it is consumed through.
    pub(crate) link_id: &'a str,
    /// The producer side's owner.
    pub(crate) owner: OwnerSpec,
    /// Service or action.
    pub(crate) channel: Channel,
    /// The entry's name.
    pub(crate) name: &'a str,
    /// The part of an action requests go to (its goals), if an action.
    pub(crate) part: Option<ActionPart>,
    /// The request format's fingerprint, sent with the probe.
    pub(crate) fingerprint: u64,
    /// How the entry reads in an `Unreachable` error.
    pub(crate) describe: Cow<'static, str>,
}

impl Entry<'_> {
    /// The key expression of this entry's servers (`instance`: one of
    /// them), without an action's part.
    pub(crate) fn base(&self, runner: &NodeRunner, instance: Option<&str>) -> String {
        let owner = self.owner.resolve(runner.node_name(), runner.node_tag());
        entry_selector(
            runner.namespace(),
            self.channel,
            owner.as_ref(),
            self.name,
            None,
            instance,
        )
    }

    /// The key expression requests go to (`instance`: one server).
    pub(crate) fn selector(&self, runner: &NodeRunner, instance: Option<&str>) -> String {
        let base = self.base(runner, instance);
        match self.part {
            Some(part) => action_part_key(&base, part),
            None => base,
        }
    }

    fn unreachable(&self) -> Error {
        Error::ServiceUnreachable {
            service_name: self.describe.to_string(),
            instance_id: None,
        }
    }
}

/// A query header from this node.
pub(crate) fn header(runner: &NodeRunner, kind: QueryKind, fingerprint: u64) -> Vec<u8> {
    QueryHeader::encode_parts(kind, fingerprint, runner.core_node(), runner.instance_id())
}

/// The server instance a request through `entry`'s slot goes to.
pub(crate) async fn choose(
    runner: &NodeRunner,
    entry: &Entry<'_>,
    deadline: Instant,
) -> Result<String> {
    let slot = runner.slot(entry.link_id)?;
    if let Some(server) = slot.named_server() {
        return Ok(server.to_string());
    }
    let budget = deadline
        .saturating_duration_since(Instant::now())
        .min(PROBE_TIMEOUT);
    // An interface's key is shared by every conforming node: a node slot
    // keeps only instances of its own node.
    let members = match (slot.kind, entry.owner) {
        (SlotKind::Node, OwnerSpec::Interface { .. }) => Some(
            live_instances(
                runner.session(),
                runner.namespace(),
                &slot.target.name,
                &slot.target.tag,
                budget,
            )
            .await?,
        ),
        _ => None,
    };
    let replies = runner
        .session()
        .get(entry.selector(runner, None))
        .attachment(header(runner, QueryKind::Probe, entry.fingerprint))
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(budget.max(Duration::from_millis(1)))
        .await?;
    loop {
        let reply = tokio::select! {
            r = replies.recv_async() => match r {
                Ok(r) => r,
                Err(_) => break,
            },
            () = runner.messaging_stop().cancelled() => return Err(Error::ShuttingDown),
        };
        let Ok(sample) = reply.result() else { continue };
        let Some(sender) = parse_entry_key(sample.key_expr().as_str()) else {
            continue;
        };
        let runs_slot_node = members
            .as_ref()
            .is_none_or(|m| m.contains(&sender.core, &sender.instance));
        if runs_slot_node && slot.filter.accepts(&sender.instance) {
            return Ok(sender.instance);
        }
    }
    Err(entry.unreachable())
}
