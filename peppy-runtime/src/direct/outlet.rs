//! The producer's side of direct links: the socket consumers connect to,
//! and each emitted topic's links.

use std::io::{ErrorKind, IoSlice, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};

use peppy_schema::QosProfile;
use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::sample::SourceInfo;
use zenoh::session::Session;

use super::burst::{Burst, Pushed, SideCopies, Writer};
use super::{
    BURST_GAP, FRAME_MESSAGE, FRAME_SIDE, HOLD_LIMIT, Hello, INLINE_MAX, WRITE_LIMIT, header,
};
#[cfg(target_os = "linux")]
use super::{FRAME_SHARED, HEADER, SHARED_HEADER};
use crate::qos;

/// One emitted topic's direct links. Every publication of the topic takes
/// its lock: messages are numbered in the order Zenoh gets them, and a link
/// is added between two publications, never during one.
#[derive(Debug)]
pub(crate) struct DirectOutlet {
    key: String,
    qos: QosProfile,
    fingerprint: u64,
    /// The Zenoh publisher's id, which its samples carry.
    source: super::SourceId,
    /// Where a sole link's side publisher is declared.
    session: Session,
    /// Whether Zenoh knows a subscriber of the topic's own key: with none
    /// (its consumers all read through sole links), the own key's copy is
    /// not published.
    readers: Arc<AtomicBool>,
    links: Mutex<Links>,
    /// Whether a consumer reads the topic through a side key (a sole
    /// link's, open or ended): then a large message goes into Zenoh's
    /// shared memory even with no subscriber of the topic's own key.
    sole_readers: AtomicBool,
    /// The clock a burst is told by, made when the first link is added
    /// (making it calibrates the CPU's counter, which takes a few
    /// milliseconds). `Instant::now` cost a flood of small messages a
    /// twentieth of its rate here (a virtual machine's clock); reading the
    /// counter costs a few nanoseconds.
    clock: OnceLock<quanta::Clock>,
}

#[derive(Debug, Default)]
struct Links {
    open: Vec<Link>,
    /// The id the next link gets.
    next_id: u64,
    /// The last message's number.
    sequence: u32,
    /// When the last small message published while linked was out (the
    /// clock's raw counter).
    last: Option<u64>,
    /// The side keys of sole links that ended, while their consumer may
    /// still read them: every message goes there until it has gone back
    /// to the topic's own key.
    orphans: Vec<Side>,
}

/// A sole link's side key: what the link does not carry is published
/// there for its consumer, which reads the producer through the link and
/// this key alone.
#[derive(Debug)]
struct Side {
    /// Shared with the link's writer, which publishes here what it could
    /// not write.
    publisher: Arc<Publisher<'static>>,
    /// Whether Zenoh knows the consumer's subscription to it.
    matching: Arc<AtomicBool>,
    /// Whether it has been seen matching (since its link ended, for an
    /// ended link's): its consumer is gone from it once it no longer
    /// matches.
    seen: bool,
    /// When its link ended.
    ended: Option<Instant>,
}

impl Side {
    /// Whether an ended link's side key is still to be published to: its
    /// consumer has not been seen to leave it, and (if it was never seen
    /// on it) its subscription may still be on its way.
    fn wanted(&mut self, now: Instant) -> bool {
        let matching = self.matching.load(Ordering::Relaxed);
        self.seen |= matching;
        matching || (!self.seen && self.ended.is_none_or(|t| now - t < ORPHAN_GRACE))
    }
}

/// How long an ended sole link's side key is published to while its
/// consumer's subscription to it has never been seen: a subscription
/// declared just before the link ended reaches the producer within it.
const ORPHAN_GRACE: Duration = Duration::from_secs(5);
#[derive(Debug)]
struct Link {
    /// Which link of the topic it is: a message placed in its memory is
    /// sent over it alone.
    #[cfg_attr(not(target_os = "linux"), allow(dead_code))]
    id: u64,
    /// Shared with its writer ([`Burst`]), which writes while the producer
    /// does not.
    stream: Arc<UnixStream>,
    /// The consumer (`<core node>/<instance>`), for the log.
    consumer: String,
    /// A sole link's side key.
    side: Option<Side>,
    /// The number of the last message written to it: one it did not get
    /// goes to its side key.
    carried: Option<u32>,
    /// Messages of a dropping topic not written since the last report.
    dropped: u64,
    /// The writer of a sole link's bursts, from its first burst on.
    burst: Option<Burst>,
    /// The link's shared memory, where its large messages go.
    #[cfg(target_os = "linux")]
    ring: Option<super::segment::Ring>,
}

impl DirectOutlet {
    pub(crate) fn new(
        session: &Session,
        publisher: &Publisher<'static>,
        readers: Arc<AtomicBool>,
        qos: QosProfile,
        fingerprint: u64,
    ) -> Self {
        DirectOutlet {
            key: publisher.key_expr().to_string(),
            qos,
            fingerprint,
            source: super::source_id(&publisher.id()),
            session: session.clone(),
            readers,
            links: Mutex::new(Links::default()),
            sole_readers: AtomicBool::new(false),
            clock: OnceLock::new(),
        }
    }

    /// Whether a consumer reads the topic through a side key.
    pub(crate) fn sole_readers(&self) -> bool {
        self.sole_readers.load(Ordering::Relaxed)
    }

    /// Publishes `payload` through Zenoh, and over every link of the topic
    /// when it is small and not part of a burst (it comes within a burst's
    /// gap of the end of the topic's previous publication), or over the
    /// sole links when it is part of one and below 16 KiB; then its Zenoh
    /// copy carries its number in its source info. Every message counts
    /// towards the numbers.
    pub(crate) fn publish(
        &self,
        publisher: &Publisher<'static>,
        payload: ZBytes,
        attachment: ZBytes,
    ) -> zenoh::Result<()> {
        let Ok(mut links) = self.links.lock() else {
            return publisher.put(payload).attachment(attachment).wait();
        };
        self.publish_timed(&mut links, publisher, payload, attachment)
    }

