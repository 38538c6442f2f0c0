//! Large messages through shared memory.
//!
//! A node that emits a message at or above its threshold (default 4 KiB)
//! encodes it straight into a chunk of its own shared-memory pool and
//! publishes the chunk: a consumer on the same host maps the same pages and
//! decodes from them, so a camera frame is written once and copied never.
//! A consumer on another host gets the bytes over the network; Zenoh copies
//! the chunk into the transport for it, with no change in node code.
//!
//! The pool is made on the first large message (a node that only emits
//! small messages maps nothing). When it cannot be made (`/dev/shm` too
//! small, the memory-lock limit too low) or is full (readers holding every
//! chunk), messages are encoded into ordinary buffers instead; each reason
//! is logged once.

use std::collections::HashMap;
use std::fmt;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex, RwLock};

use tracing::{info, warn};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::shm::{GarbageCollect, PosixShmProviderBackend, ShmProvider, ShmProviderBuilder};

use crate::spec::TopicSpec;
use crate::wire::codec::{Encode, Writer};

/// The environment variable that sets a node's shared-memory use: `off`,
/// `on` (the defaults), or the size from which a message goes through
/// shared memory (`4096`, `64KiB`, `1MiB`). It overrides
/// [`NodeBuilder::shared_memory`](crate::NodeBuilder::shared_memory).
pub const SHM_ENV: &str = "PEPPY_SHM";

/// How a node uses shared memory for the messages it emits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SharedMemory {
    threshold: Option<usize>,
    pool_bytes: usize,
}

impl Default for SharedMemory {
    fn default() -> Self {
        SharedMemory {
            threshold: Some(Self::DEFAULT_THRESHOLD),
            pool_bytes: Self::DEFAULT_POOL,
        }
    }
}

impl SharedMemory {
    /// Messages from this size up go through shared memory by default.
    pub const DEFAULT_THRESHOLD: usize = 4 << 10;
    /// The largest pool a node makes by default: eight 4 MiB frames in
    /// flight.
    pub const DEFAULT_POOL: usize = 32 << 20;
    /// The smallest pool a node makes.
    pub const MIN_POOL: usize = 2 << 20;
    /// A pool holds this many messages of the size that made it.
    pub const POOL_MESSAGES: usize = 16;

    /// Never: every message is sent as bytes, and Zenoh's own shared-memory
    /// transport and the shared memory of the node's direct links are
    /// turned off, so the node behaves as on a remote host.
    pub const fn off() -> Self {
        SharedMemory {
            threshold: None,
            pool_bytes: Self::DEFAULT_POOL,
        }
    }

    /// Messages of at least `bytes` go through shared memory.
    pub const fn from_size(bytes: usize) -> Self {
        SharedMemory {
            threshold: Some(bytes),
            pool_bytes: Self::DEFAULT_POOL,
        }
    }

    /// The most bytes the pool may hold (messages sent and not yet dropped
    /// by every reader). The pool is made on the first large message, room
    /// for [`Self::POOL_MESSAGES`] of its size, at least
    /// [`Self::MIN_POOL`] and at most this: every reader on the host maps
    /// and locks it, so a small camera does not take 32 MiB of everyone's
    /// memory. A node whose process hosts other nodes with shared memory
    /// on makes it this large at once (docs/FAULTS.md, L2). Capped by what
    /// the host allows too.
    pub const fn pool(mut self, bytes: usize) -> Self {
        self.pool_bytes = bytes;
        self
    }

    /// The size from which messages go through shared memory (`None`: off).
    pub const fn threshold(&self) -> Option<usize> {
        self.threshold
    }

    /// Whether shared memory is used at all.
    pub const fn enabled(&self) -> bool {
        self.threshold.is_some()
    }

    /// Reads [`SHM_ENV`]; `Ok(None)` when it is not set.
    pub fn from_env() -> Result<Option<SharedMemory>, String> {
        match std::env::var(SHM_ENV) {
            Ok(v) => v
                .parse()
                .map(Some)
                .map_err(|e| format!("{SHM_ENV}=`{v}`: {e}")),
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(std::env::VarError::NotUnicode(_)) => Err(format!("{SHM_ENV} is not valid UTF-8")),
        }
    }
}

