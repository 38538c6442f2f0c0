//! The clock a harness serves its node, driven by the test.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::time::Duration;

use crate::clock::ClockServer;
use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::wire::keys::{ClockSource, clock_tick_key};

/// How long [`TestClock::tick`] waits for the node to see a tick.
const TICK_WAIT: Duration = Duration::from_secs(10);

/// The stack clock as a test drives it: the harness serves its node the
/// launcher's side of the clock (`clock/sync` answers and ticks), in wall
/// time (the OS clock, moved by [`TestClock::set_offset_ns`]) or, with
/// `use_sim_time`, in simulated time that moves only on
/// [`TestClock::tick`].
pub struct TestClock {
    router: zenoh::Session,
    namespace: String,
    sim: bool,
    offset: Arc<AtomicI64>,
    /// The last sim time ticked.
    now: AtomicU64,
    node: std::sync::Weak<NodeRunner>,
    _server: ClockServer,
}

impl std::fmt::Debug for TestClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TestClock")
            .field("sim", &self.sim)
            .field("offset_ns", &self.offset.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

impl TestClock {
    pub(crate) async fn serve(
        router: &zenoh::Session,
        namespace: &str,
        sim: bool,
    ) -> Result<TestClock> {
        let offset = Arc::new(AtomicI64::new(0));
        let server = crate::clock::serve_with(router, namespace, offset.clone()).await?;
        Ok(TestClock {
            router: router.clone(),
            namespace: namespace.to_string(),
            sim,
            offset,
            now: AtomicU64::new(0),
            node: std::sync::Weak::new(),
            _server: server,
        })
    }

    pub(crate) fn watch_node(&mut self, node: &Arc<NodeRunner>) {
        self.node = Arc::downgrade(node);
    }

    /// Whether the clock serves simulated time.
    pub fn is_sim(&self) -> bool {
        self.sim
    }

    /// Moves the wall clock the harness serves by `offset_ns` (signed):
    /// `clock::synchronize` on the node then measures that offset. An
    /// error on a sim-time clock, which has no wall time to move.
    pub fn set_offset_ns(&self, offset_ns: i64) -> Result<()> {
        if self.sim {
            return Err(Error::Testing(
                "set_offset_ns moves the wall clock, and this harness serves sim time (use tick)"
                    .into(),
            ));
        }
        self.offset.store(offset_ns, Ordering::Relaxed);
        Ok(())
    }

    /// Moves simulated time `delta_ns` past the last tick (from 0), as
    /// [`TestClock::tick`] does.
    pub async fn advance(&self, delta_ns: u64) -> Result<()> {
        let to = self.now.load(Ordering::Relaxed).saturating_add(delta_ns);
        self.tick(to).await
    }

    /// The last sim time ticked (0 before the first).
    pub fn sim_now_ns(&self) -> u64 {
        self.now.load(Ordering::Relaxed)
    }

    /// Publishes `time_ns` as the stack's simulated time and returns once
    /// the node's clock reads it, so the next `clock::now_ns()` on the node
    /// gives `time_ns`. An error on a wall-time clock, and when the node
    /// has not bound its clock (`clock::init`) within 10 s.
    pub async fn tick(&self, time_ns: u64) -> Result<()> {
        if !self.sim {
            return Err(Error::Testing(
                "tick publishes sim time, and this harness serves wall time (start it with use_sim_time)"
                    .into(),
            ));
        }
        let key = clock_tick_key(&self.namespace, ClockSource::Sim);
        let deadline = tokio::time::Instant::now() + TICK_WAIT;
        loop {
            // Published again until seen: the node's subscription may not
            // have reached the router when the first one went out.
            self.router
                .put(key.as_str(), time_ns.to_le_bytes().to_vec())
                .await?;
            let seen = self
                .node
                .upgrade()
                .and_then(|node| crate::clock::sim_time_seen_by(&node));
            if seen == Some(Some(time_ns)) {
                self.now.store(time_ns, Ordering::Relaxed);
                return Ok(());
            }
            if tokio::time::Instant::now() >= deadline {
                return Err(Error::Testing(format!(
                    "tick({time_ns}): the node's clock did not read it within {} s; does the node call clock::init (with use_sim_time)?",
                    TICK_WAIT.as_secs()
                )));
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }
}
