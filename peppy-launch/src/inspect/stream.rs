//! Taking a topic's samples off the wire without disturbing anyone: the
//! choice of samples (`TOPIC`, `--from`, `--slot`), a subscription that
//! never blocks the publishers, the formats to decode with, and the
//! `--count` / `--timeout` limits every streaming command shares.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::Duration;

use peppy_runtime::describe::{ConsumedTopic, EmittedTopic, InstanceInfo, OwnerInfo};
use peppy_runtime::wire::attachment;
use peppy_runtime::wire::keys::{Channel, EntrySelector, Sender, entry_selector, parse_entry_key};
use peppy_schema::{Identity, MessageFormat, RouteFilter, SlotKind};
use tokio::time::Instant;

use super::{Observer, SelectError};
use crate::cli::{StreamArgs, TopicSelect};
use crate::error::{InspectError, Result, SetupError};

/// How many received samples wait for a slow reader (a terminal) before
/// newer ones are dropped: the observer never holds a publisher back.
const BACKLOG: usize = 256;

/// A `TOPIC` argument: `NAME`, `OWNER/NAME`, or `KIND/OWNER/NAME` with
/// KIND `node` or `interface`, for the rare stack where a node and an
/// interface share a `name:tag` (a node named like an interface it does not
/// conform to).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct TopicArg {
    /// The topic name.
    pub(crate) name: String,
    /// The owner, if given.
    pub(crate) owner: Option<Identity>,
    /// The owner's kind, if given.
    pub(crate) kind: Option<SlotKind>,
}

impl TopicArg {
    pub(crate) fn parse(arg: &str) -> std::result::Result<TopicArg, SelectError> {
        let bad = || SelectError::NotATopic {
            arg: arg.to_string(),
        };
        let parts: Vec<&str> = arg.split('/').collect();
        let (kind, owner, name) = match parts.as_slice() {
            [name] => (None, None, *name),
            [owner, name] => (None, Some(*owner), *name),
            ["node", owner, name] => (Some(SlotKind::Node), Some(*owner), *name),
            ["interface", owner, name] => (Some(SlotKind::Interface), Some(*owner), *name),
            _ => return Err(bad()),
        };
        if !peppy_runtime::wire::keys::is_segment(name) {
            return Err(bad());
        }
        let owner = match owner {
            Some(o) => Some(Identity::parse(o).ok_or_else(bad)?),
            None => None,
        };
        Ok(TopicArg {
            name: name.to_string(),
            owner,
            kind,
        })
    }

    /// Whether an entry of `owner` named `name` is this topic.
    pub(crate) fn is(&self, owner: &OwnerInfo, name: &str) -> bool {
        name == self.name
            && self
                .owner
                .as_ref()
                .is_none_or(|w| owner.name == w.name && owner.tag == w.tag)
            && self.kind.is_none_or(|k| owner.kind == k)
    }

    /// Every running instance emitting this topic, with its entry.
    pub(crate) fn emitters<'a>(
        &self,
        all: &'a BTreeMap<String, InstanceInfo>,
    ) -> Vec<(&'a InstanceInfo, &'a EmittedTopic)> {
        all.values()
            .flat_map(|i| i.emits.iter().map(move |t| (i, t)))
            .filter(|(_, t)| self.is(&t.owner, &t.name))
            .collect()
    }

    /// Whether a consumer's entry receives this topic: its owner is this
    /// topic's (any owner for an external topic).
    pub(crate) fn received_by(&self, consumed: &ConsumedTopic) -> bool {
        match &consumed.owner {
            Some(o) => self.is(o, &consumed.name),
            None => consumed.name == self.name,
        }
    }
}

/// Every topic name any running instance emits or consumes, for messages.
pub(crate) fn topic_names(all: &BTreeMap<String, InstanceInfo>) -> Vec<String> {
    let names: BTreeSet<&str> = all
        .values()
        .flat_map(|i| {
            i.emits
                .iter()
                .map(|t| t.name.as_str())
                .chain(i.consumes.iter().map(|t| t.name.as_str()))
        })
        .collect();
    names.into_iter().map(str::to_string).collect()
}