impl std::str::FromStr for SharedMemory {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "off" | "false" => Ok(SharedMemory::off()),
            "on" | "true" => Ok(SharedMemory::default()),
            size => parse_size(size)
                .map(SharedMemory::from_size)
                .ok_or_else(|| {
                    "expected `off`, `on` or a size such as `4096`, `64KiB` or `1MiB`".to_string()
                }),
        }
    }
}

impl fmt::Display for SharedMemory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.threshold {
            None => f.write_str("off"),
            Some(t) => write!(f, "from {t} bytes, pool {} MiB", self.pool_bytes >> 20),
        }
    }
}

/// `4096`, `4KiB`, `4 KiB`, `1MiB`, `2GiB` (binary units; `K`, `M`, `G`
/// and `KB`-style spellings mean the same).
fn parse_size(s: &str) -> Option<usize> {
    let digits = s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
    let (n, unit) = s.split_at(digits);
    let n: usize = n.parse().ok()?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        _ => return None,
    };
    n.checked_mul(1 << shift)
}

/// How many nodes of this process have their shared memory on. With more
/// than one, a node makes its pool whole at once rather than growing it:
/// making a pool locks its pages, and while the process does so Zenoh's
/// watchdog thread, which every reader in the process shares, was seen to
/// miss its 100 ms deadline; Zenoh then marks the chunks a reader holds or
/// is about to map as lapsed, and drops the messages not yet mapped. In a
/// process of its own a node's readers are elsewhere and its pool grows as
/// it needs (docs/FAULTS.md, L2).
static NODES_SHARING: AtomicUsize = AtomicUsize::new(0);

/// A node's shared-memory state: its settings, per-topic overrides and the
/// pool, made when first needed.
pub(crate) struct Shm {
    settings: SharedMemory,
    overrides: RwLock<HashMap<usize, Option<usize>>>,
    /// No topic's threshold is below this (`usize::MAX`: shared memory is
    /// off), so a small message skips the overrides' lock and lookup.
    lowest: AtomicUsize,
    /// Every pool made, the newest (largest) last. A pool grows by making
    /// a larger one; older ones stay mapped, since a reader may not have
    /// opened a message still in flight in them.
    pools: Mutex<Vec<Arc<Pool>>>,
    /// A pool could not be made: do not try again (and warn again) for
    /// every message; keep using the pool there is, if any.
    cannot_grow: AtomicBool,
    warned_full: AtomicBool,
    warned_size: AtomicBool,
    warned_encode: AtomicBool,
    /// Whether it counts among [`NODES_SHARING`] (its node's shared memory
    /// is on).
    counted: bool,
}

impl fmt::Debug for Shm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Shm")
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl Drop for Shm {
    fn drop(&mut self) {
        if self.counted {
            NODES_SHARING.fetch_sub(1, Relaxed);
        }
    }
}

impl Shm {
    pub(crate) fn new(settings: SharedMemory) -> Self {
        let counted = settings.enabled();
        if counted {
            NODES_SHARING.fetch_add(1, Relaxed);
        }
        Shm {
            counted,
            settings,
            overrides: RwLock::new(HashMap::new()),
            lowest: AtomicUsize::new(settings.threshold().map_or(usize::MAX, |t| t.max(1))),
            pools: Mutex::new(Vec::new()),
            cannot_grow: AtomicBool::new(false),
            warned_full: AtomicBool::new(false),
            warned_size: AtomicBool::new(false),
            warned_encode: AtomicBool::new(false),
        }
    }

    pub(crate) fn settings(&self) -> SharedMemory {
        self.settings
    }

