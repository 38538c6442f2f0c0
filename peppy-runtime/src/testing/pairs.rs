//! Mock pairing peers and observed sources: each a node of its own with
//! one pairing slot, `mock_peer` (claiming the node's participant slot,
//! which the harness pins to it) or `mock_source` (playing the role an
//! observer slot watches). What the node consumes through the slot the mock
//! publishes; what the node emits to it the mock reads.

use std::collections::HashMap;
use std::marker::PhantomData;
use std::sync::Arc;
use std::time::Duration;

use peppy_schema::{Identity, NodeModel, PairingSlot, ParameterSchema, Spelling};
use tracing::warn;
use zenoh::bytes::ZBytes;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;

use super::HARNESS_CORE;
use super::watch::Watch;
use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::pairing::PeerInfo;
use crate::producer_ref::ProducerRef;
use crate::spec::{ConsumedPairedTopicSpec, NodeDescriptor, PairedTopicSpec};
use crate::startup::{self, StandaloneConfig};
use crate::wire::attachment;
use crate::wire::codec::{Decode, Encode, from_bytes, to_bytes};
use crate::wire::keys::pairing_topic_key;

use super::mocks::SUBSCRIBER_WAIT;

/// The slot of a mock pairing peer.
pub const MOCK_PEER_SLOT: &str = "mock_peer";
/// The slot of a mock observed source.
pub const MOCK_SOURCE_SLOT: &str = "mock_source";

/// One pairing slot of the node under test as generated code describes
/// it: the topics its mocks publish and read.
#[derive(Debug)]
pub struct PairingSlotSpec {
    /// The node's pairing slot.
    pub link_id: &'static str,
    /// What the node consumes through the slot: the mocks publish it.
    pub consumed: &'static [&'static ConsumedPairedTopicSpec],
    /// What the node emits through the slot (a participant): the mock
    /// peer reads it.
    pub emitted: &'static [&'static PairedTopicSpec],
}

/// A mock's node has no entries of its own.
static EMPTY: NodeDescriptor = NodeDescriptor {
    model: "",
    document_path: "(a test mock)",
    emitted_topics: &[],
    consumed_topics: &[],
    exposed_services: &[],
    exposed_actions: &[],
};

/// A mock pairing peer or observed source: a node on the harness's router
/// with one pairing slot.
pub struct PairMock {
    runner: Arc<NodeRunner>,
    slot: PairingSlot,
    spec: &'static PairingSlotSpec,
    /// The node's instance and slot (the mock's peer).
    node: (String, String),
    /// What the node emits to the mock, read from the mock's start.
    taps: HashMap<&'static str, flume::Receiver<Sample>>,
    _subscribers: Vec<Subscriber<()>>,
    watch: Watch,
}

impl std::fmt::Debug for PairMock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PairMock")
            .field("slot", &self.spec.link_id)
            .field("instance_id", &self.runner.instance_id())
            .finish_non_exhaustive()
    }
}

impl PairMock {
    /// Starts a mock of the node's pairing slot `node_slot` (of instance
    /// `node_instance`) as instance `instance_id`: its peer for a
    /// participant slot, claiming the node's slot when `claim` names the
    /// node (`None`: an unpaired optional slot), a source for an observer
    /// slot.
    pub(crate) async fn start(
        spec: &'static PairingSlotSpec,
        node_slot: &PairingSlot,
        node_instance: &str,
        claim: Option<&str>,
        instance_id: &str,
        port: u16,
        watch: Watch,
    ) -> Result<PairMock> {
        let (link, role, counterpart) = if node_slot.observer {
            (
                MOCK_SOURCE_SLOT,
                node_slot.role.clone(),
                node_slot.counterpart.clone(),
            )
        } else {
            (
                MOCK_PEER_SLOT,
                node_slot.counterpart.clone(),
                node_slot.role.clone(),
            )
        };
        let slot = PairingSlot {
            link_id: link.to_string(),
            pairing: node_slot.pairing.clone(),
            role,
            counterpart,
            observer: false,
            sha256: None,
            optional: true,
            cardinality: peppy_schema::Cardinality::One,
            loc: Default::default(),
        };
        let doc = NodeModel {
            spelling: Spelling::UnderscoreIds,
            api: Spelling::UnderscoreIds.node_api(),
            identity: Identity::new(format!("mock_{}", node_slot.link_id), "v1"),
            dependencies: Vec::new(),
            parameters: ParameterSchema::default(),
            pairings: vec![slot.clone()],
        };
        let mut standalone = StandaloneConfig::new()
            .with_instance_id(instance_id)
            .with_messaging("127.0.0.1", port)
            .with_core_node(super::MOCK_CORE);
        if let Some(node) = claim.filter(|_| !node_slot.observer) {
            standalone = standalone.with_bound_producer(
                link,
                HARNESS_CORE,
                format!("{node}/{}", node_slot.link_id),
            );
        }
        let config = startup::load(&doc, vec!["peppy-mock".into()], None, &standalone)?;
        let runner = NodeRunner::open(
            &doc,
            &EMPTY,
            config,
            crate::DEFAULT_RESULT_RETENTION,
            crate::shm::usable(crate::SharedMemory::default()),
            crate::DEFAULT_SHUTDOWN_GRACE,
        )
        .await?;
        // What the node emits is read from here on, before its setup runs.
        let mut taps = HashMap::new();
        let mut subscribers = Vec::new();
        for t in spec.emitted {
            let key = pairing_topic_key(
                runner.namespace(),
                &slot.pairing.name,
                &slot.pairing.tag,
                t.topic.name,
                HARNESS_CORE,
                node_instance,
                &node_slot.link_id,
            );
            let (tx, rx) = flume::unbounded();
            let s = runner
                .session()
                .declare_subscriber(key)
                .callback(move |s| {
                    let _ = tx.send(s);
                })
                .await?;
            subscribers.push(s);
            taps.insert(t.topic.name, rx);
        }
        Ok(PairMock {
            runner,
            slot,
            spec,
            node: (node_instance.to_string(), node_slot.link_id.to_string()),
            taps,
            _subscribers: subscribers,
            watch,
        })
    }

