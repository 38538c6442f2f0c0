//! Topics: publishing, and consumer inboxes that hand their reader only
//! messages of the slot's producers in the reader's format.

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex};

use peppy_schema::RouteFilter;
use tracing::{debug, error, info, warn};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::sample::{Sample, SampleFields};

use crate::error::{Error, Result};
use crate::members::Members;
use crate::node::{NodeRunner, Outlet};
use crate::producers::{Declarer, Producer, Producers};
use crate::qos::{QueuePolicy, queue};
use crate::spec::{ConsumedTopicSpec, TopicSpec};
use crate::stop;
use crate::wire::attachment;
use crate::wire::codec::{Decode, DecodeError, Encode, from_bytes};
use crate::wire::keys::{Channel, entry_selector};

/// One received message, not yet decoded, from an admitted producer. The
/// payload is Zenoh's own buffer: queueing it copies nothing.
#[derive(Debug)]
pub(crate) struct Delivery {
    pub(crate) producer: Arc<Producer>,
    pub(crate) payload: ZBytes,
    /// Whether the payload is read in place from shared memory.
    pub(crate) in_place: bool,
}

/// One message as queued. Zenoh's receiving thread runs the subscription
/// callback and reads the link for every topic of the node, so it does as
/// little as it can: a keep-all topic queues what arrived and its reader
/// admits it (producer, routing filter, format); a keep-newest topic admits
/// before queueing, so a message the slot refuses never evicts one it keeps.
#[derive(Debug)]
pub(crate) struct Arrival {
    /// The admitted producer; `None` until the reader admits it.
    producer: Option<Arc<Producer>>,
    pub(crate) key: KeyExpr<'static>,
    payload: ZBytes,
    attachment: Option<ZBytes>,
    /// Whether the payload is read in place from shared memory (Zenoh's,
    /// or a direct link's).
    in_place: bool,
}

impl Arrival {
    /// Its payload (tests read what was queued).
    #[cfg(test)]
    pub(crate) fn payload(&self) -> &ZBytes {
        &self.payload
    }

    /// A message as it came (through Zenoh, or over a direct link), under
    /// its producer's key, not yet admitted.
    pub(crate) fn new(key: KeyExpr<'static>, payload: ZBytes, attachment: Option<ZBytes>) -> Self {
        Arrival {
            producer: None,
            key,
            in_place: payload.as_shm().is_some(),
            payload,
            attachment,
        }
    }

    /// The same message, its payload read in place from a direct link's
    /// shared memory.
    pub(crate) fn read_in_place(mut self) -> Self {
        self.in_place = true;
        self
    }
}

/// The queue of one consumed topic; filled by a Zenoh callback.
#[derive(Debug)]
pub(crate) struct Inbox {
    pub(crate) rx: flume::Receiver<Arrival>,
    pub(crate) backlog: Arc<Backlog>,
    admission: Arc<Admission>,
    /// Whether the node's code has asked for the topic's messages
    /// (`subscribe`, or a first `next`): what a test harness's mock
    /// publisher waits for, as PeppyOS's waits for the subscription that
    /// code opens.
    read: std::sync::atomic::AtomicBool,
}

impl Inbox {
    /// Records that the node's code reads this topic.
    pub(crate) fn mark_read(&self) {
        // A load first: the store happens once, not on every message.
        if !self.read.load(Relaxed) {
            self.read.store(true, Relaxed);
        }
    }

    /// Whether the node's code has asked for this topic's messages.
    #[cfg(feature = "testing")]
    pub(crate) fn is_read(&self) -> bool {
        self.read.load(Relaxed)
    }
}

/// What one inbox holds unread, shared by its intake and its reader, so a
/// reader falling behind is seen (and bounded) as it happens.
#[derive(Debug, Default)]
pub(crate) struct Backlog {
    /// Payload bytes queued.
    bytes: AtomicUsize,
    /// Messages queued: counted here, since asking the channel takes its
    /// lock on every message.
    messages: AtomicUsize,
    /// The queue length that earns the next warning (0: none given yet).
    next_warning: AtomicUsize,
    /// Messages dropped since the reader last caught up.
    dropped: AtomicU64,
    /// Messages that arrived in shared memory (mapped, not copied).
    pub(crate) shared: AtomicU64,
    /// Messages that arrived over a direct link.
    pub(crate) direct: AtomicU64,
}