/// Which samples a streaming command takes, and how to read them.
#[derive(Debug)]
pub(crate) struct Selection {
    /// The topic name.
    pub(crate) topic: String,
    /// The key expression to subscribe to.
    pub(crate) selector: String,
    /// Through `--slot`: the consumer's entry, whose routing decides.
    pub(crate) slot: Option<ConsumedTopic>,
    /// `instance -> node` of every running instance.
    pub(crate) nodes: HashMap<String, Identity>,
    /// Formats by fingerprint, from the descriptions.
    pub(crate) formats: HashMap<u64, String>,
    /// Instances whose description was asked for after start.
    asked: std::collections::HashSet<String>,
    /// Through `--pair`: the pairing slots whose sends are taken.
    pub(crate) pair: Option<super::pairs::Senders>,
}

impl Selection {
    /// Chooses the samples from the descriptions of the running instances.
    pub(crate) fn new(
        args: &TopicSelect,
        ns: &str,
        all: &BTreeMap<String, InstanceInfo>,
    ) -> Result<Selection> {
        if let Some(pair) = &args.pair {
            return super::pairs::selection(args, pair, ns, all);
        }
        let topic = TopicArg::parse(&args.topic)?;
        let name = topic.name.clone();
        let emitters = topic.emitters(all);
        let consumed: Vec<(&InstanceInfo, &ConsumedTopic)> = all
            .values()
            .flat_map(|i| i.consumes.iter().map(move |t| (i, t)))
            .filter(|(_, t)| topic.received_by(t))
            .collect();
        if emitters.is_empty() && consumed.is_empty() {
            return Err(SelectError::NoSuchTopic {
                topic: args.topic.clone(),
                topics: topic_names(all),
            }
            .into());
        }
        let owners: BTreeSet<(&str, &str, &str)> = emitters
            .iter()
            .map(|(_, t)| {
                (
                    t.owner.kind.as_str(),
                    t.owner.name.as_str(),
                    t.owner.tag.as_str(),
                )
            })
            .collect();
        if topic.owner.is_some() && owners.len() > 1 {
            return Err(SelectError::NodeOrInterface {
                topic: args.topic.clone(),
            }
            .into());
        }
        if let Some(from) = &args.from
            && !emitters.iter().any(|(i, _)| &i.instance_id == from)
        {
            return Err(SelectError::NotAProducer {
                instance: from.clone(),
                topic: args.topic.clone(),
                producers: emitters
                    .iter()
                    .map(|(i, _)| i.instance_id.clone())
                    .collect(),
            }
            .into());
        }
        let mut formats = HashMap::new();
        for (_, t) in &emitters {
            formats.insert(t.format.fingerprint, t.format.canonical.clone());
        }
        for (_, t) in &consumed {
            formats.insert(t.format.fingerprint, t.format.canonical.clone());
        }
        let nodes = all
            .values()
            .map(|i| (i.instance_id.clone(), i.node.clone()))
            .collect();
        let mut selection = Selection {
            topic: name.clone(),
            selector: String::new(),
            slot: None,
            nodes,
            formats,
            asked: Default::default(),
            pair: None,
        };
        match &args.slot {
            Some(slot) => selection.through_slot(slot, &name, &consumed, args.from.as_deref())?,
            None => {
                // A named owner narrows the key; with none, every owner's
                // topic of that name (node-owned, interface-owned) is shown.
                let owner = match (&topic.owner, emitters.first()) {
                    (Some(_), Some((_, t))) => Some(t.owner.clone()),
                    (Some(o), None) => {
                        // Nobody emits it now: a consumer's slot names the
                        // owner's kind, or the argument must.
                        let kind = topic.kind.or_else(|| {
                            consumed.iter().find_map(|(_, c)| {
                                c.owner
                                    .as_ref()
                                    .filter(|co| co.name == o.name && co.tag == o.tag)
                                    .map(|co| co.kind)
                            })
                        });
                        let Some(kind) = kind else {
                            return Err(SelectError::OwnerKindUnknown {
                                topic: args.topic.clone(),
                            }
                            .into());
                        };
                        Some(OwnerInfo {
                            kind,
                            name: o.name.clone(),
                            tag: o.tag.clone(),
                        })
                    }
                    (None, _) => None,
                };
                selection.selector = entry_selector(
                    ns,
                    Channel::Topic,
                    owner.as_ref().map(OwnerInfo::as_owner).as_ref(),
                    &name,
                    None,
                    args.from.as_deref(),
                );
            }
        }
        Ok(selection)
    }