    /// Waits until `node`'s session knows this mock's readers of what the
    /// node emits to it: the node's first message then reaches the mock.
    pub(crate) async fn taps_reach(&self, node: &NodeRunner, timeout: Duration) -> Result<()> {
        for t in self.spec.emitted {
            let key = pairing_topic_key(
                node.namespace(),
                &self.slot.pairing.name,
                &self.slot.pairing.tag,
                t.topic.name,
                node.core_node(),
                &self.node.0,
                &self.node.1,
            );
            let probe = node.session().declare_publisher(key).await?;
            let deadline = tokio::time::Instant::now() + timeout;
            while !probe.matching_status().await?.matching() {
                if tokio::time::Instant::now() >= deadline {
                    return Err(super::watch::timed_out(
                        &format!(
                            "mock `{}`'s reader of pairing topic `{}` to reach the node",
                            self.instance_id(),
                            t.topic.name
                        ),
                        timeout,
                    ));
                }
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        }
        Ok(())
    }

    /// The node's pairing slot this mock plays against.
    pub fn link_id(&self) -> &'static str {
        self.spec.link_id
    }

    /// The mock's instance id (`mock-<link_id>`, `mock-<link_id>-<n>`).
    pub fn instance_id(&self) -> &str {
        self.runner.instance_id()
    }

    /// The mock as the node sees it.
    pub fn producer_ref(&self) -> ProducerRef {
        ProducerRef::new(self.runner.core_node(), self.runner.instance_id())
    }

    /// The mock as the node's `paired` names it.
    pub fn peer_info(&self) -> PeerInfo {
        PeerInfo {
            producer: self.producer_ref(),
            peer_link_id: self.slot.link_id.clone(),
        }
    }

    /// The mock's own runner.
    pub fn runner(&self) -> &Arc<NodeRunner> {
        &self.runner
    }

    /// Stops the mock as its process dying would: a peer's pair dissolves.
    /// The stop begins when this returns; awaiting waits for its end (see
    /// [`super::Stopping`]).
    pub fn stop(&self) -> super::Stopping {
        super::Stopping::begin(&self.runner)
    }

    /// Whether the mock peer is paired with the node (always `false` for
    /// an observed source).
    pub fn paired(&self) -> bool {
        crate::pairing::paired(&self.runner, &self.slot.link_id)
            .ok()
            .flatten()
            .is_some()
    }

    /// The publisher of the node's consumed pairing topic `spec`.
    ///
    /// # Panics
    ///
    /// When `spec` is not a topic of this slot: generated code asks only
    /// for the slot's own topics.
    pub fn publisher<M: Encode + ?Sized>(
        &self,
        spec: &'static ConsumedPairedTopicSpec,
    ) -> Result<PairTopicMock<M>> {
        assert!(
            self.spec.consumed.iter().any(|s| std::ptr::eq(*s, spec)),
            "topic `{}` is not consumed through slot `{}`",
            spec.topic.name,
            self.spec.link_id
        );
        let key = pairing_topic_key(
            self.runner.namespace(),
            &self.slot.pairing.name,
            &self.slot.pairing.tag,
            spec.topic.name,
            self.runner.core_node(),
            self.runner.instance_id(),
            &self.slot.link_id,
        );
        // Declared without a round trip: generated code builds its mocks
        // outside of async code.
        let publisher = zenoh::Wait::wait(self.runner.session().declare_publisher(key))?;
        Ok(PairTopicMock {
            publisher,
            name: spec.topic.name,
            attachment: ZBytes::from(attachment::topic(spec.topic.format.fingerprint)),
            matched: std::sync::atomic::AtomicBool::new(false),
            watch: self.watch.clone(),
            _message: PhantomData,
        })
    }

