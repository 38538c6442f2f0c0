//! The consumer's side of direct links: which producers of a consumed
//! topic are read over one, and how a link's messages and Zenoh's are
//! merged back into the producer's order.
//!
//! Per producer (its topic key) the consumer keeps the number of the next
//! message to hand on. Zenoh brings every message; the link brings some
//! of them sooner. Whichever copy of the next message comes first is
//! handed on and the other dropped; a link message ahead of the next one
//! waits until Zenoh has brought those before it (messages the producer
//! sent through Zenoh alone: large ones, the rest of a burst, those from
//! before the link).
//!
//! Only a message the producer also wrote to a link carries its number
//! through Zenoh; the consumer counts the others, which Zenoh delivers in
//! the publisher's order. The count is exact once a numbered message has
//! come through Zenoh from the publisher the lane follows, and until a
//! wait runs out (messages handed on without those before them) or the
//! publisher changes; until then a link's messages wait for the next
//! numbered one, so a count that is not known never hands a message on
//! early, and a message Zenoh alone carried is never taken for a copy.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;

use super::feed::{Feed, Sole};
use super::{
    FRAME_MESSAGE, FRAME_SHARED, FRAME_SIDE, HEADER, HOLD_LIMIT, Hello, INLINE_MAX, SHARED_HEADER,
    SourceId,
};
use crate::topics::{Arrival, Intake};
use crate::wire::keys::{parse_pairing_topic_key, split_entry_key};

/// How long a producer without a socket is left on Zenoh before the next
/// of its messages tries again (a producer restarted with direct links).
const RETRY_AFTER: Duration = Duration::from_secs(5);

/// How long after a link to a producer closed the next of its messages
/// may link it again.
const RELINK_AFTER: Duration = Duration::from_secs(1);

/// The most producers of one consumed topic tried for a link.
const MAX_LINKS: usize = 256;

/// How long a link's message waits for Zenoh's messages before it on a
/// topic that drops: Zenoh may have dropped them.
const DROPPING_HOLD: Duration = Duration::from_millis(50);

/// A node's direct links as a consumer: where producers' sockets are, who
/// it is, and the links it reads.
#[derive(Debug)]
pub(crate) struct Consumer {
    dir: PathBuf,
    /// `<core node>/<instance>`, for the producers' logs.
    name: String,
    /// Whether its links take a segment of shared memory (the node's
    /// shared memory is on).
    shared: bool,
    runtime: tokio::runtime::Handle,
    token: CancellationToken,
    /// One link per producer key, whatever the number of the node's
    /// entries reading that key: the producer writes each message once to
    /// this node, and every entry's lane is handed it.
    links: Mutex<HashMap<Box<str>, Arc<Link>, foldhash::fast::FixedState>>,
}

impl Consumer {
    pub(crate) fn new(
        dir: PathBuf,
        name: String,
        shared: bool,
        runtime: tokio::runtime::Handle,
        token: CancellationToken,
    ) -> Arc<Consumer> {
        Arc::new(Consumer {
            dir,
            name,
            shared,
            runtime,
            token,
            links: Mutex::new(HashMap::default()),
        })
    }

    /// Makes `member`'s lane (its state locked by the caller, as `state`)
    /// read its producer over this node's link to it: the link already
    /// open (or opening) to the same publisher, else a new one.
    fn join(self: &Arc<Self>, member: Member, state: &mut LaneState, path: PathBuf) {
        let key = member.lane.key.clone();
        let Ok(mut links) = self.links.lock() else {
            state.link = LinkState::Closed;
            return;
        };
        if let Some(link) = links.get(key.as_str())
            && let Ok(mut shared) = link.shared.lock()
        {
            // A link answered by the publisher the lane has moved on from
            // is a restarted producer's predecessor, about to end; any
            // other (the lane's own publisher, or the one that replaced
            // it) is the one to read.
            let current = match &shared.answer {
                Some((source, _)) => state.previous != Some(*source),
                None => true,
            };
            if !shared.ended && current {
                if let Some((source, attachment)) = &shared.answer {
                    let intake = member.intake.upgrade();
                    let was_switched = state.switched;
                    state.answered(*source, attachment.clone(), intake.as_deref());
                    if link.sole && member.sole {
                        state.side = Some(super::side_key(key.as_str(), &self.name));
                    }
                    if let Some(intake) = &intake {
                        settle_sole(intake, &member.lane, state, was_switched);
                    }
                }
                shared.members.push(member);
                return;
            }
        }
        let sole = member.sole;
        let link = Arc::new(Link {
            key: key.clone(),
            sole,
            shared: Mutex::new(Shared {
                members: vec![member],
                answer: None,
                ended: false,
            }),
        });
        links.insert(key.as_str().into(), link.clone());
        drop(links);
        let hello = Hello {
            key: key.as_str().to_string(),
            consumer: self.name.clone(),
            shared: self.shared,
            sole,
        };
        let consumer = self.clone();
        self.runtime.spawn(async move {
            let outcome = read_link(&consumer, &link, path, hello).await;
            if let Ok(mut links) = consumer.links.lock()
                && links
                    .get(key.as_str())
                    .is_some_and(|l| Arc::ptr_eq(l, &link))
            {
                links.remove(key.as_str());
            }
            let members = match link.shared.lock() {
                Ok(mut shared) => {
                    shared.ended = true;
                    std::mem::take(&mut shared.members)
                }
                Err(_) => Vec::new(),
            };
            for member in members {
                let (consumer, outcome) = (consumer.clone(), outcome.clone());
                tokio::spawn(async move { member.ended(&consumer, outcome).await });
            }
        });
    }
}

/// A consumer node's link to one producer's topic.
#[derive(Debug)]
struct Link {
    key: KeyExpr<'static>,
    /// Whether it was asked as a sole link: the producer publishes what it
    /// does not carry under this node's side key too.
    sole: bool,
    shared: Mutex<Shared>,
}

/// What a link's reader and the lanes joining it share.
#[derive(Debug)]
struct Shared {
    /// The lanes it hands its messages to.
    members: Vec<Member>,
    /// The producer's answer (its publisher and the topic's attachment),
    /// once it came: a lane joining later takes it at once.
    answer: Option<(SourceId, ZBytes)>,
    /// It ended: a lane must open another.
    ended: bool,
}

/// A lane reading a link, as of one of its connections.
#[derive(Debug, Clone)]
struct Member {
    lane: Arc<Lane>,
    intake: Weak<Intake>,
    /// The lane's connection this is: a lane that moved on (to a
    /// restarted producer) is dropped from the link.
    generation: u64,
    /// Whether its entry can read the producer through the link and a
    /// side key alone (it is pinned to the producer).
    sole: bool,
}