    /// [`Self::publish_locked`], and the end of the publication kept for
    /// telling the next one's burst.
    fn publish_timed(
        &self,
        links: &mut Links,
        publisher: &Publisher<'static>,
        payload: ZBytes,
        attachment: ZBytes,
    ) -> zenoh::Result<()> {
        let (sent, timed) = self.publish_locked(links, publisher, payload, attachment);
        if timed && let Some(clock) = self.clock.get() {
            // A burst is told by the producer's time between two messages
            // out of here: a flooding producer's put waits now and then for
            // Zenoh's full queue, and counted as a pause that wait put the
            // next message on the links, where it reached its consumer
            // before its predecessors (still in Zenoh's batches) and waited
            // for them.
            links.last = Some(clock.raw());
        }
        sent
    }

    /// Encodes a message of `len` bytes straight into the shared memory of
    /// the topic's one link (`encode` fills the region it is given, and
    /// says whether it filled it exactly), when that link's consumer alone
    /// reads the topic: a sole link whose side key is read, with no
    /// subscriber of the topic's own key, no ended link's side key still
    /// read and no burst of small messages being written, and room in its
    /// memory. Then the message costs the producer one copy, its encoding,
    /// as through Zenoh's shared memory, and no Zenoh put;
    /// [`Self::publish_placed`] sends it.
    ///
    /// Neither a burst nor a consumer behind keeps such a message off the
    /// link, as they keep a message copied into its memory: that copy is
    /// what they avoid, and a placed message has none. The link then
    /// carries a flood whole while its memory has room, and a round trip's
    /// messages never pass for a burst.
    ///
    /// `None` (and `encode` not called, or its region let go) otherwise:
    /// the message is encoded for Zenoh as any other.
    #[cfg(target_os = "linux")]
    pub(crate) fn place(
        &self,
        len: usize,
        encode: impl FnOnce(&mut [u8]) -> bool,
    ) -> Option<Placed> {
        if !placed(len) || self.readers.load(Ordering::Relaxed) {
            return None;
        }
        let (link, mut region) = {
            let mut links = self.links.lock().ok()?;
            let link = links.only()?;
            if !link.alone() {
                return None;
            }
            (link.id, link.ring.as_mut()?.reserve(len)?)
        };
        // Encoded outside the topic's lock: the region is held, and this
        // call's alone. Other publications and links go on meanwhile, and
        // an encoder that panics poisons nothing (its region is let go).
        if !encode(region.bytes_mut()) {
            return None;
        }
        region.filled();
        Some(Placed { link, region })
    }

    /// Where a message is encoded without direct links' shared memory: never
    /// in a link's.
    #[cfg(not(target_os = "linux"))]
    pub(crate) fn place(
        &self,
        _len: usize,
        _encode: impl FnOnce(&mut [u8]) -> bool,
    ) -> Option<Placed> {
        None
    }

    /// Whether a message of `len` bytes would go over the topic's one link,
    /// through its socket, to a consumer that reads the topic through that
    /// link and its side key alone: then Zenoh carries it only if the link
    /// does not take it (a full socket), and the node's shared memory is
    /// not worth a chunk for it (a 4 KiB round trip took 54 µs without,
    /// 61 µs with, in two benchmark runs of the same hour).
    pub(crate) fn carries_alone(&self, len: usize) -> bool {
        if len >= INLINE_MAX || shared(len) || self.readers.load(Ordering::Relaxed) {
            return false;
        }
        let Ok(mut links) = self.links.lock() else {
            return false;
        };
        links
            .only()
            .is_some_and(|l| l.side.as_ref().is_some_and(|s| s.seen))
    }

    /// Publishes a message [placed](Self::place) in a link's memory: over
    /// that link, numbered like every other, when its consumer still reads
    /// the topic alone; else, copied out of the link's memory, as
    /// [`Self::publish`] publishes any message.
    pub(crate) fn publish_placed(
        &self,
        publisher: &Publisher<'static>,
        placed: Placed,
        attachment: ZBytes,
    ) -> zenoh::Result<()> {
        let Ok(mut links) = self.links.lock() else {
            return publisher.put(placed.copied()).attachment(attachment).wait();
        };
        let placed = if self.readers.load(Ordering::Relaxed) {
            placed
        } else {
            match links.carry_placed(placed, self.drops()) {
                Ok(()) => {
                    if let Some(clock) = self.clock.get() {
                        links.last = Some(clock.raw());
                    }
                    return Ok(());
                }
                Err(placed) => placed,
            }
        };
        self.publish_timed(&mut links, publisher, placed.copied(), attachment)
    }

    /// [`Self::publish`] under the topic's lock: what it sent, and whether
    /// the message counts towards telling a burst.
    fn publish_locked(
        &self,
        links: &mut Links,
        publisher: &Publisher<'static>,
        payload: ZBytes,
        attachment: ZBytes,
    ) -> (zenoh::Result<()>, bool) {
        links.sequence = links.sequence.wrapping_add(1);
        let number = links.sequence;
        let sides = links.has_sides();
        if sides {
            links.announce_sides(number, self.drops());
        }
        let (mut linked, mut timed) = (false, false);
        let len = payload.len();
        if let (false, Some(clock)) = (links.open.is_empty(), self.clock.get())
            && (len < INLINE_MAX || shared(len))
        {
            timed = true;
            let now = clock.raw();
            let burst = links
                .last
                .is_some_and(|t| clock.delta_as_nanos(t, now) < burst_gap_ns(len));
            if !burst {
                // The links first: they are what a consumer on this host
                // reads.
                linked = links.write(number, &payload.to_bytes(), self.drops());
            } else if sides && len < LARGE {
                // In a burst a sole link's writer gathers the messages into
                // large writes; the other links leave it to Zenoh's batches.
                linked = links.gather(number, &payload.to_bytes(), self.drops(), &attachment);
            }
        }
        if sides {
            // Sole consumers that did not get it over their link get it
            // under their side key, numbered like its other copies.
            let published = links.publish_sides(&payload, &attachment, number);
            if !published.any {
                self.sole_readers.store(false, Ordering::Relaxed);
            }
            if published.only && !self.readers.load(Ordering::Relaxed) {
                // Every consumer on a link reads through its side key, and
                // Zenoh knows no other subscriber of the topic's key: its
                // copy would go nowhere, at the cost of a put (a flood of
                // small messages lost a tenth of its rate to it). That
                // status is trusted only here: a linked consumer's own
                // subscription of the topic's key came before its side
                // key's (Zenoh passes one session's declarations on in
                // order), so it is known by now; a producer just started
                // may not know yet of subscriptions its router routes to.
                return (published.sent, timed);
            }
        }
        let put = publisher.put(payload).attachment(attachment);
        let sent = if linked || sides {
            // Its consumers tell its copies apart by this number: a sole
            // consumer reads the topic's own key too while it moves to its
            // side key and back.
            put.source_info(SourceInfo::new(publisher.id(), number))
                .wait()
        } else {
            // Zenoh alone carries it: no number on the wire (in a flood,
            // Zenoh's source info costs a quarter of the rate), its
            // consumers count it.
            put.wait()
        };
        (sent, timed)
    }

