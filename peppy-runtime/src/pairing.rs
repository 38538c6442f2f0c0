//! Pairings on the wire (docs/PAIRINGS.md §3): each participant slot's
//! claim token, the pair that holds while two slots claim each other,
//! paired publishers and subscriptions, and observers' subscriptions to
//! their sources.
//!
//! Everything a slot knows comes from liveliness tokens, which Zenoh
//! withdraws when a session closes or its link is lost: one task per slot
//! reads the pairing's claims (and, for an observer, its sources' presence
//! tokens) and moves the slot from one state to the next. A consumed
//! pairing topic reuses the topics' intake ([`Intake`]): each pair (and
//! each run of an observed source) gets a fresh intake and inbox, so a
//! queue never holds a message from before the pair it is read in.

use std::collections::{HashMap, HashSet};
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, Weak};

use peppy_schema::{PairEnd, PairPlan, PairingSlot, RouteFilter};
use tokio::sync::{Notify, watch};
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::{Sample, SampleKind};

use crate::describe::{PairingSlotInfo, PeerEndInfo, SourceInfo};
use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::producer_ref::ProducerRef;
use crate::producers::Declarer;
use crate::publisher::OutgoingMessage;
use crate::qos;
use crate::spec::{ConsumedPairedTopicSpec, ConsumedTopicSpec, PairedTopicSpec};
use crate::stop;
use crate::topics::{self, Delivery, Inbox, Intake};
use crate::wire::attachment;
use crate::wire::codec::{Decode, from_bytes};
use crate::wire::keys::{
    Claim, all_liveliness_selector, claim_selector, pairing_topic_key, pairing_topic_selector,
    parse_liveliness_key,
};

/// The peer a participant slot is paired with.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PeerInfo {
    /// The peer instance and the launch that started it.
    pub producer: ProducerRef,
    /// The peer's pairing slot.
    pub peer_link_id: String,
}

/// A source an observer slot watches.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ObservedSource {
    /// The source instance and the launch that started it (this node's
    /// launch until the source's presence token has been seen).
    pub producer: ProducerRef,
    /// The source's pairing slot (empty until known: the plan named only
    /// the instance and no claim of it has been seen yet).
    pub source_link_id: String,
}

/// Fingerprint-mismatch reporting, as the node's topics do it.
pub(crate) type Mismatch = Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync>;

/// What every inbox of the node's pairing slots is built with.
#[derive(Clone)]
pub(crate) struct Tools {
    pub(crate) declarer: Declarer,
    pub(crate) mismatch: Mismatch,
}

/// Who a lane's messages are from, handed out with each message.
#[derive(Debug, Clone)]
enum Label {
    Peer(PeerInfo),
    Source(ObservedSource),
}

/// The inbox of the current pair (or source run) of one lane.
struct Current {
    intake: Intake,
    inbox: Inbox,
    label: Label,
}

/// One consumed pairing topic from one sender (the peer, or one observed
/// source): a Zenoh subscription on the sender's key, and the inbox of the
/// current pair.
pub(crate) struct Lane {
    spec: &'static ConsumedTopicSpec,
    tools: Tools,
    current: Mutex<Option<Current>>,
    subscriber: tokio::sync::Mutex<Option<(String, Subscriber<()>)>>,
    /// Shared by the lanes one subscription reads.
    notify: Arc<Notify>,
}

impl Lane {
    fn new(spec: &'static ConsumedTopicSpec, tools: Tools, notify: Arc<Notify>) -> Arc<Lane> {
        Arc::new(Lane {
            spec,
            tools,
            current: Mutex::new(None),
            subscriber: tokio::sync::Mutex::new(None),
            notify,
        })
    }

    /// Zenoh's callback: queued only while a pair (or run) is current.
    fn accept(&self, sample: Sample) {
        let queued = {
            let current = self.current.lock().unwrap_or_else(|p| p.into_inner());
            match current.as_ref() {
                Some(c) => {
                    c.intake.accept(sample);
                    true
                }
                None => false,
            }
        };
        if queued {
            self.notify.notify_one();
        }
    }

