//! The consumer's side of direct links: which producers of a consumed
//! topic are read over one, and the order their messages are handed on in.

use std::collections::{HashMap, VecDeque};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;

use super::{
    FRAME_MESSAGE, FRAME_PLACEHOLDER, HEADER, HOLD_LIMIT, Hello, INLINE_MAX, SourceId, after,
};
use crate::topics::{Arrival, Intake};
use crate::wire::keys::split_entry_key;

/// How long a producer without a socket is left on Zenoh before the next
/// of its messages tries again (a producer restarted with direct links).
const RETRY_AFTER: Duration = Duration::from_secs(5);

/// The most producers of one consumed topic tried for a link.
const MAX_LINKS: usize = 256;

/// Messages kept that came through Zenoh before the link told of them.
const EARLY_MAX: usize = 64;

/// A node's direct links as a consumer: where producers' sockets are, and
/// who it is.
#[derive(Debug)]
pub(crate) struct Consumer {
    dir: PathBuf,
    /// `<core node>/<instance>`, for the producers' logs.
    name: String,
    runtime: tokio::runtime::Handle,
    token: CancellationToken,
}

impl Consumer {
    pub(crate) fn new(
        dir: PathBuf,
        name: String,
        runtime: tokio::runtime::Handle,
        token: CancellationToken,
    ) -> Arc<Consumer> {
        Arc::new(Consumer {
            dir,
            name,
            runtime,
            token,
        })
    }
}

/// One consumed topic's direct links, by producer key.
#[derive(Debug)]
pub(crate) struct Inlet {
    consumer: Arc<Consumer>,
    links: Mutex<HashMap<Box<str>, Link, foldhash::fast::FixedState>>,
    intake: OnceLock<Weak<Intake>>,
}

#[derive(Debug)]
enum Link {
    /// The producer has no socket: its messages come through Zenoh.
    Unavailable {
        until: Instant,
    },
    Linked(Arc<Lane>),
    /// The link ended: Zenoh's copies of what it delivered are dropped,
    /// anything newer is taken (and links the producer again).
    Ended(Ended),
}

#[derive(Debug, Clone)]
struct Ended {
    source: SourceId,
    /// The last message the link delivered.
    last: u32,
    /// Large messages announced on the link that it ended before: taken
    /// when they come.
    expected: Vec<u32>,
}

/// What a message that came through Zenoh is to its reader.
pub(crate) enum Route {
    /// Queue it.
    Take(Arrival),
    /// The link has it (or placed it): nothing to queue now.
    Handled,
}

impl Inlet {
    pub(crate) fn new(consumer: Arc<Consumer>) -> Inlet {
        Inlet {
            consumer,
            links: Mutex::new(HashMap::default()),
            intake: OnceLock::new(),
        }
    }

    /// The intake the links queue into, once it is shared.
    pub(crate) fn bind(&self, intake: &Arc<Intake>) {
        let _ = self.intake.set(Arc::downgrade(intake));
    }

    /// Routes a message that came through Zenoh, with the publisher and
    /// sequence number its source info carries (a producer with direct
    /// links numbers every message).
    pub(crate) fn route(&self, arrival: Arrival, source: Option<(SourceId, u32)>) -> Route {
        let Some(intake) = self.intake.get().and_then(Weak::upgrade) else {
            return Route::Take(arrival);
        };
        let Ok(mut links) = self.links.lock() else {
            return Route::Take(arrival);
        };
        let lane = match links.get_mut(arrival.key.as_str()) {
            Some(Link::Linked(lane)) => lane.clone(),
            Some(Link::Unavailable { until }) if Instant::now() < *until => {
                return Route::Take(arrival);
            }
            Some(Link::Ended(ended)) => {
                if let Some((id, sequence)) = source
                    && id == ended.source
                {
                    if let Some(at) = ended.expected.iter().position(|&s| s == sequence) {
                        ended.expected.swap_remove(at);
                        return Route::Take(arrival);
                    }
                    if !after(sequence, ended.last) {
                        return Route::Handled;
                    }
                }
                // Newer than the link: the producer is read through Zenoh,
                // and linked again.
                self.relink(&mut links, arrival, source, &intake);
                return Route::Handled;
            }
            _ => {
                if links.len() >= MAX_LINKS {
                    return Route::Take(arrival);
                }
                self.relink(&mut links, arrival, source, &intake);
                return Route::Handled;
            }
        };
        let Ok(mut state) = lane.state.lock() else {
            return Route::Take(arrival);
        };
        match (state.source, source) {
            (None, _) => {
                // Not answered yet: Zenoh's to hand on, before the answer
                // (under the lane's lock) can let the link's messages by.
                if let Some(seen) = source {
                    state.seen = Some(seen);
                }
                intake.queue(arrival);
            }
            (Some(linked), Some((id, sequence))) if id == linked => {
                drop(links);
                state.from_zenoh(sequence, arrival, &intake);
            }
            _ => {
                // Another process publishes under this key (the producer
                // restarted): the link is to one that is gone.
                drop(state);
                self.relink(&mut links, arrival, source, &intake);
            }
        }
        Route::Handled
    }