    /// A `--pair` selection: `senders`' samples on `selector`, read with
    /// `formats`.
    pub(crate) fn of_pair(
        topic: String,
        selector: String,
        formats: HashMap<u64, String>,
        senders: super::pairs::Senders,
    ) -> Selection {
        Selection {
            topic,
            selector,
            slot: None,
            nodes: HashMap::new(),
            formats,
            asked: Default::default(),
            pair: Some(senders),
        }
    }

    /// `--slot INSTANCE.SLOT`: exactly what that slot receives.
    fn through_slot(
        &mut self,
        slot: &str,
        name: &str,
        consumed: &[(&InstanceInfo, &ConsumedTopic)],
        from: Option<&str>,
    ) -> Result<()> {
        let (instance, link) = match slot.split_once('.') {
            Some((i, l)) => (i, Some(l)),
            None => (slot, None),
        };
        let found = consumed
            .iter()
            .find(|(i, t)| i.instance_id == instance && t.slot.as_deref() == link);
        let Some((_, t)) = found else {
            return Err(SelectError::NotReceivedBy {
                slot: slot.to_string(),
                topic: name.to_string(),
                slots: consumed
                    .iter()
                    .map(|(i, t)| match &t.slot {
                        Some(l) => format!("{}.{l}", i.instance_id),
                        None => i.instance_id.clone(),
                    })
                    .collect(),
            }
            .into());
        };
        if let Some(f) = from
            && !t.filter.accepts(f)
        {
            return Err(SelectError::FilteredOut {
                slot: slot.to_string(),
                from: f.to_string(),
                keeps: t.filter.clone(),
            }
            .into());
        }
        self.selector = match from {
            // Narrow the consumer's own selector to one producer.
            Some(f) => match EntrySelector::parse(&t.selector) {
                Some(any @ EntrySelector { instance: None, .. }) => EntrySelector {
                    instance: Some(f),
                    ..any
                }
                .to_string(),
                _ => t.selector.clone(),
            },
            None => t.selector.clone(),
        };
        self.slot = Some((*t).clone());
        Ok(())
    }

    /// Whether a sample from `sender` with `fingerprint` is one the command
    /// takes: through `--slot`, only what the slot's routing keeps (its
    /// producer filter, its node's instances, its own format).
    pub(crate) fn keeps(&self, sender: &Sender, fingerprint: Option<u64>) -> bool {
        self.slot.as_ref().is_none_or(|c| {
            fingerprint == Some(c.format.fingerprint)
                && slot_keeps(c, &sender.instance, self.nodes.get(&sender.instance))
        })
    }

    /// Learns the node of a producer that started after the command did,
    /// when the slot keeps only one node's instances (asked once each).
    pub(crate) async fn learn(&mut self, observer: &Observer, sender: &Sender) {
        if self.slot.as_ref().is_none_or(|c| c.members_of.is_none())
            || self.nodes.contains_key(&sender.instance)
            || !self.asked.insert(sender.instance.clone())
        {
            return;
        }
        if let Some(info) = observer
            .describe_instance(&sender.core, &sender.instance)
            .await
        {
            self.nodes.insert(info.instance_id, info.node);
        }
    }

    /// The parsed format of `fingerprint`, asking the producer for its text
    /// when no description named it (cached, asked once).
    pub(crate) async fn format(
        &mut self,
        observer: &Observer,
        cache: &mut HashMap<u64, Option<MessageFormat>>,
        fingerprint: u64,
        producer: &str,
    ) -> Option<MessageFormat> {
        if let Some(known) = cache.get(&fingerprint) {
            return known.clone();
        }
        let text = match self.formats.get(&fingerprint) {
            Some(t) => Some(t.clone()),
            None => ask_format(observer, fingerprint, producer).await,
        };
        // A text that does not hash to the fingerprint it was asked for is
        // not that format: decoding with it would print wrong values.
        let parsed = text
            .and_then(|t| MessageFormat::from_canonical(&t).ok())
            .filter(|f| {
                f.fingerprint() == fingerprint || (fingerprint == 0 && f.fields.is_empty())
            });
        cache.insert(fingerprint, parsed.clone());
        parsed
    }
}

