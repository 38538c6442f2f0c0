//! The stack clock: one time for every node of a launch, wall or simulated.
//!
//! Each launch (`peppy-launch up`) publishes its OS clock ten times a second
//! on `peppy/<ns>/clock/tick/wall` and answers synchronization queries on
//! `peppy/<ns>/clock/sync`; a simulator publishes its own time on
//! `peppy/<ns>/clock/tick/sim` ([`publish_sim_time`]). A node follows one
//! of the two, fixed at start-up ([`NodeRunner::use_sim_time`]: the
//! instance's `framework.use_sim_time`, or `--use-sim-time`):
//!
//! - wall time: [`now_ns`] is this host's OS clock (ns since the Unix
//!   epoch); [`synchronize`] measures how far it is from the launcher's;
//! - sim time: [`now_ns`] is the latest sim tick this node has received,
//!   and [`crate::Error::ClockNotReady`] until the first arrives.
//!
//! ```ignore
//! peppy::clock::init(&runner).await?;
//! let stamp = peppy::clock::now_ns()?;
//! ```
//!
//! Every payload is little-endian u64 nanoseconds (docs/WIRE.md, "Clock").
//! A payload of the wrong length is dropped, with one warning per
//! subscription.

use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};
use zenoh::Wait;
use zenoh::query::{ConsolidationMode, QueryTarget};

use crate::error::{Error, Result};
use crate::node::NodeRunner;
pub use crate::wire::keys::ClockSource;
use crate::wire::keys::{clock_sync_key, clock_tick_key};

/// How long [`synchronize`] waits for the launcher's answer by default.
pub const DEFAULT_SYNC_TIMEOUT: Duration = Duration::from_secs(10);

/// How often a launch publishes its wall tick.
pub const WALL_TICK_PERIOD: Duration = Duration::from_millis(100);

/// A sync query's payload: t0 (u64 LE) and the source byte.
const QUERY_LEN: usize = 9;
/// A sync reply's payload: t0, t1, t2 (each u64 LE).
const REPLY_LEN: usize = 24;

/// This host's OS clock, ns since the Unix epoch (0 before it, saturated
/// after year 2554).
pub fn os_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// A tick's time, if the payload is one: exactly 8 bytes.
fn decode_time(bytes: &[u8]) -> Option<u64> {
    <[u8; 8]>::try_from(bytes).ok().map(u64::from_le_bytes)
}

/// The latest time seen on a tick key.
#[derive(Debug, Default)]
struct Latest(Mutex<Option<u64>>);

impl Latest {
    fn set(&self, t: u64) {
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = Some(t);
    }