    /// Hands on `arrival` and links its producer (again).
    fn relink(
        &self,
        links: &mut HashMap<Box<str>, Link, foldhash::fast::FixedState>,
        arrival: Arrival,
        source: Option<(SourceId, u32)>,
        intake: &Intake,
    ) {
        match self.link(links, &arrival.key, source) {
            // Queued under the new lane's lock: its answer cannot let the
            // link's first messages by before this one.
            Some(lane) => {
                let _state = lane.state.lock();
                intake.queue(arrival);
            }
            None => intake.queue(arrival),
        }
    }

    /// Starts linking the producer of `key`, if it names one; `seen` is
    /// the message through Zenoh that prompted it.
    fn link(
        &self,
        links: &mut HashMap<Box<str>, Link, foldhash::fast::FixedState>,
        key: &KeyExpr<'static>,
        seen: Option<(SourceId, u32)>,
    ) -> Option<Arc<Lane>> {
        let sender = split_entry_key(key.as_str())?;
        let intake = self.intake.get().cloned()?;
        let path = super::socket_path(&self.consumer.dir, sender.core, sender.instance);
        let lane = Arc::new(Lane {
            key: key.clone(),
            state: Mutex::new(LaneState {
                seen,
                ..LaneState::default()
            }),
        });
        links.insert(key.as_str().into(), Link::Linked(lane.clone()));
        let reader = lane.clone();
        let hello = Hello {
            key: key.as_str().to_string(),
            consumer: self.consumer.name.clone(),
        };
        let consumer = self.consumer.clone();
        self.consumer.runtime.spawn(async move {
            let lane = reader;
            let outcome = read_link(&consumer, &lane, path, hello, &intake).await;
            if let Some(intake) = intake.upgrade() {
                let ended = lane.close(&intake);
                if let Some(inlet) = intake.direct() {
                    inlet.unlink(&lane, (!outcome.is_unavailable()).then_some(ended));
                }
            }
            match outcome {
                Outcome::Stopped => {}
                Outcome::Unavailable(why) => {
                    debug!(topic = %lane.key, why, "no direct link to this producer: its messages come through Zenoh");
                }
                Outcome::Closed(why) => {
                    debug!(topic = %lane.key, why, "a direct link closed: this producer's messages come through Zenoh again");
                }
            }
        });
        Some(lane)
    }

    /// Forgets a link that ended (`ended`: what Zenoh may still bring of
    /// it; `None`: the producer has no socket, and is left on Zenoh for a
    /// while).
    fn unlink(&self, lane: &Arc<Lane>, ended: Option<Option<Ended>>) {
        let Ok(mut links) = self.links.lock() else {
            return;
        };
        let key = lane.key.as_str();
        if !matches!(links.get(key), Some(Link::Linked(l)) if Arc::ptr_eq(l, lane)) {
            return;
        }
        match ended {
            None => {
                let until = Instant::now() + RETRY_AFTER;
                links.insert(key.into(), Link::Unavailable { until });
            }
            Some(Some(ended)) => {
                links.insert(key.into(), Link::Ended(ended));
            }
            Some(None) => {
                links.remove(key);
            }
        }
    }
}

/// One producer's link, as its consumer reads it.
#[derive(Debug)]
struct Lane {
    key: KeyExpr<'static>,
    state: Mutex<LaneState>,
}

#[derive(Debug, Default)]
struct LaneState {
    /// Zenoh brought every message before the link's first (or is past
    /// it, or was waited for long enough): the link's messages are the
    /// reader's, Zenoh's copies are dropped.
    live: bool,
    /// When the producer answered: the wait for Zenoh starts.
    answered: Option<Instant>,
    /// The number of the first message the link carries.
    first: u32,
    /// The last message Zenoh brought before the answer.
    seen: Option<(SourceId, u32)>,
    /// The producer's topic attachment, from its answer.
    attachment: Option<ZBytes>,
    /// The producer's Zenoh publisher, from its answer.
    source: Option<SourceId>,
    /// The sequence number of the last message the link delivered or
    /// announced.
    last: Option<u32>,
    /// What the link delivered that waits for Zenoh's messages before it
    /// or for a large message ahead of it.
    held: VecDeque<Held>,
    /// Messages that came through Zenoh before the link told of them.
    early: VecDeque<(u32, Arrival)>,
}

