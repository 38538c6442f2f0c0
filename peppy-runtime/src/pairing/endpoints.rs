//! What generated code holds on a pair: the paired publisher (a no-op
//! while unpaired), the paired subscription (the current peer only) and
//! the observed subscription (fanned in over the sources).

use super::*;

/// What a [`TopicPublisher`] of a pairing topic this node's role emits
/// holds: it sends to the current peer (and the pair's observers), and
/// sends nothing while the slot is unpaired.
pub(crate) struct PairedSender {
    runner: Arc<NodeRunner>,
    spec: &'static PairedTopicSpec,
    participant: Arc<Participant>,
    publisher: Publisher<'static>,
    readers_known: Arc<AtomicBool>,
    attachment: ZBytes,
    /// Its direct links to a peer on this host, when the launch gives the
    /// node a directory for them.
    direct: Option<Arc<crate::direct::outlet::DirectOutlet>>,
}

impl PairedSender {
    /// Sends `message` (already checked to be of this topic) to the peer; a
    /// successful no-op while the slot is unpaired. Works while the node is
    /// stopping; once its session is closed it returns
    /// `Error::ShuttingDown`.
    pub(crate) async fn send(&self, message: &(dyn Encode + Send + Sync)) -> Result<()> {
        if !self.participant.is_paired() {
            return Ok(());
        }
        let encoded = crate::topics::encode(
            &self.runner,
            &self.spec.topic,
            message,
            self.direct.as_deref(),
            self.readers_known.load(Ordering::Relaxed),
        );
        crate::topics::check_size(self.spec.topic.name, encoded.len())?;
        let sent = crate::topics::put(
            self.direct.as_deref(),
            &self.publisher,
            encoded,
            self.attachment.clone(),
        );
        match sent {
            Ok(()) => Ok(()),
            Err(_) if self.runner.session().is_closed() => Err(stop::refused().await),
            Err(e) => Err(Error::from(e)),
        }
    }

    /// The peer, while paired.
    pub(crate) fn peer(&self) -> Option<PeerInfo> {
        self.participant.peer()
    }

    /// Whether Zenoh knows a subscriber of this topic (the peer's, or an
    /// observer's).
    pub(crate) fn has_readers(&self) -> bool {
        self.readers_known.load(Ordering::Relaxed)
    }

    /// How many consumers on this host read this topic from it over a
    /// direct link now.
    pub(crate) fn direct_links_served(&self) -> usize {
        self.direct.as_ref().map_or(0, |d| d.links())
    }

    /// The topic this sender sends on.
    pub(crate) fn topic(&self) -> &'static crate::spec::TopicSpec {
        &self.spec.topic
    }

    /// The pairing slot it sends through.
    pub(crate) fn link_id(&self) -> &'static str {
        self.spec.link_id
    }
}

/// Declares a publisher of a pairing topic (generated code offers it as
/// `paired_topics::<link_id>::<topic>::declare_publisher`).
pub async fn declare_paired_publisher(
    runner: &NodeRunner,
    spec: &'static PairedTopicSpec,
) -> Result<TopicPublisher> {
    let participant = runner.pairings().participant(spec.link_id)?.clone();
    let mut senders = participant.senders.lock().await;
    if let Some(sender) = senders.get(spec.topic.name).and_then(Weak::upgrade) {
        return Ok(TopicPublisher::paired(sender));
    }
    let slot = &participant.slot;
    let key = pairing_topic_key(
        runner.namespace(),
        &slot.pairing.name,
        &slot.pairing.tag,
        spec.topic.name,
        runner.core_node(),
        runner.instance_id(),
        &slot.link_id,
    );
    let qos = spec.topic.qos;
    let publisher = runner
        .session()
        .declare_publisher(key)
        .congestion_control(qos::congestion(qos))
        .priority(qos::priority(qos))
        .express(qos::express(qos))
        .await?;
    // Shared memory only while a reader is known, as for other topics.
    let known = Arc::new(AtomicBool::new(
        publisher
            .matching_status()
            .await
            .is_ok_and(|s| s.matching()),
    ));
    let flag = known.clone();
    publisher
        .matching_listener()
        .callback(move |status| flag.store(status.matching(), Ordering::Relaxed))
        .background()
        .await?;
    let sender = Arc::new(PairedSender {
        runner: runner.arc()?,
        spec,
        participant: participant.clone(),
        direct: runner.paired_outlet(&publisher, &known, &spec.topic),
        publisher,
        readers_known: known,
        attachment: ZBytes::from(attachment::topic(spec.topic.format.fingerprint)),
    });
    senders.retain(|_, s| s.strong_count() > 0);
    senders.insert(spec.topic.name, Arc::downgrade(&sender));
    Ok(TopicPublisher::paired(sender))
}