    /// How many links the topic has open.
    pub(crate) fn links(&self) -> usize {
        self.links.lock().map_or(0, |l| l.open.len())
    }

    /// Closes every link (the node stops): each consumer reads the rest of
    /// its link, then goes back to Zenoh.
    ///
    /// The writers of its sole links' bursts are told to end, and handed
    /// back to be waited for (once every topic's are told).
    fn close(&self) -> Vec<Burst> {
        let Ok(mut links) = self.links.lock() else {
            return Vec::new();
        };
        let (mut ended, mut writers) = (Vec::new(), Vec::new());
        for link in std::mem::take(&mut links.open) {
            ended.extend(link.side);
            if let Some(burst) = link.burst {
                burst.end();
                writers.push(burst);
            }
        }
        links.orphan(ended);
        writers
    }

    /// Whether the topic drops a message rather than wait for a slow
    /// reader (its Zenoh publisher's congestion control).
    fn drops(&self) -> bool {
        qos::congestion(self.qos) == CongestionControl::Drop
    }

    /// Adds the link a consumer asked for, under the lock (between two
    /// publications), with a segment of shared memory when `shared` (both
    /// nodes' shared memory is on), and a side key when `sole`.
    fn attach(
        &self,
        mut stream: UnixStream,
        consumer: String,
        shared: bool,
        sole: bool,
    ) -> std::io::Result<()> {
        self.clock.get_or_init(quanta::Clock::new);
        // Declared before the lock: Zenoh's calls are not made under it.
        let side = sole.then(|| self.side(&consumer)).transpose()?;
        let mut links = self
            .links
            .lock()
            .map_err(|_| std::io::Error::other("a publisher panicked"))?;
        let attachment = crate::wire::attachment::topic(self.fingerprint);
        let answer = super::answer(&attachment, self.source);
        stream.set_write_timeout(Some(HOLD_LIMIT))?;
        #[cfg(target_os = "linux")]
        let ring = match shared.then(super::segment::Ring::create) {
            Some(Ok((ring, fd))) => {
                use std::os::fd::AsFd;
                super::segment::send_with_fd(&stream, &answer, fd.as_fd())?;
                Some(ring)
            }
            Some(Err(e)) => {
                static SAID: std::sync::atomic::AtomicBool =
                    std::sync::atomic::AtomicBool::new(false);
                if !SAID.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    warn!(consumer, error = %e, "direct links without shared memory: their messages of 16 KiB or more go through Zenoh alone, or the socket (logged once)");
                }
                stream.write_all(&answer)?;
                None
            }
            None => {
                stream.write_all(&answer)?;
                None
            }
        };
        #[cfg(not(target_os = "linux"))]
        {
            let _ = shared;
            stream.write_all(&answer)?;
        }
        stream.set_nonblocking(true)?;
        if let Some(side) = &side {
            self.sole_readers.store(true, Ordering::Relaxed);
            // The consumer's earlier link's side key is this one's: the
            // new link's publishes there from now on, numbered until its
            // subscription is seen, so the consumer never meets two
            // publishers' counts on one key.
            let key = side.publisher.key_expr();
            links.orphans.retain(|o| o.publisher.key_expr() != key);
        }
        links.next_id += 1;
        let id = links.next_id;
        links.open.push(Link {
            id,
            stream: Arc::new(stream),
            consumer,
            side,
            carried: None,
            dropped: 0,
            burst: None,
            #[cfg(target_os = "linux")]
            ring,
        });
        Ok(())
    }

    /// The side key of a sole link to `consumer`, and its publisher:
    /// published like the topic's own key.
    fn side(&self, consumer: &str) -> std::io::Result<Side> {
        let publisher = self
            .session
            .declare_publisher(super::side_key(&self.key, consumer))
            .congestion_control(qos::congestion(self.qos))
            .priority(qos::priority(self.qos))
            .express(qos::express(self.qos))
            .wait()
            .map_err(std::io::Error::other)?;
        let matching = Arc::new(AtomicBool::new(false));
        let flag = matching.clone();
        publisher
            .matching_listener()
            .callback(move |status| flag.store(status.matching(), Ordering::Relaxed))
            .background()
            .wait()
            .map_err(std::io::Error::other)?;
        Ok(Side {
            publisher: Arc::new(publisher),
            matching,
            seen: false,
            ended: None,
        })
    }
}

impl Links {
    /// The topic's one link, when it has one and no ended link is still
    /// read: the link a message for a sole consumer may go over alone.
    fn only(&mut self) -> Option<&mut Link> {
        match (self.orphans.is_empty(), self.open.as_mut_slice()) {
            (true, [link]) => Some(link),
            _ => None,
        }
    }