impl Backlog {
    /// A message of `size` bytes is about to be queued: the bytes and
    /// messages then queued.
    fn queueing(&self, size: usize) -> (usize, usize) {
        (
            self.bytes.fetch_add(size, Relaxed) + size,
            self.messages.fetch_add(1, Relaxed) + 1,
        )
    }

    /// A message of `size` bytes left the queue without being read (it
    /// could not be queued, or made room for a newer one).
    fn unqueued(&self, size: usize) {
        self.bytes.fetch_sub(size, Relaxed);
        self.messages.fetch_sub(1, Relaxed);
    }

    /// The reader took a message of `size` bytes; catching up with the
    /// queue ends a warning episode.
    fn taken(&self, topic: &str, size: usize) {
        self.bytes.fetch_sub(size, Relaxed);
        let empty = self.messages.fetch_sub(1, Relaxed) == 1;
        if empty && self.next_warning.swap(0, Relaxed) != 0 {
            let dropped = self.dropped.swap(0, Relaxed);
            info!(
                topic,
                dropped, "the reader of this topic has caught up with its queue"
            );
        }
    }
}

/// Which messages of a consumed topic are its reader's: from a producer
/// the slot routes to it, in the reader's format.
pub(crate) struct Admission {
    spec: &'static ConsumedTopicSpec,
    filter: RouteFilter,
    /// For a node slot on an interface's key: the instances of its node.
    members: Option<Arc<Members>>,
    producers: Producers,
    backlog: Arc<Backlog>,
    /// Producers already warned about, so each is named once.
    warned: Mutex<HashSet<String>>,
    mismatch: Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync>,
}

impl std::fmt::Debug for Admission {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Admission")
            .field("topic", &self.spec.name)
            .field("filter", &self.filter)
            .finish_non_exhaustive()
    }
}

impl Admission {
    /// Whether the slot routes the producer publishing under `key` to the
    /// reader (its format aside).
    fn routes(&self, key: &str) -> bool {
        self.producers
            .of(key)
            .is_some_and(|producer| self.routes_producer(&producer))
    }

    /// Whether the slot routes `producer` to the reader: its filter, and a
    /// node slot's members.
    fn routes_producer(&self, producer: &Producer) -> bool {
        self.filter.accepts(&producer.instance)
            && self
                .members
                .as_ref()
                .is_none_or(|m| m.contains(&producer.core, &producer.instance))
    }

    /// The producer of a message under `key`, if the reader is to have it.
    fn admit(
        &self,
        key: &str,
        attachment: Option<&ZBytes>,
        in_place: bool,
    ) -> Option<Arc<Producer>> {
        let Some(producer) = self.producers.of(key) else {
            debug!(key, "dropping a sample with a malformed key");
            return None;
        };
        if !self.routes_producer(&producer) {
            return None;
        }
        let fingerprint = attachment.and_then(|a| attachment::parse_topic(&a.to_bytes()));
        if fingerprint != Some(self.spec.format.fingerprint) {
            let first = self
                .warned
                .lock()
                .map(|mut w| w.insert(producer.instance.to_string()))
                .unwrap_or(false);
            match fingerprint {
                Some(fp) if first => (self.mismatch)(self.spec, producer.instance.to_string(), fp),
                None if first => {
                    warn!(topic = self.spec.name, producer = %producer.instance, "dropping messages without a valid peppy attachment");
                }
                _ => {}
            }
            return None;
        }
        if in_place && self.backlog.shared.fetch_add(1, Relaxed) == 0 {
            info!(topic = self.spec.name, producer = %producer.instance, "receiving this topic through shared memory");
        }
        Some(producer)
    }
}

/// What the subscription callback needs.
pub(crate) struct Intake {
    admission: Arc<Admission>,
    tx: flume::Sender<Arrival>,
    rx: flume::Receiver<Arrival>,
    policy: QueuePolicy,
    backlog: Arc<Backlog>,
    /// The producers read over direct links (instances of one launch on
    /// this host), when the launch gives the node a directory for them.
    direct: Option<crate::direct::inlet::Inlet>,
    /// Told of every message queued, for a reader that waits on several
    /// inboxes (a pairing's fan-in) rather than on this one's channel.
    notify: Option<Arc<tokio::sync::Notify>>,
}