    /// Starts a new pair (or run): an empty inbox that admits `instance`
    /// only, then a subscription on `selector` unless one is held already.
    async fn attach(
        self: &Arc<Self>,
        session: &zenoh::Session,
        selector: String,
        label: Label,
        instance: &str,
    ) -> Result<()> {
        self.reset(label, instance);
        let mut held = self.subscriber.lock().await;
        if held.as_ref().is_some_and(|(s, _)| *s == selector) {
            return Ok(());
        }
        // Weak: the subscription must not keep its own lane alive.
        let lane = Arc::downgrade(self);
        let subscriber = session
            .declare_subscriber(selector.clone())
            .callback(move |s| {
                if let Some(lane) = lane.upgrade() {
                    lane.accept(s);
                }
            })
            .await?;
        *held = Some((selector, subscriber));
        Ok(())
    }

    /// A fresh inbox: whatever the previous one held is dropped with it.
    fn reset(&self, label: Label, instance: &str) {
        let (intake, inbox) = Intake::new(
            self.spec,
            RouteFilter::Pin(instance.to_string()),
            None,
            self.tools.declarer.clone(),
            self.tools.mismatch.clone(),
        );
        *self.current.lock().unwrap_or_else(|p| p.into_inner()) = Some(Current {
            intake,
            inbox,
            label,
        });
    }

    /// No pair: nothing is queued, and what was is dropped.
    fn clear(&self) {
        *self.current.lock().unwrap_or_else(|p| p.into_inner()) = None;
    }

    /// The next queued message, without waiting.
    fn take(&self) -> Option<(Label, Delivery)> {
        let current = self.current.lock().unwrap_or_else(|p| p.into_inner());
        let c = current.as_ref()?;
        topics::take_ready(&c.inbox, self.spec).map(|d| (c.label.clone(), d))
    }
}

/// The lanes one subscription reads, in turn.
struct FanIn {
    lanes: Vec<Arc<Lane>>,
    notify: Arc<Notify>,
    turn: usize,
}

impl FanIn {
    /// The next message of any lane; `None` once the node stops.
    async fn next(&mut self, stop: &CancellationToken) -> Option<(Label, Delivery)> {
        loop {
            if stop.is_cancelled() {
                return None;
            }
            let n = self.lanes.len();
            for k in 0..n {
                let i = (self.turn + k) % n;
                if let Some(got) = self.lanes[i].take() {
                    self.turn = i + 1;
                    return Some(got);
                }
            }
            // A message queued since the scan left a permit: no wake-up
            // is lost.
            tokio::select! {
                () = self.notify.notified() => {}
                () = stop.cancelled() => return None,
            }
        }
    }
}

/// The current pair of a participant slot; `generation` counts pairs.
#[derive(Debug, Clone, Default)]
struct Pair {
    generation: u64,
    peer: Option<PeerInfo>,
}

/// A claim as read from its token.
#[derive(Debug, Clone)]
struct SeenClaim {
    role: String,
    core: String,
    instance: String,
    link_id: String,
    peer: Option<(String, String)>,
}

impl SeenClaim {
    fn read(key: &str, slot: &PairingSlot) -> Option<SeenClaim> {
        let c = Claim::parse(key)?;
        (c.pairing == slot.pairing.name && c.tag == slot.pairing.tag).then(|| SeenClaim {
            role: c.role.to_string(),
            core: c.core.to_string(),
            instance: c.instance.to_string(),
            link_id: c.link_id.to_string(),
            peer: c.peer.map(|(i, l)| (i.to_string(), l.to_string())),
        })
    }

    fn claims(&self, instance: &str, link_id: &str) -> bool {
        self.peer
            .as_ref()
            .is_some_and(|(i, l)| i == instance && l == link_id)
    }

    fn is(&self, instance: &str, link_id: &str) -> bool {
        self.instance == instance && self.link_id == link_id
    }
}

/// One participant slot of this instance.
pub(crate) struct Participant {
    slot: PairingSlot,
    ns: String,
    core: String,
    instance: String,
    session: zenoh::Session,
    tools: Tools,
    state: watch::Sender<Pair>,
    /// The slot it claims (for `node info`).
    claiming: Mutex<Option<PairEnd>>,
    lanes: Mutex<Vec<Weak<Lane>>>,
    /// Held while lanes are attached: a new pair and a new subscription
    /// never interleave.
    transitions: tokio::sync::Mutex<()>,
}