    fn get(&self) -> Option<u64> {
        *self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// Reads a tick sample's time; a malformed one is dropped, and the first
/// such of a subscription logged.
fn tick_of(sample: &zenoh::sample::Sample, warned: &AtomicBool) -> Option<u64> {
    let bytes = sample.payload().to_bytes();
    let time = decode_time(&bytes);
    if time.is_none() && !warned.swap(true, Ordering::Relaxed) {
        warn!(
            key = %sample.key_expr(),
            "dropping a clock tick of {} bytes (a tick is 8: u64 little-endian ns); further malformed ticks here are dropped silently",
            bytes.len()
        );
    }
    time
}

/// The node [`now_ns`] answers for.
struct Binding {
    /// `(core node, instance id)`.
    node: (String, String),
    /// The latest sim tick; `None` following wall time.
    sim: Option<Arc<Latest>>,
}

static BOUND: Mutex<Option<Binding>> = Mutex::new(None);
/// Held while a binding is made, so two `init`s of one node make one.
static BINDING: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

fn node_of(runner: &NodeRunner) -> (String, String) {
    (
        runner.core_node().to_string(),
        runner.instance_id().to_string(),
    )
}

/// Binds [`now_ns`] to this node's clock. Following sim time, it
/// subscribes to the stack's sim ticks and keeps the latest; following
/// wall time, it has nothing to set up. Idempotent for one node; a
/// different node (another runner in the same process) takes the clock
/// over.
pub async fn init(runner: &NodeRunner) -> Result<()> {
    let _making = BINDING.lock().await;
    let node = node_of(runner);
    let already = BOUND
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .as_ref()
        .is_some_and(|b| b.node == node);
    if already {
        return Ok(());
    }
    let sim = if runner.use_sim_time() {
        let latest = Arc::new(Latest::default());
        let (seen, warned) = (latest.clone(), AtomicBool::new(false));
        // Lives as long as the node's session.
        runner
            .session()
            .declare_subscriber(clock_tick_key(runner.namespace(), ClockSource::Sim))
            .callback(move |sample| {
                if let Some(t) = tick_of(&sample, &warned) {
                    seen.set(t);
                }
            })
            .background()
            .await?;
        Some(latest)
    } else {
        None
    };
    *BOUND.lock().unwrap_or_else(|p| p.into_inner()) = Some(Binding { node, sim });
    Ok(())
}

/// The stack time now, in ns: the OS clock following wall time, the latest
/// sim tick following sim time. [`Error::ClockNotReady`] before [`init`],
/// and following sim time until the first tick arrives.
pub fn now_ns() -> Result<u64> {
    match &*BOUND.lock().unwrap_or_else(|p| p.into_inner()) {
        None => Err(Error::ClockNotReady),
        Some(Binding { sim: None, .. }) => Ok(os_now_ns()),
        Some(Binding { sim: Some(l), .. }) => l.get().ok_or(Error::ClockNotReady),
    }
}

/// The latest sim tick the clock bound to `runner` has seen: `None` when
/// the process's clock is not bound to that node following sim time (a
/// test harness's tick waits on this).
#[cfg(feature = "testing")]
pub(crate) fn sim_time_seen_by(runner: &NodeRunner) -> Option<Option<u64>> {
    let node = node_of(runner);
    match &*BOUND.lock().unwrap_or_else(|p| p.into_inner()) {
        Some(Binding {
            node: n,
            sim: Some(l),
        }) if *n == node => Some(l.get()),
        _ => None,
    }
}

/// The clock `runner` reads, for synchronizing: the OS clock, or the
/// latest sim tick [`init`] has given it (0 without one).
fn client_now(runner: &NodeRunner) -> u64 {
    if !runner.use_sim_time() {
        return os_now_ns();
    }
    let node = node_of(runner);
    match &*BOUND.lock().unwrap_or_else(|p| p.into_inner()) {
        Some(Binding {
            node: n,
            sim: Some(l),
        }) if *n == node => l.get().unwrap_or(0),
        _ => 0,
    }
}

/// Publishes `time_ns` as the stack's simulated time
/// (`peppy/<ns>/clock/tick/sim`): what a simulator calls at each step.
pub async fn publish_sim_time(runner: &NodeRunner, time_ns: u64) -> Result<()> {
    let key = clock_tick_key(runner.namespace(), ClockSource::Sim);
    match runner
        .session()
        .put(key, time_ns.to_le_bytes().to_vec())
        .await
    {
        Ok(()) => Ok(()),
        Err(_) if runner.session().is_closed() => Err(Error::ShuttingDown),
        Err(e) => Err(e.into()),
    }
}

/// The three times a launcher's sync reply carries, each in ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockResponse {
    /// t0: when the client sent the query, by the client's clock (echoed).
    pub client_send_time: u64,
    /// t1: when the launcher received it, by the launcher's clock.
    pub server_recv_time: u64,
    /// t2: when the launcher replied, by the launcher's clock.
    pub server_send_time: u64,
}

impl ClockResponse {
    fn decode(bytes: &[u8]) -> Option<ClockResponse> {
        if bytes.len() != REPLY_LEN {
            return None;
        }
        let at = |i: usize| decode_time(&bytes[i * 8..i * 8 + 8]);
        Some(ClockResponse {
            client_send_time: at(0)?,
            server_recv_time: at(1)?,
            server_send_time: at(2)?,
        })
    }

    fn encode(&self) -> Vec<u8> {
        [
            self.client_send_time,
            self.server_recv_time,
            self.server_send_time,
        ]
        .iter()
        .flat_map(|t| t.to_le_bytes())
        .collect()
    }