    /// Writes message `number` to every link that takes it, closing the
    /// links that fail: whether any got it.
    fn write(&mut self, number: u32, body: &[u8], may_drop: bool) -> bool {
        let large = body.len() >= LARGE;
        let mut any = false;
        let mut ended = Vec::new();
        self.open.retain_mut(|link| {
            if large && unread(&link.stream) != Some(0) {
                // The consumer has not read the link's last frames: it is
                // busy, not waiting, and Zenoh's shared memory moves a
                // large message there without a copy.
                return true;
            }
            let (written, keep) = link.send(number, body, may_drop);
            any |= written;
            if written {
                link.carried = Some(number);
            }
            if !keep {
                ended.extend(link.side.take());
            }
            keep
        });
        self.orphan(ended);
        any
    }

    /// Sends the next message, placed in a link's memory, over that link
    /// when it is still the topic's only one and its consumer reads nothing
    /// else (see [`DirectOutlet::place`]); the message back when it was not
    /// written. A link that failed is closed.
    fn carry_placed(&mut self, placed: Placed, may_drop: bool) -> Result<(), Placed> {
        #[cfg(target_os = "linux")]
        {
            let number = self.sequence.wrapping_add(1);
            let Some(link) = self.only().filter(|l| l.id == placed.link && l.alone()) else {
                return Err(placed);
            };
            let region = &placed.region;
            let head = shared_head(number, region.len(), region.offset());
            let (written, keep) = link.write(&head, &[], may_drop);
            if written {
                link.carried = Some(number);
                self.sequence = number;
            }
            if !keep {
                let ended: Vec<Side> = self.open.drain(..).filter_map(|l| l.side).collect();
                self.orphan(ended);
            }
            if !written {
                return Err(placed);
            }
            placed.region.sent();
            Ok(())
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = may_drop;
            match placed {}
        }
    }

    /// Hands message `number`, one of a burst, to the writer of every sole
    /// link whose consumer reads its side key (starting it at the link's
    /// first burst), closing the links whose writer failed: whether any
    /// took it. The other links do not carry it.
    fn gather(&mut self, number: u32, body: &[u8], may_drop: bool, attachment: &ZBytes) -> bool {
        let mut any = false;
        let mut ended = Vec::new();
        self.open.retain_mut(|link| {
            let Some(side) = link.side.as_ref().filter(|side| side.seen) else {
                return true;
            };
            if link.burst.is_none() {
                let copies = SideCopies {
                    publisher: side.publisher.clone(),
                    attachment: attachment.clone(),
                };
                match Burst::start(link.stream.clone(), copies, link.consumer.clone(), may_drop) {
                    Ok(burst) => link.burst = Some(burst),
                    Err(e) => {
                        debug!(consumer = %link.consumer, error = %e, "no writer for a direct link's bursts: Zenoh carries them");
                        return true;
                    }
                }
            }
            let (carried, keep) = link
                .burst
                .as_ref()
                .map_or(Pushed::Refused, |b| b.push(number, body, may_drop))
                .carried_kept();
            if carried {
                link.carried = Some(number);
                any = true;
            }
            if !keep {
                ended.extend(link.side.take());
            }
            keep
        });
        self.orphan(ended);
        any
    }

    /// Tells each sole link whose consumer's side key subscription has
    /// just been seen that from message `number` on, what it does not
    /// carry goes there.
    fn announce_sides(&mut self, number: u32, may_drop: bool) {
        let due = |link: &Link| {
            link.side
                .as_ref()
                .is_some_and(|s| !s.seen && s.matching.load(Ordering::Relaxed))
        };
        if !self.open.iter().any(due) {
            return;
        }
        let mut ended = Vec::new();
        self.open.retain_mut(|link| {
            if !due(link) {
                return true;
            }
            // On a topic that drops, a full socket drops the frame too, and
            // the next message tries again.
            let (written, keep) = link.write(&header(FRAME_SIDE, number, 0), &[], may_drop);
            if written && let Some(side) = &mut link.side {
                side.seen = true;
            }
            if !keep {
                ended.extend(link.side.take());
            }
            keep
        });
        self.orphan(ended);
    }

    /// Sole links ended: their side keys are published to until their
    /// consumers have gone back to the topic's own key.
    fn orphan(&mut self, sides: Vec<Side>) {
        for mut side in sides {
            side.ended = Some(Instant::now());
            side.seen = false;
            self.orphans.push(side);
        }
    }

    /// Whether any side key is published to.
    fn has_sides(&self) -> bool {
        !self.orphans.is_empty() || self.open.iter().any(|l| l.side.is_some())
    }

    /// Publishes message `number` under the side keys of the open sole
    /// links that did not get it and of the ended ones still read;
    /// forgets the ended ones no longer read. One pass over the links,
    /// which also tells what the topic's own key is for.
    fn publish_sides(&mut self, payload: &ZBytes, attachment: &ZBytes, number: u32) -> Published {
        let mut published = Published {
            sent: Ok(()),
            any: false,
            only: true,
        };
        for link in &self.open {
            let Some(side) = &link.side else {
                published.only = false;
                continue;
            };
            published.any = true;
            published.only &= side.seen;
            if link.carried != Some(number) {
                if let Some(burst) = &link.burst {
                    // A writer that failed publishes what it held under the
                    // side key first: asking waits for it.
                    burst.writer();
                }
                published.keep_first_error(side.put(payload, attachment, number));
            }
        }
        if !self.orphans.is_empty() {
            let now = Instant::now();
            self.orphans.retain_mut(|side| side.wanted(now));
            for side in &self.orphans {
                published.keep_first_error(side.put(payload, attachment, number));
            }
        }
        published.any |= !self.orphans.is_empty();
        published.only &= published.any;
        published
    }
}

/// What publishing a message under the side keys did and found.
struct Published {
    /// The first put that failed, if one did (the others are still made).
    sent: zenoh::Result<()>,
    /// Whether a side key is still published to.
    any: bool,
    /// Whether every open link is a sole one whose consumer's side key
    /// subscription has been seen, and some side key is published to:
    /// then the topic's own key has no reader on a link.
    only: bool,
}