impl Participant {
    /// Whether a claim's role is this slot's counterpart. Before resolution
    /// filled it in, any other role is.
    fn counterpart(&self, role: &str) -> bool {
        if self.slot.counterpart.is_empty() {
            role != self.slot.role
        } else {
            role == self.slot.counterpart
        }
    }

    fn claim_key(&self, target: Option<&PairEnd>) -> String {
        let peer = target.and_then(|t| Some((t.instance.as_str(), t.link_id.as_deref()?)));
        Claim {
            pairing: &self.slot.pairing.name,
            tag: &self.slot.pairing.tag,
            role: &self.slot.role,
            core: &self.core,
            instance: &self.instance,
            link_id: &self.slot.link_id,
            peer,
        }
        .key(&self.ns)
    }

    fn peer_selector(&self, spec: &ConsumedTopicSpec, peer: &PeerInfo) -> String {
        pairing_topic_selector(
            &self.ns,
            &self.slot.pairing.name,
            &self.slot.pairing.tag,
            spec.name,
            None,
            Some(&peer.producer.instance_id),
            Some(&peer.peer_link_id),
        )
    }

    /// The peer, while paired.
    pub(crate) fn peer(&self) -> Option<PeerInfo> {
        self.state.borrow().peer.clone()
    }

    /// Waits until paired; `None` once `stop` fires.
    async fn wait_paired(&self, stop: &CancellationToken) -> Option<PeerInfo> {
        let mut rx = self.state.subscribe();
        tokio::select! {
            r = rx.wait_for(|p| p.peer.is_some()) => r.ok().and_then(|p| p.peer.clone()),
            () = stop.cancelled() => None,
        }
    }

    /// Declares the slot's first claim and starts the task that follows
    /// the pairing's claims.
    async fn start(self: &Arc<Self>, plan: Option<PairEnd>, stop: CancellationToken) -> Result<()> {
        let key = self.claim_key(plan.as_ref());
        let token = self.session.liveliness().declare_token(key.clone()).await?;
        *self.claiming.lock().unwrap_or_else(|p| p.into_inner()) = plan.clone();
        let claims = self
            .session
            .liveliness()
            .declare_subscriber(claim_selector(
                &self.ns,
                &self.slot.pairing.name,
                &self.slot.pairing.tag,
            ))
            .history(true)
            .await?;
        let me = self.clone();
        tokio::spawn(async move {
            let mut follow = Follow {
                target: plan,
                claim_key: key,
                token,
                claims: HashMap::new(),
                warned: HashSet::new(),
            };
            me.follow(&mut follow, claims, stop).await;
        });
        Ok(())
    }

    async fn follow(
        &self,
        f: &mut Follow,
        claims: Subscriber<FifoChannelHandler<Sample>>,
        stop: CancellationToken,
    ) {
        loop {
            let sample = tokio::select! {
                s = claims.recv_async() => match s {
                    Ok(s) => s,
                    Err(_) => return,
                },
                () = stop.cancelled() => return,
            };
            // What is already queued is read before deciding: the history
            // of a new subscription is one picture, not a sequence.
            let mut peer_went = self.absorb(f, &sample);
            while let Ok(Some(s)) = claims.try_recv() {
                peer_went |= self.absorb(f, &s);
            }
            if let Err(e) = self.step(f, peer_went).await {
                warn!(slot = %self.slot.link_id, error = %e, "pairing: could not follow a change of claims");
            }
        }
    }

    /// Records one claim's arrival or departure; whether it was the
    /// current peer's claim that went.
    fn absorb(&self, f: &mut Follow, sample: &Sample) -> bool {
        let key = sample.key_expr().as_str();
        match sample.kind() {
            SampleKind::Put => {
                if let Some(c) = SeenClaim::read(key, &self.slot) {
                    f.claims.insert(key.to_string(), c);
                }
                false
            }
            SampleKind::Delete => {
                let gone = f.claims.remove(key);
                let peer = self.peer();
                gone.zip(peer).is_some_and(|(c, p)| {
                    c.is(&p.producer.instance_id, &p.peer_link_id)
                        && c.claims(&self.instance, &self.slot.link_id)
                })
            }
        }
    }