    /// The clock offset and round-trip delay, with `t3` the client's
    /// clock when the reply arrived (NTP's arithmetic).
    pub fn sync(self, t3: u64) -> ClockSync {
        let (t0, t1, t2, t3) = (
            i128::from(self.client_send_time),
            i128::from(self.server_recv_time),
            i128::from(self.server_send_time),
            i128::from(t3),
        );
        // Floor division, as Python's `//`: both runtimes give one answer.
        let offset = ((t1 - t0) + (t2 - t3)).div_euclid(2);
        let delay = (t3 - t0) - (t2 - t1);
        ClockSync {
            offset_ns: offset.clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64,
            round_trip_delay_ns: delay.clamp(0, i128::from(u64::MAX)) as u64,
            raw: self,
        }
    }
}

/// How this node's clock stands against its launcher's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockSync {
    /// What to add to this node's clock to read the launcher's.
    pub offset_ns: i64,
    /// The round trip's time on the wire, the launcher's own time taken
    /// out (never negative).
    pub round_trip_delay_ns: u64,
    /// The reply the two were computed from.
    pub raw: ClockResponse,
}

/// Asks the launcher's clock (`peppy/<ns>/clock/sync`) and measures this
/// node's offset from it. Following wall time, both sides read their OS
/// clocks; following sim time, the launcher answers with the latest sim
/// tick it has seen (and this node's side is its own latest, 0 before
/// [`init`] or the first tick), or refuses with [`Error::ClockNotReady`]
/// when it has seen none. The first reply counts. `timeout` defaults to
/// 10 s; with no answer by then, [`Error::ServiceUnreachable`].
pub async fn synchronize(runner: &NodeRunner, timeout: Option<Duration>) -> Result<ClockSync> {
    let source = if runner.use_sim_time() {
        ClockSource::Sim
    } else {
        ClockSource::Wall
    };
    let key = clock_sync_key(runner.namespace());
    let deadline = tokio::time::Instant::now() + timeout.unwrap_or(DEFAULT_SYNC_TIMEOUT);
    loop {
        let left = deadline.saturating_duration_since(tokio::time::Instant::now());
        if let Some(sync) = ask_clock(runner, &key, source, left).await? {
            return Ok(sync);
        }
        // Nobody answered. A query that reaches no queryable ends at once,
        // and a node just started may not have heard of the launcher's
        // yet: ask again until the timeout is spent.
        let left = deadline.saturating_duration_since(tokio::time::Instant::now());
        if left.is_zero() {
            return Err(Error::ServiceUnreachable {
                service_name: "clock sync".into(),
                instance_id: None,
            });
        }
        tokio::select! {
            () = tokio::time::sleep(left.min(SYNC_RETRY)) => {}
            () = runner.messaging_stop().cancelled() => return Err(Error::ShuttingDown),
        }
    }
}

/// How long `synchronize` waits before asking again when nobody answered.
const SYNC_RETRY: Duration = Duration::from_millis(50);

/// One `clock/sync` query: the first answer, or `None` when none came
/// within `timeout`.
async fn ask_clock(
    runner: &NodeRunner,
    key: &str,
    source: ClockSource,
    timeout: Duration,
) -> Result<Option<ClockSync>> {
    let t0 = client_now(runner);
    let mut query = t0.to_le_bytes().to_vec();
    query.push(source.as_byte());
    let replies = runner
        .session()
        .get(key)
        .payload(query)
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(timeout.max(Duration::from_millis(1)))
        .await?;
    loop {
        let reply = tokio::select! {
            r = replies.recv_async() => match r {
                Ok(r) => r,
                Err(_) => return Ok(None),
            },
            () = runner.messaging_stop().cancelled() => return Err(Error::ShuttingDown),
        };
        let t3 = client_now(runner);
        match reply.result() {
            Ok(sample) => match ClockResponse::decode(&sample.payload().to_bytes()) {
                Some(r) => return Ok(Some(r.sync(t3))),
                None => debug!(key, "dropping a clock sync reply that is not 24 bytes"),
            },
            Err(e) => {
                let why = e.payload().try_to_string().unwrap_or_default().into_owned();
                // Zenoh ends a query whose time is up with an error reply
                // of its own, not from the launcher.
                if why == "Timeout" {
                    return Ok(None);
                }
                debug!(key, reason = %why, "the launcher refused to synchronize");
                return Err(Error::ClockNotReady);
            }
        }
    }
}

/// One tick of the node's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockTick {
    /// The tick's time, in ns.
    pub time: u64,
}

