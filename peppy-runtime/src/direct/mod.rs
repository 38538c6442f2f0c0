//! Direct links: topic messages handed between two instances of one
//! launch on one host over a Unix socket of their own, beside Zenoh.
//!
//! Zenoh stays the one engine: every message is still published through
//! it whenever it has a subscriber (other consumers, other hosts,
//! inspection tools and Python nodes get it there), and discovery,
//! routing, formats and security are Zenoh's as before. What a direct link removes is the cost of a small message on
//! one host: Zenoh hands it from the publishing task to its transmit
//! queue, a link task, the socket, the receiving link task, the
//! subscription callback and the reader's task, each hand-off a thread
//! wake-up. Over a direct link the publishing task writes the message into
//! the consumer's socket itself and the consumer's reading task is woken
//! by that socket (docs/PERFORMANCE.md, "The hand-off floor, and links on
//! one host"; docs/WIRE.md, "Direct links").
//!
//! How a consumer comes to read a producer directly, without losing,
//! doubling or reordering a message:
//!
//! 1. A producer with direct links numbers every message of each emitted
//!    topic; a message it also writes to a link carries its number in its
//!    Zenoh copy's source info, the others go without (in a flood that
//!    would cost a quarter of the rate) and are counted by the consumer.
//! 2. The first message a consumed topic receives through Zenoh from a
//!    producer makes the consumer connect to that producer's socket in the
//!    launch's directory (named after its core node and instance:
//!    [`socket_path`]). No socket (a producer of another launch, host or
//!    language) leaves that producer on Zenoh.
//! 3. The consumer names the key it reads ([`Hello`]). The producer,
//!    holding the topic's lock (so no message is published meanwhile),
//!    answers with the publisher's id its Zenoh copies carry, and adds the
//!    link.
//! 4. From then on a message goes over the link too, unless it follows
//!    the end of the topic's previous publication within [`BURST_GAP`]
//!    and a little more the larger it is (in a burst, Zenoh's batching
//!    moves more), or it is 16 KiB or more and the consumer has not read
//!    the link's last frames yet (`outlet`). Below 16 KiB the socket
//!    carries it; from 16 KiB to 384 KiB (on Linux) the link's own
//!    shared memory does, the socket carrying only where it is
//!    (`segment`). A larger message goes through Zenoh alone, through
//!    its shared memory. A sole link (below) takes a burst's small
//!    messages too, gathered into large writes by a thread of its own
//!    (`burst`): a flood then costs the producer a copy per message. A consumer instance has one link per producer
//!    key, shared by its entries on that key, and links only the
//!    producers its slots route to it.
//! 5. The consumer merges the two by number (`inlet`): whichever copy of
//!    the next message comes first is handed on, the other dropped; a link
//!    message ahead of it waits until Zenoh has brought those before it.
//!    A consumer whose entry is pinned to the producer asks for a *sole*
//!    link: the producer publishes what the link does not carry under the
//!    consumer's [`side_key`] too, and the consumer moves its
//!    subscription there (`feed`), so Zenoh no longer brings it a copy of
//!    what the link carried; with no subscriber of the topic's own key
//!    left, the producer does not publish there.
//! 6. When the link breaks (the producer stopped, a write timed out) Zenoh
//!    alone goes on (a sole link's consumer subscribes to the topic's key
//!    again first), counted as before; a message from another
//!    publisher under the same key (the producer restarted) starts the
//!    numbers afresh and links the new one.

pub(crate) mod burst;
pub(crate) mod feed;
pub(crate) mod inlet;
pub(crate) mod outlet;
#[cfg(target_os = "linux")]
pub(crate) mod segment;

use std::path::{Path, PathBuf};
use std::time::Duration;

/// Where a link has no shared memory (not Linux, or its segment could
/// not be made), messages of this size or more travel through Zenoh alone
/// (its shared memory on one host carries them without a copy). Below it
/// the socket is faster: measured round trips over a link against Zenoh's
/// shared memory were 76 to 97 µs against 150 µs at 64 KiB, and no faster
/// at 128 KiB (a socket buffer holds about 200 KiB; a larger message is
/// written in several turns, each a wake-up). It is also the longest
/// message frame a consumer reads.
pub(crate) const INLINE_MAX: usize = 128 * 1024;

/// How long a link's message waits for the messages before it to come
/// through Zenoh, on a topic that never drops, before going on without
/// them.
pub(crate) const HOLD_LIMIT: Duration = Duration::from_secs(2);

/// A message published sooner than this after the topic's previous one
/// goes through Zenoh alone: in a burst Zenoh's batching moves more
/// messages than a write per message could, and a reader waiting for one
/// message at a time is not in a burst.
pub(crate) const BURST_GAP: Duration = Duration::from_micros(20);

