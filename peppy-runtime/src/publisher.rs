//! Today's publishing API: a message built ahead of time
//! (`build_message`) and a declared publisher that sends it
//! (`declare_publisher` then `publish`).
//!
//! The node already declares one Zenoh publisher per emitted topic at
//! start-up; a [`TopicPublisher`] is a handle on it, so declaring one is
//! cheap and several handles of one topic share it.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::spec::TopicSpec;
use crate::wire::codec::Encode;

/// A message of one emitted topic, built and ready to publish. It is
/// encoded when published, straight into shared memory when it goes there,
/// so building it ahead copies nothing.
pub struct OutgoingMessage {
    pub(crate) topic: &'static TopicSpec,
    pub(crate) body: Box<dyn Encode + Send + Sync>,
}

impl OutgoingMessage {
    /// A message of `topic`.
    pub fn new<M: Encode + Send + Sync + 'static>(topic: &'static TopicSpec, message: M) -> Self {
        OutgoingMessage {
            topic,
            body: Box::new(message),
        }
    }

    /// The topic it was built for.
    pub fn topic(&self) -> &'static str {
        self.topic.name
    }
}

impl std::fmt::Debug for OutgoingMessage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OutgoingMessage")
            .field("topic", &self.topic.name)
            .finish_non_exhaustive()
    }
}

/// A declared publisher of one emitted topic. It holds the node, so it can
/// move into a spawned task.
#[derive(Clone)]
pub struct TopicPublisher {
    runner: Arc<NodeRunner>,
    topic: &'static TopicSpec,
}

impl std::fmt::Debug for TopicPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TopicPublisher")
            .field("topic", &self.topic.name)
            .finish_non_exhaustive()
    }
}

impl TopicPublisher {
    /// Publishes `message`, which must have been built for this publisher's
    /// topic (`Error::WrongTopic` otherwise). Works while the node is
    /// stopping (shutdown hooks may publish); once its session is closed it
    /// returns `Error::ShuttingDown`.
    pub async fn publish(&self, message: OutgoingMessage) -> Result<()> {
        if !std::ptr::eq(message.topic, self.topic) {
            return Err(Error::WrongTopic {
                publisher: self.topic.name.to_string(),
                message: message.topic.name.to_string(),
            });
        }
        crate::topics::emit(&self.runner, self.topic, &*message.body).await
    }

    /// The topic this publisher sends on.
    pub fn topic(&self) -> &'static str {
        self.topic.name
    }
}

/// Declares a publisher of `topic` on `runner` (generated code offers it
/// as `emitted_topics::<topic>::declare_publisher`).
pub async fn declare_publisher(
    runner: &NodeRunner,
    topic: &'static TopicSpec,
) -> Result<TopicPublisher> {
    if runner.outlet(topic).is_none() {
        return Err(Error::Undeclared(format!("emitted topic `{}`", topic.name)));
    }
    Ok(TopicPublisher {
        runner: runner.arc()?,
        topic,
    })
}