    /// Sets one topic's threshold, overriding the node's.
    pub(crate) fn set_threshold(&self, spec: &'static TopicSpec, threshold: Option<usize>) {
        if let Ok(mut o) = self.overrides.write() {
            o.insert(std::ptr::from_ref(spec) as usize, threshold);
        }
        if let Some(t) = threshold
            && self.settings.enabled()
        {
            self.lowest.fetch_min(t.max(1), Relaxed);
        }
    }

    fn threshold(&self, spec: &'static TopicSpec) -> Option<usize> {
        if !self.settings.enabled() {
            return None;
        }
        let key = std::ptr::from_ref(spec) as usize;
        match self
            .overrides
            .read()
            .ok()
            .and_then(|o| o.get(&key).copied())
        {
            Some(t) => t,
            None => self.settings.threshold,
        }
    }

    /// Encodes `message` for `spec`, `len` bytes encoded
    /// ([`encoded_len`](crate::wire::codec::encoded_len)): into a
    /// shared-memory chunk when it is large enough, a chunk is free and
    /// Zenoh carries it to a reader (`through_zenoh`, asked only of a
    /// message large enough), else into an ordinary buffer.
    pub(crate) fn payload<M: Encode + ?Sized>(
        &self,
        spec: &'static TopicSpec,
        message: &M,
        len: usize,
        through_zenoh: impl FnOnce() -> bool,
    ) -> ZBytes {
        if len >= self.lowest.load(Relaxed)
            && let Some(threshold) = self.threshold(spec)
            && len >= threshold.max(1)
            && through_zenoh()
            && let Some(bytes) = self.encode_shared(spec, message, len)
        {
            return bytes;
        }
        let mut out = Vec::with_capacity(len);
        message.encode(&mut Writer::new(&mut out));
        ZBytes::from(out)
    }

    /// The pool to take `len` bytes from: the newest, or a new one when
    /// there is none yet or the newest has room for fewer than
    /// [`SharedMemory::POOL_MESSAGES`] messages of `len` bytes and may grow.
    /// A pool too small for the stream it carries is full of frames the
    /// readers still hold, and every later frame goes as an ordinary buffer
    /// (a 2 MiB pool made for 64 KiB messages carried 1 MiB frames at a
    /// third of raw Zenoh's rate).
    fn pool_for(&self, len: usize) -> Option<Arc<Pool>> {
        let mut pools = self.pools.lock().ok()?;
        let stuck = self.cannot_grow.load(Relaxed);
        let newest = pools.last().map(|p| p.bytes);
        match next_pool(newest, len, self.settings.pool_bytes, stuck, self.whole()) {
            Some(size) => self.open_next(&mut pools, size),
            None => pools.last().cloned(),
        }
    }

    /// A larger pool than `full`, whose every chunk readers still hold:
    /// double it, up to the node's bound (or the bound at once, made whole). A stream read a little behind
    /// holds more chunks than its first sixteen (64 KiB messages flooding
    /// a 2 MiB pool went as ordinary buffers at half raw Zenoh's rate).
    /// `None` once the bound is reached: what follows goes as bytes until
    /// readers let go.
    fn grown_from(&self, full: &Arc<Pool>) -> Option<Arc<Pool>> {
        let mut pools = self.pools.lock().ok()?;
        let newest = pools.last()?;
        if !Arc::ptr_eq(newest, full) {
            // Another message grew it meanwhile.
            return Some(newest.clone());
        }
        let most = self.settings.pool_bytes;
        if self.cannot_grow.load(Relaxed) || full.bytes >= most {
            return None;
        }
        let size = if self.whole() {
            most
        } else {
            full.bytes.saturating_mul(2).min(most)
        };
        self.open_next(&mut pools, size)
    }

    /// Whether a pool is made whole at once: other nodes of the process
    /// share its memory ([`NODES_SHARING`]).
    fn whole(&self) -> bool {
        self.counted && NODES_SHARING.load(Relaxed) > 1
    }

