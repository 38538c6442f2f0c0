//! A direct link's shared memory (Linux): messages of [`SHARED_MIN`]
//! bytes or more are handed to the consumer in place, where a socket
//! would copy them through the kernel twice and Zenoh's path would wake
//! four threads.
//!
//! Each link has a segment of its own: a sealed `memfd` the producer makes
//! when the consumer links and sends with its answer (`SCM_RIGHTS`). The
//! producer copies a message into a free region of it, or encodes it there
//! ([`Ring::reserve`]), and writes a frame naming the region over the
//! socket, which is the consumer's wake-up. The consumer hands the region
//! on as the message's bytes, without a copy, and marks it free when the
//! last handle on those bytes drops. A segment of its own per link means a
//! link that closes takes nothing from any other, and a consumer that still
//! holds a message of a closed link keeps it intact: the producer never
//! writes that segment again.
//!
//! A region is 64 bytes of header (its busy flag first, set by the
//! producer, cleared by the consumer) and the message. The producer
//! reuses regions in the order it gave them; a region held longer than
//! the ones after it (a reader keeping a message) holds those back too,
//! and when nothing fits the message goes through Zenoh alone. The
//! segment is [`CAPACITY`] bytes of address space, and memory is taken
//! as regions are first written (and kept until the link ends). Placing
//! goes back to the segment's beginning whenever the message fits below
//! the oldest region held, so a link whose reader keeps a message or two
//! touches only a few messages' worth, and one whose reader holds more
//! touches at most about [`IN_FLIGHT`] and two messages more.

use std::collections::VecDeque;
use std::io;
use std::num::NonZeroUsize;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, OwnedFd};
use std::ptr::NonNull;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use nix::fcntl::{FcntlArg, SealFlag, fcntl};
use nix::sys::memfd::{MemFdCreateFlag, memfd_create};
use nix::sys::mman::{MapFlags, ProtFlags, mmap, munmap};

/// Messages of this size or more go over a link through its segment;
/// smaller ones through the socket itself.
pub(crate) const SHARED_MIN: usize = 16 * 1024;

/// A segment's size: address space, of which only the regions written
/// take memory (see the module's documentation for how much).
pub(crate) const CAPACITY: usize = 32 << 20;

/// The largest message copied into a segment (one already encoded for
/// Zenoh); a larger one goes through Zenoh alone, unless it is encoded
/// straight into the segment ([`PLACED_MAX`]). The copy costs the producer
/// one Zenoh's shared memory does not, and what a copy costs here moves
/// two- to threefold with the host (docs/PERFORMANCE_HISTORY.md, "The Zenoh
/// copy, floods, and the segment's bound"): with fast copies the segment
/// still won at 1 MiB (round trips of 266 to 273 µs against 279 to 302 µs
/// through Zenoh) and at 256 and 512 KiB, with slow ones it lost from 512
/// KiB (282 to 304 µs against 260 to 274 µs; 1 MiB 766 to 1058 µs against
/// 458 to 539 µs). At 384 KiB it was even with slow copies (227 to 242 µs
/// against 229 to 233 µs), and with fast ones (not measured at 384 KiB) it
/// won on both sides of it.
pub(crate) const MAX_MESSAGE: usize = 3 << 17;

/// The largest message encoded straight into a segment
/// ([`Ring::reserve`]): with no copy of the producer's own, the segment
/// costs no more memory traffic than Zenoh's shared memory at any size, and
/// takes its threads' wake-ups out of the way. A quarter of the segment; a
/// reader that still holds one message this large when the next comes
/// gets that next one through Zenoh (the regions held would pass
/// [`IN_FLIGHT`]).
pub(crate) const PLACED_MAX: usize = CAPACITY / 4;

/// The most bytes of a link's regions held at once: past it, while its
/// reader holds messages, the link's messages go through Zenoh alone.
const IN_FLIGHT: usize = 16 << 20;

