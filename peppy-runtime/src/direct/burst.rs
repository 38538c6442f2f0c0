//! A sole link's bursts: the messages a producer publishes one right after
//! another go over the link too, gathered into large writes by a thread of
//! the link's own, so a flood costs the producer a copy into memory per
//! message rather than a Zenoh put (or a write of its own) per message.
//!
//! Only a sole link whose consumer reads its side key takes bursts: every
//! message then reaches that consumer through the link or the side key
//! alone, both numbered, and it merges them by number. A message the link
//! cannot take (no room in time, a dropping topic's full pending frames)
//! goes under the side key instead; messages the writer could not write
//! when its link failed are published there too, before the link ends, so
//! none is lost.

use std::io::{ErrorKind, Write};
use std::os::unix::net::UnixStream;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use tracing::{debug, warn};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::sample::SourceInfo;

use super::{FRAME_MESSAGE, HEADER, WRITE_LIMIT, header};

/// How many bytes of frames wait for the writer before a producer waits
/// for room (or, on a topic that drops, sends the message under the side
/// key): about a socket buffer's worth, so the writer always has a whole
/// write ready while the consumer reads the last one.
const PENDING_MAX: usize = 256 * 1024;

/// What a producer told the link about one message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Pushed {
    /// The link carries it.
    Carried,
    /// The link has no room for it: the side key carries it.
    Refused,
    /// The link failed: it is to be closed, and the side key carries this
    /// message and the ones after it.
    Failed,
}

impl Pushed {
    /// Whether the link carries the message, and whether to keep the link.
    pub(crate) fn carried_kept(self) -> (bool, bool) {
        match self {
            Pushed::Carried => (true, true),
            Pushed::Refused => (false, true),
            Pushed::Failed => (false, false),
        }
    }
}

/// Where the link's writer is, as the producer asks before a write of
/// its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Writer {
    /// Nothing pushed waits or is being written: the producer may write
    /// to the link itself.
    Idle,
    /// It has frames to write: a write of the producer's own would
    /// overtake them.
    Busy,
    /// It failed: the link is to be closed.
    Failed,
}

/// A sole link's writer: frames pushed by the producer (under the topic's
/// lock), written in order by the link's own thread.
#[derive(Debug)]
pub(crate) struct Burst {
    shared: Arc<Shared>,
}

#[derive(Debug)]
struct Shared {
    /// Whether the topic drops a message rather than wait for a slow
    /// reader: then a consumer that stops reading does not end the link.
    drops: bool,
    state: Mutex<State>,
    /// Frames were pushed, or the link ends.
    work: Condvar,
    /// The writer took the pending frames.
    room: Condvar,
}

#[derive(Debug, Default)]
struct State {
    /// Whole frames not yet taken by the writer.
    pending: Vec<u8>,
    /// The writer holds frames it took and has not written yet.
    writing: bool,
    /// The writer failed: nothing more is pushed.
    failed: bool,
    /// The link ended: the writer writes what is pending, then stops.
    stop: bool,
    /// The writer's thread is done.
    exited: bool,
}

/// Where a failed writer publishes what it could not write.
pub(crate) struct SideCopies {
    /// The side key's publisher.
    pub(crate) publisher: Arc<Publisher<'static>>,
    /// The topic's attachment, which every copy carries.
    pub(crate) attachment: ZBytes,
}

impl Burst {
    /// Starts the writer of the link on `stream` (non-blocking, shared with
    /// the producer's own writes, which it makes only while
    /// [`Writer::Idle`]), for `consumer` (for the log).
    pub(crate) fn start(
        stream: Arc<UnixStream>,
        side: SideCopies,
        consumer: String,
        drops: bool,
    ) -> std::io::Result<Burst> {
        let shared = Arc::new(Shared {
            drops,
            state: Mutex::new(State::default()),
            work: Condvar::new(),
            room: Condvar::new(),
        });
        let writer = shared.clone();
        std::thread::Builder::new()
            .name("peppy-link".into())
            .spawn(move || {
                writer.run(&stream, &side, &consumer);
                if let Ok(mut state) = writer.state.lock() {
                    state.exited = true;
                }
                writer.room.notify_all();
            })?;
        Ok(Burst { shared })
    }

    /// Ends the link: the writer writes what is pending, then stops.
    pub(crate) fn end(&self) {
        if let Ok(mut state) = self.shared.state.lock() {
            state.stop = true;
        }
        self.shared.work.notify_one();
    }