impl Member {
    /// The link ended as `outcome`: the lane goes back to Zenoh alone, and
    /// what the link brought ahead of Zenoh is handed on once Zenoh
    /// catches up, or when the wait runs out.
    async fn ended(&self, consumer: &Consumer, outcome: Outcome) {
        let Some(switched) = self.lane.ended(self.generation, outcome) else {
            return; // Replaced by a link to a restarted producer.
        };
        if switched && let Some(feed) = self.intake.upgrade().and_then(|i| i.direct()?.feed()) {
            // Back to the topic's own key, before the side key is left.
            feed.switch(None);
        }
        while let Some(intake) = self.intake.upgrade() {
            let deadline = match self.lane.state.lock() {
                Ok(state) => state.deadline(intake.drops()),
                Err(_) => None,
            };
            let Some(deadline) = deadline else { break };
            tokio::select! {
                () = tokio::time::sleep_until(deadline.into()) => {}
                () = consumer.token.cancelled() => break,
            }
            if let Ok(mut state) = self.lane.state.lock() {
                state.expire(Instant::now(), &self.lane.key, &intake);
            }
        }
    }
}

/// One consumed topic's producers on direct links, by key.
#[derive(Debug)]
pub(crate) struct Inlet {
    consumer: Arc<Consumer>,
    lanes: Mutex<Lanes>,
    intake: OnceLock<Weak<Intake>>,
    /// The entry's subscription, when it is pinned to one producer: a sole
    /// link moves it to the producer's side key.
    feed: OnceLock<Weak<Feed>>,
}

/// A consumed topic's lanes by producer key.
#[derive(Debug, Default)]
struct Lanes {
    by_key: HashMap<Box<str>, Arc<Lane>, foldhash::fast::FixedState>,
    /// The lane found last: a topic read from one producer (or a flood
    /// from one of several) finds it by comparing the key, without
    /// hashing it for every message.
    last: Option<Arc<Lane>>,
}

impl Lanes {
    /// Makes the lane of `key` the last found; whether there is one.
    fn find(&mut self, key: &str) -> bool {
        if self.last.as_ref().is_some_and(|l| l.key.as_str() == key) {
            return true;
        }
        let Some(lane) = self.by_key.get(key) else {
            return false;
        };
        self.last = Some(lane.clone());
        true
    }

    fn insert(&mut self, lane: Arc<Lane>) {
        self.by_key.insert(lane.key.as_str().into(), lane.clone());
        self.last = Some(lane);
    }
}

/// What a message that came through Zenoh is to its reader.
pub(crate) enum Route {
    /// Queue it.
    Take(Arrival),
    /// Handed on, held or dropped here: nothing to queue.
    Handled,
}

impl Inlet {
    pub(crate) fn new(consumer: Arc<Consumer>) -> Inlet {
        Inlet {
            consumer,
            lanes: Mutex::new(Lanes::default()),
            intake: OnceLock::new(),
            feed: OnceLock::new(),
        }
    }

    /// The entry's subscription, which sole links move: the entry is
    /// pinned to one producer.
    pub(crate) fn bind_feed(&self, feed: &Arc<Feed>) {
        let _ = self.feed.set(Arc::downgrade(feed));
    }

    /// The entry's subscription, if it is pinned and still read.
    fn feed(&self) -> Option<Arc<Feed>> {
        self.feed.get()?.upgrade()
    }

    /// The intake the links queue into, once it is shared.
    pub(crate) fn bind(&self, intake: &Arc<Intake>) {
        let _ = self.intake.set(Arc::downgrade(intake));
    }

    /// Routes a message that came through Zenoh, with the publisher and
    /// number its source info carries (a producer numbers the messages it
    /// also wrote to a link; the others are counted).
    ///
    /// Every message of the topic comes through here (a flood's too), so
    /// it takes its two locks and no reference count: the lane is used
    /// under the lanes' lock (the only order the two are taken in) rather
    /// than cloned out of it, and `intake` is the caller's.
    pub(crate) fn route(
        &self,
        intake: &Intake,
        arrival: Arrival,
        source: Option<(SourceId, u32)>,
    ) -> Route {
        // A lane's state poisoned under this lock falls back to Zenoh
        // (below) on its own; the others' lanes go on being read.
        let mut lanes = self.lanes.lock().unwrap_or_else(|p| p.into_inner());
        if !lanes.find(arrival.key.as_str()) {
            // A producer the slot does not route here (yet: a node slot's
            // members can grow) is not linked: its messages are dropped
            // by the reader's admission, and a link would have the
            // producer write each one for nothing.
            if lanes.by_key.len() >= MAX_LINKS || !intake.routes(arrival.key.as_str()) {
                return Route::Take(arrival);
            }
            let lane = Lane::new(arrival.key.clone(), source);
            lanes.insert(lane.clone());
            // Queued under the lane's lock, before the link can bring the
            // next message (which takes that lock): queued after it, on
            // another thread, this message was read after the link's next
            // one.
            let Ok(mut state) = lane.state.lock() else {
                return Route::Take(arrival);
            };
            intake.queue(arrival);
            self.connect_locked(&lane, &mut state);
            return Route::Handled;
        }
        let Some(lane) = lanes.last.as_ref() else {
            return Route::Take(arrival);
        };
        let Ok(mut state) = lane.state.lock() else {
            return Route::Take(arrival);
        };
        match source {
            None => state.zenoh_counted(arrival, intake),
            Some((id, number)) if state.source.is_none() => {
                // The first numbered message of a lane that has only
                // counted (no link answered yet, so nothing is held): the
                // lane follows its publisher from here.
                state.follow(id, number);
                intake.queue(arrival);
            }
            // The last messages of a publisher already replaced.
            Some((id, _)) if state.source != Some(id) && state.previous == Some(id) => {
                return Route::Take(arrival);
            }
            Some((id, number)) if state.source != Some(id) => {
                // Another publisher under this key: the producer restarted.
                // Its numbers start afresh, and it is linked anew.
                state.restart(id, number, intake);
                intake.queue(arrival);
                self.connect_locked(lane, &mut state);
                return Route::Handled;
            }
            Some((_, number)) => {
                state.zenoh_brought(number, arrival, intake);
                if state.side.is_some() {
                    settle_sole(intake, lane, &mut state, false);
                }
                if state.side_from.is_some() {
                    leave_own(intake, &mut state);
                }
            }
        }
        if state.link == LinkState::Closed && state.retry_due() {
            self.connect_locked(lane, &mut state);
        }
        Route::Handled
    }