    /// Opens a pool of `size` bytes as the newest of `pools` (the one
    /// messages are taken from), or notes that none can be made.
    fn open_next(&self, pools: &mut Vec<Arc<Pool>>, size: usize) -> Option<Arc<Pool>> {
        match open_pool(size) {
            Some(p) => {
                // A pool the host capped is as large as it will get.
                if p.bytes < size {
                    self.cannot_grow.store(true, Relaxed);
                }
                pools.push(Arc::new(p));
            }
            None => self.cannot_grow.store(true, Relaxed),
        }
        pools.last().cloned()
    }

    fn encode_shared<M: Encode + ?Sized>(
        &self,
        spec: &'static TopicSpec,
        message: &M,
        len: usize,
    ) -> Option<ZBytes> {
        let pool = self.pool_for(len)?;
        pool.reclaim_before(len);
        let alloc = |pool: &Pool| {
            pool.provider
                .alloc(len)
                .with_policy::<GarbageCollect>()
                .wait()
        };
        let mut chunk = match alloc(&pool).or_else(|e| {
            match (len <= pool.bytes)
                .then(|| self.grown_from(&pool))
                .flatten()
            {
                Some(grown) => alloc(&grown),
                None => Err(e),
            }
        }) {
            Ok(chunk) => chunk,
            Err(e) => {
                let (flag, why) = if len > pool.bytes {
                    (&self.warned_size, "the message is larger than the pool")
                } else {
                    (
                        &self.warned_full,
                        "every chunk of the pool is still held by readers",
                    )
                };
                if !flag.swap(true, Relaxed) {
                    warn!(
                        topic = spec.name,
                        bytes = len,
                        error = ?e,
                        "{why}; sending such messages as ordinary buffers (logged once)"
                    );
                }
                return None;
            }
        };
        let mut w = Writer::fill(chunk.as_mut());
        message.encode(&mut w);
        if w.filled() {
            return Some(ZBytes::from(chunk));
        }
        if !self.warned_encode.swap(true, Relaxed) {
            warn!(
                topic = spec.name,
                "this message's Encode impl wrote a different size than it counted; sending it as an ordinary buffer (logged once)"
            );
        }
        None
    }
}

/// A node's pool and its size.
struct Pool {
    provider: ShmProvider<PosixShmProviderBackend>,
    bytes: usize,
    /// Bytes handed out since chunks readers let go were last reclaimed.
    since_reclaim: AtomicUsize,
}

impl Pool {
    /// Reclaims the chunks every reader has let go once
    /// [`Pool::RECLAIM_EVERY`] bytes have been handed out since the last
    /// time, counting the `len` about to be. Zenoh frees a chunk only when
    /// asked, and left alone it asks only when the pool is full, so
    /// messages would walk the whole pool and each be written into memory
    /// long out of cache; reclaimed, the chunk just released is the next
    /// one handed out. The count spreads the scan of held chunks over many
    /// small messages.
    fn reclaim_before(&self, len: usize) {
        let handed = self
            .since_reclaim
            .fetch_add(len, Relaxed)
            .saturating_add(len);
        if handed >= Self::RECLAIM_EVERY {
            self.since_reclaim.store(0, Relaxed);
            self.provider.garbage_collect();
        }
    }

    /// What a writer's chunks cycle through: small enough to stay in a
    /// core's second-level cache (256 KiB to 2 MiB on current cores). A
    /// 1 MiB round trip through shared memory took 255 µs instead of 370
    /// (docs/PERFORMANCE.md).
    const RECLAIM_EVERY: usize = 256 << 10;
}

/// The size of the pool to make for a message of `len` bytes when the
/// newest pool has `newest` bytes (`None`: no pool yet); `None` when the
/// newest will do or no pool can be made. Growing at least doubles, so
/// slowly growing messages make a few pools, not one each; `whole` (other
/// nodes of the process share its memory) makes the largest at once.
fn next_pool(
    newest: Option<usize>,
    len: usize,
    most: usize,
    stuck: bool,
    whole: bool,
) -> Option<usize> {
    let wanted = pool_size(len, most);
    match newest {
        _ if stuck => None,
        Some(n) if n >= wanted || n >= most => None,
        _ if whole => Some(most),
        Some(n) => Some(wanted.max(n.saturating_mul(2)).min(most)),
        None => Some(wanted),
    }
}