    /// Decides the slot's claim and pair from the claims seen.
    async fn step(&self, f: &mut Follow, peer_went: bool) -> Result<()> {
        let (me, my_link) = (self.instance.as_str(), self.slot.link_id.as_str());
        let theirs = |c: &&SeenClaim| self.counterpart(&c.role) && !c.is(me, my_link);
        // A plan naming only the instance: its one slot of the
        // counterpart role, or the one already claiming this slot.
        if let Some(t) = f.target.as_mut()
            && t.link_id.is_none()
        {
            let of_peer: Vec<&SeenClaim> = f
                .claims
                .values()
                .filter(theirs)
                .filter(|c| c.instance == t.instance)
                .collect();
            let links: HashSet<&str> = of_peer.iter().map(|c| c.link_id.as_str()).collect();
            let chosen = of_peer
                .iter()
                .find(|c| c.claims(me, my_link))
                .map(|c| c.link_id.clone())
                .or_else(|| (links.len() == 1).then(|| of_peer[0].link_id.clone()));
            if let Some(link) = chosen {
                debug!(slot = my_link, peer = %t.instance, peer_slot = %link, "pairing: found the peer's slot");
                t.link_id = Some(link);
            }
        }
        let peer_of = |t: &PairEnd| {
            let link = t.link_id.as_deref()?;
            f.claims
                .values()
                .filter(theirs)
                .find(|c| c.is(&t.instance, link) && c.claims(me, my_link))
                .map(|c| PeerInfo {
                    producer: ProducerRef::new(&c.core, &c.instance),
                    peer_link_id: c.link_id.clone(),
                })
        };
        let mut peer = f.target.as_ref().and_then(peer_of);
        if peer.is_none() {
            // Unpaired: a slot claiming this one becomes its peer.
            let target = f.target.clone();
            let mut claimers: Vec<&SeenClaim> = f
                .claims
                .values()
                .filter(theirs)
                .filter(|c| c.claims(me, my_link))
                .filter(|c| {
                    target
                        .as_ref()
                        .is_none_or(|t| !c.is(&t.instance, t.link_id.as_deref().unwrap_or("")))
                })
                .collect();
            claimers.sort_by(|a, b| (&a.instance, &a.link_id).cmp(&(&b.instance, &b.link_id)));
            if let Some(c) = claimers.first() {
                info!(slot = my_link, peer = %c.instance, peer_slot = %c.link_id, "pairing: taking a new peer that claims this slot");
                f.target = Some(PairEnd {
                    instance: c.instance.clone(),
                    link_id: Some(c.link_id.clone()),
                });
                peer = Some(PeerInfo {
                    producer: ProducerRef::new(&c.core, &c.instance),
                    peer_link_id: c.link_id.clone(),
                });
            }
        } else if let Some(p) = &peer {
            for c in f.claims.values().filter(theirs) {
                if c.claims(me, my_link)
                    && !c.is(&p.producer.instance_id, &p.peer_link_id)
                    && f.warned.insert(format!("{}/{}", c.instance, c.link_id))
                {
                    warn!(slot = my_link, claimer = %format_args!("{}/{}", c.instance, c.link_id), peer = %p.producer.instance_id, "pairing: ignoring a claim on a paired slot");
                }
            }
        }
        let key = self.claim_key(f.target.as_ref());
        if key != f.claim_key {
            let token = self.session.liveliness().declare_token(key.clone()).await?;
            // The old claim goes once the new one is out.
            let old = std::mem::replace(&mut f.token, token);
            let _ = old.undeclare().await;
            f.claim_key = key;
            *self.claiming.lock().unwrap_or_else(|p| p.into_inner()) = f.target.clone();
        }
        let current = self.peer();
        if current != peer || (peer_went && peer.is_some()) {
            self.apply(peer).await;
        }
        Ok(())
    }