/// A region's header: its busy flag, then padding to a cache line.
const REGION_HEAD: usize = 64;

/// Regions start on cache lines.
const ALIGN: usize = 64;

/// One process's mapping of a segment, unmapped when the last holder
/// drops it.
#[derive(Debug)]
pub(crate) struct Mapping {
    base: NonNull<u8>,
    len: usize,
}

// SAFETY: the mapping is plain shared memory. The only state two threads
// (or processes) both write is each region's busy flag, which is only
// ever touched through an `AtomicU32`; a region's bytes are written by the
// producer while the flag says no consumer holds it, and read by the
// consumer only while it holds the region.
unsafe impl Send for Mapping {}
// SAFETY: as for `Send`.
unsafe impl Sync for Mapping {}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `base` and `len` are exactly what `mmap` returned and was
        // given, and nothing borrows the mapping once its last owner drops.
        let _ = unsafe { munmap(self.base.cast(), self.len) };
    }
}

impl Mapping {
    /// Maps all of `fd`, `len` bytes, shared, for reading and writing.
    fn map(fd: BorrowedFd<'_>, len: usize) -> io::Result<Mapping> {
        let size = NonZeroUsize::new(len).ok_or_else(|| io::Error::other("an empty segment"))?;
        // SAFETY: a fresh mapping chosen by the kernel aliases nothing of
        // this process; the file is sealed against shrinking (checked by
        // the consumer, set by the producer), so no access within `len`
        // can fault.
        let base = unsafe {
            mmap(
                None,
                size,
                ProtFlags::PROT_READ | ProtFlags::PROT_WRITE,
                MapFlags::MAP_SHARED,
                fd,
                0,
            )
        }?;
        Ok(Mapping {
            base: base.cast(),
            len,
        })
    }

    /// The busy flag of the region at `offset` (a multiple of [`ALIGN`],
    /// with its header within the mapping: checked by callers).
    fn flag(&self, offset: usize) -> &AtomicU32 {
        debug_assert!(offset.is_multiple_of(ALIGN) && offset + REGION_HEAD <= self.len);
        // SAFETY: in bounds and aligned (above); the flag is only accessed
        // atomically, by either side.
        unsafe { AtomicU32::from_ptr(self.base.as_ptr().add(offset).cast()) }
    }
}

/// The producer's side of a link's segment: where the next message goes,
/// and the regions its consumer may still hold.
#[derive(Debug)]
pub(crate) struct Ring {
    /// Shared with the regions given out and not yet sent ([`Region`]).
    map: Arc<Mapping>,
    /// Regions given out, oldest first: (offset, bytes taken).
    regions: VecDeque<(usize, usize)>,
    /// Where the next region goes when it fits there.
    head: usize,
    /// The bytes of the regions given out.
    held: usize,
}

impl Ring {
    /// Makes a link's segment: the ring, and the descriptor to send the
    /// consumer.
    pub(crate) fn create() -> io::Result<(Ring, OwnedFd)> {
        let flags = MemFdCreateFlag::MFD_CLOEXEC | MemFdCreateFlag::MFD_ALLOW_SEALING;
        let name = c"peppy-direct-link";
        // Not executable: a kernel with `vm.memfd_noexec=2` refuses any
        // other memfd, one before Linux 6.3 does not know the flag.
        let fd = memfd_create(
            name,
            flags | MemFdCreateFlag::from_bits_retain(libc::MFD_NOEXEC_SEAL),
        )
        .or_else(|_| memfd_create(name, flags))?;
        nix::unistd::ftruncate(&fd, CAPACITY as i64)?;
        // Sealed at its size: a consumer maps all of it without a fault to
        // fear, whatever the producer does later.
        fcntl(
            fd.as_raw_fd(),
            FcntlArg::F_ADD_SEALS(
                SealFlag::F_SEAL_SHRINK | SealFlag::F_SEAL_GROW | SealFlag::F_SEAL_SEAL,
            ),
        )?;
        let map = Arc::new(Mapping::map(fd.as_fd(), CAPACITY)?);
        let ring = Ring {
            map,
            regions: VecDeque::new(),
            head: 0,
            held: 0,
        };
        Ok((ring, fd))
    }