impl std::fmt::Debug for Intake {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Intake")
            .field("topic", &self.admission.spec.name)
            .finish_non_exhaustive()
    }
}

impl Intake {
    pub(crate) fn new(
        spec: &'static ConsumedTopicSpec,
        filter: RouteFilter,
        members: Option<Arc<Members>>,
        declarer: Declarer,
        mismatch: Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync>,
    ) -> (Intake, Inbox) {
        let policy = queue(spec.qos);
        let (tx, rx) = match policy {
            QueuePolicy::KeepNewest(n) => flume::bounded(n),
            QueuePolicy::KeepAll { .. } => flume::unbounded(),
        };
        let backlog = Arc::new(Backlog::default());
        let admission = Arc::new(Admission {
            spec,
            filter,
            members,
            producers: Producers::new(declarer),
            backlog: backlog.clone(),
            warned: Mutex::new(HashSet::new()),
            mismatch,
        });
        (
            Intake {
                admission: admission.clone(),
                tx,
                rx: rx.clone(),
                policy,
                backlog: backlog.clone(),
                direct: None,
                notify: None,
            },
            Inbox {
                rx,
                backlog,
                admission,
                read: std::sync::atomic::AtomicBool::new(false),
            },
        )
    }

    /// The intake, shared, reading the producers that offer it over
    /// `consumer`'s direct links (when the node has them): its inlet is
    /// bound to it, so the links queue into it.
    pub(crate) fn linked(
        mut self,
        consumer: Option<&Arc<crate::direct::inlet::Consumer>>,
    ) -> Arc<Self> {
        self.direct = consumer.map(|c| crate::direct::inlet::Inlet::new(c.clone()));
        let intake = Arc::new(self);
        if let Some(inlet) = intake.direct() {
            inlet.bind(&intake);
        }
        intake
    }

    /// Tells `notify` of every message queued, whether Zenoh or a direct
    /// link brought it.
    pub(crate) fn with_notify(mut self, notify: Arc<tokio::sync::Notify>) -> Self {
        self.notify = Some(notify);
        self
    }

    /// Whether the topic drops messages rather than wait (a keep-newest
    /// queue).
    #[cfg(unix)]
    pub(crate) fn drops(&self) -> bool {
        matches!(self.policy, QueuePolicy::KeepNewest(_))
    }

    /// Counts a message that arrived over a direct link.
    #[cfg(unix)]
    pub(crate) fn counted_direct(&self) {
        self.backlog.direct.fetch_add(1, Relaxed);
    }

    /// Whether the slot routes the producer publishing under `key` to this
    /// topic's reader: a direct link is made only to such a producer.
    #[cfg(unix)]
    pub(crate) fn routes(&self, key: &str) -> bool {
        self.admission.routes(key)
    }

    /// The topic's direct links, if it has them.
    pub(crate) fn direct(&self) -> Option<&crate::direct::inlet::Inlet> {
        self.direct.as_ref()
    }

    /// The Zenoh callback: queue (a keep-newest topic admits first), unless
    /// a direct link delivers the message.
    pub(crate) fn accept(&self, sample: Sample) {
        let source = self.direct.as_ref().and_then(|_| {
            let info = sample.source_info()?;
            Some((crate::direct::source_id(info.source_id()), info.source_sn()))
        });
        let SampleFields {
            key_expr,
            payload,
            attachment,
            ..
        } = sample.into();
        let arrival = Arrival::new(key_expr, payload, attachment);
        let arrival = match &self.direct {
            None => arrival,
            Some(direct) => match direct.route(self, arrival, source) {
                crate::direct::inlet::Route::Take(a) => a,
                crate::direct::inlet::Route::Handled => return,
            },
        };
        self.queue(arrival);
    }

    /// The callback of a sole link's side key: a copy of a message of the
    /// producer publishing under `key`, numbered in its source info.
    #[cfg(unix)]
    pub(crate) fn accept_side(&self, key: &KeyExpr<'static>, sample: Sample) {
        let Some(direct) = &self.direct else {
            return;
        };
        let Some(numbered) = sample.source_info().map(|i| {
            let source = crate::direct::source_id(i.source_id());
            (source.0, i.source_sn())
        }) else {
            debug!(topic = %key, "dropping a side copy without its number");
            return;
        };
        let SampleFields {
            payload,
            attachment,
            ..
        } = sample.into();
        let arrival = Arrival::new(key.clone(), payload, attachment);
        if let crate::direct::inlet::Route::Take(a) = direct.route_side(self, arrival, numbered) {
            self.queue(a);
        }
    }