/// The ticks of this node's clock, from [`subscribe`].
pub struct ClockSubscription {
    ticks: flume::Receiver<u64>,
    stop: CancellationToken,
    _subscriber: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for ClockSubscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClockSubscription").finish_non_exhaustive()
    }
}

/// Ticks kept for a reader that falls behind: the oldest go first.
const TICKS_KEPT: usize = 16;

/// Subscribes to this node's clock ticks: the launcher's wall ticks, or
/// the simulator's sim ticks following sim time.
pub async fn subscribe(runner: &NodeRunner) -> Result<ClockSubscription> {
    let source = if runner.use_sim_time() {
        ClockSource::Sim
    } else {
        ClockSource::Wall
    };
    let (tx, ticks) = flume::bounded(TICKS_KEPT);
    let (oldest, warned) = (ticks.clone(), AtomicBool::new(false));
    let subscriber = runner
        .session()
        .declare_subscriber(clock_tick_key(runner.namespace(), source))
        .callback(move |sample| {
            let Some(t) = tick_of(&sample, &warned) else {
                return;
            };
            if let Err(flume::TrySendError::Full(t)) = tx.try_send(t) {
                let _ = oldest.try_recv();
                let _ = tx.try_send(t);
            }
        })
        .await?;
    Ok(ClockSubscription {
        ticks,
        stop: runner.cancellation_token().clone(),
        _subscriber: subscriber,
    })
}

impl ClockSubscription {
    /// The next tick; `None` once the node stops.
    pub async fn on_next_tick(&self) -> Result<Option<ClockTick>> {
        if self.stop.is_cancelled() {
            return Ok(None);
        }
        tokio::select! {
            t = self.ticks.recv_async() => Ok(t.ok().map(|time| ClockTick { time })),
            () = self.stop.cancelled() => Ok(None),
        }
    }
}

/// A launch's side of the clock: publishes wall ticks, answers sync
/// queries and follows sim ticks, until dropped. `peppy-launch up` runs
/// one per launch.
pub struct ClockServer {
    ticker: tokio::task::JoinHandle<()>,
    _sync: zenoh::query::Queryable<()>,
    _sim: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for ClockServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClockServer").finish_non_exhaustive()
    }
}

impl Drop for ClockServer {
    fn drop(&mut self) {
        self.ticker.abort();
    }
}

/// What a sync query gets: the reply's payload, or the refusal's reason.
fn answer_sync(
    query: &[u8],
    received: u64,
    sim: &Latest,
    ns: &str,
    offset: i64,
) -> Result<Vec<u8>, String> {
    let Some(source) = (query.len() == QUERY_LEN)
        .then(|| ClockSource::from_byte(query[8]))
        .flatten()
    else {
        return Err(format!(
            "a clock sync query is 9 bytes (t0 as u64 little-endian, then 0 for wall or 1 for sim); got {} bytes",
            query.len()
        ));
    };
    let t0 = decode_time(&query[..8]).unwrap_or_default();
    let (t1, t2) = match source {
        ClockSource::Wall => (shifted(received, offset), shifted(os_now_ns(), offset)),
        ClockSource::Sim => match sim.get() {
            Some(t) => (t, t),
            None => {
                return Err(format!(
                    "no sim tick has been published on {} yet",
                    clock_tick_key(ns, ClockSource::Sim)
                ));
            }
        },
    };
    Ok(ClockResponse {
        client_send_time: t0,
        server_recv_time: t1,
        server_send_time: t2,
    }
    .encode())
}

/// Starts a launch's clock for `namespace` on `session` (the launch's
/// router): a wall tick every 100 ms, answers on `clock/sync`, and the
/// latest sim tick followed for sim-time answers. Needs a tokio runtime.
pub async fn serve(session: &zenoh::Session, namespace: &str) -> Result<ClockServer> {
    serve_with(session, namespace, Arc::new(AtomicI64::new(0))).await
}

/// `t` moved by `offset` ns, saturating.
fn shifted(t: u64, offset: i64) -> u64 {
    t.saturating_add_signed(offset)
}