    /// The reader of the node's emitted pairing topic `spec`.
    ///
    /// # Panics
    ///
    /// When `spec` is not a topic of this slot.
    pub fn reader<M: Decode>(&self, spec: &'static PairedTopicSpec) -> PairTopicReader<M> {
        let rx = self
            .taps
            .get(spec.topic.name)
            .unwrap_or_else(|| {
                panic!(
                    "topic `{}` is not emitted through slot `{}`",
                    spec.topic.name, self.spec.link_id
                )
            })
            .clone();
        PairTopicReader {
            rx,
            name: spec.topic.name,
            fingerprint: spec.topic.format.fingerprint,
            node: self.node.0.clone(),
            watch: self.watch.clone(),
            _message: PhantomData,
        }
    }
}

/// A mock's publisher of one pairing topic the node consumes.
pub struct PairTopicMock<M: ?Sized> {
    publisher: Publisher<'static>,
    name: &'static str,
    attachment: ZBytes,
    matched: std::sync::atomic::AtomicBool,
    watch: Watch,
    _message: PhantomData<fn(&M)>,
}

impl<M: ?Sized> std::fmt::Debug for PairTopicMock<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PairTopicMock")
            .field("topic", &self.name)
            .finish_non_exhaustive()
    }
}

impl<M: Encode + ?Sized> PairTopicMock<M> {
    /// Publishes `message` to the node. The first call waits (up to
    /// [`SUBSCRIBER_WAIT`]) until the node's subscription to the topic is
    /// known, so nothing is sent before the node listens.
    pub async fn publish(&self, message: &M) -> Result<()> {
        use std::sync::atomic::Ordering;
        if !self.matched.load(Ordering::Acquire) {
            if !self.wait_for_subscriber(SUBSCRIBER_WAIT).await? {
                return Err(Error::Testing(format!(
                    "pairing topic `{}`: the node under test has no subscription to it after {} s (does it subscribe to it?)",
                    self.name,
                    SUBSCRIBER_WAIT.as_secs()
                )));
            }
            self.matched.store(true, Ordering::Release);
        }
        self.publisher
            .put(to_bytes(message))
            .attachment(self.attachment.clone())
            .await?;
        Ok(())
    }

    /// Waits up to `timeout` until the node's subscription is known here.
    pub async fn wait_for_subscriber(&self, timeout: Duration) -> Result<bool> {
        let publisher = &self.publisher;
        self.watch
            .unbounded(async move {
                let deadline = tokio::time::Instant::now() + timeout;
                loop {
                    if publisher.matching_status().await?.matching() {
                        return Ok(true);
                    }
                    if tokio::time::Instant::now() >= deadline {
                        return Ok(false);
                    }
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
            })
            .await
    }

    /// The topic's name.
    pub fn topic(&self) -> &'static str {
        self.name
    }
}

/// A mock peer's reader of one pairing topic the node emits.
pub struct PairTopicReader<M> {
    rx: flume::Receiver<Sample>,
    name: &'static str,
    fingerprint: u64,
    node: String,
    watch: Watch,
    _message: PhantomData<fn() -> M>,
}

impl<M> std::fmt::Debug for PairTopicReader<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PairTopicReader")
            .field("topic", &self.name)
            .finish_non_exhaustive()
    }
}

impl<M: Decode> PairTopicReader<M> {
    /// The next message the node sent the mock; `None` once the mock's
    /// session is gone. A message in another format, or one that does not
    /// decode, is dropped with a warning.
    pub async fn next(&mut self) -> Result<Option<M>> {
        let rx = &self.rx;
        let (name, fingerprint, node) = (self.name, self.fingerprint, &self.node);
        self.watch
            .unbounded(async move {
                loop {
                    let Ok(sample) = rx.recv_async().await else {
                        return Ok(None);
                    };
                    let fp = sample
                        .attachment()
                        .and_then(|a| attachment::parse_topic(&a.to_bytes()));
                    if fp != Some(fingerprint) {
                        warn!(topic = name, producer = %node, "mock peer: dropping a message in another format");
                        continue;
                    }
                    match from_bytes::<M>(&sample.payload().to_bytes()) {
                        Ok(m) => return Ok(Some(m)),
                        Err(e) => {
                            warn!(topic = name, error = %e, "mock peer: dropping a message that does not decode")
                        }
                    }
                }
            })
            .await
    }

    /// The topic's name.
    pub fn topic(&self) -> &'static str {
        self.name
    }
}