    /// Queues a message, as the topic's profile says.
    pub(crate) fn queue(&self, mut arrival: Arrival) {
        let size = arrival.payload.len();
        let queued = match self.policy {
            QueuePolicy::KeepAll { warn_at, max_bytes } => {
                self.keep(arrival, size, warn_at, max_bytes)
            }
            QueuePolicy::KeepNewest(_) => {
                arrival.producer = self.admission.admit(
                    arrival.key.as_str(),
                    arrival.attachment.as_ref(),
                    arrival.in_place,
                );
                if arrival.producer.is_none() {
                    return;
                }
                self.backlog.queueing(size);
                loop {
                    match self.tx.try_send(arrival) {
                        Ok(()) => break true,
                        Err(flume::TrySendError::Full(a)) => {
                            if let Ok(oldest) = self.rx.try_recv() {
                                self.backlog.unqueued(oldest.payload.len());
                            }
                            arrival = a;
                        }
                        Err(flume::TrySendError::Disconnected(_)) => {
                            self.backlog.unqueued(size);
                            break false;
                        }
                    }
                }
            }
        };
        if queued && let Some(notify) = &self.notify {
            notify.notify_one();
        }
    }

    /// Queues a message of a keep-all topic without ever blocking, warning
    /// as the backlog grows eightfold and dropping (counted, logged) only
    /// past `max_bytes` unread. Whether it was queued.
    fn keep(&self, arrival: Arrival, size: usize, warn_at: usize, max_bytes: usize) -> bool {
        let topic = self.admission.spec.name;
        let (queued, unread) = self.backlog.queueing(size);
        if queued > max_bytes {
            self.backlog.unqueued(size);
            let dropped = self.backlog.dropped.fetch_add(1, Relaxed) + 1;
            if dropped.is_power_of_two() {
                error!(
                    topic,
                    dropped,
                    unread_mib = queued >> 20,
                    "the reader of this reliable topic is not reading; dropping what arrives until it does"
                );
            }
            return false;
        }
        if self.tx.send(arrival).is_err() {
            self.backlog.unqueued(size);
            return false;
        }
        let next = self.backlog.next_warning.load(Relaxed);
        let threshold = if next == 0 { warn_at } else { next };
        if unread >= threshold
            && self
                .backlog
                .next_warning
                .compare_exchange(next, threshold.saturating_mul(8), Relaxed, Relaxed)
                .is_ok()
        {
            warn!(
                topic,
                unread,
                unread_kib = queued >> 10,
                "the reader of this reliable topic is falling behind; every message is kept, the node's other traffic goes on"
            );
        }
        true
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

/// The largest message a node receives: Zenoh's receive limit
/// (`transport/link/rx/max_message_size`, 1 GiB), which peppy keeps. A
/// larger message would be dropped by every reader with no word to anyone,
/// so publishing one is refused with [`Error::MessageTooLarge`].
pub const MAX_MESSAGE_BYTES: usize = 1 << 30;

/// [`MAX_MESSAGE_BYTES`] checked for a message of `bytes` on `topic`.
pub(crate) fn check_size(topic: &str, bytes: usize) -> Result<()> {
    if bytes > MAX_MESSAGE_BYTES {
        return Err(Error::MessageTooLarge {
            topic: topic.to_string(),
            bytes,
            limit: MAX_MESSAGE_BYTES,
        });
    }
    Ok(())
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
    let outlet = runner.outlet(spec);
    let encoded = encode(
        runner,
        spec,
        message,
        outlet.and_then(|o| o.direct.as_deref()),
        outlet.is_some_and(Outlet::readers_known),
    );
    // This future is built and moved for every message, so it holds little:
    // Zenoh's put is synchronous (its future is `ready(put.wait())`) and is
    // waited for here, keeping the publication builder out of it; the
    // session's state is read only when a put fails (the put reads it
    // anyway); the pause of a refused call is boxed.
    async move {
        let Some(outlet) = outlet else {
            return Err(Error::Undeclared(format!("emitted topic `{}`", spec.name)));
        };
        check_size(spec.name, encoded.len())?;
        let sent = put(
            outlet.direct.as_deref(),
            &outlet.publisher,
            encoded,
            outlet.attachment.clone(),
        );
        match sent {
            Ok(()) => Ok(()),
            Err(_) if runner.session().is_closed() => Err(Box::pin(stop::refused()).await),
            Err(e) => Err(Error::from(e)),
        }
    }
}

/// A message encoded for publication on an emitted or pairing topic.
#[derive(Debug)]
pub(crate) enum Encoded {
    /// Into the shared memory of the topic's one direct link, whose consumer
    /// alone reads it.
    Placed(crate::direct::outlet::Placed),
    /// For Zenoh: into the node's shared memory or an ordinary buffer.
    Payload(ZBytes),
}

impl Encoded {
    /// The encoded message's length.
    pub(crate) fn len(&self) -> usize {
        match self {
            Encoded::Placed(placed) => placed.len(),
            Encoded::Payload(payload) => payload.len(),
        }
    }
}

/// Encodes `message` for `spec`: straight into a direct link's shared
/// memory when that link's consumer alone reads the topic
/// ([`DirectOutlet::place`](crate::direct::outlet::DirectOutlet::place)),
/// else for Zenoh (`readers_known`: whether anyone reads the topic through
/// Zenoh or a sole link's side key), into the node's shared memory only
/// when Zenoh is to carry it: not when a sole link that alone reads the
/// topic takes it over its socket.
pub(crate) fn encode<M: Encode + ?Sized>(
    runner: &NodeRunner,
    spec: &'static TopicSpec,
    message: &M,
    direct: Option<&crate::direct::outlet::DirectOutlet>,
    readers_known: bool,
) -> Encoded {
    // Sizing is a pass over the message without writing; it saves the
    // buffer's regrowth (a copy of all written so far each time).
    let len = crate::wire::codec::encoded_len(message);
    let placed = direct.and_then(|d| {
        d.place(len, |region| {
            let mut w = crate::wire::codec::Writer::fill(region);
            message.encode(&mut w);
            w.filled()
        })
    });
    if let Some(placed) = placed {
        return Encoded::Placed(placed);
    }
    let through_zenoh = || readers_known && !direct.is_some_and(|d| d.carries_alone(len));
    Encoded::Payload(runner.shm().payload(spec, message, len, through_zenoh))
}

/// Publishes a topic's message through Zenoh, and over the topic's direct
/// links when it has them (an emitted topic's or a pairing topic's).
pub(crate) fn put(
    direct: Option<&crate::direct::outlet::DirectOutlet>,
    publisher: &zenoh::pubsub::Publisher<'static>,
    encoded: Encoded,
    attachment: ZBytes,
) -> zenoh::Result<()> {
    match (encoded, direct) {
        (Encoded::Payload(payload), Some(direct)) => direct.publish(publisher, payload, attachment),
        (Encoded::Payload(payload), None) => publisher.put(payload).attachment(attachment).wait(),
        (Encoded::Placed(placed), Some(direct)) => {
            direct.publish_placed(publisher, placed, attachment)
        }
        // Only a topic's direct links place a message; were one placed
        // elsewhere, Zenoh still gets it.
        (Encoded::Placed(placed), None) => {
            publisher.put(placed.copied()).attachment(attachment).wait()
        }
    }
}

/// Which producers a read accepts, on top of the slot's own routing: a
/// message from any other producer is taken off the queue and dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Senders<'a> {
    /// Only instances started by this launch (core node).
    pub core_node: Option<&'a str>,
    /// Only this producer instance.
    pub instance_id: Option<&'a str>,
}

impl Senders<'_> {
    fn accept(&self, producer: &Producer) -> bool {
        self.core_node.is_none_or(|c| c == &*producer.core)
            && self.instance_id.is_none_or(|i| i == &*producer.instance)
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
    let senders = Senders {
        core_node: from_core_node,
        instance_id: None,
    };
    next_message_from(runner, spec, senders).await
}

/// [`next_message`] keeping only messages from `senders`: the form of
/// external consumed topics (and of every consumed topic of a legacy
/// `schema_version: 1` node), whose third argument names one producer
/// instance since no binding does.
pub async fn next_message_from<M: Decode>(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    senders: Senders<'_>,
) -> Result<(String, M)> {
    loop {
        let delivery = next_delivery(runner, spec, senders).await?;
        match from_bytes::<M>(&delivery.payload.to_bytes()) {
            Ok(m) => return Ok((String::from(&*delivery.producer.instance), m)),
            Err(e) => {
                warn!(topic = spec.name, producer = %delivery.producer.instance, error = %e, "dropping a message that does not decode")
            }
        }
    }
}

/// The next message of a consumed topic with the producer that sent it,
/// for the peppylib API's held subscriptions. Messages that do not
/// decode are dropped with a warning.
pub(crate) async fn next_from_producer<M: Decode>(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
) -> Result<(crate::ProducerRef, M)> {
    loop {
        let delivery = next_delivery(runner, spec, Senders::default()).await?;
        match from_bytes::<M>(&delivery.payload.to_bytes()) {
            Ok(m) => {
                let producer =
                    crate::ProducerRef::new(&*delivery.producer.core, &*delivery.producer.instance);
                return Ok((producer, m));
            }
            Err(e) => {
                warn!(topic = spec.name, producer = %delivery.producer.instance, error = %e, "dropping a message that does not decode")
            }
        }
    }
}

/// Like [`next_message`], without decoding: `(producer instance id, the
/// message's bytes as they arrived)`.
pub async fn next_payload(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    from_core_node: Option<&str>,
) -> Result<(String, Payload)> {
    let senders = Senders {
        core_node: from_core_node,
        instance_id: None,
    };
    next_payload_from(runner, spec, senders).await
}

/// [`next_payload`] keeping only messages from `senders`.
pub async fn next_payload_from(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    senders: Senders<'_>,
) -> Result<(String, Payload)> {
    let delivery = next_delivery(runner, spec, senders).await?;
    Ok((
        String::from(&*delivery.producer.instance),
        Payload {
            bytes: delivery.payload,
            in_place: delivery.in_place,
        },
    ))
}

/// The next queued message of `inbox` its reader is to have, without
/// waiting: what a pairing's fan-in reads from each of its inboxes.
pub(crate) fn take_ready(inbox: &Inbox, spec: &'static ConsumedTopicSpec) -> Option<Delivery> {
    loop {
        let arrival = inbox.rx.try_recv().ok()?;
        inbox.backlog.taken(spec.name, arrival.payload.len());
        let producer = match arrival.producer {
            Some(p) => p,
            None => match inbox.admission.admit(
                arrival.key.as_str(),
                arrival.attachment.as_ref(),
                arrival.in_place,
            ) {
                Some(p) => p,
                None => continue,
            },
        };
        return Some(Delivery {
            producer,
            payload: arrival.payload,
            in_place: arrival.in_place,
        });
    }
}

async fn next_delivery(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    senders: Senders<'_>,
) -> Result<Delivery> {
    let inbox = runner.inbox(spec)?;
    if runner.cancellation_token().is_cancelled() {
        return Err(stop::refused().await);
    }
    inbox.mark_read();
    loop {
        // A message already queued is taken without parking the task.
        let arrival = match inbox.rx.try_recv() {
            Ok(a) => a,
            Err(_) => tokio::select! {
                a = inbox.rx.recv_async() => a.map_err(|_| Error::ShuttingDown)?,
                () = runner.cancellation_token().cancelled() => return Err(Error::ShuttingDown),
            },
        };
        inbox.backlog.taken(spec.name, arrival.payload.len());
        let producer = match arrival.producer {
            Some(p) => p,
            None => match inbox.admission.admit(
                arrival.key.as_str(),
                arrival.attachment.as_ref(),
                arrival.in_place,
            ) {
                Some(p) => p,
                None => continue,
            },
        };
        if senders.accept(&producer) {
            return Ok(Delivery {
                producer,
                payload: arrival.payload,
                in_place: arrival.in_place,
            });
        }
    }
}

/// A received message, not decoded: its bytes where they arrived. A large
/// message from a producer on this host is still in the producer's shared
/// memory, so [`Payload::bytes`] borrows it in place and a
/// [`Decoder`](crate::wire::codec::Decoder) walking it hands out byte
/// fields (`Decoder::take`) as slices of those pages: a camera frame read
/// without one copy. [`Payload::decode`] gives the owned message.
#[derive(Debug, Clone)]
pub struct Payload {
    bytes: ZBytes,
    in_place: bool,
}

impl Payload {
    /// The encoded message (docs/WIRE.md §5). Borrowed whenever it is one
    /// piece, which a shared-memory message always is; a message the
    /// network split into pieces is joined into one copy.
    pub fn bytes(&self) -> std::borrow::Cow<'_, [u8]> {
        self.bytes.to_bytes()
    }