/// A held subscription to one of the peer's pairing topics: only the
/// current peer's messages, none from before the current pair.
pub struct PairedSubscription<M> {
    pub(super) runner: Arc<NodeRunner>,
    pub(super) spec: &'static ConsumedPairedTopicSpec,
    pub(super) fan_in: FanIn,
    pub(super) _message: PhantomData<fn() -> M>,
}

impl<M> std::fmt::Debug for PairedSubscription<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PairedSubscription")
            .field("slot", &self.spec.link_id)
            .field("topic", &self.spec.topic.name)
            .finish_non_exhaustive()
    }
}

impl<M: Decode> PairedSubscription<M> {
    /// The next message of the current peer; waits while unpaired;
    /// `Ok(None)` once the node is stopping. A message that does not
    /// decode is dropped with a logged warning.
    #[allow(clippy::should_implement_trait)]
    pub async fn next(&mut self) -> Result<Option<(PeerInfo, M)>> {
        loop {
            let Some((label, delivery)) = self.fan_in.next(self.runner.cancellation_token()).await
            else {
                return Ok(None);
            };
            let Label::Peer(peer) = label else { continue };
            match from_bytes::<M>(&delivery.payload.to_bytes()) {
                Ok(m) => return Ok(Some((peer, m))),
                Err(e) => {
                    warn!(topic = self.spec.topic.name, producer = %delivery.producer.instance, error = %e, "dropping a message that does not decode")
                }
            }
        }
    }

    /// The topic this subscription reads.
    pub fn topic(&self) -> &'static str {
        self.spec.topic.name
    }

    /// How many of the current pair's messages came over a direct link (a
    /// peer of the same launch on this host), read or not.
    pub fn received_over_direct_links(&self) -> u64 {
        self.fan_in.received_over_direct_links()
    }
}

/// Subscribes to one of the peer's pairing topics (generated code offers
/// it as `paired_topics::<link_id>::<topic>::subscribe`).
pub async fn subscribe_paired<M: Decode>(
    runner: &NodeRunner,
    spec: &'static ConsumedPairedTopicSpec,
) -> Result<PairedSubscription<M>> {
    let participant = runner.pairings().participant(spec.link_id)?;
    let (lane, notify) = participant.lane(&spec.topic).await?;
    Ok(PairedSubscription {
        runner: runner.arc()?,
        spec,
        fan_in: FanIn {
            lanes: vec![lane],
            notify,
            turn: 0,
        },
        _message: PhantomData,
    })
}

/// A held subscription to one observed pairing topic, fanned in over the
/// slot's sources.
pub struct ObservedSubscription<M> {
    pub(super) runner: Arc<NodeRunner>,
    pub(super) spec: &'static ConsumedPairedTopicSpec,
    pub(super) fan_in: FanIn,
    pub(super) _message: PhantomData<fn() -> M>,
}

impl<M> std::fmt::Debug for ObservedSubscription<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObservedSubscription")
            .field("slot", &self.spec.link_id)
            .field("topic", &self.spec.topic.name)
            .finish_non_exhaustive()
    }
}

impl<M: Decode> ObservedSubscription<M> {
    /// The next message of any source, with the source; `Ok(None)` once
    /// the node is stopping. What a source queued before it restarted is
    /// dropped.
    #[allow(clippy::should_implement_trait)]
    pub async fn next(&mut self) -> Result<Option<(ObservedSource, M)>> {
        loop {
            let Some((label, delivery)) = self.fan_in.next(self.runner.cancellation_token()).await
            else {
                return Ok(None);
            };
            let Label::Source(source) = label else {
                continue;
            };
            match from_bytes::<M>(&delivery.payload.to_bytes()) {
                Ok(m) => return Ok(Some((source, m))),
                Err(e) => {
                    warn!(topic = self.spec.topic.name, producer = %delivery.producer.instance, error = %e, "dropping a message that does not decode")
                }
            }
        }
    }

    /// The topic this subscription reads.
    pub fn topic(&self) -> &'static str {
        self.spec.topic.name
    }

    /// How many messages of the sources' current runs came over a direct
    /// link (sources of the same launch on this host), read or not.
    pub fn received_over_direct_links(&self) -> u64 {
        self.fan_in.received_over_direct_links()
    }
}

/// Subscribes to an observed pairing topic over every source of the slot
/// (generated code offers it as `paired_topics::<link_id>::<topic>::subscribe`).
pub async fn subscribe_observed<M: Decode>(
    runner: &NodeRunner,
    spec: &'static ConsumedPairedTopicSpec,
) -> Result<ObservedSubscription<M>> {
    let observer = runner.pairings().observer(spec.link_id)?;
    let fan_in = observer.fan_in(&spec.topic).await?;
    Ok(ObservedSubscription {
        runner: runner.arc()?,
        spec,
        fan_in,
        _message: PhantomData,
    })
}