    /// Copies `bytes` into a free region, marked held: its offset, or
    /// `None` when no region is free for it (the consumer holds too much).
    pub(crate) fn put(&mut self, bytes: &[u8]) -> Option<u32> {
        if bytes.len() > MAX_MESSAGE {
            return None;
        }
        let mut region = self.reserve(bytes.len())?;
        region.bytes_mut().copy_from_slice(bytes);
        region.filled();
        Some(region.sent())
    }

    /// Takes a free region of `len` bytes (at most [`PLACED_MAX`]), marked
    /// held, for its holder to fill ([`Region::bytes_mut`]) and mark
    /// [filled](Region::filled): `None` when no region is free for it. A
    /// region dropped before it is [sent](Region::sent) is free again.
    pub(crate) fn reserve(&mut self, len: usize) -> Option<Region> {
        if len > PLACED_MAX {
            return None;
        }
        self.reclaim();
        let size = (REGION_HEAD + len).next_multiple_of(ALIGN);
        if self.held > 0 && self.held + size > IN_FLIGHT {
            return None;
        }
        let offset = self.place(size)?;
        let region = Region {
            map: self.map.clone(),
            offset: u32::try_from(offset).ok()?,
            len,
            sent: false,
        };
        // Held before it is written: dropped unfilled, it is let go like
        // any region its consumer is done with, and never reclaimed before.
        self.map.flag(offset).store(1, Ordering::Relaxed);
        self.regions.push_back((offset, size));
        self.held += size;
        self.head = offset + size;
        Some(region)
    }

    /// Frees the region at `offset`, which its consumer never got (the
    /// frame naming it was not written).
    pub(crate) fn unput(&mut self, offset: u32) {
        let offset = offset as usize;
        if self.regions.iter().any(|&(o, _)| o == offset) {
            self.map.flag(offset).store(0, Ordering::Release);
        }
    }

    /// Takes back the oldest regions the consumer let go of.
    fn reclaim(&mut self) {
        while let Some(&(offset, size)) = self.regions.front() {
            if self.map.flag(offset).load(Ordering::Acquire) != 0 {
                break;
            }
            self.regions.pop_front();
            self.held -= size;
        }
        if self.regions.is_empty() {
            // Nothing held: start again at the beginning, so a reader that
            // keeps up keeps touching the same memory.
            self.head = 0;
        }
    }

    /// Where a region of `size` bytes fits after the newest: back at the
    /// beginning when it fits below the oldest region held (the memory
    /// already touched), else after the newest.
    fn place(&self, size: usize) -> Option<usize> {
        let Some(&(tail, _)) = self.regions.front() else {
            return (size <= CAPACITY).then_some(0);
        };
        if self.head > tail {
            if size <= tail {
                Some(0)
            } else {
                (self.head + size <= CAPACITY).then_some(self.head)
            }
        } else {
            (self.head + size <= tail).then_some(self.head)
        }
    }
}

/// A region the producer holds and has not yet named to its consumer: it
/// fills the region, marks it [filled](Region::filled), then writes its
/// frame and marks it [sent](Region::sent). Dropped unsent, it is let go.
#[derive(Debug)]
pub(crate) struct Region {
    map: Arc<Mapping>,
    offset: u32,
    len: usize,
    sent: bool,
}

impl Region {
    /// Where it is in the segment.
    pub(crate) fn offset(&self) -> u32 {
        self.offset
    }

