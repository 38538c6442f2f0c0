//! The peppylib publishing API: a message built ahead of time
//! (`build_message`) and a declared publisher that sends it
//! (`declare_publisher` then `publish`).
//!
//! The node already declares one Zenoh publisher per emitted topic at
//! start-up; a [`TopicPublisher`] is a handle on it, so declaring one is
//! cheap and several handles of one topic share it. A pairing topic's
//! publisher is the same type (PeppyOS has one publisher type for both):
//! it sends to the current peer, and nothing while the slot is unpaired.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::pairing::{PairedSender, PeerInfo};
use crate::spec::TopicSpec;
use crate::wire::codec::Encode;

/// A message of one emitted topic, built and ready to publish. It is
/// encoded when published, straight into shared memory when it goes there,
/// so building it ahead copies nothing. A clone shares the message (one
/// built message may go out through several publishers, or again later).
#[derive(Clone)]
pub struct OutgoingMessage {
    pub(crate) topic: &'static TopicSpec,
    pub(crate) body: Arc<dyn Encode + Send + Sync>,
}

impl OutgoingMessage {
    /// A message of `topic`.
    pub fn new<M: Encode + Send + Sync + 'static>(topic: &'static TopicSpec, message: M) -> Self {
        OutgoingMessage {
            topic,
            body: Arc::new(message),
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

/// A declared publisher of one emitted topic, or of a pairing topic this
/// node's role emits. It holds what it needs of the node, so it can move
/// into a spawned task.
#[derive(Clone)]
pub struct TopicPublisher {
    route: Route,
}

/// Where a publisher's messages go.
#[derive(Clone)]
enum Route {
    /// The node's declared publisher of an emitted topic.
    Emitted {
        runner: Arc<NodeRunner>,
        topic: &'static TopicSpec,
    },
    /// A pairing slot's topic: the current peer only.
    Paired(Arc<PairedSender>),
}

/// The older name of a pairing topic's publisher: it is a [`TopicPublisher`].
pub type PairedPublisher = TopicPublisher;

impl std::fmt::Debug for TopicPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("TopicPublisher");
        if let Route::Paired(p) = &self.route {
            d.field("slot", &p.link_id());
        }
        d.field("topic", &self.topic()).finish_non_exhaustive()
    }
}

impl TopicPublisher {
    pub(crate) fn paired(sender: Arc<PairedSender>) -> Self {
        TopicPublisher {
            route: Route::Paired(sender),
        }
    }

    fn spec(&self) -> &'static TopicSpec {
        match &self.route {
            Route::Emitted { topic, .. } => topic,
            Route::Paired(p) => p.topic(),
        }
    }

    /// Publishes `message`, which must have been built for this publisher's
    /// topic (`Error::WrongTopic` otherwise). A pairing topic's message goes
    /// to the current peer, and publishing while the slot is unpaired is a
    /// successful no-op. Works while the node is stopping (shutdown hooks
    /// may publish); once its session is closed it returns
    /// `Error::ShuttingDown`.
    pub async fn publish(&self, message: OutgoingMessage) -> Result<()> {
        let topic = self.spec();
        if !std::ptr::eq(message.topic, topic) {
            return Err(Error::WrongTopic {
                publisher: topic.name.to_string(),
                message: message.topic.name.to_string(),
            });
        }
        match &self.route {
            Route::Emitted { runner, topic } => {
                crate::topics::emit(runner, topic, &*message.body).await
            }
            Route::Paired(p) => p.send(&*message.body).await,
        }
    }

    /// The topic this publisher sends on.
    pub fn topic(&self) -> &'static str {
        self.spec().name
    }

    /// The peer a pairing topic's publisher sends to, while paired (`None`
    /// while unpaired, and for an emitted topic, which has no peer).
    pub fn peer(&self) -> Option<PeerInfo> {
        match &self.route {
            Route::Emitted { .. } => None,
            Route::Paired(p) => p.peer(),
        }
    }

    /// How many consumers of this launch on this host read this topic
    /// from this node over a direct link now (for a pairing topic: its
    /// peer and observers there).
    pub fn direct_links_served(&self) -> usize {
        match &self.route {
            Route::Emitted { runner, topic } => runner.direct_links_served(topic),
            Route::Paired(p) => p.direct_links_served(),
        }
    }

    /// Whether Zenoh knows a subscriber of this topic.
    pub fn has_readers(&self) -> bool {
        match &self.route {
            Route::Emitted { runner, topic } => runner
                .outlet(topic)
                .is_some_and(crate::node::Outlet::readers_known),
            Route::Paired(p) => p.has_readers(),
        }
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
        route: Route::Emitted {
            runner: runner.arc()?,
            topic,
        },
    })
}