    /// Moves to a new pair (or none): every lane starts an empty inbox on
    /// the new peer's keys, or is cleared.
    async fn apply(&self, peer: Option<PeerInfo>) {
        let _held = self.transitions.lock().await;
        let generation = self.state.borrow().generation + u64::from(peer.is_some());
        for lane in self.live_lanes() {
            match &peer {
                Some(p) => {
                    let selector = self.peer_selector(lane.spec, p);
                    let label = Label::Peer(p.clone());
                    if let Err(e) = lane
                        .attach(&self.session, selector, label, &p.producer.instance_id)
                        .await
                    {
                        warn!(slot = %self.slot.link_id, topic = lane.spec.name, error = %e, "pairing: could not subscribe to the peer");
                    }
                }
                None => lane.clear(),
            }
        }
        match &peer {
            Some(p) => {
                info!(slot = %self.slot.link_id, peer = %p.producer.instance_id, peer_slot = %p.peer_link_id, "paired")
            }
            None => info!(slot = %self.slot.link_id, "unpaired"),
        }
        self.state.send_replace(Pair { generation, peer });
    }

    fn live_lanes(&self) -> Vec<Arc<Lane>> {
        let mut lanes = self.lanes.lock().unwrap_or_else(|p| p.into_inner());
        lanes.retain(|l| l.strong_count() > 0);
        lanes.iter().filter_map(Weak::upgrade).collect()
    }

    /// A new lane of `spec`, attached to the current peer if any.
    async fn lane(&self, spec: &'static ConsumedTopicSpec) -> Result<(Arc<Lane>, Arc<Notify>)> {
        let notify = Arc::new(Notify::new());
        let lane = Lane::new(spec, self.tools.clone(), notify.clone());
        let _held = self.transitions.lock().await;
        self.lanes
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Arc::downgrade(&lane));
        if let Some(p) = self.peer() {
            let selector = self.peer_selector(spec, &p);
            let instance = p.producer.instance_id.clone();
            lane.attach(&self.session, selector, Label::Peer(p), &instance)
                .await?;
        }
        Ok((lane, notify))
    }

    fn info(&self) -> PairingSlotInfo {
        PairingSlotInfo {
            link_id: self.slot.link_id.clone(),
            pairing: self.slot.pairing.clone(),
            role: self.slot.role.clone(),
            observer: false,
            claiming: self
                .claiming
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .as_ref()
                .map(ToString::to_string),
            peer: self.peer().map(|p| PeerEndInfo {
                core_node: p.producer.core_node,
                instance_id: p.producer.instance_id,
                link_id: p.peer_link_id,
            }),
            sources: Vec::new(),
        }
    }
}

/// What a participant's task keeps between claims.
struct Follow {
    /// The slot claimed (or waited for, its slot not yet known).
    target: Option<PairEnd>,
    claim_key: String,
    token: LivelinessToken,
    claims: HashMap<String, SeenClaim>,
    /// Claimers ignored while paired, each logged once.
    warned: HashSet<String>,
}

/// One source of an observer slot.
struct Source {
    instance: String,
    /// From the plan, or learned from the source's claim.
    link_id: Mutex<Option<String>>,
    planned_link: Option<String>,
    /// From the source's presence token.
    core: Mutex<Option<String>>,
    live: AtomicBool,
    lanes: Mutex<Vec<Weak<Lane>>>,
}

/// One observer slot of this instance.
pub(crate) struct Observer {
    slot: PairingSlot,
    ns: String,
    own_core: String,
    session: zenoh::Session,
    tools: Tools,
    sources: Vec<Source>,
    transitions: tokio::sync::Mutex<()>,
}

impl Observer {
    fn source_info(&self, s: &Source) -> ObservedSource {
        let core = s.core.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let link = s.link_id.lock().unwrap_or_else(|p| p.into_inner()).clone();
        ObservedSource {
            producer: ProducerRef::new(core.unwrap_or_else(|| self.own_core.clone()), &s.instance),
            source_link_id: link.unwrap_or_default(),
        }
    }

    fn selector(&self, spec: &ConsumedTopicSpec, s: &Source) -> String {
        pairing_topic_selector(
            &self.ns,
            &self.slot.pairing.name,
            &self.slot.pairing.tag,
            spec.name,
            None,
            Some(&s.instance),
            s.planned_link.as_deref(),
        )
    }

    /// The sources, in link order.
    pub(crate) fn sources(&self) -> Vec<ObservedSource> {
        self.sources.iter().map(|s| self.source_info(s)).collect()
    }