impl Published {
    fn keep_first_error(&mut self, put: zenoh::Result<()>) {
        if self.sent.is_ok() {
            self.sent = put;
        }
    }
}

impl Side {
    /// Publishes message `number` under the side key, its number in its
    /// source info (a consumer that subscribes late, or again, places
    /// every copy it gets by it alone).
    fn put(&self, payload: &ZBytes, attachment: &ZBytes, number: u32) -> zenoh::Result<()> {
        self.publisher
            .put(payload.clone())
            .attachment(attachment.clone())
            .source_info(SourceInfo::new(self.publisher.id(), number))
            .wait()
    }
}

impl Link {
    /// Whether its consumer reads the topic through it and its side key
    /// alone, and a frame of the producer's own may be written now: its
    /// side key is read, and it has no burst to write (a frame written
    /// now would overtake it).
    #[cfg(target_os = "linux")]
    fn alone(&self) -> bool {
        self.side.as_ref().is_some_and(|s| s.seen)
            && self
                .burst
                .as_ref()
                .is_none_or(|b| b.writer() == Writer::Idle)
    }

    /// Sends message `number`: in the link's shared memory when it is
    /// large and there is room, else through the socket when it is small
    /// enough. Whether it was written, and whether to keep the link.
    fn send(&mut self, number: u32, body: &[u8], may_drop: bool) -> (bool, bool) {
        if let Some(burst) = &self.burst {
            match burst.writer() {
                Writer::Idle => {}
                Writer::Failed => return (false, false),
                // Its writer still has a burst to write: a write of the
                // producer's own would overtake it. A small message joins
                // the burst; a larger one goes under the side key.
                Writer::Busy if body.len() >= LARGE => return (false, true),
                Writer::Busy => return burst.push(number, body, may_drop).carried_kept(),
            }
        }
        #[cfg(target_os = "linux")]
        if shared(body.len())
            && let Some(ring) = &mut self.ring
        {
            // No room (the consumer holds too much): Zenoh alone.
            let Some(offset) = ring.put(body) else {
                return (false, true);
            };
            let sent = self.write(&shared_head(number, body.len(), offset), &[], may_drop);
            if !sent.0
                && let Some(ring) = &mut self.ring
            {
                ring.unput(offset);
            }
            return sent;
        }
        if body.len() >= INLINE_MAX {
            return (false, true);
        }
        self.write(
            &header(FRAME_MESSAGE, number, body.len() as u32),
            body,
            may_drop,
        )
    }

    /// Writes one frame: whether it was written, and whether to keep the
    /// link.
    fn write(&mut self, head: &[u8], body: &[u8], may_drop: bool) -> (bool, bool) {
        let link = self;
        match write_frame(&link.stream, head, body, may_drop) {
            Ok(true) => {
                if link.dropped > 0 {
                    debug!(consumer = %link.consumer, dropped = link.dropped, "a direct link has room again");
                    link.dropped = 0;
                }
                (true, true)
            }
            Ok(false) => {
                link.dropped += 1;
                if link.dropped.is_power_of_two() {
                    debug!(consumer = %link.consumer, dropped = link.dropped, "a direct link's reader is behind: dropping as the topic's profile says");
                }
                (false, true)
            }
            Err(e) if matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::ConnectionReset) => {
                debug!(consumer = %link.consumer, "a consumer closed its direct link");
                (false, false)
            }
            Err(e) => {
                warn!(consumer = %link.consumer, error = %e, "closing a direct link: the consumer reads this topic through Zenoh alone");
                (false, false)
            }
        }
    }
}

/// A shared frame: message `number`, of `len` bytes, at `offset` in the
/// link's memory.
#[cfg(target_os = "linux")]
fn shared_head(number: u32, len: usize, offset: u32) -> [u8; SHARED_HEADER] {
    let mut head = [0; SHARED_HEADER];
    head[..HEADER].copy_from_slice(&header(FRAME_SHARED, number, len as u32));
    head[HEADER..].copy_from_slice(&offset.to_le_bytes());
    head
}

/// A message encoded into a link's shared memory, to be sent over that
/// link ([`DirectOutlet::place`]). Dropped unsent, its region is let go.
#[cfg(target_os = "linux")]
#[derive(Debug)]
pub(crate) struct Placed {
    link: u64,
    region: super::segment::Region,
}

/// No link has shared memory here.
#[cfg(not(target_os = "linux"))]
#[derive(Debug)]
pub(crate) enum Placed {}

impl Placed {
    /// Its message's length.
    pub(crate) fn len(&self) -> usize {
        #[cfg(target_os = "linux")]
        {
            self.region.len()
        }
        #[cfg(not(target_os = "linux"))]
        match *self {}
    }

    /// Its message, copied out of the link's memory for Zenoh (the link
    /// did not take it), its region let go.
    pub(crate) fn copied(self) -> ZBytes {
        #[cfg(target_os = "linux")]
        {
            ZBytes::from(self.region.bytes().to_vec())
        }
        #[cfg(not(target_os = "linux"))]
        match self {}
    }
}

/// Whether a message of `len` bytes may be encoded straight into a link's
/// shared memory.
#[cfg(target_os = "linux")]
fn placed(len: usize) -> bool {
    (super::segment::SHARED_MIN..=super::segment::PLACED_MAX).contains(&len)
}

/// Whether a message of `len` bytes goes over a link through its shared
/// memory (where the link has some).
fn shared(len: usize) -> bool {
    #[cfg(target_os = "linux")]
    {
        (super::segment::SHARED_MIN..=super::segment::MAX_MESSAGE).contains(&len)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = len;
        false
    }
}