    /// Routes a copy that came through a sole link's side key, numbered:
    /// like the link's own messages, it is one of the producer's messages
    /// the link did not carry, not the whole stream (which the topic's own
    /// key is), so one ahead of the next waits for those before it rather
    /// than taking them for lost.
    /// `session` is the Zenoh session that published the copy (a side
    /// publisher shares its producer's): a copy from any but the one
    /// whose publisher the lane follows (a restarted producer's, its
    /// predecessor's) is dropped, its numbers are not the lane's.
    pub(crate) fn route_side(
        &self,
        intake: &Intake,
        arrival: Arrival,
        (session, number): ([u8; 16], u32),
    ) -> Route {
        let mut lanes = self.lanes.lock().unwrap_or_else(|p| p.into_inner());
        if !lanes.find(arrival.key.as_str()) {
            return Route::Take(arrival);
        }
        let Some(lane) = lanes.last.as_ref() else {
            return Route::Take(arrival);
        };
        let Ok(mut state) = lane.state.lock() else {
            return Route::Take(arrival);
        };
        if state.source.map(|(zid, _)| zid) != Some(session) {
            return Route::Handled;
        }
        state.link_brought(number, arrival, intake);
        if state.side_from.is_some() {
            leave_own(intake, &mut state);
        }
        Route::Handled
    }

    /// Starts reading `lane`'s producer over a link (its state locked by
    /// the caller).
    fn connect_locked(&self, lane: &Arc<Lane>, state: &mut LaneState) {
        let (Some((core, instance)), Some(intake)) =
            (sender_of(lane.key.as_str()), self.intake.get().cloned())
        else {
            state.link = LinkState::Closed;
            state.retry_at = Some(Instant::now() + Duration::from_secs(3600));
            return;
        };
        state.link = LinkState::Connecting;
        state.retry_at = None;
        state.generation += 1;
        let member = Member {
            lane: lane.clone(),
            intake,
            generation: state.generation,
            sole: self.feed.get().is_some(),
        };
        let path = super::socket_path(&self.consumer.dir, core, instance);
        self.consumer.join(member, state, path);
    }
}

/// Moves `lane`'s entry to its producer's side key once the lane knows
/// where the link's numbers stand (its state locked by the caller): from
/// then on every message of the producer comes numbered, over the link or
/// through the side key. An entry that read through a side key
/// (`was_switched`) and is answered by a link that is not sole goes back
/// to the topic's key.
fn settle_sole(intake: &Intake, lane: &Lane, state: &mut LaneState, was_switched: bool) {
    let Some(feed) = intake.direct().and_then(Inlet::feed) else {
        return;
    };
    if was_switched && state.side.is_none() {
        feed.switch(None);
        return;
    }
    if let (Some(side), Some(source)) = (state.sole_due(), state.source) {
        feed.switch(Some(Sole {
            side,
            key: lane.key.clone(),
            source,
        }));
    }
}

/// Lets `lane`'s entry leave the topic's own key (its state locked by
/// the caller) once it has every message before the one from which the
/// producer publishes to its side key: none is left on the way through
/// the own key alone.
fn leave_own(intake: &Intake, state: &mut LaneState) {
    if state.side_from.is_some_and(|n| state.next >= n)
        && let (Some(feed), Some(side)) = (intake.direct().and_then(Inlet::feed), &state.side)
    {
        state.side_from = None;
        feed.leave_own(side);
    }
}

/// The core node and instance publishing under `key`: a topic's producer,
/// or a pairing topic's sender.
fn sender_of(key: &str) -> Option<(&str, &str)> {
    if let Some(sender) = split_entry_key(key) {
        return Some((sender.core, sender.instance));
    }
    parse_pairing_topic_key(key).map(|sender| (sender.core, sender.instance))
}

/// One producer of a consumed topic, as its consumer merges it.
#[derive(Debug)]
struct Lane {
    key: KeyExpr<'static>,
    state: Mutex<LaneState>,
}

impl Lane {
    /// The lane of a producer Zenoh just brought a message of (numbered or
    /// not).
    fn new(key: KeyExpr<'static>, source: Option<(SourceId, u32)>) -> Arc<Lane> {
        Arc::new(Lane {
            key,
            state: Mutex::new(LaneState::new(source)),
        })
    }