    async fn start(self: &Arc<Self>, stop: CancellationToken) -> Result<()> {
        if self.sources.is_empty() {
            return Ok(());
        }
        let live = self
            .session
            .liveliness()
            .declare_subscriber(all_liveliness_selector(&self.ns))
            .history(true)
            .await?;
        let claims = self
            .session
            .liveliness()
            .declare_subscriber(claim_selector(
                &self.ns,
                &self.slot.pairing.name,
                &self.slot.pairing.tag,
            ))
            .history(true)
            .await?;
        let me = self.clone();
        tokio::spawn(async move {
            loop {
                tokio::select! {
                    s = live.recv_async() => match s {
                        Ok(s) => me.presence(&s).await,
                        Err(_) => return,
                    },
                    s = claims.recv_async() => match s {
                        Ok(s) => me.claim(&s),
                        Err(_) => return,
                    },
                    () = stop.cancelled() => return,
                }
            }
        });
        Ok(())
    }

    /// A source's presence token came or went: a new run starts with
    /// empty inboxes.
    async fn presence(&self, sample: &Sample) {
        let Some((core, instance)) = parse_liveliness_key(sample.key_expr().as_str()) else {
            return;
        };
        let Some(source) = self.sources.iter().find(|s| s.instance == instance) else {
            return;
        };
        match sample.kind() {
            SampleKind::Delete => source.live.store(false, Ordering::Relaxed),
            SampleKind::Put => {
                *source.core.lock().unwrap_or_else(|p| p.into_inner()) = Some(core);
                if source.live.swap(true, Ordering::Relaxed) {
                    return;
                }
                let _held = self.transitions.lock().await;
                let label = Label::Source(self.source_info(source));
                let lanes: Vec<Arc<Lane>> = {
                    let mut lanes = source.lanes.lock().unwrap_or_else(|p| p.into_inner());
                    lanes.retain(|l| l.strong_count() > 0);
                    lanes.iter().filter_map(Weak::upgrade).collect()
                };
                for lane in lanes {
                    lane.reset(label.clone(), &source.instance);
                }
                debug!(slot = %self.slot.link_id, source = %source.instance, "observing a new run of a source");
            }
        }
    }

    /// A claim of the watched role tells a source's slot when the plan
    /// did not.
    fn claim(&self, sample: &Sample) {
        if sample.kind() != SampleKind::Put {
            return;
        }
        let Some(c) = SeenClaim::read(sample.key_expr().as_str(), &self.slot) else {
            return;
        };
        if c.role != self.slot.role {
            return;
        }
        for s in self.sources.iter().filter(|s| s.instance == c.instance) {
            if s.planned_link.is_none() {
                *s.link_id.lock().unwrap_or_else(|p| p.into_inner()) = Some(c.link_id.clone());
            }
            let mut core = s.core.lock().unwrap_or_else(|p| p.into_inner());
            core.get_or_insert_with(|| c.core.clone());
        }
    }

    /// One lane per source, sharing one wake-up.
    async fn fan_in(&self, spec: &'static ConsumedTopicSpec) -> Result<FanIn> {
        let notify = Arc::new(Notify::new());
        let mut lanes = Vec::new();
        let _held = self.transitions.lock().await;
        for s in &self.sources {
            let lane = Lane::new(spec, self.tools.clone(), notify.clone());
            s.lanes
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(Arc::downgrade(&lane));
            let label = Label::Source(self.source_info(s));
            lane.attach(&self.session, self.selector(spec, s), label, &s.instance)
                .await?;
            lanes.push(lane);
        }
        Ok(FanIn {
            lanes,
            notify,
            turn: 0,
        })
    }

    fn info(&self) -> PairingSlotInfo {
        PairingSlotInfo {
            link_id: self.slot.link_id.clone(),
            pairing: self.slot.pairing.clone(),
            role: self.slot.role.clone(),
            observer: true,
            claiming: None,
            peer: None,
            sources: self
                .sources
                .iter()
                .map(|s| {
                    let o = self.source_info(s);
                    SourceInfo {
                        core_node: o.producer.core_node,
                        instance_id: o.producer.instance_id,
                        link_id: (!o.source_link_id.is_empty()).then_some(o.source_link_id),
                        live: s.live.load(Ordering::Relaxed),
                    }
                })
                .collect(),
        }
    }
}