/// How soon after the topic's previous message one of `len` bytes is part
/// of a burst: [`BURST_GAP`], and more the larger it is. Below 16 KiB the
/// socket carries a message, a copy through the kernel: half a nanosecond
/// more per byte (8 µs at 16 KiB). From 16 KiB a link's shared memory
/// does (where a link has none, the socket up to 128 KiB), one copy more
/// for the producer than Zenoh's path: an eighth of a nanosecond per byte
/// (69 µs at 384 KiB). Either is worth it to a consumer waiting for the
/// message, not in a producer's flood: when the segment took messages up
/// to 1.5 MiB, round trips of 1 MiB came 270 µs apart, and a flood of
/// them (about 100 µs apart) went at ×0.79 of raw Zenoh's rate over links
/// with a flat gap, where Zenoh alone carried them at its rate. A message
/// placed in the link's memory ([`DirectOutlet::place`]) has no such copy
/// and no gap.
fn burst_gap_ns(len: usize) -> u64 {
    let per_byte = if shared(len) { len / 8 } else { len / 2 };
    BURST_GAP.as_nanos() as u64 + per_byte as u64
}

/// A message of this size or more goes over a link only to a consumer that
/// has read everything the link brought it (one waiting for a message, not
/// one behind in a flood). Measured without it, a flood of 64 KiB
/// messages on a link lost a fifth of its rate: each pause of the
/// producer longer than a burst's gap wrote a message through the socket.
const LARGE: usize = 16 * 1024;

/// The bytes written to `stream` that its reader has not read yet; `None`
/// where the system cannot say.
fn unread(stream: &UnixStream) -> Option<usize> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let mut queued: libc::c_int = 0;
        // SAFETY: TIOCOUTQ (SIOCOUTQ) writes one c_int through the pointer,
        // which points at a live local; the descriptor is the stream's own.
        let done = unsafe { libc::ioctl(stream.as_raw_fd(), libc::TIOCOUTQ, &mut queued) };
        (done == 0).then(|| usize::try_from(queued).unwrap_or(0))
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = stream;
        None
    }
}

/// Writes a whole frame to a non-blocking socket: `Ok(false)` when it was
/// dropped because the socket was full before its first byte and the topic
/// drops; otherwise it waits for room, up to [`WRITE_LIMIT`].
fn write_frame(
    mut stream: &UnixStream,
    head: &[u8],
    body: &[u8],
    may_drop: bool,
) -> std::io::Result<bool> {
    let total = head.len() + body.len();
    let mut done = 0;
    let mut deadline: Option<Instant> = None;
    let result = loop {
        if done == total {
            break Ok(true);
        }
        let slices = if done < head.len() {
            [IoSlice::new(&head[done..]), IoSlice::new(body)]
        } else {
            [IoSlice::new(&body[done - head.len()..]), IoSlice::new(&[])]
        };
        match stream.write_vectored(&slices) {
            Ok(0) => break Err(ErrorKind::WriteZero.into()),
            Ok(n) => done += n,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                if done == 0 && may_drop {
                    break Ok(false);
                }
                // Full: wait for room in blocking mode, with what is left
                // of the limit as the write's timeout.
                let until = *deadline.get_or_insert_with(|| Instant::now() + WRITE_LIMIT);
                let left = until.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    break Err(ErrorKind::TimedOut.into());
                }
                if let Err(e) = stream
                    .set_nonblocking(false)
                    .and_then(|()| stream.set_write_timeout(Some(left)))
                {
                    break Err(e);
                }
            }
            Err(e) => break Err(e),
        }
    };
    if deadline.is_some() {
        stream.set_nonblocking(true)?;
    }
    result
}

/// The topics a node's socket serves: its emitted topics from start-up,
/// and its pairing topics once their publishers are declared. Held weakly:
/// a topic whose publisher is gone is not linked.
#[derive(Debug, Default)]
pub(crate) struct Outlets(Mutex<Vec<Weak<DirectOutlet>>>);

impl Outlets {
    /// Serves `outlet` from now on.
    pub(crate) fn add(&self, outlet: &Arc<DirectOutlet>) {
        if let Ok(mut all) = self.0.lock() {
            all.retain(|o| o.strong_count() > 0);
            all.push(Arc::downgrade(outlet));
        }
    }

    /// Closes every link of every topic served (the node stops).
    ///
    /// Waits, up to [`CLOSE_LIMIT`] in all, for the links' writers to be
    /// done with the bursts they hold: the node closes its session next,
    /// and what a writer could not write goes under a side key through it.
    pub(crate) fn close_all(&self) {
        let outlets: Vec<_> = match self.0.lock() {
            Ok(all) => all.iter().filter_map(Weak::upgrade).collect(),
            Err(_) => return,
        };
        let writers: Vec<Burst> = outlets.iter().flat_map(|o| o.close()).collect();
        let deadline = Instant::now() + CLOSE_LIMIT;
        for writer in &writers {
            writer.wait_done(deadline);
        }
    }

    /// The topic published under `key`, while its publisher lives.
    fn find(&self, key: &str) -> Option<Arc<DirectOutlet>> {
        let all = self.0.lock().ok()?;
        all.iter().filter_map(Weak::upgrade).find(|o| o.key == key)
    }
}

/// How long a stopping node waits for its links' writers, in all: a
/// writer gives up on a consumer that reads nothing within
/// [`WRITE_LIMIT`], then publishes what it holds under the side key.
const CLOSE_LIMIT: Duration = Duration::from_secs(2);

/// A node's socket for direct links, removed when the node stops.
#[derive(Debug)]
pub(crate) struct Listener {
    path: PathBuf,
}