/// How long a producer waits for a consumer to make room in its socket
/// for a message of a topic that never drops (or for the rest of a frame
/// it began), before closing the link (the consumer then reads that topic
/// through Zenoh again, and is linked again once it reads on). Zenoh
/// carries every message too, so a link is only a shortcut, and the wait
/// holds the topic's other consumers with the producer: a consumer that
/// stopped reading was seen to hold them all for the whole wait when it
/// was 10 s (docs/FAULTS.md, L4).
pub(crate) const WRITE_LIMIT: Duration = Duration::from_millis(250);

/// The first bytes of a consumer's hello.
const MAGIC: &[u8; 4] = b"PPYD";

/// The version of the direct link's framing: 2 added shared frames, 3
/// the hello's `sole` flag. A producer still reads a hello of version 2.
const VERSION: u8 = 3;

/// The oldest hello a producer reads.
const OLDEST_VERSION: u8 = 2;

/// A frame's kind: a message follows.
pub(crate) const FRAME_MESSAGE: u8 = 0;

/// A frame's kind: the message is in the link's shared memory, at the
/// offset (`u32` little-endian) that follows the header.
pub(crate) const FRAME_SHARED: u8 = 2;

/// A frame's kind, with no message: from the number it carries on, every
/// message the link does not carry goes to the consumer's side key (the
/// producer has seen its subscription there), so once the consumer has
/// every message before it, it can leave the topic's own key.
pub(crate) const FRAME_SIDE: u8 = 3;

/// A shared frame: the header, then the message's offset.
pub(crate) const SHARED_HEADER: usize = HEADER + 4;

/// A frame's header: its kind, the message's number (the one its Zenoh
/// copy carries in its source info), and the length of the message that
/// follows, both `u32` little-endian.
pub(crate) const HEADER: usize = 9;

/// Which publisher a Zenoh sample comes from: its session's id and the
/// publisher's number in it (Zenoh's `EntityGlobalId`, which peppy cannot
/// build from its parts).
pub(crate) type SourceId = ([u8; 16], u32);

/// The source id of a publisher or a sample's source info.
pub(crate) fn source_id(id: &zenoh::session::EntityGlobalId) -> SourceId {
    (id.zid().to_le_bytes(), id.eid())
}

/// The socket a node listens on for direct links, in its launch's
/// directory: named by a hash of its core node and instance, since an
/// instance id can be longer than a socket path allows.
pub(crate) fn socket_path(dir: &Path, core: &str, instance: &str) -> PathBuf {
    let hash = fnv(core.bytes().chain([0]).chain(instance.bytes()));
    dir.join(format!("d{hash:016x}.sock"))
}

/// A consumer's request for a direct link.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Hello {
    /// The topic key the consumer reads from this producer.
    pub(crate) key: String,
    /// Who asks (`<core node>/<instance>`), for the producer's log.
    pub(crate) consumer: String,
    /// Whether the consumer maps a segment of shared memory for the link
    /// (its node's shared memory is on).
    pub(crate) shared: bool,
    /// Whether the consumer reads this producer through the link and the
    /// producer's side key alone once linked (its entry is pinned to the
    /// producer): the producer then publishes every message the link does
    /// not carry under [`side_key`] too.
    pub(crate) sole: bool,
}

impl Hello {
    /// The longest hello a producer reads.
    pub(crate) const MAX: usize = 4096;

    /// The hello as sent: its length (`u16`, little-endian), then it:
    /// the magic, the version, the two strings and a flags byte (bit 0:
    /// [`Hello::shared`], bit 1: [`Hello::sole`]).
    pub(crate) fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(11 + self.key.len() + self.consumer.len());
        out.extend_from_slice(&[0, 0]);
        out.extend_from_slice(MAGIC);
        out.push(VERSION);
        for text in [&self.key, &self.consumer] {
            out.extend_from_slice(&(text.len().min(Self::MAX) as u16).to_le_bytes());
            out.extend_from_slice(&text.as_bytes()[..text.len().min(Self::MAX)]);
        }
        out.push(u8::from(self.shared) | u8::from(self.sole) << 1);
        let len = (out.len() - 2).min(usize::from(u16::MAX)) as u16;
        out[..2].copy_from_slice(&len.to_le_bytes());
        out
    }

    /// Decodes a whole hello (after its length); `None` for anything
    /// malformed.
    pub(crate) fn decode(bytes: &[u8]) -> Option<Hello> {
        let rest = bytes.strip_prefix(MAGIC)?;
        let (&version, mut rest) = rest.split_first()?;
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return None;
        }
        let mut text = || -> Option<String> {
            let n = u16::from_le_bytes(rest.get(..2)?.try_into().ok()?) as usize;
            let s = std::str::from_utf8(rest.get(2..2 + n)?).ok()?.to_string();
            rest = &rest[2 + n..];
            Some(s)
        };
        let key = text()?;
        let consumer = text()?;
        let (&flags, rest) = rest.split_first()?;
        let known = if version == OLDEST_VERSION { 1 } else { 3 };
        (rest.is_empty() && flags <= known).then_some(Hello {
            key,
            consumer,
            shared: flags & 1 == 1,
            sole: flags & 2 == 2,
        })
    }
}