    /// Its message's length.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// Where its message starts in this process's mapping.
    fn start(&self) -> *mut u8 {
        // SAFETY: `Ring::reserve` placed the region, header and message,
        // within the mapping.
        unsafe {
            self.map
                .base
                .as_ptr()
                .add(self.offset as usize + REGION_HEAD)
        }
    }

    /// Its bytes, to fill: no one else writes or reads them until it is
    /// sent.
    pub(crate) fn bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: within the mapping (`Ring::reserve`), which `map` keeps
        // alive; held (its flag set), so the producer's ring gives it to no
        // one else, and unsent, so no consumer has been told of it; `&mut
        // self` makes this the only view of it in this process.
        unsafe { std::slice::from_raw_parts_mut(self.start(), self.len) }
    }

    /// Marks its bytes written: the consumer that sees its flag set sees
    /// them (the flag's release).
    pub(crate) fn filled(&self) {
        self.map
            .flag(self.offset as usize)
            .store(1, Ordering::Release);
    }

    /// Its message.
    pub(crate) fn bytes(&self) -> &[u8] {
        // SAFETY: within the mapping (`Ring::reserve`), which `map` keeps
        // alive; held, so no one else writes it.
        unsafe { std::slice::from_raw_parts(self.start(), self.len) }
    }

    /// Its frame is written: the consumer lets it go from now on. Its
    /// offset.
    pub(crate) fn sent(mut self) -> u32 {
        self.sent = true;
        self.offset
    }
}

impl Drop for Region {
    fn drop(&mut self) {
        if !self.sent {
            self.map
                .flag(self.offset as usize)
                .store(0, Ordering::Release);
        }
    }
}

/// The consumer's side of a link's segment.
#[derive(Debug, Clone)]
pub(crate) struct Segment(Arc<Mapping>);

impl Segment {
    /// Maps the segment a producer sent: a sealed memory file that cannot
    /// shrink (so reading it can never fault), of a sensible size.
    pub(crate) fn open(fd: OwnedFd) -> io::Result<Segment> {
        let seals = fcntl(fd.as_raw_fd(), FcntlArg::F_GET_SEALS)?;
        let seals = SealFlag::from_bits_truncate(seals);
        if !seals.contains(SealFlag::F_SEAL_SHRINK) {
            return Err(io::Error::other("the segment can shrink"));
        }
        let len = usize::try_from(nix::sys::stat::fstat(fd.as_raw_fd())?.st_size)
            .map_err(io::Error::other)?;
        if !(REGION_HEAD..=4 * CAPACITY).contains(&len) {
            return Err(io::Error::other(format!("a segment of {len} bytes")));
        }
        Ok(Segment(Arc::new(Mapping::map(fd.as_fd(), len)?)))
    }

    /// The message of `len` bytes in the region at `offset`, in place, or
    /// `None` when the frame names no region the producer gave out (a
    /// malformed frame). Its region is let go when the last handle on the
    /// bytes drops.
    pub(crate) fn take(&self, offset: u32, len: u32) -> Option<bytes::Bytes> {
        let (offset, len) = (offset as usize, len as usize);
        let end = offset.checked_add(REGION_HEAD)?.checked_add(len)?;
        if !offset.is_multiple_of(ALIGN) || end > self.0.len {
            return None;
        }
        if self.0.flag(offset).load(Ordering::Acquire) == 0 {
            return None;
        }
        Some(bytes::Bytes::from_owner(Held {
            map: self.0.clone(),
            offset,
            len,
        }))
    }
}

/// A message held in place in a segment.
#[derive(Debug)]
struct Held {
    map: Arc<Mapping>,
    offset: usize,
    len: usize,
}

impl AsRef<[u8]> for Held {
    fn as_ref(&self) -> &[u8] {
        // SAFETY: within the mapping (`Segment::take`), which `map` keeps
        // alive; the producer does not write a region while its flag is
        // set, and this holder clears it only when dropped.
        unsafe {
            std::slice::from_raw_parts(
                self.map.base.as_ptr().add(self.offset + REGION_HEAD),
                self.len,
            )
        }
    }
}