#[derive(Debug)]
enum Held {
    Message(Arrival),
    Large { sequence: u32, since: Instant },
}

impl Lane {
    /// The link ended: what it delivered is handed on, and what Zenoh may
    /// still bring of it is returned.
    fn close(&self, intake: &Intake) -> Option<Ended> {
        let Ok(mut state) = self.state.lock() else {
            return None;
        };
        state.live = true;
        let mut expected = Vec::new();
        while let Some(held) = state.held.pop_front() {
            match held {
                Held::Message(a) => intake.queue(a),
                Held::Large { sequence, .. } => expected.push(sequence),
            }
        }
        // Copies Zenoh brought first of messages the link never did.
        let last = state.last;
        let mut early: Vec<_> = state.early.drain(..).collect();
        early.sort_by(|a, b| {
            if after(a.0, b.0) {
                std::cmp::Ordering::Greater
            } else {
                std::cmp::Ordering::Less
            }
        });
        for (sequence, arrival) in early {
            if last.is_none_or(|l| after(sequence, l)) {
                intake.queue(arrival);
            }
        }
        Some(Ended {
            source: state.source?,
            last: last?,
            expected,
        })
    }
}

impl LaneState {
    /// Hands on everything the link delivered that is not behind a large
    /// message still on its way, once live.
    fn drain(&mut self, intake: &Intake) {
        if !self.live {
            return;
        }
        while let Some(Held::Message(_)) = self.held.front() {
            if let Some(Held::Message(a)) = self.held.pop_front() {
                intake.queue(a);
            }
        }
    }

    /// A message from the link.
    fn message(&mut self, sequence: u32, arrival: Arrival, intake: &Intake) {
        self.last = Some(sequence);
        if let Some(at) = self.early.iter().position(|(s, _)| *s == sequence) {
            // Zenoh's copy came first: the link's is the one in order.
            self.early.remove(at);
        }
        if self.live && self.held.is_empty() {
            intake.queue(arrival);
        } else {
            self.held.push_back(Held::Message(arrival));
        }
    }

    /// A large message's placeholder from the link.
    fn placeholder(&mut self, sequence: u32, intake: &Intake) {
        self.last = Some(sequence);
        if let Some(at) = self.early.iter().position(|(s, _)| *s == sequence) {
            let (_, arrival) = self.early.remove(at).expect("found");
            self.held.push_back(Held::Message(arrival));
            self.drain(intake);
        } else {
            self.held.push_back(Held::Large {
                sequence,
                since: Instant::now(),
            });
        }
    }

    /// The producer answered: the link carries messages from `first` on.
    fn answered(&mut self, source: SourceId, first: u32, attachment: ZBytes) {
        self.source = Some(source);
        self.first = first;
        self.attachment = Some(attachment);
        self.answered = Some(Instant::now());
        // Zenoh already brought the message before the first (or there is
        // none): nothing to wait for.
        let before = first.wrapping_sub(1);
        self.live = match self.seen {
            Some((id, seen)) if id == source => !after(before, seen),
            _ => false,
        };
    }

    /// Ends the wait for Zenoh: the link's messages flow.
    fn go_live(&mut self, intake: &Intake) {
        if !self.live {
            self.live = true;
            self.drain(intake);
        }
    }

    /// A message of the linked producer through Zenoh: one from before the
    /// link is handed on (ending the wait when it is the last before it); a
    /// large one goes where its placeholder is; a copy of what the link
    /// delivered is dropped; one the link has not told of yet waits for it.
    fn from_zenoh(&mut self, sequence: u32, arrival: Arrival, intake: &Intake) {
        if after(self.first, sequence) {
            intake.queue(arrival);
            if sequence == self.first.wrapping_sub(1) {
                self.go_live(intake);
            }
            return;
        }
        // Zenoh is past the link's first message: whatever came before it
        // that has not arrived was dropped.
        self.go_live(intake);
        let slot = self
            .held
            .iter()
            .position(|h| matches!(h, Held::Large { sequence: s, .. } if *s == sequence));
        if let Some(at) = slot {
            self.held[at] = Held::Message(arrival);
            self.drain(intake);
        } else if self.last.is_some_and(|l| !after(sequence, l)) {
            // Delivered by the link, or given up on.
        } else {
            if self.early.len() == EARLY_MAX {
                self.early.pop_front();
            }
            self.early.push_back((sequence, arrival));
        }
    }