    /// Waits, up to `deadline`, for the writer of an ended link to be
    /// done: the pending frames written, or published under the side key
    /// if the consumer reads nothing (the node stops, and closes its
    /// session next).
    pub(crate) fn wait_done(&self, deadline: Instant) {
        let Ok(mut state) = self.shared.state.lock() else {
            return;
        };
        while !state.exited {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return;
            }
            state = match self.shared.room.wait_timeout(state, left) {
                Ok((state, _)) => state,
                Err(_) => return,
            };
        }
    }

    /// Where the writer is. A writer that failed holds the lock until it
    /// has published what it had not written, so a message the producer
    /// sends under the side key after asking comes after those.
    pub(crate) fn writer(&self) -> Writer {
        match self.shared.state.lock() {
            Err(_) => Writer::Failed,
            Ok(s) if s.failed => Writer::Failed,
            Ok(s) if s.pending.is_empty() && !s.writing => Writer::Idle,
            Ok(_) => Writer::Busy,
        }
    }

    /// Pushes message `number` for the writer. With no room, a topic that
    /// never drops waits for the writer to take what is pending, or to
    /// fail (within [`WRITE_LIMIT`] of its last progress), up to twice
    /// that limit.
    pub(crate) fn push(&self, number: u32, body: &[u8], may_drop: bool) -> Pushed {
        let Ok(mut state) = self.shared.state.lock() else {
            return Pushed::Failed;
        };
        // Read only when there is no room: the clock costs a flood of
        // small messages a share of its rate on a virtual machine.
        let mut deadline = None;
        while !state.failed && state.pending.len() >= PENDING_MAX {
            if may_drop {
                return Pushed::Refused;
            }
            let until = *deadline.get_or_insert_with(|| Instant::now() + 2 * WRITE_LIMIT);
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Pushed::Refused;
            }
            state = match self.shared.room.wait_timeout(state, left) {
                Ok((state, _)) => state,
                Err(_) => return Pushed::Failed,
            };
        }
        if state.failed {
            return Pushed::Failed;
        }
        let wake = state.pending.is_empty() && !state.writing;
        state.pending.reserve(HEADER + body.len());
        state
            .pending
            .extend_from_slice(&header(FRAME_MESSAGE, number, body.len() as u32));
        state.pending.extend_from_slice(body);
        drop(state);
        if wake {
            self.shared.work.notify_one();
        }
        Pushed::Carried
    }
}

impl Drop for Burst {
    /// The link ends: the writer writes what is pending, then stops (the
    /// consumer reads the rest of the link, then goes back to Zenoh).
    fn drop(&mut self) {
        self.end();
    }
}

impl Shared {
    /// The writer's thread: takes what is pending and writes it, until the
    /// link ends or a write fails.
    fn run(&self, stream: &UnixStream, side: &SideCopies, consumer: &str) {
        let mut frames = Vec::new();
        loop {
            let Some(state) = self.next(&mut frames) else {
                return;
            };
            drop(state);
            self.room.notify_one();
            let Err((written, end)) = self.write_all(stream, &frames) else {
                frames.clear();
                continue;
            };
            // The link failed: what the consumer will not read goes under
            // the side key, in order, before the socket is shut (finding
            // the link closed, the consumer goes back to the topic's own
            // key, where a newer message must not come before these). The
            // lock is held meanwhile: the producer, which asks it before
            // anything under the side key, waits.
            let mut state = match self.state.lock() {
                Ok(state) => state,
                Err(e) => e.into_inner(),
            };
            let rest = std::mem::take(&mut state.pending);
            let unwritten = unwritten_frames(&frames, written).chain(unwritten_frames(&rest, 0));
            let (mut published, mut lost) = (0_usize, 0_usize);
            let mut error = None;
            for (number, body) in unwritten {
                if error.is_some() {
                    // The session is closing (the node stops): the rest
                    // would fail alike.
                    lost += 1;
                    continue;
                }
                match side
                    .publisher
                    .put(body.to_vec())
                    .attachment(side.attachment.clone())
                    .source_info(SourceInfo::new(side.publisher.id(), number))
                    .wait()
                {
                    Ok(()) => published += 1,
                    Err(e) => {
                        lost += 1;
                        error = Some(e);
                    }
                }
            }
            state.failed = true;
            state.writing = false;
            drop(state);
            self.room.notify_all();
            let _ = stream.shutdown(std::net::Shutdown::Write);
            match (error, end) {
                (None, End::Stalled) => warn!(
                    consumer,
                    published,
                    "closing a direct link: its consumer read nothing for {WRITE_LIMIT:?}; what the link had not written went under its side key, and the consumer reads this topic through Zenoh alone"
                ),
                (None, End::Gone | End::Ended) => debug!(
                    consumer,
                    published,
                    "a direct link ended: what it had not written went under its side key"
                ),
                (Some(e), _) => warn!(
                    consumer,
                    published,
                    lost,
                    error = %e,
                    "a direct link failed, and some of what it had not written could not go under its side key either"
                ),
            }
            return;
        }
    }