/// The pairing slots of one instance.
#[derive(Default, Clone)]
pub(crate) struct Pairings {
    participants: HashMap<String, Arc<Participant>>,
    observers: HashMap<String, Arc<Observer>>,
    /// In the model's order, for the description.
    order: Vec<String>,
}

/// Who the node is, for its claims and keys.
pub(crate) struct Own<'a> {
    pub(crate) session: &'a zenoh::Session,
    pub(crate) ns: &'a str,
    pub(crate) core: &'a str,
    pub(crate) instance: &'a str,
}

impl Pairings {
    /// Declares every participant slot's claim (so claims exist as soon as
    /// the node is up) and starts following claims and sources.
    pub(crate) async fn start(
        own: Own<'_>,
        slots: &[PairingSlot],
        plans: &[PairPlan],
        tools: Tools,
        stop: &CancellationToken,
    ) -> Result<Pairings> {
        let mut pairings = Pairings::default();
        for slot in slots {
            let plan = plans.iter().find(|p| p.link_id == slot.link_id);
            let peers = plan.map_or(&[][..], |p| p.peers.as_slice());
            pairings.order.push(slot.link_id.clone());
            if slot.observer {
                let observer = Arc::new(Observer {
                    slot: slot.clone(),
                    ns: own.ns.to_string(),
                    own_core: own.core.to_string(),
                    session: own.session.clone(),
                    tools: tools.clone(),
                    sources: peers
                        .iter()
                        .map(|p| Source {
                            instance: p.instance.clone(),
                            link_id: Mutex::new(p.link_id.clone()),
                            planned_link: p.link_id.clone(),
                            core: Mutex::new(None),
                            live: AtomicBool::new(false),
                            lanes: Mutex::new(Vec::new()),
                        })
                        .collect(),
                    transitions: tokio::sync::Mutex::new(()),
                });
                observer.start(stop.clone()).await?;
                pairings.observers.insert(slot.link_id.clone(), observer);
            } else {
                let participant = Arc::new(Participant {
                    slot: slot.clone(),
                    ns: own.ns.to_string(),
                    core: own.core.to_string(),
                    instance: own.instance.to_string(),
                    session: own.session.clone(),
                    tools: tools.clone(),
                    state: watch::Sender::new(Pair::default()),
                    claiming: Mutex::new(None),
                    lanes: Mutex::new(Vec::new()),
                    transitions: tokio::sync::Mutex::new(()),
                });
                participant
                    .start(peers.first().cloned(), stop.clone())
                    .await?;
                pairings
                    .participants
                    .insert(slot.link_id.clone(), participant);
            }
        }
        Ok(pairings)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    pub(crate) fn participant(&self, link_id: &str) -> Result<&Arc<Participant>> {
        self.participants
            .get(link_id)
            .ok_or_else(|| Error::Undeclared(format!("pairing slot `{link_id}`")))
    }

    pub(crate) fn observer(&self, link_id: &str) -> Result<&Arc<Observer>> {
        self.observers
            .get(link_id)
            .ok_or_else(|| Error::Undeclared(format!("observer slot `{link_id}`")))
    }

    /// Every slot and its live state, in the model's order.
    pub(crate) fn info(&self) -> Vec<PairingSlotInfo> {
        self.order
            .iter()
            .filter_map(|l| {
                self.participants
                    .get(l)
                    .map(|p| p.info())
                    .or_else(|| self.observers.get(l).map(|o| o.info()))
            })
            .collect()
    }
}

/// The peer of participant slot `link_id`, while paired (generated code
/// offers it as `paired_topics::<link_id>::<topic>::paired`).
pub fn paired(runner: &NodeRunner, link_id: &str) -> Result<Option<PeerInfo>> {
    Ok(runner.pairings().participant(link_id)?.peer())
}

/// Waits until participant slot `link_id` is paired. Once the node stops
/// it returns [`Error::ShuttingDown`].
pub async fn wait_paired(runner: &NodeRunner, link_id: &str) -> Result<PeerInfo> {
    let participant = runner.pairings().participant(link_id)?;
    if runner.cancellation_token().is_cancelled() {
        return Err(stop::refused().await);
    }
    participant
        .wait_paired(runner.cancellation_token())
        .await
        .ok_or(Error::ShuttingDown)
}

/// The sources of observer slot `link_id`, in link order.
pub fn observed_sources(runner: &NodeRunner, link_id: &str) -> Result<Vec<ObservedSource>> {
    Ok(runner.pairings().observer(link_id)?.sources())
}

/// The first source of observer slot `link_id` (its one source, for a
/// slot of cardinality `one`); `None` when it watches none.
pub fn observed_source(runner: &NodeRunner, link_id: &str) -> Result<Option<ObservedSource>> {
    Ok(observed_sources(runner, link_id)?.into_iter().next())
}

/// A declared publisher of a pairing topic this node's role emits: it
/// sends to the current peer (and the pair's observers), and sends nothing
/// while the slot is unpaired.
#[derive(Clone)]
pub struct PairedPublisher {
    runner: Arc<NodeRunner>,
    spec: &'static PairedTopicSpec,
    participant: Arc<Participant>,
    publisher: Arc<Publisher<'static>>,
    readers_known: Arc<AtomicBool>,
    attachment: ZBytes,
}

impl std::fmt::Debug for PairedPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PairedPublisher")
            .field("slot", &self.spec.link_id)
            .field("topic", &self.spec.topic.name)
            .finish_non_exhaustive()
    }
}