    /// When the oldest wait ends.
    fn deadline(&self) -> Option<Instant> {
        if !self.live {
            return self.answered.map(|t| t + HOLD_LIMIT);
        }
        match self.held.front() {
            Some(Held::Large { since, .. }) => Some(*since + HOLD_LIMIT),
            _ => None,
        }
    }

    /// Ends the waits that have run out.
    fn expire(&mut self, now: Instant, key: &KeyExpr<'static>, intake: &Intake) {
        if !self.live && self.answered.is_some_and(|t| now >= t + HOLD_LIMIT) {
            debug!(topic = %key, "Zenoh never brought the message before a direct link's first: reading the link without it");
            self.live = true;
        }
        while let Some(&Held::Large { since, .. }) = self.held.front() {
            if now < since + HOLD_LIMIT {
                break;
            }
            warn!(topic = %key, "a large message announced on a direct link never came through Zenoh; going on without it");
            self.held.pop_front();
            self.drain(intake);
        }
        self.drain(intake);
    }
}

/// How a link's reading ended.
enum Outcome {
    /// The producer has no socket, or refused.
    Unavailable(String),
    /// The link broke or sent something malformed.
    Closed(String),
    /// The node stopped.
    Stopped,
}

impl Outcome {
    fn is_unavailable(&self) -> bool {
        matches!(self, Outcome::Unavailable(_))
    }
}

/// Connects to a producer and reads its link until it ends.
async fn read_link(
    consumer: &Consumer,
    lane: &Arc<Lane>,
    path: PathBuf,
    hello: Hello,
    intake: &Weak<Intake>,
) -> Outcome {
    let handshake = async {
        let mut stream = tokio::net::UnixStream::connect(&path)
            .await
            .map_err(|e| e.to_string())?;
        stream
            .write_all(&hello.encode())
            .await
            .map_err(|e| e.to_string())?;
        let status = stream.read_u8().await.map_err(|e| e.to_string())?;
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
        let first = stream.read_u32_le().await.map_err(|e| e.to_string())?;
        Ok::<_, String>((stream, attachment, (zid, eid), first))
    };
    let (mut stream, attachment, source, first) =
        match tokio::time::timeout(HOLD_LIMIT, handshake).await {
            Ok(Ok(linked)) => linked,
            Ok(Err(e)) => return Outcome::Unavailable(e),
            Err(_) => return Outcome::Unavailable("no answer".into()),
        };
    if let Ok(mut state) = lane.state.lock() {
        state.answered(source, first, ZBytes::from(attachment));
        if state.live {
            debug!(topic = %lane.key, "reading a producer over a direct link");
        }
    }
    let mut buf = bytes::BytesMut::with_capacity(64 * 1024);
    loop {
        let deadline = lane.state.lock().ok().and_then(|s| s.deadline());
        let read = tokio::select! {
            read = stream.read_buf(&mut buf) => read,
            () = sleep_until(deadline) => {
                let Some(intake) = intake.upgrade() else { return Outcome::Stopped };
                if let Ok(mut state) = lane.state.lock() {
                    state.expire(Instant::now(), &lane.key, &intake);
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
        let Some(intake) = intake.upgrade() else {
            return Outcome::Stopped;
        };
        if let Err(why) = take_frames(&mut buf, lane, &intake) {
            return Outcome::Closed(why);
        }
    }
}

/// Hands on every whole frame in `buf`.
fn take_frames(buf: &mut bytes::BytesMut, lane: &Lane, intake: &Intake) -> Result<(), String> {
    let Ok(mut state) = lane.state.lock() else {
        return Err("poisoned".into());
    };
    while buf.len() >= HEADER {
        let sequence = u32::from_le_bytes([buf[1], buf[2], buf[3], buf[4]]);
        let len = u32::from_le_bytes([buf[5], buf[6], buf[7], buf[8]]) as usize;
        match buf[0] {
            FRAME_MESSAGE => {
                if len >= INLINE_MAX {
                    return Err(format!("a message of {len} bytes on a direct link"));
                }
                if buf.len() < HEADER + len {
                    buf.reserve(HEADER + len - buf.len());
                    break;
                }
                let _ = buf.split_to(HEADER);
                let payload = ZBytes::from(buf.split_to(len).freeze());
                let arrival = Arrival::direct(lane.key.clone(), payload, state.attachment.clone());
                intake.counted_direct();
                state.message(sequence, arrival, intake);
            }
            FRAME_PLACEHOLDER if len == 0 => {
                let _ = buf.split_to(HEADER);
                state.placeholder(sequence, intake);
            }
            kind => return Err(format!("a malformed frame (kind {kind}) on a direct link")),
        }
    }
    Ok(())
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(at) => tokio::time::sleep_until(at.into()).await,
        None => std::future::pending().await,
    }
}