    /// Whether the bytes are in shared memory (mapped, never copied):
    /// Zenoh's, or a direct link's (docs/WIRE.md, "Direct links").
    pub fn in_shared_memory(&self) -> bool {
        self.in_place
    }

    /// The encoded length.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// Whether the message has no bytes (a format with no payload).
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Decodes the whole message.
    pub fn decode<M: Decode>(&self) -> std::result::Result<M, DecodeError> {
        from_bytes(&self.bytes())
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

/// A consumed topic for the intake's tests (here and in `direct`).
#[cfg(test)]
pub(crate) static TEST_TICKS: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: None,
    owner: crate::spec::OwnerSpec::Any,
    name: "ticks",
    qos: peppy_schema::QosProfile::Reliable,
    format: crate::spec::FormatSpec::EMPTY,
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{FormatSpec, OwnerSpec};
    use crate::wire::keys::{Owner, entry_key};
    use peppy_schema::QosProfile;

    use super::TEST_TICKS as TICKS;

    const TICKER: &str = "peppy/lab/topic/node/clock/v1/ticks/core/ticker";

    fn arrival(byte: u8) -> Arrival {
        Arrival {
            producer: None,
            key: KeyExpr::try_from(TICKER).unwrap(),
            payload: ZBytes::from(vec![byte; 100]),
            attachment: None,
            in_place: false,
        }
    }

    /// A sample of `instance` in a format of `fingerprint` (`None`: no
    /// attachment).
    fn sample(instance: &str, fingerprint: Option<u64>) -> Sample {
        let clock = Owner::Node {
            name: "clock",
            tag: "v1",
        };
        let key = entry_key("lab", Channel::Topic, &clock, "ticks", "core", instance);
        let key = KeyExpr::try_from(key).unwrap();
        let b = zenoh::sample::SampleBuilder::put(key, vec![7u8; 10]);
        match fingerprint {
            Some(fp) => b.attachment(attachment::topic(fp)).into(),
            None => b.into(),
        }
    }

    /// An intake of `spec` keeping messages of `ticker` only, and the
    /// producers it reported a format mismatch of.
    fn pinned(spec: &'static ConsumedTopicSpec) -> (Intake, Inbox, Arc<Mutex<Vec<String>>>) {
        let mismatched = Arc::new(Mutex::new(Vec::new()));
        let m = mismatched.clone();
        let (intake, inbox) = Intake::new(
            spec,
            RouteFilter::Pin("ticker".into()),
            None,
            Declarer::none(),
            Arc::new(move |_, producer, _| m.lock().unwrap().push(producer)),
        );
        (intake, inbox, mismatched)
    }

    /// Zenoh drops a message past its receive limit at every reader with
    /// only a trace line (a 1 GiB + 64 KiB message was seen vanish while
    /// `emit` returned `Ok`); peppy refuses to publish one, with figures.
    #[test]
    fn a_message_no_node_would_receive_is_refused_with_figures() {
        assert!(check_size("frames", MAX_MESSAGE_BYTES).is_ok());
        let refused = check_size("frames", MAX_MESSAGE_BYTES + 1).unwrap_err();
        assert!(
            matches!(refused, Error::MessageTooLarge { bytes, .. } if bytes == MAX_MESSAGE_BYTES + 1)
        );
        assert_eq!(
            refused.to_string(),
            "a message of 1073741825 bytes cannot be published on topic `frames`: \
             nodes receive messages of at most 1073741824 bytes"
        );
    }

    #[test]
    fn a_keep_all_topic_queues_as_it_arrives_and_its_reader_admits() {
        let (intake, inbox, mismatched) = pinned(&TICKS);
        let fp = TICKS.format.fingerprint;
        for s in [
            sample("ticker", Some(fp)),
            sample("other", Some(fp)),
            sample("ticker", Some(fp ^ 1)),
            sample("ticker", Some(fp ^ 1)),
            sample("ticker", None),
        ] {
            intake.accept(s);
        }
        assert_eq!(inbox.rx.len(), 5, "the receiving thread admits nothing");
        let admitted: Vec<bool> = inbox
            .rx
            .drain()
            .map(|a| {
                assert!(a.producer.is_none());
                inbox
                    .admission
                    .admit(a.key.as_str(), a.attachment.as_ref(), a.in_place)
                    .is_some()
            })
            .collect();
        assert_eq!(admitted, [true, false, false, false, false]);
        assert_eq!(
            *mismatched.lock().unwrap(),
            ["ticker"],
            "a mismatch is reported once per producer"
        );
    }

    #[test]
    fn a_keep_newest_topic_admits_before_queueing() {
        static FRAMES: ConsumedTopicSpec = ConsumedTopicSpec {
            qos: QosProfile::SensorData,
            ..TICKS
        };
        let (intake, inbox, _) = pinned(&FRAMES);
        assert!(matches!(intake.policy, QueuePolicy::KeepNewest(_)));
        let fp = FRAMES.format.fingerprint;
        intake.accept(sample("ticker", Some(fp)));
        for _ in 0..100 {
            intake.accept(sample("other", Some(fp)));
            intake.accept(sample("ticker", Some(fp ^ 1)));
        }
        assert_eq!(inbox.rx.len(), 1, "refused messages never evict a kept one");
        let kept = inbox.rx.try_recv().unwrap();
        assert_eq!(&*kept.producer.unwrap().instance, "ticker");
    }

    #[test]
    fn a_keep_all_inbox_keeps_everything_up_to_its_byte_bound_then_counts_drops() {
        let (intake, inbox) = Intake::new(
            &TICKS,
            RouteFilter::Any,
            None,
            Declarer::none(),
            Arc::new(|_, _, _| {}),
        );
        assert!(matches!(intake.policy, QueuePolicy::KeepAll { .. }));
        for n in 0..12 {
            intake.keep(arrival(n), 100, 4, 1_000);
        }
        assert_eq!(
            inbox.rx.len(),
            10,
            "ten 100-byte messages fit in 1000 bytes"
        );
        assert_eq!(intake.backlog.dropped.load(Relaxed), 2);
        assert_eq!(
            intake.backlog.next_warning.load(Relaxed),
            32,
            "warned at 4, then at 32"
        );
        let first = inbox.rx.try_recv().unwrap();
        assert_eq!(first.payload.to_bytes()[0], 0, "the oldest is read first");
        inbox.backlog.taken("ticks", 100);
        intake.keep(arrival(12), 100, 4, 1_000);
        assert_eq!(inbox.rx.len(), 10, "room for one more once one is read");
        while let Ok(d) = inbox.rx.try_recv() {
            inbox.backlog.taken("ticks", d.payload.len());
        }
        assert_eq!(intake.backlog.bytes.load(Relaxed), 0);
        assert_eq!(intake.backlog.messages.load(Relaxed), 0);
        assert_eq!(
            intake.backlog.dropped.load(Relaxed),
            0,
            "caught up: a new episode"
        );
        assert_eq!(intake.backlog.next_warning.load(Relaxed), 0);
    }

    /// `emit`'s future is built and moved for every message sent; a large
    /// one showed up as a memcpy per message in the small-message profile.
    #[test]
    fn the_emit_future_stays_small() {
        fn size_of_output<R>(_: fn(&'static NodeRunner) -> R) -> usize {
            std::mem::size_of::<R>()
        }
        static STREAM: TopicSpec = TopicSpec {
            owner: OwnerSpec::Any,
            name: "stream",
            qos: QosProfile::Reliable,
            format: FormatSpec::EMPTY,
        };
        fn emit_one(r: &'static NodeRunner) -> impl Future<Output = Result<()>> {
            emit(r, &STREAM, &0u64)
        }
        let size = size_of_output(emit_one);
        assert!(size <= 128, "emit's future is {size} bytes");
    }
}
