//! The peppylib receiving API: `subscribe` once, then `next` in a loop.
//!
//! A consumed topic's messages are queued from node start-up in the node's
//! inbox for that topic (as for `on_next_message_received`), so nothing is
//! lost between two calls of `next`, nor before the first `subscribe`.
//! Several subscriptions of one topic share that queue: each message goes
//! to one of them.

use std::marker::PhantomData;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::producer_ref::ProducerRef;
use crate::spec::ConsumedTopicSpec;
use crate::wire::codec::Decode;

/// A held subscription to one consumed topic, yielding `(producer,
/// message)` from the producers bound to its slot. It holds the node, so
/// it can move into a spawned task.
pub struct Subscription<M> {
    runner: Arc<NodeRunner>,
    topic: &'static ConsumedTopicSpec,
    _message: PhantomData<fn() -> M>,
}

impl<M> std::fmt::Debug for Subscription<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscription")
            .field("topic", &self.topic.name)
            .finish_non_exhaustive()
    }
}

impl<M: Decode> Subscription<M> {
    /// The next message and the producer that sent it; `Ok(None)` once the
    /// node is stopping. A message that does not decode is dropped with a
    /// logged warning, as one in another format is.
    #[allow(clippy::should_implement_trait)]
    pub async fn next(&mut self) -> Result<Option<(ProducerRef, M)>> {
        match crate::topics::next_from_producer(&self.runner, self.topic).await {
            Ok(received) => Ok(Some(received)),
            Err(Error::ShuttingDown) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// The topic this subscription reads.
    pub fn topic(&self) -> &'static str {
        self.topic.name
    }
}

/// Subscribes to `topic` on `runner` (generated code offers it as
/// `consumed_topics::<slot>::<topic>::subscribe`).
pub async fn subscribe<M: Decode>(
    runner: &NodeRunner,
    topic: &'static ConsumedTopicSpec,
) -> Result<Subscription<M>> {
    runner.inbox(topic)?.mark_read();
    Ok(Subscription {
        runner: runner.arc()?,
        topic,
        _message: PhantomData,
    })
}