/// The key a producer publishes a topic's messages under, beside its own,
/// for the consumer (`<core node>/<instance>`) that reads it through a
/// sole link and this key alone: what the link does not carry. One of its
/// chunks is verbatim (`@direct`), so no wildcard subscription of the
/// topic (`*`, `**`) matches it: only the consumer that names it gets
/// these copies.
pub(crate) fn side_key(key: &str, consumer: &str) -> String {
    format!("{key}/@direct/{:016x}", fnv(consumer.bytes()))
}

/// FNV-1a: the same hash in every process, whatever its build.
fn fnv(bytes: impl Iterator<Item = u8>) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in bytes {
        hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
    }
    hash
}

/// A frame's header.
pub(crate) fn header(kind: u8, sequence: u32, len: u32) -> [u8; HEADER] {
    let mut out = [kind, 0, 0, 0, 0, 0, 0, 0, 0];
    out[1..5].copy_from_slice(&sequence.to_le_bytes());
    out[5..].copy_from_slice(&len.to_le_bytes());
    out
}

/// The producer's answer to a hello that names one of its topics: `0`,
/// the topic's attachment (a length byte, then it), and the source id its
/// Zenoh copies carry (the session's id, then the publisher's number,
/// `u32` little-endian).
pub(crate) fn answer(attachment: &[u8], source: SourceId) -> Vec<u8> {
    let mut out = vec![0, attachment.len() as u8];
    out.extend_from_slice(attachment);
    out.extend_from_slice(&source.0);
    out.extend_from_slice(&source.1.to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hello_decodes_to_itself_and_nothing_else_decodes() {
        let hello = Hello {
            key: "peppy/ns/topic/cam/v1/frames/core/cam-1".into(),
            consumer: "core/sink".into(),
            shared: true,
            sole: true,
        };
        let sent = hello.encode();
        assert_eq!(
            usize::from(u16::from_le_bytes([sent[0], sent[1]])),
            sent.len() - 2
        );
        let bytes = sent[2..].to_vec();
        assert_eq!(Hello::decode(&bytes), Some(hello.clone()));
        for cut in 0..bytes.len() {
            assert_eq!(Hello::decode(&bytes[..cut]), None, "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(Hello::decode(&longer), None);
        let mut other = bytes.clone();
        other[4] = VERSION + 1;
        assert_eq!(Hello::decode(&other), None);
        // A hello of version 2 (no `sole` flag) is still read.
        let mut older = bytes.clone();
        older[4] = OLDEST_VERSION;
        *older.last_mut().unwrap() = 1;
        assert_eq!(
            Hello::decode(&older),
            Some(Hello {
                sole: false,
                ..hello
            })
        );
        *older.last_mut().unwrap() = 3;
        assert_eq!(Hello::decode(&older), None, "version 2 knew one flag");
    }

    #[test]
    fn a_side_key_is_matched_by_no_wildcard_of_the_topic() {
        let key = "peppy/ns/topic/cam/v1/frames/core/cam-1";
        let side = zenoh::key_expr::KeyExpr::try_from(side_key(key, "core/sink")).unwrap();
        for wildcard in [
            "peppy/ns/topic/cam/v1/frames/*/*",
            "peppy/ns/topic/cam/v1/frames/*/cam-1",
            "peppy/ns/topic/cam/v1/frames/**",
            "peppy/**",
        ] {
            let wildcard = zenoh::key_expr::KeyExpr::try_from(wildcard).unwrap();
            assert!(!wildcard.intersects(&side), "{wildcard}");
        }
        assert!(side.intersects(&side));
        assert_ne!(side_key(key, "core/sink"), side_key(key, "core/sink-2"));
    }

    #[test]
    fn socket_names_are_short_and_differ_by_instance() {
        let dir = Path::new("/run/peppy-1");
        let a = socket_path(dir, "core", "cam-1");
        let b = socket_path(dir, "core", "cam-2");
        let c = socket_path(dir, "corec", "am-1");
        assert_ne!(a, b);
        assert_ne!(a, c);
        assert_eq!(a, socket_path(dir, "core", "cam-1"));
        assert_eq!(a.file_name().unwrap().len(), "d0123456789abcdef.sock".len());
    }
}