    /// Link `generation` ended as `outcome`: whether the lane read its
    /// producer through the side key (and goes back to the topic's own);
    /// `None` if the lane has moved on to a newer link.
    fn ended(&self, generation: u64, outcome: Outcome) -> Option<bool> {
        let Ok(mut state) = self.state.lock() else {
            return None;
        };
        if state.generation != generation {
            return None;
        }
        match outcome {
            Outcome::Stopped => {}
            Outcome::Unavailable(why) => {
                debug!(topic = %self.key, why, "no direct link to this producer: its messages come through Zenoh");
                state.retry_at = Some(Instant::now() + RETRY_AFTER);
            }
            Outcome::Closed(why) => {
                debug!(topic = %self.key, why, "a direct link closed: this producer's messages come through Zenoh again");
                state.retry_at = Some(Instant::now() + RELINK_AFTER);
            }
        }
        state.link = LinkState::Closed;
        state.side = None;
        state.side_from = None;
        Some(std::mem::take(&mut state.switched))
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LinkState {
    Connecting,
    Open,
    Closed,
}

#[derive(Debug)]
struct LaneState {
    /// The producer's Zenoh publisher whose numbers `next` follows (none
    /// until a numbered message or the link's answer names it).
    source: Option<SourceId>,
    /// The publisher it replaced (a restarted producer's last messages).
    previous: Option<SourceId>,
    /// The number of the next message to hand on, unwrapped: the `u32`
    /// numbers on the wire are read as the nearest value to it.
    next: i64,
    /// Whether `next` is among the publisher's numbers at all: not until a
    /// numbered message of it came through Zenoh (or a wait ran out), so
    /// a number is never read against a guess.
    located: bool,
    /// Link messages that came while the lane was not located, in order.
    unplaced: Vec<(u32, Arrival)>,
    /// Whether `next` is exact: a numbered message of `source` came
    /// through Zenoh, and every message since was counted. Until it is,
    /// a link's messages wait.
    counted: bool,
    /// Whether a link to this publisher was ever answered, or a link
    /// message or side copy of it came: only then can a Zenoh message be
    /// a copy of one already handed on.
    linked: bool,
    link: LinkState,
    /// Which connection is the lane's: an older one's reader stops.
    generation: u64,
    /// When a closed link may be tried again.
    retry_at: Option<Instant>,
    /// The producer's topic attachment, from its answer.
    attachment: Option<ZBytes>,
    /// The producer's side key for this node, once a sole link to it is
    /// answered and the entry can read through it.
    side: Option<String>,
    /// Whether the entry reads the producer through the link and the side
    /// key alone: then every message comes numbered.
    switched: bool,
    /// The message from which the producer publishes to the side key what
    /// the link does not carry, until the lane has every one before it.
    side_from: Option<i64>,
    /// Link messages ahead of `next`, by number.
    held: BTreeMap<i64, Arrival>,
    /// Since when the oldest held message waits.
    held_since: Option<Instant>,
}

impl LaneState {
    /// The state of a producer Zenoh just brought a message of: numbered,
    /// the lane follows its publisher from there; else it has yet to
    /// learn where the numbers are.
    fn new(source: Option<(SourceId, u32)>) -> LaneState {
        LaneState {
            source: source.map(|(id, _)| id),
            previous: None,
            next: source.map_or(0, |(_, number)| i64::from(number) + 1),
            located: source.is_some(),
            unplaced: Vec::new(),
            counted: source.is_some(),
            linked: false,
            link: LinkState::Closed,
            generation: 0,
            retry_at: None,
            attachment: None,
            side: None,
            switched: false,
            side_from: None,
            held: BTreeMap::new(),
            held_since: None,
        }
    }

    /// Whether a closed link may be tried again.
    fn retry_due(&self) -> bool {
        self.retry_at.is_none_or(|t| Instant::now() >= t)
    }

    /// `number` unwrapped: the value nearest to `next`.
    fn unwrap(&self, number: u32) -> i64 {
        let distance = number.wrapping_sub(self.next as u32) as i32;
        self.next + i64::from(distance)
    }

    /// A new publisher under the key, whose message `number` is about to
    /// be queued: what the link brought of the one it replaces goes first.
    fn restart(&mut self, source: SourceId, number: u32, intake: &Intake) {
        self.release(Some(intake));
        self.previous = self.source;
        self.follow(source, number);
        self.linked = false;
    }

    /// Follows `source`'s numbers from its message `number`, just taken.
    fn follow(&mut self, source: SourceId, number: u32) {
        self.source = Some(source);
        self.next = i64::from(number) + 1;
        self.located = true;
        self.counted = true;
    }

    /// Hands on, in order, what the link brought and still waits (the
    /// messages of a publisher the lane stops following: Zenoh may never
    /// bring them); with no reader left, drops it. What was never placed
    /// is dropped (`expire`).
    fn release(&mut self, intake: Option<&Intake>) {
        let held = std::mem::take(&mut self.held).into_values();
        self.unplaced.clear();
        if let Some(intake) = intake {
            for arrival in held {
                intake.queue(arrival);
            }
        }
        self.held_since = None;
    }

    /// The entry moves to the side key now, if it waits for that and the
    /// lane knows where the link's numbers stand: the side key it moves
    /// to.
    fn sole_due(&mut self) -> Option<String> {
        if self.switched || self.link != LinkState::Open || !self.located || !self.counted {
            return None;
        }
        let side = self.side.clone()?;
        self.switched = true;
        Some(side)
    }

    /// The producer answered: its link is open.
    fn answered(&mut self, source: SourceId, attachment: ZBytes, intake: Option<&Intake>) {
        self.attachment = Some(attachment);
        self.link = LinkState::Open;
        self.linked = true;
        self.side = None;
        self.switched = false;
        self.side_from = None;
        if self.source != Some(source) {
            // A publisher the lane has not followed (a restarted producer,
            // or one whose messages were only counted): where its numbers
            // are is learnt from its first numbered message through Zenoh,
            // which lets what the link holds go.
            self.release(intake);
            self.previous = self.source;
            self.source = Some(source);
            self.located = false;
            self.counted = false;
        }
    }

    /// Places the lane among its publisher's numbers at `number`, that of
    /// the first numbered message through Zenoh: the link's messages that
    /// came before it are read against it. One numbered below it is not
    /// the reader's: its Zenoh copy (numbered, as every linked message's
    /// is) would have placed the lane already, had it come since the
    /// lane's first message, so it is older than that (a link the lane
    /// joined already open: another entry's, or a previous pair's), or a
    /// message Zenoh dropped on a topic that drops.
    fn locate(&mut self, number: u32) {
        self.next = i64::from(number);
        self.located = true;
        for (n, arrival) in std::mem::take(&mut self.unplaced) {
            let n = self.unwrap(n);
            if n >= self.next {
                self.held.insert(n, arrival);
            }
        }
    }

    /// A message through Zenoh. Everything before it that has not come is
    /// lost (Zenoh keeps a publisher's order, so it dropped them): the
    /// link's messages held before it go first, then it, or the link's
    /// copy of it if that came first.
    fn zenoh_brought(&mut self, number: u32, arrival: Arrival, intake: &Intake) {
        if !self.located {
            self.locate(number);
        }
        let number = self.unwrap(number);
        if number < self.next {
            // Late: the count is known again only once Zenoh has brought
            // the last message handed on (a wait that ran out handed on
            // some ahead of it).
            if number + 1 == self.next {
                self.counted = true;
            }
            if !self.linked {
                // No link has brought anything: a message Zenoh itself
                // delivered late is still the reader's.
                intake.queue(arrival);
            }
            return; // Else the link brought it.
        }
        self.counted = true;
        while let Some(entry) = self.held.first_entry() {
            if *entry.key() > number {
                break;
            }
            let at = *entry.key();
            intake.queue(entry.remove());
            if at == number {
                self.next = number + 1;
                self.drain(intake);
                return;
            }
        }
        intake.queue(arrival);
        self.next = number + 1;
        self.drain(intake);
    }

    /// A message through Zenoh without a number: the next of its
    /// publisher (Zenoh keeps a publisher's order), which the link never
    /// carried.
    fn zenoh_counted(&mut self, arrival: Arrival, intake: &Intake) {
        intake.queue(arrival);
        if self.counted {
            self.next += 1;
            self.drain(intake);
        }
    }

    /// A message from the link, or a copy through a side key.
    fn link_brought(&mut self, number: u32, arrival: Arrival, intake: &Intake) {
        // Zenoh's copy of what this hands on is a copy from now on, also
        // when a side key brought it before the lane's link was answered
        // (a restarted producer read through the side key its predecessor
        // was read through): queued as a late message, it came twice.
        self.linked = true;
        if !self.located {
            self.unplaced.push((number, arrival));
            self.held_since.get_or_insert_with(Instant::now);
            return;
        }
        let number = self.unwrap(number);
        if !self.counted {
            // Zenoh may still bring messages before it.
            self.held.insert(number, arrival);
            self.held_since.get_or_insert_with(Instant::now);
        } else if number == self.next {
            intake.queue(arrival);
            self.next = number + 1;
            self.drain(intake);
        } else if number > self.next {
            // Zenoh has not brought those before it yet.
            self.held.insert(number, arrival);
            self.held_since.get_or_insert_with(Instant::now);
        }
        // Else Zenoh brought it already.
    }

    /// Hands on the held messages that are next in order.
    fn drain(&mut self, intake: &Intake) {
        while let Some(entry) = self.held.first_entry() {
            if *entry.key() != self.next {
                break;
            }
            intake.queue(entry.remove());
            self.next += 1;
        }
        if self.held.is_empty() {
            self.held_since = None;
        }
    }

    /// When the wait of the oldest held message ends.
    fn deadline(&self, dropping: bool) -> Option<Instant> {
        let limit = if dropping { DROPPING_HOLD } else { HOLD_LIMIT };
        self.held_since.map(|t| t + limit)
    }

    /// Ends a wait that has run out: the held messages go, in order, and
    /// Zenoh's copies of anything before them will be dropped.
    fn expire(&mut self, now: Instant, key: &KeyExpr<'static>, intake: &Intake) {
        let Some(deadline) = self.deadline(intake.drops()) else {
            return;
        };
        if now < deadline {
            return;
        }
        if !intake.drops() {
            warn!(topic = %key, "messages from a direct link waited too long for the ones before them through Zenoh; going on without those");
        }
        // Never placed, a link message cannot be told from one older than
        // the lane's first (a link joined already open): it is dropped,
        // and its Zenoh copy, numbered, places the lane when it comes.
        self.unplaced.clear();
        for (number, arrival) in std::mem::take(&mut self.held) {
            intake.queue(arrival);
            self.next = number + 1;
        }
        self.held_since = None;
        // Zenoh may yet bring messages from before those: counted, they
        // would be taken for later ones. Read through the side key, every
        // message comes numbered: nothing is counted.
        self.counted = self.switched;
    }
}

/// How a link's reading ended.
#[derive(Debug, Clone)]
enum Outcome {
    /// The producer has no socket, or refused.
    Unavailable(String),
    /// The link broke or sent something malformed.
    Closed(String),
    /// The node stopped.
    Stopped,
}

/// Connects to a producer and reads its link until it ends, handing each
/// message to every lane the link has.
async fn read_link(consumer: &Consumer, link: &Link, path: PathBuf, hello: Hello) -> Outcome {
    let handshake = async {
        let mut stream = tokio::net::UnixStream::connect(&path)
            .await
            .map_err(|e| e.to_string())?;
        stream
            .write_all(&hello.encode())
            .await
            .map_err(|e| e.to_string())?;
        let (status, memory) = read_status(&stream).await.map_err(|e| e.to_string())?;
        if status != 0 {
            return Err(format!("refused ({status})"));
        }
        let len = usize::from(stream.read_u8().await.map_err(|e| e.to_string())?);
        let mut attachment = vec![0; len];
        stream
            .read_exact(&mut attachment)
            .await
            .map_err(|e| e.to_string())?;
        let mut zid = [0; 16];
        stream
            .read_exact(&mut zid)
            .await
            .map_err(|e| e.to_string())?;
        let eid = stream.read_u32_le().await.map_err(|e| e.to_string())?;
        Ok::<_, String>((stream, attachment, (zid, eid), memory))
    };
    let (mut stream, attachment, source, memory) =
        match tokio::time::timeout(HOLD_LIMIT, handshake).await {
            Ok(Ok(linked)) => linked,
            Ok(Err(e)) => return Outcome::Unavailable(e),
            Err(_) => return Outcome::Unavailable("no answer".into()),
        };
    let attachment = ZBytes::from(attachment);
    let members = match link.shared.lock() {
        Ok(mut shared) => {
            shared.answer = Some((source, attachment.clone()));
            shared.members.clone()
        }
        Err(_) => return Outcome::Stopped,
    };
    for member in &members {
        if let Ok(mut state) = member.lane.state.lock()
            && state.generation == member.generation
        {
            let intake = member.intake.upgrade();
            let was_switched = state.switched;
            state.answered(source, attachment.clone(), intake.as_deref());
            if link.sole && member.sole {
                state.side = Some(super::side_key(link.key.as_str(), &consumer.name));
            }
            if let Some(intake) = &intake {
                settle_sole(intake, &member.lane, &mut state, was_switched);
            }
        }
    }
    debug!(topic = %link.key, "reading a producer over a direct link");
    let mut buf = bytes::BytesMut::with_capacity(INLINE_MAX + HEADER);
    let mut frames = Vec::new();
    loop {
        let Ok(members) = link.shared.lock().map(|s| s.members.clone()) else {
            return Outcome::Stopped;
        };
        if members.is_empty() {
            return Outcome::Stopped;
        }
        let deadline = members.iter().filter_map(Member::deadline).min();
        let read = tokio::select! {
            read = stream.read_buf(&mut buf) => read,
            () = sleep_until(deadline) => {
                for member in &members {
                    member.expire();
                }
                continue;
            }
            () = consumer.token.cancelled() => return Outcome::Stopped,
        };
        match read {
            Ok(0) => return Outcome::Closed("the producer closed it".into()),
            Ok(_) => {}
            Err(e) => return Outcome::Closed(e.to_string()),
        }
        let mut side_from = None;
        if let Err(why) = whole_frames(&mut buf, &mut frames, &mut side_from, memory.as_ref()) {
            return Outcome::Closed(why);
        }
        if let Some(number) = side_from {
            for member in &members {
                member.side_from(number);
            }
        }
        let gone: Vec<(usize, u64)> = members
            .iter()
            .filter(|member| !member.take(&frames))
            .map(Member::id)
            .collect();
        frames.clear();
        if !gone.is_empty()
            && let Ok(mut shared) = link.shared.lock()
        {
            shared.members.retain(|m| !gone.contains(&m.id()));
        }
    }
}

/// Moves every whole frame in `buf` to `frames` (its number, its message,
/// and whether the message is read in place), taking shared frames'
/// messages from the link's `memory`; a side frame's number goes to
/// `side_from`.
fn whole_frames(
    buf: &mut bytes::BytesMut,
    frames: &mut Vec<(u32, ZBytes, bool)>,
    side_from: &mut Option<u32>,
    memory: Option<&LinkMemory>,
) -> Result<(), String> {
    while buf.len() >= HEADER {
        let number = u32::from_le_bytes([buf[1], buf[2], buf[3], buf[4]]);
        let len = u32::from_le_bytes([buf[5], buf[6], buf[7], buf[8]]);
        let malformed = || {
            format!(
                "a malformed frame (kind {}, {len} bytes) on a direct link",
                buf[0]
            )
        };
        match buf[0] {
            FRAME_MESSAGE if (len as usize) < INLINE_MAX => {
                let len = len as usize;
                if buf.len() < HEADER + len {
                    buf.reserve(HEADER + len - buf.len());
                    break;
                }
                let _ = buf.split_to(HEADER);
                frames.push((number, ZBytes::from(buf.split_to(len).freeze()), false));
            }
            FRAME_SHARED => {
                if buf.len() < SHARED_HEADER {
                    break;
                }
                let offset = u32::from_le_bytes([buf[9], buf[10], buf[11], buf[12]]);
                let message = memory
                    .and_then(|m| m.take(offset, len))
                    .ok_or_else(malformed)?;
                let _ = buf.split_to(SHARED_HEADER);
                frames.push((number, ZBytes::from(message), true));
            }
            FRAME_SIDE if len == 0 => {
                let _ = buf.split_to(HEADER);
                *side_from = Some(number);
            }
            _ => return Err(malformed()),
        }
    }
    Ok(())
}

/// A link's shared memory, as its consumer reads it.
#[cfg(target_os = "linux")]
type LinkMemory = super::segment::Segment;

/// No shared memory off Linux: a shared frame is malformed.
#[cfg(not(target_os = "linux"))]
#[derive(Debug)]
struct LinkMemory;

#[cfg(not(target_os = "linux"))]
impl LinkMemory {
    fn take(&self, _offset: u32, _len: u32) -> Option<bytes::Bytes> {
        None
    }
}

/// Reads the producer's answer's first byte, and the link's shared memory
/// sent with it (none from a producer that could not make it).
#[cfg(target_os = "linux")]
async fn read_status(stream: &tokio::net::UnixStream) -> std::io::Result<(u8, Option<LinkMemory>)> {
    use std::os::fd::AsFd;
    let (status, fd) = loop {
        stream.readable().await?;
        match stream.try_io(tokio::io::Interest::READABLE, || {
            super::segment::recv_with_fd(stream.as_fd())
        }) {
            Ok(got) => break got,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) => return Err(e),
        }
    };
    let memory = fd.map(super::segment::Segment::open).transpose()?;
    Ok((status, memory))
}

/// Reads the producer's answer's first byte.
#[cfg(not(target_os = "linux"))]
async fn read_status(stream: &tokio::net::UnixStream) -> std::io::Result<(u8, Option<LinkMemory>)> {
    let mut byte = [0];
    loop {
        stream.readable().await?;
        match stream.try_read(&mut byte) {
            Ok(0) => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            Ok(_) => return Ok((byte[0], None)),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) => return Err(e),
        }
    }
}