    /// Waits for pending frames and takes them into `frames` (the lock
    /// still held, `writing` set); `None` when the link ended with
    /// nothing pending.
    fn next(&self, frames: &mut Vec<u8>) -> Option<MutexGuard<'_, State>> {
        let mut state = self.state.lock().ok()?;
        state.writing = false;
        loop {
            if !state.pending.is_empty() {
                std::mem::swap(&mut state.pending, frames);
                state.writing = true;
                return Some(state);
            }
            if state.stop {
                return None;
            }
            state = self.work.wait(state).ok()?;
        }
    }
}

/// Why a link's writer stopped before writing everything.
#[derive(Debug, Clone, Copy)]
enum End {
    /// The consumer closed the link (or the socket failed).
    Gone,
    /// The consumer of a topic that never drops read nothing for
    /// [`WRITE_LIMIT`].
    Stalled,
    /// The link ended (the producer dropped it) while the consumer read
    /// nothing.
    Ended,
}

impl Shared {
    /// Writes `bytes` to the non-blocking `stream`, waiting for room while
    /// the consumer reads on; on a topic that drops, also while it does
    /// not, until the link ends. Else how many bytes were written, and
    /// why no more.
    fn write_all(&self, mut stream: &UnixStream, bytes: &[u8]) -> Result<(), (usize, End)> {
        let mut done = 0;
        let mut since = Instant::now();
        while done < bytes.len() {
            match stream.write(&bytes[done..]) {
                Ok(0) => return Err((done, End::Gone)),
                Ok(n) => {
                    done += n;
                    since = Instant::now();
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    let left = WRITE_LIMIT.saturating_sub(since.elapsed());
                    if writable(stream, left.max(Duration::from_millis(1))) {
                        continue;
                    }
                    if self.state.lock().map_or(true, |s| s.stop) {
                        return Err((done, End::Ended));
                    }
                    if !self.drops && since.elapsed() >= WRITE_LIMIT {
                        return Err((done, End::Stalled));
                    }
                    if self.drops {
                        // What the producer pushes meanwhile goes under the
                        // side key; this waits for the reader, a limit at a
                        // time, noticing the link's end.
                        since = Instant::now();
                    }
                }
                Err(_) => return Err((done, End::Gone)),
            }
        }
        Ok(())
    }
}

/// Waits up to `limit` for room in `stream`.
fn writable(stream: &UnixStream, limit: Duration) -> bool {
    use std::os::fd::AsRawFd;
    let mut poll = libc::pollfd {
        fd: stream.as_raw_fd(),
        events: libc::POLLOUT,
        revents: 0,
    };
    let ms = libc::c_int::try_from(limit.as_millis().max(1)).unwrap_or(libc::c_int::MAX);
    // SAFETY: one pollfd, a live local, for the stream's own descriptor.
    let ready = unsafe { libc::poll(&mut poll, 1, ms) };
    ready > 0 && poll.revents & libc::POLLOUT != 0
}

/// The messages of the whole frames in `frames` that start at or after
/// `written` bytes, or that began before it and were cut there: the
/// consumer reads only whole frames.
fn unwritten_frames(frames: &[u8], written: usize) -> impl Iterator<Item = (u32, &[u8])> {
    let mut at = 0;
    std::iter::from_fn(move || {
        loop {
            let head = frames.get(at..at + HEADER)?;
            let number = u32::from_le_bytes([head[1], head[2], head[3], head[4]]);
            let len = u32::from_le_bytes([head[5], head[6], head[7], head[8]]) as usize;
            let body = frames.get(at + HEADER..at + HEADER + len)?;
            let end = at + HEADER + len;
            at = end;
            if end > written {
                return Some((number, body));
            }
        }
    })
}

#[cfg(test)]
pub(super) mod tests {
    use std::io::Read;
    use std::time::Duration;

    use super::*;