/// Whether a consumer's entry keeps a sample from `producer`, an instance
/// of `node` (`None`: not known): the slot's producer filter and, for a node
/// slot on an interface's key, the node. The consumer side's per-sample
/// routing (docs/WIRE.md section 1), shared by `--slot` and `graph --live`.
pub(crate) fn slot_keeps(
    consumed: &ConsumedTopic,
    producer: &str,
    node: Option<&Identity>,
) -> bool {
    consumed.filter.accepts(producer)
        && consumed.members_of.as_ref().is_none_or(|m| node == Some(m))
}

/// A slot filter, for people.
pub(crate) fn filter_text(filter: &RouteFilter) -> String {
    let join = |set: &BTreeSet<String>| set.iter().cloned().collect::<Vec<_>>().join(", ");
    match filter {
        RouteFilter::Pin(p) => format!("only `{p}`"),
        RouteFilter::OnlyFrom(set) => format!("only {}", join(set)),
        RouteFilter::AnyExcept(set) => format!("any producer except {}", join(set)),
        RouteFilter::Any => "any producer".into(),
    }
}

/// Asks a producer for the text of a format (its format queryable).
async fn ask_format(observer: &Observer, fingerprint: u64, producer: &str) -> Option<String> {
    let (session, namespace) = (&observer.session, &observer.reach.namespace);
    peppy_runtime::describe::ask_format(
        session,
        namespace,
        fingerprint,
        producer,
        Duration::from_secs(1),
    )
    .await
}

/// One sample as received.
#[derive(Debug)]
pub(crate) struct Received {
    /// Who sent it (from its key).
    pub(crate) sender: Sender,
    /// The format fingerprint in its attachment (`None`: no valid attachment).
    pub(crate) fingerprint: Option<u64>,
    /// The payload (empty when the tap keeps only sizes).
    pub(crate) payload: Vec<u8>,
    /// The payload's size in bytes.
    pub(crate) size: usize,
    /// When it arrived.
    pub(crate) at: Instant,
}

/// A subscription feeding a bounded queue: a full queue drops the newest
/// sample and counts it, so a slow terminal never back-pressures the stack.
pub(crate) struct Tap {
    _subscriber: zenoh::pubsub::Subscriber<()>,
    rx: flume::Receiver<Received>,
    dropped: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

impl Tap {
    /// Subscribes to `selector`; `keep_payload: false` keeps only sizes
    /// (rates need no copy of a camera frame).
    pub(crate) async fn open(
        observer: &Observer,
        selector: &str,
        keep_payload: bool,
    ) -> Result<Tap> {
        Tap::open_with(observer, selector, keep_payload, parse_entry_key).await
    }

    /// [`Tap::open`] of a selection: its keys read by the selection's own
    /// reader (a pair's keys are not an owner's).
    pub(crate) async fn of(
        observer: &Observer,
        selection: &Selection,
        keep_payload: bool,
    ) -> Result<Tap> {
        match &selection.pair {
            Some(senders) => {
                let senders = senders.clone();
                let read = move |key: &str| super::pairs::sender(key, &senders);
                Tap::open_with(observer, &selection.selector, keep_payload, read).await
            }
            None => Tap::open(observer, &selection.selector, keep_payload).await,
        }
    }