impl Member {
    /// Which lane, as of which connection.
    fn id(&self) -> (usize, u64) {
        (Arc::as_ptr(&self.lane) as usize, self.generation)
    }

    /// When the oldest message its lane holds stops waiting.
    fn deadline(&self) -> Option<Instant> {
        let dropping = self.intake.upgrade()?.drops();
        self.lane.state.lock().ok()?.deadline(dropping)
    }

    /// Ends its lane's waits that have run out.
    fn expire(&self) {
        if let (Some(intake), Ok(mut state)) = (self.intake.upgrade(), self.lane.state.lock()) {
            state.expire(Instant::now(), &self.lane.key, &intake);
        }
    }

    /// The producer publishes what the link does not carry to the side key
    /// from message `number` on: the lane leaves the topic's own key once
    /// it has every message before that.
    fn side_from(&self, number: u32) {
        let (Some(intake), Ok(mut state)) = (self.intake.upgrade(), self.lane.state.lock()) else {
            return;
        };
        if state.generation == self.generation && state.switched {
            state.side_from = Some(state.unwrap(number));
            leave_own(&intake, &mut state);
        }
    }

    /// Hands `frames` to its lane; `false` when the lane no longer reads
    /// this link (its reader is gone, or it moved on to a restarted
    /// producer's).
    fn take(&self, frames: &[(u32, ZBytes, bool)]) -> bool {
        let Some(intake) = self.intake.upgrade() else {
            return false;
        };
        let Ok(mut state) = self.lane.state.lock() else {
            return false;
        };
        if state.generation != self.generation {
            return false;
        }
        for (number, payload, in_place) in frames {
            let mut arrival = Arrival::new(
                self.lane.key.clone(),
                payload.clone(),
                state.attachment.clone(),
            );
            if *in_place {
                arrival = arrival.read_in_place();
            }
            intake.counted_direct();
            state.link_brought(*number, arrival, &intake);
        }
        if state.side_from.is_some() {
            leave_own(&intake, &mut state);
        }
        true
    }
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(at) => tokio::time::sleep_until(at.into()).await,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::producers::Declarer;
    use crate::topics::{Inbox, TEST_TICKS};
    use peppy_schema::RouteFilter;