/// [`serve`] with the wall clock it gives moved by `offset` ns (read at
/// each answer and tick): a test harness's clock skew.
pub(crate) async fn serve_with(
    session: &zenoh::Session,
    namespace: &str,
    offset: Arc<AtomicI64>,
) -> Result<ClockServer> {
    let sim = Arc::new(Latest::default());
    let (seen, warned) = (sim.clone(), AtomicBool::new(false));
    let sim_sub = session
        .declare_subscriber(clock_tick_key(namespace, ClockSource::Sim))
        .callback(move |sample| {
            if let Some(t) = tick_of(&sample, &warned) {
                seen.set(t);
            }
        })
        .await?;
    let sync_key = clock_sync_key(namespace);
    let (reply_key, ns, skew) = (sync_key.clone(), namespace.to_string(), offset.clone());
    let sync = session
        .declare_queryable(sync_key)
        .callback(move |q| {
            let received = os_now_ns();
            let payload = q.payload().map(|p| p.to_bytes()).unwrap_or_default();
            let skew = skew.load(Ordering::Relaxed);
            let _ = match answer_sync(&payload, received, &sim, &ns, skew) {
                Ok(reply) => q.reply(reply_key.as_str(), reply).wait(),
                Err(why) => q.reply_err(why).wait(),
            };
        })
        .await?;
    let publisher = session
        .declare_publisher(clock_tick_key(namespace, ClockSource::Wall))
        .await?;
    let ticker = tokio::spawn(async move {
        let mut every = tokio::time::interval(WALL_TICK_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            if publisher
                .put(
                    shifted(os_now_ns(), offset.load(Ordering::Relaxed))
                        .to_le_bytes()
                        .to_vec(),
                )
                .await
                .is_err()
            {
                // The session is closed: the launch is over.
                break;
            }
        }
    });
    Ok(ClockServer {
        ticker,
        _sync: sync,
        _sim: sim_sub,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_and_delay_follow_ntp_and_saturate() {
        let r = ClockResponse {
            client_send_time: 100,
            server_recv_time: 1_150,
            server_send_time: 1_160,
        };
        // 50 ns each way, the server's clock 1000 ns ahead.
        let s = r.sync(220);
        assert_eq!((s.offset_ns, s.round_trip_delay_ns), (995, 110));
        assert_eq!(ClockResponse::decode(&r.encode()), Some(r));
        assert_eq!(ClockResponse::decode(&r.encode()[..23]), None);
        // Far apart: saturated, and a delay never negative.
        let far = ClockResponse {
            client_send_time: u64::MAX,
            server_recv_time: 0,
            server_send_time: 0,
        }
        .sync(u64::MAX);
        assert_eq!(far.offset_ns, i64::MIN);
        assert_eq!(far.round_trip_delay_ns, 0);
        // Floor, not truncation, for an odd negative sum.
        let odd = ClockResponse {
            client_send_time: 10,
            server_recv_time: 9,
            server_send_time: 10,
        }
        .sync(10);
        assert_eq!((odd.offset_ns, odd.round_trip_delay_ns), (-1, 0));
    }

    #[test]
    fn sync_answers_wall_and_sim_and_refuses_the_rest() {
        let sim = Latest::default();
        let mut q = 7u64.to_le_bytes().to_vec();
        q.push(0);
        let wall = ClockResponse::decode(&answer_sync(&q, 40, &sim, "lab", 0).unwrap()).unwrap();
        assert_eq!((wall.client_send_time, wall.server_recv_time), (7, 40));
        assert!(wall.server_send_time > 40);
        q[8] = 1;
        let e = answer_sync(&q, 40, &sim, "lab", 0).unwrap_err();
        assert!(e.contains("peppy/lab/clock/tick/sim"), "{e}");
        sim.set(5_000);
        let r = ClockResponse::decode(&answer_sync(&q, 40, &sim, "lab", 0).unwrap()).unwrap();
        assert_eq!((r.server_recv_time, r.server_send_time), (5_000, 5_000));
        q[8] = 2;
        assert!(answer_sync(&q, 40, &sim, "lab", 0).is_err());
        assert!(answer_sync(&q[..8], 40, &sim, "lab", 0).is_err());
        assert_eq!(decode_time(&[1, 0, 0, 0, 0, 0, 0, 0]), Some(1));
        assert_eq!(decode_time(&[1, 0, 0]), None);
    }
}