/// The pool for a first large message of `len` bytes, at most `most`.
fn pool_size(len: usize, most: usize) -> usize {
    len.saturating_mul(SharedMemory::POOL_MESSAGES)
        .max(SharedMemory::MIN_POOL)
        .min(most)
}

/// Makes the pool, no larger than the host allows: pages are locked in
/// memory (so a message is never paged out under a reader), so the pool
/// must fit under the memory-lock limit and in half of `/dev/shm`.
fn open_pool(wanted: usize) -> Option<Pool> {
    let (bytes, limited_by) = host_cap(wanted);
    if bytes < SharedMemory::DEFAULT_THRESHOLD {
        warn!(
            wanted_mib = wanted >> 20,
            limited_by,
            "no room for a shared-memory pool; large messages are sent as ordinary buffers"
        );
        return None;
    }
    match ShmProviderBuilder::default_backend(bytes).wait() {
        Ok(p) => {
            if bytes < wanted {
                info!(
                    pool_mib = bytes >> 20,
                    wanted_mib = wanted >> 20,
                    limited_by,
                    "large messages go through shared memory to readers on this host, in a smaller pool than asked"
                );
            } else {
                info!(
                    pool_mib = bytes >> 20,
                    "large messages go through shared memory to readers on this host"
                );
            }
            Some(Pool {
                provider: p,
                bytes,
                since_reclaim: AtomicUsize::new(0),
            })
        }
        Err(e) => {
            warn!(
                pool_bytes = bytes,
                error = %e,
                "cannot make a shared-memory pool; large messages are sent as ordinary buffers"
            );
            None
        }
    }
}

/// `wanted`, capped by the memory-lock limit and half of `/dev/shm`'s free
/// space; with what capped it.
fn host_cap(wanted: usize) -> (usize, &'static str) {
    let mut cap = (wanted, "the node's setting");
    if let Some(lock) = memlock_limit()
        && lock < cap.0
    {
        // Leave room for Zenoh's own small segments under the same limit.
        cap = (lock / 2, "the memory-lock limit (ulimit -l)");
    }
    if let Some(free) = shm_free()
        && free / 2 < cap.0
    {
        cap = (free / 2, "free space in /dev/shm");
    }
    cap
}

/// The least a process must be allowed to lock to use shared memory: a
/// reader maps (and Zenoh locks) the whole pool of every producer it
/// hears from, and Zenoh drops a message whose pool it cannot map.
pub(crate) const MIN_LOCKABLE: usize = 256 << 20;

/// `settings`, or off when this process may not lock enough memory to map
/// its producers' pools (logged): better a copy than a lost message.
pub(crate) fn usable(settings: SharedMemory) -> SharedMemory {
    if !settings.enabled() {
        return settings;
    }
    match memlock_limit() {
        Some(limit) if limit < MIN_LOCKABLE => {
            info!(
                lockable_mib = limit >> 20,
                "shared memory off: readers lock every producer's pool they map, and this process may lock only this much (ulimit -l); raise it (`ulimit -l unlimited`, systemd `LimitMEMLOCK=infinity`) to send large messages through shared memory"
            );
            SharedMemory::off()
        }
        _ => settings,
    }
}

/// How much memory this process may lock; `None`: no limit (unlimited, or
/// `CAP_IPC_LOCK`, which root usually has and which bypasses the limit).
#[cfg(target_os = "linux")]
fn memlock_limit() -> Option<usize> {
    const CAP_IPC_LOCK: u32 = 14;
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let can_lock_anything = status
        .lines()
        .find_map(|l| l.strip_prefix("CapEff:"))
        .and_then(|hex| u64::from_str_radix(hex.trim(), 16).ok())
        .is_some_and(|caps| caps & (1 << CAP_IPC_LOCK) != 0);
    if can_lock_anything {
        return None;
    }
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes one rlimit through a valid pointer.
    if unsafe { libc::getrlimit(libc::RLIMIT_MEMLOCK, &mut r) } != 0 {
        return None;
    }
    (r.rlim_cur != libc::RLIM_INFINITY).then(|| usize::try_from(r.rlim_cur).unwrap_or(usize::MAX))
}