impl PairedPublisher {
    /// Publishes `message` (built for this publisher's topic, or
    /// `Error::WrongTopic`) to the peer; a successful no-op while the slot
    /// is unpaired. Works while the node is stopping; once its session is
    /// closed it returns `Error::ShuttingDown`.
    pub async fn publish(&self, message: OutgoingMessage) -> Result<()> {
        if !std::ptr::eq(message.topic, &self.spec.topic) {
            return Err(Error::WrongTopic {
                publisher: self.spec.topic.name.to_string(),
                message: message.topic.name.to_string(),
            });
        }
        if self.participant.peer().is_none() {
            return Ok(());
        }
        let payload = self.runner.shm().payload(
            &self.spec.topic,
            &*message.body,
            self.readers_known.load(Ordering::Relaxed),
        );
        match self
            .publisher
            .put(payload)
            .attachment(self.attachment.clone())
            .wait()
        {
            Ok(()) => Ok(()),
            Err(_) if self.runner.session().is_closed() => Err(stop::refused().await),
            Err(e) => Err(Error::from(e)),
        }
    }

    /// The peer, while paired.
    pub fn peer(&self) -> Option<PeerInfo> {
        self.participant.peer()
    }

    /// Whether Zenoh knows a subscriber of this topic (the peer's, or an
    /// observer's).
    pub fn has_readers(&self) -> bool {
        self.readers_known.load(Ordering::Relaxed)
    }

    /// The topic this publisher sends on.
    pub fn topic(&self) -> &'static str {
        self.spec.topic.name
    }
}

/// Declares a publisher of a pairing topic (generated code offers it as
/// `paired_topics::<link_id>::<topic>::declare_publisher`).
pub async fn declare_paired_publisher(
    runner: &NodeRunner,
    spec: &'static PairedTopicSpec,
) -> Result<PairedPublisher> {
    let participant = runner.pairings().participant(spec.link_id)?.clone();
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
    Ok(PairedPublisher {
        runner: runner.arc()?,
        spec,
        participant,
        publisher: Arc::new(publisher),
        readers_known: known,
        attachment: ZBytes::from(attachment::topic(spec.topic.format.fingerprint)),
    })
}

/// A held subscription to one of the peer's pairing topics: only the
/// current peer's messages, none from before the current pair.
pub struct PairedSubscription<M> {
    runner: Arc<NodeRunner>,
    spec: &'static ConsumedPairedTopicSpec,
    fan_in: FanIn,
    _message: PhantomData<fn() -> M>,
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
    runner: Arc<NodeRunner>,
    spec: &'static ConsumedPairedTopicSpec,
    fan_in: FanIn,
    _message: PhantomData<fn() -> M>,
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