impl Drop for Listener {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Listens at `path` for consumers of `outlets` (the node's topics by key)
/// until `token` fires, giving each link a segment of shared memory when
/// `shared` (the node's shared memory is on) and its consumer takes one.
/// `None` (the node's topics stay on Zenoh alone) when the socket cannot
/// be made.
pub(crate) fn serve(
    path: &Path,
    outlets: Arc<Outlets>,
    shared: bool,
    token: CancellationToken,
) -> Option<Listener> {
    // A socket left by an earlier run of this instance (killed) is stale.
    let _ = std::fs::remove_file(path);
    let listener = match std::os::unix::net::UnixListener::bind(path)
        .and_then(|l| l.set_nonblocking(true).map(|()| l))
        .and_then(tokio::net::UnixListener::from_std)
    {
        Ok(l) => l,
        Err(e) => {
            warn!(path = %path.display(), error = %e, "no direct links for this node's topics: its socket cannot be made");
            return None;
        }
    };
    tokio::spawn(async move {
        loop {
            let stream = tokio::select! {
                accepted = listener.accept() => match accepted {
                    Ok((stream, _)) => stream,
                    Err(e) => {
                        warn!(error = %e, "direct links: accepting a consumer failed");
                        tokio::time::sleep(Duration::from_millis(100)).await;
                        continue;
                    }
                },
                () = token.cancelled() => return,
            };
            let outlets = outlets.clone();
            tokio::spawn(async move {
                if let Err(e) = welcome(stream, &outlets, shared).await {
                    debug!(error = %e, "a direct link was not made");
                }
            });
        }
    });
    Some(Listener {
        path: path.to_path_buf(),
    })
}

/// Reads a consumer's hello and links it to the topic it names.
async fn welcome(
    mut stream: tokio::net::UnixStream,
    outlets: &Outlets,
    shared: bool,
) -> std::io::Result<()> {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let hello = tokio::time::timeout(HOLD_LIMIT, async {
        let len = usize::from(stream.read_u16_le().await?);
        if len > Hello::MAX {
            return Err(std::io::Error::other("hello too long"));
        }
        let mut bytes = vec![0; len];
        stream.read_exact(&mut bytes).await?;
        Hello::decode(&bytes).ok_or_else(|| std::io::Error::other("malformed hello"))
    })
    .await
    .map_err(|_| std::io::Error::from(ErrorKind::TimedOut))??;
    let Some(outlet) = outlets.find(&hello.key) else {
        stream.write_all(&[1]).await?;
        return Err(std::io::Error::other(format!(
            "no topic published under `{}`",
            hello.key
        )));
    };
    let stream = stream.into_std()?;
    stream.set_nonblocking(false)?;
    let Hello {
        key,
        consumer,
        shared: takes_shared,
        ..
    } = hello;
    let who = consumer.clone();
    let shared = shared && takes_shared;
    let sole = hello.sole;
    tokio::task::spawn_blocking(move || outlet.attach(stream, who, shared, sole))
        .await
        .map_err(std::io::Error::other)??;
    debug!(
        consumer,
        topic = key,
        "a consumer on this host reads a topic over a direct link"
    );
    Ok(())
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use std::io::Read;
    use std::os::fd::AsFd;
    use std::sync::atomic::AtomicBool;

    use super::*;
    use crate::direct::burst::tests::lone_session;
    use crate::direct::segment::{PLACED_MAX, Segment};

    /// A topic with one sole link whose side key is read: the topic, its
    /// publisher, the consumer's end of the link, the link's memory as the
    /// consumer maps it, and the side key's copies (number, body) as they
    /// come.
    struct Linked {
        outlet: DirectOutlet,
        publisher: Publisher<'static>,
        reader: UnixStream,
        memory: Segment,
        copies: Arc<Mutex<Vec<SideCopy>>>,
        _side: zenoh::pubsub::Subscriber<()>,
    }

    /// A side key's copy: its number and body.
    type SideCopy = (u32, Vec<u8>);

    async fn linked(session: &Session, key: &str) -> Linked {
        let publisher = session.declare_publisher(key.to_string()).await.unwrap();
        let readers = Arc::new(AtomicBool::new(false));
        let outlet = DirectOutlet::new(session, &publisher, readers, QosProfile::Reliable, 1);
        let (producer, mut reader) = UnixStream::pair().unwrap();
        outlet
            .attach(producer, "core/sink".into(), true, true)
            .unwrap();
        // The answer: `0`, the attachment (a length byte, then it), the
        // source id; the segment's descriptor with its first byte.
        let (first, fd) = super::super::segment::recv_with_fd(reader.as_fd()).unwrap();
        assert_eq!(first, 0);
        let memory = Segment::open(fd.expect("a segment")).unwrap();
        let mut len = [0u8];
        reader.read_exact(&mut len).unwrap();
        let mut rest = vec![0u8; usize::from(len[0]) + 16 + 4];
        reader.read_exact(&mut rest).unwrap();
        let copies = Arc::new(Mutex::new(Vec::new()));
        let seen = copies.clone();
        let side = session
            .declare_subscriber(super::super::side_key(key, "core/sink"))
            .callback(move |sample| {
                let number = sample.source_info().expect("numbered").source_sn();
                let body = sample.payload().to_bytes().to_vec();
                seen.lock().unwrap().push((number, body));
            })
            .await
            .unwrap();
        let linked = Linked {
            outlet,
            publisher,
            reader,
            memory,
            copies,
            _side: side,
        };
        // Small messages until the side key's subscription is seen (its
        // frame announces it).
        tokio::time::timeout(Duration::from_secs(10), async {
            while !linked.outlet.links.lock().unwrap().open[0]
                .side
                .as_ref()
                .unwrap()
                .seen
            {
                linked.publish(&[1, 2, 3]);
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
        .expect("the side key's subscription is seen");
        linked
    }

    impl Linked {
        fn publish(&self, body: &[u8]) {
            let payload = ZBytes::from(body.to_vec());
            let attachment = ZBytes::from(vec![7u8]);
            self.outlet
                .publish(&self.publisher, payload, attachment)
                .unwrap();
        }

        /// Places `body` as [`crate::topics::encode`] would.
        fn place(&self, body: &[u8]) -> Option<Placed> {
            self.outlet.place(body.len(), |region| {
                region.copy_from_slice(body);
                true
            })
        }

        /// The frames on the link from here until `number`: (kind, number,
        /// length, offset of a shared frame).
        fn frames_until(&mut self, number: u32) -> Vec<(u8, u32, u32, Option<u32>)> {
            self.reader
                .set_read_timeout(Some(Duration::from_secs(10)))
                .unwrap();
            let mut frames = Vec::new();
            loop {
                let mut head = [0u8; HEADER];
                self.reader.read_exact(&mut head).unwrap();
                let n = u32::from_le_bytes(head[1..5].try_into().unwrap());
                let len = u32::from_le_bytes(head[5..9].try_into().unwrap());
                let offset = match head[0] {
                    FRAME_SHARED => {
                        let mut offset = [0u8; 4];
                        self.reader.read_exact(&mut offset).unwrap();
                        Some(u32::from_le_bytes(offset))
                    }
                    FRAME_MESSAGE => {
                        let mut body = vec![0u8; len as usize];
                        self.reader.read_exact(&mut body).unwrap();
                        None
                    }
                    _ => None,
                };
                frames.push((head[0], n, len, offset));
                if n == number && head[0] != FRAME_SIDE {
                    return frames;
                }
            }
        }

        fn sequence(&self) -> u32 {
            self.outlet.links.lock().unwrap().sequence
        }
    }

    fn body(len: usize, seed: u8) -> Vec<u8> {
        (0..len)
            .map(|i| (i as u8).wrapping_mul(31) ^ seed)
            .collect()
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_message_placed_in_a_sole_links_memory_is_sent_over_it_in_place() {
        let session = lone_session().await;
        let mut link = linked(&session, "test/placed/sent").await;
        let message = body(1 << 20, 5);
        let placed = link.place(&message).expect("placed: the link alone reads");
        let number = link.sequence() + 1;
        link.outlet
            .publish_placed(&link.publisher, placed, ZBytes::from(vec![7u8]))
            .unwrap();
        let frames = link.frames_until(number);
        let &(kind, _, len, offset) = frames.last().unwrap();
        assert_eq!((kind, len as usize), (FRAME_SHARED, message.len()));
        let got = link
            .memory
            .take(offset.unwrap(), len)
            .expect("a region held");
        assert!(got[..] == message[..], "the message as it was encoded");
        assert!(
            link.copies
                .lock()
                .unwrap()
                .iter()
                .all(|(n, _)| *n != number),
            "no copy under the side key"
        );
        // Let go by the consumer: the next is placed where it was.
        drop(got);
        let next = link.place(&body(1 << 20, 6)).unwrap();
        assert_eq!(Some(next.region.offset()), offset);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_placed_message_never_sent_lets_its_region_go() {
        let session = lone_session().await;
        let link = linked(&session, "test/placed/dropped").await;
        let first = link.place(&body(64 << 10, 1)).unwrap();
        let offset = first.region.offset();
        drop(first);
        let again = link.place(&body(64 << 10, 2)).unwrap();
        assert_eq!(again.region.offset(), offset, "its region was let go");
        // An encoding that does not fill its region places nothing.
        drop(again);
        assert!(link.outlet.place(64 << 10, |_| false).is_none());
        assert_eq!(
            link.place(&body(64 << 10, 3)).unwrap().region.offset(),
            offset
        );
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn nothing_is_placed_for_a_topic_zenoh_also_carries_or_out_of_bounds() {
        let session = lone_session().await;
        let link = linked(&session, "test/placed/refused").await;
        assert!(link.place(&body(16 << 10, 1)).is_some());
        assert!(
            link.place(&body((16 << 10) - 1, 1)).is_none(),
            "small: the socket"
        );
        assert!(link.place(&body(PLACED_MAX + 1, 1)).is_none(), "too large");
        assert!(link.outlet.carries_alone(4096), "4 KiB: the socket alone");
        // Right after another message, not yet read: a placed message
        // costs no copy a burst or a busy consumer would be spared.
        link.publish(&[1]);
        assert!(
            link.place(&body(1 << 20, 1)).is_some(),
            "past a frame not yet read"
        );
        link.outlet.readers.store(true, Ordering::Relaxed);
        assert!(
            link.place(&body(1 << 20, 1)).is_none(),
            "a subscriber of the topic's own key needs Zenoh's copy"
        );
        assert!(!link.outlet.carries_alone(4096));
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_placed_message_goes_through_zenoh_if_a_reader_came_meanwhile() {
        let session = lone_session().await;
        let mut link = linked(&session, "test/placed/reader").await;
        let message = body(1 << 20, 4);
        let placed = link.place(&message).unwrap();
        let number = link.sequence() + 1;
        // A subscriber of the topic's own key is heard of before the
        // message is sent: it needs Zenoh's copy, and so the consumer gets
        // it under its side key, numbered, not over the link.
        link.outlet.readers.store(true, Ordering::Relaxed);
        link.outlet
            .publish_placed(&link.publisher, placed, ZBytes::from(vec![7u8]))
            .unwrap();
        assert_eq!(link.sequence(), number, "numbered once");
        tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                let copies = link.copies.lock().unwrap().clone();
                if let Some((_, got)) = copies.iter().find(|(n, _)| *n == number) {
                    assert!(got[..] == message[..], "whole, as it was encoded");
                    return;
                }
                drop(copies);
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
        .expect("the message comes under the side key");
        // The link carried nothing of it: the next small message is the
        // next frame after the ones before it.
        link.publish(&[9]);
        let frames = link.frames_until(number + 1);
        assert!(
            frames
                .iter()
                .all(|&(kind, n, _, _)| n != number || kind == FRAME_SIDE),
            "no frame of the placed message: {frames:?}"
        );
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_placed_message_whose_link_ended_goes_under_the_side_key_whole() {
        let session = lone_session().await;
        let link = linked(&session, "test/placed/ended").await;
        let message = body(1 << 20, 9);
        let placed = link.place(&message).unwrap();
        let number = link.sequence() + 1;
        // The consumer goes before the message is sent.
        let Linked {
            outlet,
            publisher,
            reader,
            copies,
            _side,
            ..
        } = link;
        drop(reader);
        outlet
            .publish_placed(&publisher, placed, ZBytes::from(vec![7u8]))
            .unwrap();
        assert_eq!(outlet.links(), 0, "the ended link is closed");
        tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                if let Some((_, got)) = copies.lock().unwrap().iter().find(|(n, _)| *n == number) {
                    assert!(got[..] == message[..], "whole, as it was encoded");
                    return;
                }
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
        .expect("the message comes under the side key");
    }
}