    const KEY: &str = "peppy/lab/topic/node/clock/v1/ticks/core/ticker";
    const SOURCE: SourceId = ([7; 16], 3);

    fn intake() -> (Intake, Inbox) {
        Intake::new(
            &TEST_TICKS,
            RouteFilter::Any,
            None,
            Declarer::none(),
            Arc::new(|_, _, _| {}),
        )
    }

    /// Message `n`: its number in its payload.
    fn message(n: u32) -> Arrival {
        let key = KeyExpr::try_from(KEY).unwrap();
        Arrival::new(key, ZBytes::from(n.to_le_bytes().to_vec()), None)
    }

    /// A linked lane whose Zenoh brought message `last` (the next is
    /// `last + 1`).
    fn lane(last: u32) -> LaneState {
        let mut state = LaneState::new(Some((SOURCE, last)));
        state.linked = true;
        state
    }

    #[test]
    fn without_a_link_nothing_zenoh_brings_is_dropped() {
        let (intake, inbox) = intake();
        let mut s = LaneState::new(Some((SOURCE, 0)));
        for n in [1, 3, 2, 4] {
            s.zenoh_brought(n, message(n), &intake);
        }
        assert_eq!(queued(&inbox), [1, 3, 2, 4], "as Zenoh delivered them");
    }

