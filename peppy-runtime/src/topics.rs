//! Topics: publishing, and consumer inboxes that apply the slot's routing
//! filter and the format fingerprint before anything is queued.

use std::collections::HashSet;
use std::sync::{Arc, Mutex};

use peppy_schema::RouteFilter;
use tracing::{debug, warn};
use zenoh::sample::Sample;

use crate::error::{Error, Result};
use crate::members::Members;
use crate::node::NodeRunner;
use crate::qos::{QueuePolicy, queue};
use crate::spec::{ConsumedTopicSpec, TopicSpec};
use crate::stop;
use crate::wire::attachment;
use crate::wire::codec::{Decode, Encode, from_bytes, to_bytes};
use crate::wire::keys::{Channel, entry_selector, parse_entry_key};

/// One received message, not yet decoded.
#[derive(Debug)]
pub(crate) struct Delivery {
    pub(crate) core: String,
    pub(crate) instance: String,
    pub(crate) payload: Vec<u8>,
}

/// The queue of one consumed topic; filled by a Zenoh callback.
#[derive(Debug)]
pub(crate) struct Inbox {
    pub(crate) rx: flume::Receiver<Delivery>,
}

/// What the subscription callback needs.
pub(crate) struct Intake {
    pub(crate) spec: &'static ConsumedTopicSpec,
    pub(crate) filter: RouteFilter,
    /// For a node slot on an interface's key: the instances of its node.
    pub(crate) members: Option<Arc<Members>>,
    pub(crate) tx: flume::Sender<Delivery>,
    pub(crate) rx: flume::Receiver<Delivery>,
    pub(crate) policy: QueuePolicy,
    pub(crate) warned: Mutex<HashSet<String>>,
    pub(crate) mismatch: Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync>,
}

impl Intake {
    pub(crate) fn new(
        spec: &'static ConsumedTopicSpec,
        filter: RouteFilter,
        members: Option<Arc<Members>>,
        mismatch: Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync>,
    ) -> (Intake, Inbox) {
        let policy = queue(spec.qos);
        let cap = match policy {
            QueuePolicy::KeepNewest(n) | QueuePolicy::Block(n) => n,
        };
        let (tx, rx) = flume::bounded(cap);
        (
            Intake {
                spec,
                filter,
                members,
                tx,
                rx: rx.clone(),
                policy,
                warned: Mutex::new(HashSet::new()),
                mismatch,
            },
            Inbox { rx },
        )
    }

    /// The Zenoh callback: route, check the fingerprint, queue.
    pub(crate) fn accept(&self, sample: Sample) {
        let key = sample.key_expr().as_str();
        let Some(sender) = parse_entry_key(key) else {
            debug!(key, "dropping a sample with a malformed key");
            return;
        };
        if !self.filter.accepts(&sender.instance)
            || self
                .members
                .as_ref()
                .is_some_and(|m| !m.contains(&sender.core, &sender.instance))
        {
            return;
        }
        let fingerprint = sample
            .attachment()
            .and_then(|a| attachment::parse_topic(&a.to_bytes()));
        match fingerprint {
            Some(fp) if fp == self.spec.format.fingerprint => {}
            Some(fp) => {
                let first = self
                    .warned
                    .lock()
                    .map(|mut w| w.insert(sender.instance.clone()))
                    .unwrap_or(false);
                if first {
                    (self.mismatch)(self.spec, sender.instance.clone(), fp);
                }
                return;
            }
            None => {
                let first = self
                    .warned
                    .lock()
                    .map(|mut w| w.insert(sender.instance.clone()))
                    .unwrap_or(false);
                if first {
                    warn!(topic = self.spec.name, producer = %sender.instance, "dropping messages without a valid peppy attachment");
                }
                return;
            }
        }
        let delivery = Delivery {
            core: sender.core,
            instance: sender.instance,
            payload: sample.payload().to_bytes().into_owned(),
        };
        match self.policy {
            QueuePolicy::Block(_) => {
                // Back-pressure: blocks this delivery thread until the reader catches up.
                let _ = self.tx.send(delivery);
            }
            QueuePolicy::KeepNewest(_) => {
                let mut delivery = delivery;
                loop {
                    match self.tx.try_send(delivery) {
                        Ok(()) => break,
                        Err(flume::TrySendError::Full(d)) => {
                            let _ = self.rx.try_recv();
                            delivery = d;
                        }
                        Err(flume::TrySendError::Disconnected(_)) => break,
                    }
                }
            }
        }
    }
}

/// The selector a consumed topic subscribes to. A pinned slot narrows the
/// key to its producer; other filters are applied per sample.
pub(crate) fn subscription_selector(
    runner: &NodeRunner,
    spec: &ConsumedTopicSpec,
    filter: &RouteFilter,
) -> String {
    let owner = spec.owner.resolve(runner.node_name(), runner.node_tag());
    let pinned = match filter {
        RouteFilter::Pin(p) => Some(p.as_str()),
        _ => None,
    };
    entry_selector(
        runner.namespace(),
        Channel::Topic,
        owner.as_ref(),
        spec.name,
        None,
        pinned,
    )
}

/// Publishes one message on an emitted topic. The message is encoded before
/// the returned future first runs, so it need not outlive the call.
///
/// Works while the node is stopping (a last message on the way out); once
/// the node's session is closed it returns [`Error::ShuttingDown`] after a
/// short pause, so a loop that ignores the error does not spin.
pub fn emit<'a, M: Encode + ?Sized>(
    runner: &'a NodeRunner,
    spec: &'static TopicSpec,
    message: &M,
) -> impl Future<Output = Result<()>> + Send + use<'a, M> {
    let payload = to_bytes(message);
    async move {
        if runner.session().is_closed() {
            return Err(stop::refused().await);
        }
        let publisher = runner.publisher(spec)?;
        publisher
            .put(payload)
            .attachment(attachment::topic(spec.format.fingerprint))
            .await
            .map_err(Error::from)
    }
}

/// Waits for the next message of a consumed topic: `(producer instance id, message)`.
///
/// `from_core_node` keeps only messages from instances started by that launch.
///
/// Once the node stops it returns [`Error::ShuttingDown`]: at once if it was
/// waiting, after a short pause if called on an already stopped node, so a
/// loop that ignores the error parks instead of spinning.
pub async fn next_message<M: Decode>(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    from_core_node: Option<&str>,
) -> Result<(String, M)> {
    let inbox = runner.inbox(spec)?;
    if runner.cancellation_token().is_cancelled() {
        return Err(stop::refused().await);
    }
    loop {
        let delivery = tokio::select! {
            d = inbox.rx.recv_async() => d.map_err(|_| Error::ShuttingDown)?,
            () = runner.cancellation_token().cancelled() => return Err(Error::ShuttingDown),
        };
        if from_core_node.is_some_and(|c| c != delivery.core) {
            continue;
        }
        match from_bytes::<M>(&delivery.payload) {
            Ok(m) => return Ok((delivery.instance, m)),
            Err(e) => {
                warn!(topic = spec.name, producer = %delivery.instance, error = %e, "dropping a message that does not decode")
            }
        }
    }
}

/// The message is encoded when `emit` is called, so a temporary works:
/// the returned future does not borrow it.
#[cfg(test)]
#[expect(dead_code, reason = "compiling it is the test")]
fn emit_accepts_a_temporary<'a>(
    runner: &'a NodeRunner,
    spec: &'static TopicSpec,
) -> impl Future<Output = Result<()>> + use<'a> {
    emit(runner, spec, &vec![1u8, 2, 3])
}