    /// [`Tap::open`], reading who sent each sample with `read` (`None`:
    /// not a sample the command takes).
    pub(crate) async fn open_with(
        observer: &Observer,
        selector: &str,
        keep_payload: bool,
        read: impl Fn(&str) -> Option<Sender> + Send + Sync + 'static,
    ) -> Result<Tap> {
        let (tx, rx) = flume::bounded(BACKLOG);
        let dropped = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
        let counter = dropped.clone();
        let subscriber = observer
            .session
            .declare_subscriber(selector.to_string())
            .callback(move |sample| {
                let Some(sender) = read(sample.key_expr().as_str()) else {
                    return;
                };
                let received = Received {
                    sender,
                    fingerprint: sample
                        .attachment()
                        .and_then(|a| attachment::parse_topic(&a.to_bytes())),
                    payload: if keep_payload {
                        sample.payload().to_bytes().into_owned()
                    } else {
                        Vec::new()
                    },
                    size: sample.payload().len(),
                    at: Instant::now(),
                };
                if tx.try_send(received).is_err() {
                    counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
            })
            .await
            .map_err(|source| SetupError::Subscribe {
                selector: selector.to_string(),
                source,
            })?;
        Ok(Tap {
            _subscriber: subscriber,
            rx,
            dropped,
        })
    }

    /// The next sample, or `None` once the limits or Ctrl-C end the stream.
    pub(crate) async fn next(&self, limits: &Limits) -> Option<Received> {
        let stop = super::interrupted();
        tokio::select! {
            r = self.rx.recv_async() => r.ok(),
            () = limits.expired() => None,
            () = stop.cancelled() => None,
        }
    }

    /// Samples dropped because the reader fell behind.
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// `--count` and `--timeout`.
#[derive(Debug, Clone)]
pub(crate) struct Limits {
    pub(crate) count: Option<u64>,
    deadline: Option<Instant>,
    timeout: Option<Duration>,
}

impl Limits {
    pub(crate) fn new(args: &StreamArgs) -> Limits {
        Limits {
            count: args.count,
            deadline: args.timeout.map(|t| Instant::now() + t),
            timeout: args.timeout,
        }
    }

    /// Whether `done` items satisfy `--count`.
    pub(crate) fn reached(&self, done: u64) -> bool {
        self.count.is_some_and(|n| done >= n)
    }

    /// Resolves at the deadline (never without `--timeout`).
    pub(crate) async fn expired(&self) {
        match self.deadline {
            Some(d) => tokio::time::sleep_until(d).await,
            None => std::future::pending().await,
        }
    }

    /// The outcome once the stream ended with `done` items of `what`:
    /// short of `--count` at the deadline is a failure.
    pub(crate) fn outcome(&self, done: u64, what: &'static str) -> Result {
        match (self.count, self.timeout) {
            (Some(n), Some(t))
                if done < n && self.deadline.is_some_and(|d| Instant::now() >= d) =>
            {
                Err(InspectError::TooFew {
                    got: done,
                    wanted: n,
                    what,
                    within: t,
                }
                .into())
            }
            _ => Ok(()),
        }
    }
}

/// The owner of a sender's entry, as `name:tag`.
pub(crate) fn sender_owner(sender: &Sender) -> String {
    format!("{}:{}", sender.name, sender.tag)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_may_name_their_owner() {
        let t = TopicArg::parse("video_stream").unwrap();
        assert_eq!(
            (t.owner, t.kind, t.name.as_str()),
            (None, None, "video_stream")
        );
        let t = TopicArg::parse("depth_camera:v1/video_stream").unwrap();
        assert_eq!(t.owner, Some(Identity::new("depth_camera", "v1")));
        let t = TopicArg::parse("node/depth_camera:v1/video_stream").unwrap();
        assert_eq!(t.kind, Some(SlotKind::Node));
        let interface = OwnerInfo {
            kind: SlotKind::Interface,
            name: "depth_camera".into(),
            tag: "v1".into(),
        };
        assert!(
            !t.is(&interface, "video_stream"),
            "the kind tells them apart"
        );
        assert!(
            TopicArg::parse("depth_camera:v1/video_stream")
                .unwrap()
                .is(&interface, "video_stream")
        );
        for bad in [
            "depth_camera/video_stream",
            "a:v1/",
            "x/a:v1/t",
            "a/b/c/d",
            "",
            "video*",
        ] {
            assert!(TopicArg::parse(bad).is_err(), "{bad}");
        }
    }
}