    /// A session of its own, reaching nothing: a side key's copies come
    /// back to its own subscriber.
    pub(in crate::direct) async fn lone_session() -> zenoh::Session {
        let mut config = zenoh::Config::default();
        for (key, value) in [
            ("mode", r#""peer""#),
            ("listen/endpoints", "[]"),
            ("scouting/multicast/enabled", "false"),
            ("transport/shared_memory/enabled", "false"),
        ] {
            config.insert_json5(key, value).unwrap();
        }
        zenoh::open(config).await.unwrap()
    }

    /// The numbers of the whole frames in `bytes`, checking each body.
    fn whole_numbers(bytes: &[u8]) -> Vec<u32> {
        unwritten_frames(bytes, 0)
            .map(|(number, body)| {
                assert_eq!(body, &body_of(number)[..], "frame {number}'s body");
                number
            })
            .collect()
    }

    fn body_of(number: u32) -> Vec<u8> {
        let len = 1 + (number as usize * 131) % 1500;
        (0..len).map(|i| (number as usize + i) as u8).collect()
    }

    /// A link's writer on one end of a socket pair, its side key `key`:
    /// the writer and the reader's end.
    async fn linked(session: &zenoh::Session, key: &str, drops: bool) -> (Burst, UnixStream) {
        let (producer, reader) = UnixStream::pair().unwrap();
        producer.set_nonblocking(true).unwrap();
        let side = SideCopies {
            publisher: Arc::new(session.declare_publisher(key.to_string()).await.unwrap()),
            attachment: ZBytes::from(vec![7_u8]),
        };
        let burst = Burst::start(Arc::new(producer), side, "core/sink".into(), drops).unwrap();
        (burst, reader)
    }

    /// The numbers of the copies published under `key`, as they come,
    /// each checked for its body and attachment; the subscriber lives as
    /// long as the first.
    async fn side_copies(
        session: &zenoh::Session,
        key: &str,
    ) -> (zenoh::pubsub::Subscriber<()>, Arc<Mutex<Vec<u32>>>) {
        let copies = Arc::new(Mutex::new(Vec::new()));
        let seen = copies.clone();
        let subscriber = session
            .declare_subscriber(key.to_string())
            .callback(move |sample| {
                let info = sample.source_info().expect("a side copy is numbered");
                assert_eq!(sample.payload().to_bytes(), &body_of(info.source_sn())[..]);
                assert_eq!(sample.attachment().unwrap().to_bytes(), &[7_u8][..]);
                seen.lock().unwrap().push(info.source_sn());
            })
            .await
            .unwrap();
        (subscriber, copies)
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_burst_reaches_the_reader_whole_and_in_order_and_the_rest_on_drop() {
        let session = lone_session().await;
        let (burst, mut reader) = linked(&session, "test/burst/whole", false).await;
        let reading = std::thread::spawn(move || {
            let mut bytes = Vec::new();
            reader.read_to_end(&mut bytes).unwrap();
            bytes
        });
        for number in 1..=20_000 {
            assert_eq!(burst.push(number, &body_of(number), false), Pushed::Carried);
        }
        // Dropped with frames still pending: they are written before the
        // writer stops and the socket closes.
        drop(burst);
        let bytes = tokio::task::spawn_blocking(move || reading.join().unwrap())
            .await
            .unwrap();
        assert_eq!(whole_numbers(&bytes), (1..=20_000).collect::<Vec<_>>());
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn what_a_stalled_reader_never_got_goes_under_the_side_key_once() {
        let session = lone_session().await;
        let key = "test/burst/stalled";
        let (_subscriber, copies) = side_copies(&session, key).await;
        let (burst, mut reader) = linked(&session, key, false).await;
        // The reader reads nothing: the socket fills, then what is pending,
        // and the writer gives up after the limit.
        let mut carried = Vec::new();
        let pushing = tokio::task::spawn_blocking(move || {
            for number in 1.. {
                match burst.push(number, &body_of(number), false) {
                    Pushed::Carried => carried.push(number),
                    Pushed::Refused => panic!("a topic that never drops waits, then fails"),
                    Pushed::Failed => return (carried, burst),
                }
            }
            unreachable!()
        });
        let (carried, burst) = tokio::time::timeout(Duration::from_secs(10), pushing)
            .await
            .expect("the writer gives up within its limit")
            .unwrap();
        assert_eq!(burst.writer(), Writer::Failed);
        assert!(carried.len() > 200, "{} carried", carried.len());
        // The link's whole frames, then its end (the writer shut it).
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).unwrap();
        let over_link = whole_numbers(&bytes);
        assert!(!over_link.is_empty());
        // A session hands its own subscriber a put before the put returns:
        // every side copy is out by the time the link ends.
        let side_copies = copies.lock().unwrap().clone();
        assert!(
            !side_copies.is_empty(),
            "what was pending went under the side key"
        );
        let mut every = over_link.clone();
        every.extend(&side_copies);
        assert_eq!(every, carried, "each once, the link's first, in order");
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn an_ended_link_of_a_stalled_reader_hands_its_rest_to_the_side_key_in_time() {
        let session = lone_session().await;
        let key = "test/burst/ended";
        let (_subscriber, copies) = side_copies(&session, key).await;
        let (burst, mut reader) = linked(&session, key, false).await;
        // More than the socket holds, less than the pending frames' room.
        let carried: Vec<u32> = (1..=450).collect();
        for &number in &carried {
            assert_eq!(burst.push(number, &body_of(number), false), Pushed::Carried);
        }
        // The node stops: its writer gives up on the reader within the
        // limit and is done before the session would close.
        let began = Instant::now();
        burst.end();
        burst.wait_done(Instant::now() + Duration::from_secs(5));
        assert!(began.elapsed() < WRITE_LIMIT * 3, "{:?}", began.elapsed());
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).unwrap();
        let mut every = whole_numbers(&bytes);
        let side_copies = copies.lock().unwrap().clone();
        assert!(!side_copies.is_empty(), "some were still pending");
        every.extend(side_copies);
        assert_eq!(every, carried);
    }

    fn frames(messages: &[(u32, &[u8])]) -> Vec<u8> {
        let mut out = Vec::new();
        for (number, body) in messages {
            out.extend_from_slice(&header(FRAME_MESSAGE, *number, body.len() as u32));
            out.extend_from_slice(body);
        }
        out
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_dropping_topic_keeps_its_link_through_a_stalled_reader() {
        let session = lone_session().await;
        let (burst, mut reader) = linked(&session, "test/burst/dropping", true).await;
        // The reader reads nothing: once the socket and the pending frames
        // are full, what comes is refused at once (it goes under the side
        // key), and the link stays.
        let mut carried = Vec::new();
        let mut number = 0;
        let began = Instant::now();
        loop {
            number += 1;
            match burst.push(number, &body_of(number), true) {
                Pushed::Carried => carried.push(number),
                Pushed::Refused => break,
                Pushed::Failed => panic!("a full link of a dropping topic refuses"),
            }
            assert!(began.elapsed() < Duration::from_secs(5), "never full");
        }
        assert!(carried.len() > 200, "{} carried", carried.len());
        tokio::time::sleep(WRITE_LIMIT * 2).await;
        assert_ne!(
            burst.writer(),
            Writer::Failed,
            "a stalled reader of a dropping topic does not end its link"
        );
        // The reader reads on: every carried frame, in order, then more.
        let more = number + 1;
        let reading = std::thread::spawn(move || {
            let mut bytes = Vec::new();
            reader.read_to_end(&mut bytes).unwrap();
            bytes
        });
        let deadline = Instant::now() + Duration::from_secs(5);
        while burst.push(more, &body_of(more), true) != Pushed::Carried {
            assert!(
                Instant::now() < deadline,
                "room again once the reader reads"
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        carried.push(more);
        drop(burst);
        let bytes = tokio::task::spawn_blocking(move || reading.join().unwrap())
            .await
            .unwrap();
        assert_eq!(whole_numbers(&bytes), carried);
    }

    #[test]
    fn what_a_cut_write_left_is_every_frame_not_written_whole() {
        let all = frames(&[(1, b"ab"), (2, b""), (3, b"cdef")]);
        let numbers = |written| {
            unwritten_frames(&all, written)
                .map(|(n, body)| (n, body.to_vec()))
                .collect::<Vec<_>>()
        };
        assert_eq!(numbers(0).len(), 3);
        // Cut inside the first frame: it is not whole at the consumer.
        assert_eq!(numbers(HEADER + 1)[0], (1, b"ab".to_vec()));
        // The first written whole; the second (empty) cut in its header.
        assert_eq!(
            numbers(HEADER + 2 + 1),
            vec![(2, vec![]), (3, b"cdef".to_vec())]
        );
        assert_eq!(numbers(2 * HEADER + 2), vec![(3, b"cdef".to_vec())]);
        assert!(numbers(all.len()).is_empty());
    }
}