    /// What the reader would read, in order.
    fn queued(inbox: &Inbox) -> Vec<u32> {
        inbox
            .rx
            .drain()
            .map(|a| u32::from_le_bytes(a.payload().to_bytes()[..4].try_into().unwrap()))
            .collect()
    }

    #[test]
    fn link_messages_ahead_of_zenoh_wait_for_the_ones_before_them() {
        let (intake, inbox) = intake();
        let mut s = lane(0);
        s.link_brought(2, message(2), &intake);
        s.link_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), Vec::<u32>::new(), "1 has not come");
        s.zenoh_brought(1, message(1), &intake);
        for n in [2, 3] {
            s.zenoh_brought(n, message(n), &intake);
        }
        assert_eq!(queued(&inbox), [1, 2, 3], "each once, in order");
        assert!(s.deadline(false).is_none(), "nothing waits");
    }

    #[test]
    fn whichever_copy_comes_first_is_handed_on() {
        let (intake, inbox) = intake();
        let mut s = lane(0);
        s.zenoh_brought(1, message(1), &intake);
        s.link_brought(1, message(1), &intake);
        s.link_brought(2, message(2), &intake);
        s.zenoh_brought(2, message(2), &intake);
        s.zenoh_brought(3, message(3), &intake);
        s.link_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), [1, 2, 3]);
    }

    #[test]
    fn a_zenoh_message_past_the_next_means_those_between_were_dropped() {
        let (intake, inbox) = intake();
        let mut s = lane(0);
        s.link_brought(3, message(3), &intake);
        // 1 and 2 were dropped (a dropping topic), 4 went through Zenoh only.
        s.zenoh_brought(4, message(4), &intake);
        s.zenoh_brought(3, message(3), &intake);
        s.link_brought(5, message(5), &intake);
        assert_eq!(queued(&inbox), [3, 4, 5]);
    }

    #[test]
    fn a_held_message_goes_when_its_wait_runs_out_and_late_ones_are_dropped() {
        let (intake, inbox) = intake();
        let mut s = lane(0);
        let key = KeyExpr::try_from(KEY).unwrap();
        s.link_brought(5, message(5), &intake);
        let deadline = s.deadline(false).expect("5 waits");
        s.expire(deadline - Duration::from_millis(1), &key, &intake);
        assert_eq!(queued(&inbox), Vec::<u32>::new(), "not yet");
        s.expire(deadline, &key, &intake);
        assert_eq!(queued(&inbox), [5]);
        s.zenoh_brought(2, message(2), &intake);
        s.zenoh_brought(6, message(6), &intake);
        assert_eq!(queued(&inbox), [6], "2 came too late");
    }

    #[test]
    fn numbers_wrap() {
        let (intake, inbox) = intake();
        let mut s = lane(u32::MAX - 1);
        s.link_brought(0, message(0), &intake);
        s.link_brought(1, message(1), &intake);
        s.zenoh_brought(u32::MAX, message(u32::MAX), &intake);
        s.zenoh_brought(0, message(0), &intake);
        s.zenoh_brought(2, message(2), &intake);
        assert_eq!(queued(&inbox), [u32::MAX, 0, 1, 2]);
    }

    #[test]
    fn a_restarted_publisher_starts_the_numbers_afresh() {
        let (intake, inbox) = intake();
        let mut s = lane(500);
        s.restart(([8; 16], 3), 1, &intake);
        s.linked = true;
        s.zenoh_brought(2, message(2), &intake);
        s.link_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), [2, 3]);
        assert_eq!(s.previous, Some(SOURCE));
    }

    #[test]
    fn messages_zenoh_alone_carried_are_counted_between_numbered_ones() {
        let (intake, inbox) = intake();
        let mut s = lane(0);
        // 1 and 2 went through Zenoh alone (a burst); 3 over the link too.
        s.link_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), Vec::<u32>::new(), "1 and 2 have not come");
        s.zenoh_counted(message(1), &intake);
        assert_eq!(queued(&inbox), [1]);
        s.zenoh_counted(message(2), &intake);
        assert_eq!(queued(&inbox), [2, 3], "3 follows 2 at once");
        s.zenoh_brought(3, message(3), &intake);
        s.zenoh_counted(message(4), &intake);
        s.link_brought(5, message(5), &intake);
        s.zenoh_brought(5, message(5), &intake);
        assert_eq!(queued(&inbox), [4, 5], "each once, in order");
    }

    #[test]
    fn until_a_numbered_message_comes_through_zenoh_a_link_waits() {
        let (intake, inbox) = intake();
        // A lane that has only counted: the producer numbered nothing yet.
        let mut s = LaneState::new(None);
        s.zenoh_counted(message(1), &intake);
        s.answered(SOURCE, ZBytes::default(), Some(&intake));
        // Zenoh has not brought 2 yet; the link's 3 must not overtake it,
        // whatever `next` guessed.
        s.link_brought(3, message(3), &intake);
        s.zenoh_counted(message(2), &intake);
        assert_eq!(queued(&inbox), [1, 2]);
        s.zenoh_brought(3, message(3), &intake);
        s.zenoh_counted(message(4), &intake);
        s.link_brought(5, message(5), &intake);
        assert_eq!(queued(&inbox), [3, 4, 5], "counted from 3 on");
    }

    #[test]
    fn after_a_wait_runs_out_the_count_is_learnt_again() {
        let (intake, inbox) = intake();
        let key = KeyExpr::try_from(KEY).unwrap();
        let mut s = lane(0);
        s.link_brought(4, message(4), &intake);
        let deadline = s.deadline(false).expect("4 waits");
        s.expire(deadline, &key, &intake);
        assert_eq!(queued(&inbox), [4]);
        // Zenoh's 1 to 3 come late: handed on, but not counted as 5 to 7,
        // so the link's 6 waits for Zenoh's numbered copy of 6.
        for n in 1..=3 {
            s.zenoh_counted(message(n), &intake);
        }
        s.zenoh_counted(message(5), &intake);
        s.link_brought(6, message(6), &intake);
        assert_eq!(queued(&inbox), [1, 2, 3, 5]);
        s.zenoh_brought(6, message(6), &intake);
        s.zenoh_counted(message(7), &intake);
        assert_eq!(queued(&inbox), [6, 7], "6 once");
    }

    #[tokio::test]
    async fn only_a_producer_the_slot_routes_here_is_linked() {
        let dir = tempfile::tempdir().unwrap();
        let consumer = Consumer::new(
            dir.path().to_path_buf(),
            "core/sink".into(),
            true,
            tokio::runtime::Handle::current(),
            CancellationToken::new(),
        );
        let routed = ["ticker"].map(String::from).into_iter().collect();
        let (intake, _inbox) = Intake::new(
            &TEST_TICKS,
            RouteFilter::OnlyFrom(routed),
            None,
            Declarer::none(),
            Arc::new(|_, _, _| {}),
        );
        let intake = intake.linked(Some(&consumer));
        let inlet = intake.direct().unwrap();
        let from = |instance: &str| {
            let key = KEY.replace("/ticker", &format!("/{instance}"));
            Arrival::new(KeyExpr::try_from(key).unwrap(), ZBytes::default(), None)
        };
        assert!(matches!(
            inlet.route(&intake, from("other"), None),
            Route::Take(_)
        ));
        assert!(matches!(
            inlet.route(&intake, from("ticker"), None),
            Route::Handled
        ));
        let lanes = inlet.lanes.lock().unwrap();
        let linked: Vec<&str> = lanes.by_key.keys().map(|k| &**k).collect();
        assert_eq!(
            linked,
            [KEY],
            "a lane, and a link tried, for the routed producer alone"
        );
    }

    #[test]
    fn a_late_numbered_message_after_a_wait_does_not_make_the_count_known() {
        let (intake, inbox) = intake();
        let key = KeyExpr::try_from(KEY).unwrap();
        let mut s = lane(8);
        // 9 and 11 through Zenoh alone; 10 and 12 over the link too, held
        // until the wait runs out.
        s.link_brought(10, message(10), &intake);
        s.link_brought(12, message(12), &intake);
        let deadline = s.deadline(false).expect("held");
        s.expire(deadline, &key, &intake);
        assert_eq!(queued(&inbox), [10, 12]);
        s.zenoh_counted(message(9), &intake);
        s.zenoh_brought(10, message(10), &intake);
        // Not counted as 13: Zenoh is still behind what the wait handed on.
        s.zenoh_counted(message(11), &intake);
        s.zenoh_brought(12, message(12), &intake);
        s.link_brought(13, message(13), &intake);
        s.zenoh_brought(13, message(13), &intake);
        s.zenoh_counted(message(14), &intake);
        assert_eq!(queued(&inbox), [9, 11, 13, 14], "none lost, none twice");
    }

    #[test]
    fn a_publisher_far_into_its_numbers_is_located_by_its_first_numbered_message() {
        let (intake, inbox) = intake();
        let far = 3_000_000_000u32;
        // Counted only, then linked: nothing says where its numbers are.
        let mut s = LaneState::new(None);
        s.zenoh_counted(message(far - 2), &intake);
        s.answered(SOURCE, ZBytes::default(), Some(&intake));
        s.link_brought(far, message(far), &intake);
        s.zenoh_counted(message(far - 1), &intake);
        s.zenoh_brought(far, message(far), &intake);
        s.zenoh_counted(message(far + 1), &intake);
        s.link_brought(far + 2, message(far + 2), &intake);
        s.zenoh_brought(far + 2, message(far + 2), &intake);
        assert_eq!(
            queued(&inbox),
            [far - 2, far - 1, far, far + 1, far + 2],
            "each once, in order"
        );
    }

    #[test]
    fn a_lane_joining_an_open_link_never_hands_on_what_came_before_it() {
        let (intake, inbox) = intake();
        let key = KeyExpr::try_from(KEY).unwrap();
        // A fresh lane (a new pair, a second entry) whose first message
        // through Zenoh is 2, unnumbered; it joins the link already open,
        // whose reader is behind and still brings 1 (another pair's, or
        // read already by the other entry).
        let mut s = LaneState::new(None);
        s.zenoh_counted(message(2), &intake);
        s.answered(SOURCE, ZBytes::default(), Some(&intake));
        s.link_brought(1, message(1), &intake);
        s.link_brought(3, message(3), &intake);
        s.zenoh_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), [2, 3], "1 is not the lane's");

        // The same, with no numbered message through Zenoh before the wait
        // runs out: what never was placed is dropped, and Zenoh's numbered
        // copy places the lane when it comes.
        let mut s = LaneState::new(None);
        s.zenoh_counted(message(2), &intake);
        s.answered(SOURCE, ZBytes::default(), Some(&intake));
        s.link_brought(1, message(1), &intake);
        s.link_brought(3, message(3), &intake);
        s.expire(s.deadline(false).unwrap(), &key, &intake);
        assert_eq!(queued(&inbox), [2]);
        s.zenoh_brought(3, message(3), &intake);
        s.zenoh_counted(message(4), &intake);
        assert_eq!(queued(&inbox), [3, 4]);

        // Across the numbers' wrap: the link's u32::MAX is before 0.
        let mut s = LaneState::new(None);
        s.zenoh_counted(message(7), &intake);
        s.answered(SOURCE, ZBytes::default(), Some(&intake));
        s.link_brought(u32::MAX, message(u32::MAX), &intake);
        s.link_brought(1, message(1), &intake);
        s.zenoh_brought(0, message(0), &intake);
        s.zenoh_brought(1, message(1), &intake);
        assert_eq!(queued(&inbox), [7, 0, 1]);
    }

    #[test]
    fn a_side_copy_before_the_link_answers_is_not_handed_on_twice() {
        let (intake, inbox) = intake();
        let mut s = lane(500);
        // A restarted producer's first numbered message through Zenoh; its
        // link to this node is not answered yet, but the side key of its
        // predecessor's link is still read and brings its copy of 2.
        s.restart(([8; 16], 3), 1, &intake);
        s.link_brought(2, message(2), &intake);
        s.zenoh_brought(2, message(2), &intake);
        s.zenoh_brought(3, message(3), &intake);
        assert_eq!(queued(&inbox), [2, 3], "each once, in order");
    }

    #[test]
    fn what_the_link_held_of_a_replaced_publisher_is_handed_on() {
        let (intake, inbox) = intake();
        let mut s = lane(7);
        // 8 and 9 went through Zenoh alone and died with the producer.
        s.link_brought(10, message(10), &intake);
        assert_eq!(queued(&inbox), Vec::<u32>::new());
        s.restart(([8; 16], 3), 1, &intake);
        assert_eq!(queued(&inbox), [10], "not thrown away");
        assert!(s.deadline(false).is_none(), "nothing waits");
    }
}