impl Drop for Held {
    fn drop(&mut self) {
        self.map.flag(self.offset).store(0, Ordering::Release);
    }
}

/// Sends `bytes` and `fd` over `stream` in one message, then the rest of
/// `bytes` if the socket took only part.
pub(crate) fn send_with_fd(
    stream: &std::os::unix::net::UnixStream,
    bytes: &[u8],
    fd: BorrowedFd<'_>,
) -> io::Result<()> {
    use nix::sys::socket::{ControlMessage, MsgFlags, sendmsg};
    use std::io::Write;
    let fds = [fd.as_raw_fd()];
    let sent = sendmsg::<()>(
        stream.as_raw_fd(),
        &[io::IoSlice::new(bytes)],
        &[ControlMessage::ScmRights(&fds)],
        MsgFlags::MSG_NOSIGNAL,
        None,
    )?;
    (&*stream).write_all(&bytes[sent..])
}

/// Reads one byte from `stream` (ready to read), and a descriptor sent
/// with it, if any.
pub(crate) fn recv_with_fd(stream: BorrowedFd<'_>) -> io::Result<(u8, Option<OwnedFd>)> {
    use nix::sys::socket::{ControlMessageOwned, MsgFlags, recvmsg};
    use std::os::fd::{FromRawFd, RawFd};
    let mut byte = [0u8; 1];
    // Room for as many descriptors as one message can carry (the kernel's
    // `SCM_MAX_FD`): none is left installed unowned by a truncation.
    let mut space = nix::cmsg_space!([RawFd; 253]);
    let mut iov = [io::IoSliceMut::new(&mut byte)];
    let message = recvmsg::<()>(
        stream.as_raw_fd(),
        &mut iov,
        Some(&mut space),
        MsgFlags::MSG_CMSG_CLOEXEC | MsgFlags::MSG_DONTWAIT,
    )?;
    if message.bytes == 0 {
        return Err(io::ErrorKind::UnexpectedEof.into());
    }
    let mut got = None;
    for cmsg in message.cmsgs()? {
        if let ControlMessageOwned::ScmRights(fds) = cmsg {
            for fd in fds {
                // SAFETY: the kernel just gave this process the descriptor;
                // nothing else owns it.
                let owned = unsafe { OwnedFd::from_raw_fd(fd) };
                // One is expected; any other is closed here.
                got.get_or_insert(owned);
            }
        }
    }
    Ok((byte[0], got))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_region_is_handed_over_in_place_and_reused_once_let_go() {
        let (mut ring, fd) = Ring::create().unwrap();
        let segment = Segment::open(fd).unwrap();
        let first = ring.put(&[7u8; 100_000]).unwrap();
        assert_eq!(first, 0);
        let held = segment.take(first, 100_000).unwrap();
        assert!(held.iter().all(|&b| b == 7));
        // Held: the next goes after it.
        let second = ring.put(&[8u8; 10]).unwrap();
        assert!(second as usize >= 100_000 + REGION_HEAD);
        let second_held = segment.take(second, 10).unwrap();
        drop(held);
        drop(second_held);
        // Both let go: placing starts again at the beginning.
        assert_eq!(ring.put(&[9u8; 10]), Some(0));
    }

    #[test]
    fn a_frame_naming_no_region_or_past_the_end_is_refused() {
        let (mut ring, fd) = Ring::create().unwrap();
        let segment = Segment::open(fd).unwrap();
        assert!(segment.take(0, 10).is_none(), "nothing given out yet");
        let at = ring.put(&[1u8; 10]).unwrap();
        assert!(segment.take(at + 1, 10).is_none(), "misaligned");
        assert!(segment.take(at, u32::MAX).is_none(), "past the end");
        assert!(
            segment.take(CAPACITY as u32 - 64, 10).is_none(),
            "header at the end, message past it"
        );
        assert!(segment.take(at, 10).is_some());
    }

    #[test]
    fn a_reader_holding_too_much_sends_the_rest_through_zenoh() {
        let (mut ring, fd) = Ring::create().unwrap();
        let segment = Segment::open(fd).unwrap();
        let message = vec![0u8; MAX_MESSAGE];
        let mut held = Vec::new();
        while let Some(at) = ring.put(&message) {
            held.push(segment.take(at, message.len() as u32).unwrap());
            assert!(held.len() < 64, "the ring never filled");
        }
        assert!(held.len() * message.len() <= IN_FLIGHT);
        // The oldest let go: room again, behind the newest.
        held.remove(0);
        assert!(ring.put(&message).is_some());
        assert!(ring.put(&vec![0u8; MAX_MESSAGE + 1]).is_none());
    }

    #[test]
    fn a_reader_keeping_one_message_touches_two_regions_not_the_segment() {
        let (mut ring, fd) = Ring::create().unwrap();
        let segment = Segment::open(fd).unwrap();
        let size = 100_000;
        let mut kept = None;
        let mut highest = 0;
        for i in 0..1000u32 {
            let at = ring.put(&vec![i as u8; size]).unwrap();
            highest = highest.max(at as usize);
            // The newest kept, the one before let go.
            kept = Some(segment.take(at, size as u32).unwrap());
        }
        assert!(kept.is_some());
        assert!(
            highest < 2 * (size + REGION_HEAD + ALIGN),
            "regions went up to {highest}"
        );
    }

    #[test]
    fn regions_wrap_around_the_end_and_never_overlap_a_held_one() {
        let (mut ring, fd) = Ring::create().unwrap();
        let segment = Segment::open(fd).unwrap();
        let size = MAX_MESSAGE;
        let mut held: VecDeque<(bytes::Bytes, u32)> = VecDeque::new();
        let mut wrapped = false;
        for i in 0..400u32 {
            let at = ring
                .put(&vec![i as u8; size])
                .expect("room after letting go");
            let bytes = segment.take(at, size as u32).unwrap();
            for (b, o) in &held {
                let (lo, hi) = (*o as usize, *o as usize + REGION_HEAD + b.len());
                assert!(
                    at as usize + REGION_HEAD + size <= lo || at as usize >= hi,
                    "region {at} overlaps {lo}..{hi}"
                );
            }
            if i > 0 && at == 0 && !held.is_empty() {
                wrapped = true;
            }
            held.push_back((bytes, at));
            if held.len() > 4 {
                let (old, _) = held.pop_front().unwrap();
                assert!(old.iter().all(|&b| b == old[0]), "a held message changed");
                drop(old);
            }
        }
        assert!(wrapped, "placing never wrapped");
    }

    #[test]
    fn a_segment_that_can_shrink_is_refused() {
        let fd = memfd_create(c"unsealed", MemFdCreateFlag::MFD_CLOEXEC).unwrap();
        nix::unistd::ftruncate(&fd, 1 << 20).unwrap();
        assert!(Segment::open(fd).is_err());
    }

    #[test]
    fn a_descriptor_travels_with_its_byte() {
        let (a, b) = std::os::unix::net::UnixStream::pair().unwrap();
        let (mut ring, fd) = Ring::create().unwrap();
        send_with_fd(&a, &[0, 1, 2], fd.as_fd()).unwrap();
        let (byte, got) = recv_with_fd(b.as_fd()).unwrap();
        assert_eq!(byte, 0);
        let segment = Segment::open(got.expect("a descriptor")).unwrap();
        let at = ring.put(b"in place").unwrap();
        assert_eq!(&segment.take(at, 8).unwrap()[..], b"in place");
        // The rest came after, without one.
        let (byte, got) = recv_with_fd(b.as_fd()).unwrap();
        assert_eq!((byte, got.is_none()), (1, true));
    }
}