#[cfg(target_os = "linux")]
fn shm_free() -> Option<usize> {
    let mut s = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: the path is a NUL-terminated literal and statvfs fills the
    // struct it points to when it returns 0.
    let s = unsafe {
        if libc::statvfs(c"/dev/shm".as_ptr(), s.as_mut_ptr()) != 0 {
            return None;
        }
        s.assume_init()
    };
    usize::try_from(s.f_bavail.saturating_mul(s.f_frsize)).ok()
}

#[cfg(not(target_os = "linux"))]
fn memlock_limit() -> Option<usize> {
    None
}

#[cfg(not(target_os = "linux"))]
fn shm_free() -> Option<usize> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::codec::encoded_len;

    #[test]
    fn settings_parse_from_the_environment_spellings() {
        assert_eq!("off".parse::<SharedMemory>(), Ok(SharedMemory::off()));
        assert_eq!("on".parse::<SharedMemory>(), Ok(SharedMemory::default()));
        assert_eq!(
            "64KiB".parse::<SharedMemory>().map(|s| s.threshold()),
            Ok(Some(64 << 10))
        );
        assert_eq!(
            "1 MiB".parse::<SharedMemory>().map(|s| s.threshold()),
            Ok(Some(1 << 20))
        );
        assert_eq!(
            "4096".parse::<SharedMemory>().map(|s| s.threshold()),
            Ok(Some(4096))
        );
        for bad in ["", "lots", "4 parsecs", "-1", "99999999999999999999GiB"] {
            let err = bad.parse::<SharedMemory>().unwrap_err();
            assert!(err.contains("expected `off`"), "{bad}: {err}");
        }
    }

    #[test]
    fn the_pool_fits_the_first_message_within_its_bounds() {
        let most = SharedMemory::DEFAULT_POOL;
        assert_eq!(pool_size(19_200, most), SharedMemory::MIN_POOL);
        assert_eq!(pool_size(1 << 20, most), 16 << 20);
        assert_eq!(pool_size(4 << 20, most), most);
        assert_eq!(pool_size(usize::MAX, 8 << 20), 8 << 20);
    }

    #[test]
    fn a_pool_grows_when_it_holds_too_few_of_the_messages_sent() {
        let most = SharedMemory::DEFAULT_POOL;
        let min = SharedMemory::MIN_POOL;
        assert_eq!(next_pool(None, 64 << 10, most, false, false), Some(min));
        assert_eq!(next_pool(Some(min), 64 << 10, most, false, false), None);
        assert_eq!(
            next_pool(Some(min), 1 << 20, most, false, false),
            Some(16 << 20),
            "64 KiB made it, 1 MiB frames need room for sixteen"
        );
        assert_eq!(
            next_pool(Some(16 << 20), (1 << 20) + 1, most, false, false),
            Some(most),
            "at least doubles"
        );
        assert_eq!(next_pool(Some(most), 4 << 20, most, false, false), None);
        assert_eq!(next_pool(Some(min), 1 << 20, most, true, false), None);
        assert_eq!(next_pool(None, 1 << 20, most, true, false), None);
    }

    #[test]
    fn beside_other_nodes_of_its_process_a_pool_is_made_whole() {
        let most = SharedMemory::DEFAULT_POOL;
        let min = SharedMemory::MIN_POOL;
        assert_eq!(next_pool(None, 4 << 10, most, false, true), Some(most));
        assert_eq!(
            next_pool(Some(min), 1 << 20, most, false, true),
            Some(most),
            "one made alone grows to the largest at once"
        );
        assert_eq!(next_pool(Some(min), 64 << 10, most, false, true), None);
        assert_eq!(next_pool(Some(most), 4 << 20, most, false, true), None);
        assert_eq!(next_pool(None, 4 << 10, most, true, true), None);
    }

    /// A topic whose messages the pool tests encode.
    static FRAMES: TopicSpec = TopicSpec {
        owner: crate::spec::OwnerSpec::Any,
        name: "frames",
        qos: peppy_schema::QosProfile::Reliable,
        format: crate::spec::FormatSpec::EMPTY,
    };

    /// A node's shared memory as in a process of its own, whatever else the
    /// tests running beside it make.
    fn alone(settings: SharedMemory) -> Shm {
        let mut shm = Shm::new(settings);
        if shm.counted {
            NODES_SHARING.fetch_sub(1, Relaxed);
            shm.counted = false;
        }
        shm
    }

    /// Readers holding every chunk make the pool double, up to the node's
    /// bound; past it messages go as bytes, and in shared memory again
    /// once readers let go.
    #[test]
    fn a_full_pool_grows_to_its_bound_then_messages_go_as_bytes() {
        let most = 8 << 20;
        let shm = alone(SharedMemory::default().pool(most));
        let frame = vec![7u8; 64 << 10];
        let mut held = Vec::new();
        let mut shared = 0;
        while held.len() < 400 {
            let bytes = shm.payload(&FRAMES, &frame, encoded_len(&frame), || true);
            if bytes.as_shm().is_none() {
                break;
            }
            shared += bytes.len();
            held.push(bytes);
        }
        let pools: Vec<usize> = shm.pools.lock().unwrap().iter().map(|p| p.bytes).collect();
        if pools
            .first()
            .is_none_or(|&first| first < SharedMemory::MIN_POOL)
        {
            return; // this host allows no pool of the smallest size: nothing to grow
        }
        assert_eq!(pools, [2 << 20, 4 << 20, most], "doubling from the first");
        assert!(
            shared > (6 << 20) && shared <= (14 << 20),
            "{shared} bytes held in shared memory"
        );
        let over = shm.payload(&FRAMES, &frame, encoded_len(&frame), || true);
        assert!(over.as_shm().is_none(), "past the bound: bytes");
        assert_eq!(over.to_bytes().len(), encoded_len(&frame));
        held.clear();
        assert!(
            shm.payload(&FRAMES, &frame, encoded_len(&frame), || true)
                .as_shm()
                .is_some(),
            "readers let go: shared memory again"
        );
    }

    /// Chunks readers let go are handed out again soon, while still in
    /// cache, not after the whole pool has been walked.
    #[test]
    fn released_chunks_are_written_again_soon() {
        let shm = alone(SharedMemory::default());
        // Where the message went (then it is dropped: every reader let go).
        let chunk_of = |frame: &Vec<u8>| {
            let bytes = shm.payload(&FRAMES, frame, encoded_len(frame), || true);
            bytes.as_shm().map(|chunk| chunk.as_ptr() as usize)
        };
        let large = vec![1u8; 1 << 20];
        let Some(first) = chunk_of(&large) else {
            return; // this host allows no pool: nothing to reuse
        };
        for _ in 0..40 {
            assert_eq!(
                chunk_of(&large),
                Some(first),
                "the 1 MiB chunk just released"
            );
        }
        let small = vec![2u8; 4 << 10];
        let mut seen = std::collections::HashSet::new();
        for i in 0..2000 {
            let chunk = chunk_of(&small);
            // The first cycle starts where the large chunks ended.
            if i >= 1000 {
                seen.extend(chunk);
            }
        }
        let cycle = Pool::RECLAIM_EVERY / encoded_len(&small) + 2;
        assert!(
            !seen.is_empty() && seen.len() <= cycle,
            "{} chunks cycled through for 4 KiB messages, at most {cycle} expected",
            seen.len()
        );
    }

    #[test]
    fn the_host_cap_never_exceeds_the_wish() {
        let (bytes, _) = host_cap(1 << 20);
        assert!(bytes <= 1 << 20);
    }
}
