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
use crate::publisher::TopicPublisher;
use crate::qos;
use crate::spec::{ConsumedPairedTopicSpec, ConsumedTopicSpec, PairedTopicSpec};
use crate::stop;
use crate::topics::{self, Delivery, Inbox, Intake};
use crate::wire::attachment;
use crate::wire::codec::Encode;
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
    /// The node's reader of direct links, when the launch gives it some.
    pub(crate) direct: Option<Arc<crate::direct::inlet::Consumer>>,
}

mod endpoints;
mod lane;
mod observer;
mod participant;

pub(crate) use endpoints::PairedSender;
pub use endpoints::{
    ObservedSubscription, PairedSubscription, declare_paired_publisher, subscribe_observed,
    subscribe_paired,
};
use lane::*;
use observer::*;
use participant::*;

/// Follows every claim on `slot`'s pairing, those already held first: a
/// participant's pair and an observer's sources' slots both come from them.
async fn follow_claims(
    session: &zenoh::Session,
    ns: &str,
    slot: &PairingSlot,
) -> Result<Subscriber<FifoChannelHandler<Sample>>> {
    Ok(session
        .liveliness()
        .declare_subscriber(claim_selector(ns, &slot.pairing.name, &slot.pairing.tag))
        .history(true)
        .await?)
}

/// The pairing slots of one instance.
#[derive(Default, Clone)]
pub(crate) struct Pairings {
    pub(super) participants: HashMap<String, Arc<Participant>>,
    pub(super) observers: HashMap<String, Arc<Observer>>,
    /// In the model's order, for the description.
    pub(super) order: Vec<String>,
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
                    senders: tokio::sync::Mutex::new(HashMap::new()),
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

/// The sources of observer slot `link_id` of cardinality `one_or_more`:
/// never empty (a slot whose plan gave it none fails here, naming it).
pub fn non_empty_observed_sources(
    runner: &NodeRunner,
    link_id: &str,
) -> Result<NonEmptyObservedSources> {
    let sources = observed_sources(runner, link_id)?;
    if sources.is_empty() {
        return Err(Error::Undeclared(format!(
            "a source of observer slot `{link_id}`"
        )));
    }
    Ok(NonEmptyObservedSources(sources))
}

/// The sources of an observer slot that always holds at least one
/// (cardinality `one_or_more`), in link order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NonEmptyObservedSources(Vec<ObservedSource>);

impl NonEmptyObservedSources {
    /// The first source, in link order.
    pub fn first(&self) -> &ObservedSource {
        &self.0[0]
    }

    /// Every source, in link order.
    pub fn as_slice(&self) -> &[ObservedSource] {
        &self.0
    }

    /// How many sources the slot watches (at least one).
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// The sources, in link order.
    pub fn iter(&self) -> std::slice::Iter<'_, ObservedSource> {
        self.0.iter()
    }

    /// The sources, as a vector.
    pub fn into_vec(self) -> Vec<ObservedSource> {
        self.0
    }
}

impl std::ops::Deref for NonEmptyObservedSources {
    type Target = [ObservedSource];

    fn deref(&self) -> &[ObservedSource] {
        &self.0
    }
}

impl IntoIterator for NonEmptyObservedSources {
    type Item = ObservedSource;
    type IntoIter = std::vec::IntoIter<ObservedSource>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl<'a> IntoIterator for &'a NonEmptyObservedSources {
    type Item = &'a ObservedSource;
    type IntoIter = std::slice::Iter<'a, ObservedSource>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

/// The first source of observer slot `link_id` (its one source, for a
/// slot of cardinality `one`); `None` when it watches none.
pub fn observed_source(runner: &NodeRunner, link_id: &str) -> Result<Option<ObservedSource>> {
    Ok(observed_sources(runner, link_id)?.into_iter().next())
}
