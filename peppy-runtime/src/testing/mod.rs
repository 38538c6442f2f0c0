//! Testing one node without a stack: what the generated test surfaces
//! (`peppygen::mock`, `peppygen::fixtures`, see docs/TESTING.md) run on.
//!
//! A [`Harness`] runs the node's own `setup` in-process against mock
//! producers over the real wire:
//!
//! 1. a private Zenoh router on a free loopback port, one per harness, so
//!    tests in parallel share nothing;
//! 2. one [`MockProducer`] per slot (its own session and identity,
//!    `mock-<link_id>`), serving what the slot consumes;
//! 3. the *fixture*, a consumer of the node bound to it, subscribed to
//!    every topic the node emits ([`Tap`]) and calling what it serves;
//! 4. the stack clock ([`TestClock`]);
//! 5. the node itself, seeded as a launcher would: the router's address,
//!    its instance id, its parameters (defaults from its document), each
//!    slot bound to its mocks;
//! 6. barriers, not sleeps: the node's publishers see the taps, the node
//!    reaches every mock and the fixture reaches the node;
//! 7. only then `setup`, spawned; [`Harness::shutdown`] stops the node the
//!    way a stop does (token, shutdown hooks, messaging) and returns
//!    setup's error, or its panic as an error.
//!
//! A node failing (setup returning an error or panicking) ends every wait
//! of its harness, mocks and taps with that failure: a test fails with
//! the node's message instead of hanging.
//!
//! The stack clock of a process is one: harnesses serving simulated time
//! run one at a time, and none runs beside them (wall-time harnesses run
//! together).

mod clock;
mod fixture;
mod mocks;
mod pairs;
mod router;
mod turned;
mod watch;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppy_schema::names::mock_instance_id;
use peppy_schema::{Cardinality, Identity, NodeModel, SlotKind};
use serde_json::Value as Json;
use tokio::task::JoinHandle;

pub use crate::actions::{CancelState, Outcome};
pub use clock::TestClock;
pub use fixture::{GoalHandle, Tap};
pub use mocks::{
    ActionMock, ActiveGoal, EXTERNAL_INSTANCE, MockProducer, PendingGoal, RejectReason, Responder,
    SUBSCRIBER_WAIT, ServiceMock, SlotSpec, Stopping, TopicMock,
};
pub use pairs::{
    MOCK_PEER_SLOT, MOCK_SOURCE_SLOT, PairMock, PairTopicMock, PairTopicReader, PairingSlotSpec,
};

use crate::actions::send_goal;
use crate::error::{Error, Result};
use crate::node::{NodeBuilder, NodeRunner};
use crate::producer_ref::ProducerRef;
use crate::spec::{ActionSpec, NodeParameters, ServiceSpec, TopicSpec};
use crate::startup::StandaloneConfig;
use crate::wire::codec::{Decode, Encode};
use crate::wire::keys::describe_key;
use watch::Watch;

/// The core node of the node a harness runs (as a standalone run's is).
pub const HARNESS_CORE: &str = "standalone-core";

/// The core node of the harness's own session, the fixture that taps the
/// node's topics and calls its services and actions (PeppyOS's
/// `fixture-core`).
pub const FIXTURE_CORE: &str = "fixture-core";

/// The fixture session's instance id (PeppyOS's `fixture-observer`); each
/// harness has a router of its own, so one id serves them all.
pub const FIXTURE_INSTANCE_ID: &str = "fixture-observer";

/// The core node of the harness's mocks (PeppyOS's `mock-core`): a mock is
/// `ProducerRef { core_node: "mock-core", instance_id: "mock-<link_id>" }`.
pub const MOCK_CORE: &str = "mock-core";

/// How long each start-up barrier may take.
const BARRIER: Duration = Duration::from_secs(10);

/// How long [`Harness::shutdown`] lets a setup still running end by itself
/// once the node is stopping, before dropping it (as a stop does).
const SETUP_STOP_BOUND: Duration = Duration::from_millis(500);

/// Sim-time harnesses run alone (write); the rest together (read).
static CLOCK_USE: tokio::sync::RwLock<()> = tokio::sync::RwLock::const_new(());

/// Instance ids handed out in this process.
static NEXT_INSTANCE: AtomicU64 = AtomicU64::new(0);

/// How many mocks one slot gets.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum SlotMocks {
    /// One for a `one`, `zero_or_one` or `one_or_more` slot (and a
    /// `node_v1` `from_any` slot), none for `zero_or_more`.
    #[default]
    Default,
    /// This many (`mock-<link_id>-<n>`, n from 0).
    Count(usize),
    /// These instance ids, in order.
    Named(Vec<String>),
    /// None, the slot left vacant (`zero_or_one` slots only).
    Vacant,
}

/// How a harness starts its node.
#[derive(Debug, Clone, Default)]
pub struct HarnessConfig {
    /// The parameters (JSON of the node's `Parameters`); `None` takes the
    /// defaults of its document, as a launch does.
    pub parameters: Option<Json>,
    /// The node's instance id; `None` makes one (`test-<pid>-<n>`).
    pub instance_id: Option<String>,
    /// Serve simulated time instead of wall time.
    pub use_sim_time: bool,
    /// Mocks per slot (by link_id); a slot not named gets
    /// [`SlotMocks::Default`].
    pub slots: Vec<(String, SlotMocks)>,
}

/// The mocks a harness started, by slot, for generated code to type.
#[derive(Debug, Default)]
pub struct MockSet {
    by_slot: HashMap<String, Vec<MockProducer>>,
    by_pairing: HashMap<String, Vec<PairMock>>,
}

impl MockSet {
    /// Takes the mocks of slot `link_id` (none after the first call).
    pub fn take(&mut self, link_id: &str) -> Vec<MockProducer> {
        self.by_slot.remove(link_id).unwrap_or_default()
    }

    /// Takes the mocks of pairing slot `link_id`: its peer, or its
    /// observed sources (none after the first call).
    pub fn take_pairing(&mut self, link_id: &str) -> Vec<PairMock> {
        self.by_pairing.remove(link_id).unwrap_or_default()
    }
}

/// What happened to the node's setup.
#[derive(Default)]
struct SetupState {
    finished: AtomicBool,
    error: Mutex<Option<Error>>,
}

/// One node running in-process against mocks: see the [module
/// docs](self).
pub struct Harness {
    node: Arc<NodeRunner>,
    fixture: Arc<NodeRunner>,
    turned: &'static fixture::Turned,
    setup: Option<JoinHandle<()>>,
    state: Arc<SetupState>,
    watch: Watch,
    clock: Arc<TestClock>,
    _core: crate::core_functions::CoreFunctions,
    router: router::PrivateRouter,
    _clock_use: ClockUse,
}

/// What a harness answers as the node's core node.
struct HarnessView {
    identity: Identity,
    instance_id: String,
    port: u16,
    started: std::time::Instant,
}

impl crate::core_functions::CoreView for HarnessView {
    fn info(&self) -> crate::info::InfoResponse {
        crate::info::InfoResponse {
            uptime_secs: self.started.elapsed().as_secs(),
            core_node_name: HARNESS_CORE.to_string(),
            core_node_instance_id: format!("harness-{}", self.instance_id),
            host_name: String::new(),
            node_count: 1,
            git_version: format!("peppy test harness {}", env!("CARGO_PKG_VERSION")),
            container_info: Default::default(),
            messaging_port: self.port,
        }
    }

    fn graph(&self, live: &std::collections::HashSet<String>) -> crate::stack::SerializedNodeGraph {
        use crate::stack::{InstanceState, NodeStage, SerializedInstance, SerializedNode};
        let up = live.contains(&self.instance_id);
        crate::stack::SerializedNodeGraph {
            nodes: vec![SerializedNode {
                name: self.identity.name.clone(),
                tag: self.identity.tag.clone(),
                core_node: HARNESS_CORE.to_string(),
                config_path: String::new(),
                artifact_path: None,
                stage: Some(NodeStage::Ready),
                instances: vec![SerializedInstance {
                    instance_id: self.instance_id.clone(),
                    state: if up {
                        InstanceState::Running
                    } else {
                        InstanceState::Starting
                    },
                    healthy: up,
                    slot_bindings: Default::default(),
                    pairing_slots: Default::default(),
                }],
            }],
            edges: Vec::new(),
        }
    }
}

enum ClockUse {
    Shared(#[allow(dead_code)] tokio::sync::RwLockReadGuard<'static, ()>),
    Alone(#[allow(dead_code)] tokio::sync::RwLockWriteGuard<'static, ()>),
}

impl std::fmt::Debug for Harness {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Harness")
            .field("node", &self.node)
            .field("port", &self.router.port)
            .finish_non_exhaustive()
    }
}

/// Shows what the node logs (and what the harness drops) in the test's
/// output; `RUST_LOG` picks the level.
fn init_test_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("RUST_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_test_writer()
        .try_init();
}

/// A panic's message.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(a panic without a message)".into())
}

/// Waits until `session` gets an answer on `key` (an instance's
/// description): the instance's queryables, declared before it, are then
/// known to `session` too.
async fn reachable(session: &zenoh::Session, key: &str, what: &str) -> Result<()> {
    let deadline = tokio::time::Instant::now() + BARRIER;
    loop {
        let replies = session.get(key).timeout(Duration::from_millis(250)).await?;
        while let Ok(reply) = replies.recv_async().await {
            if reply.result().is_ok() {
                return Ok(());
            }
        }
        if tokio::time::Instant::now() >= deadline {
            return Err(watch::timed_out(what, BARRIER));
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

impl Harness {
    /// Starts the node of `P` with `setup` against mocks of its slots
    /// (`slots`: the consumed entries of each, from generated code; the
    /// one whose link_id is empty lists the node's external consumed
    /// topics, published by one mock of its own, `mock-external`).
    /// Returns once every barrier passed and `setup` is spawned; a setup
    /// that fails makes [`Harness::shutdown`] return its error.
    pub async fn start<P, F, Fut>(
        slots: &'static [&'static SlotSpec],
        config: HarnessConfig,
        setup: F,
    ) -> Result<(Harness, MockSet)>
    where
        P: NodeParameters,
        F: FnOnce(P, Arc<NodeRunner>) -> Fut,
        Fut: Future<Output = Result<()>> + Send + 'static,
    {
        Harness::start_paired(slots, &[], config, setup).await
    }

    /// [`Harness::start`] for a node with pairing slots (`pairings`, from
    /// generated code): each participant slot is pinned to a mock peer
    /// (`mock-<link_id>`, slot [`MOCK_PEER_SLOT`]) and `setup` runs once
    /// the pair holds; each observer slot watches mock sources (slot
    /// [`MOCK_SOURCE_SLOT`]), as many as its cardinality's default (the
    /// config's `slots` entry of the link_id overrides it, as for other
    /// list slots).
    pub async fn start_paired<P, F, Fut>(
        slots: &'static [&'static SlotSpec],
        pairings: &'static [&'static PairingSlotSpec],
        config: HarnessConfig,
        setup: F,
    ) -> Result<(Harness, MockSet)>
    where
        P: NodeParameters,
        F: FnOnce(P, Arc<NodeRunner>) -> Fut,
        Fut: Future<Output = Result<()>> + Send + 'static,
    {
        init_test_logging();
        let descriptor = P::descriptor();
        let model = NodeModel::from_json(descriptor.model).map_err(|e| {
            Error::Startup(format!(
                "the model of `{}` compiled into this test is unreadable (rebuild it): {e}",
                descriptor.document_path
            ))
        })?;
        let clock_use = if config.use_sim_time {
            ClockUse::Alone(CLOCK_USE.write().await)
        } else {
            ClockUse::Shared(CLOCK_USE.read().await)
        };
        let instance_id = config.instance_id.clone().unwrap_or_else(|| {
            format!(
                "test-{}-{}",
                std::process::id(),
                NEXT_INSTANCE.fetch_add(1, Ordering::Relaxed)
            )
        });
        let router = router::PrivateRouter::start().await?;
        let port = router.port;
        let namespace = crate::DEFAULT_NAMESPACE;
        let mut clock = TestClock::serve(router.session(), namespace, config.use_sim_time).await?;
        // The harness is the node's core node: a datastore of the test's
        // own, `info`, and a stack of the node and its mocks.
        let core = crate::core_functions::serve(
            router.session(),
            namespace,
            HARNESS_CORE,
            Arc::new(HarnessView {
                identity: model.identity.clone(),
                instance_id: instance_id.clone(),
                port,
                started: std::time::Instant::now(),
            }),
        )
        .await?;
        let watch = Watch::default();

        let mut standalone = StandaloneConfig::new()
            .with_instance_id(instance_id.clone())
            .with_messaging("127.0.0.1", port)
            .with_core_node(HARNESS_CORE)
            .with_use_sim_time(config.use_sim_time);
        if let Some(p) = &config.parameters {
            standalone = standalone.with_parameters_json(p.clone());
        }
        let mut mocks = MockSet::default();
        for dep in &model.dependencies {
            let wanted = config
                .slots
                .iter()
                .find(|(l, _)| *l == dep.link_id)
                .map(|(_, m)| m.clone())
                .unwrap_or_default();
            let ids = mock_ids(&dep.link_id, dep.cardinality, dep.from_any, &wanted)?;
            if wanted == SlotMocks::Vacant {
                standalone = standalone.with_vacant_producer_slot(dep.link_id.clone());
                continue;
            }
            let Some(slot) = slots.iter().find(|s| s.link_id == dep.link_id) else {
                return Err(Error::Testing(format!(
                    "slot `{}` has no mock description: regenerate the node's code (peppy-launch sync)",
                    dep.link_id
                )));
            };
            let identity = match dep.kind {
                // A node slot follows its node's instances by identity.
                SlotKind::Node => dep.target.clone(),
                SlotKind::Interface => Identity::new(format!("mock_{}", dep.link_id), "v1"),
            };
            let mut started = Vec::new();
            for id in ids {
                standalone =
                    standalone.with_bound_producer(dep.link_id.clone(), MOCK_CORE, id.clone());
                started.push(
                    MockProducer::start(slot, identity.clone(), &id, port, watch.clone()).await?,
                );
            }
            mocks.by_slot.insert(dep.link_id.clone(), started);
        }

        if let Some(external) = slots.iter().find(|s| s.link_id.is_empty()) {
            let identity = Identity::new(mocks::EXTERNAL_NAME, mocks::EXTERNAL_TAG);
            let mock =
                MockProducer::start(external, identity, EXTERNAL_INSTANCE, port, watch.clone())
                    .await?;
            mocks.by_slot.insert(String::new(), vec![mock]);
        }

        let mut unpaired_slots = Vec::new();
        for slot in &model.pairings {
            let Some(spec) = pairings.iter().find(|s| s.link_id == slot.link_id) else {
                return Err(Error::Testing(format!(
                    "pairing slot `{}` has no mock description: regenerate the node's code (peppy-launch sync)",
                    slot.link_id
                )));
            };
            let wanted = config
                .slots
                .iter()
                .find(|(l, _)| *l == slot.link_id)
                .map(|(_, m)| m.clone())
                .unwrap_or_default();
            let (ids, mock_slot) = if slot.observer {
                let ids = mock_ids(&slot.link_id, slot.cardinality, false, &wanted)?;
                (ids, MOCK_SOURCE_SLOT)
            } else {
                (vec![mock_instance_id(&slot.link_id, None)], MOCK_PEER_SLOT)
            };
            // An optional participant left unpaired: its mock peer runs
            // (the test may still read from it, and pair it later), but
            // neither side names the other.
            let unpaired = !slot.observer && wanted == SlotMocks::Vacant;
            if unpaired && !slot.optional {
                return Err(Error::Testing(format!(
                    "pairing slot `{}` cannot start unpaired: it is not `optional`",
                    slot.link_id
                )));
            }
            if unpaired {
                unpaired_slots.push(slot.link_id.clone());
            }
            let mut started = Vec::new();
            for id in ids {
                if !unpaired {
                    standalone = standalone.with_bound_producer(
                        slot.link_id.clone(),
                        MOCK_CORE,
                        format!("{id}/{mock_slot}"),
                    );
                }
                let node_end = (!unpaired).then_some(instance_id.as_str());
                started.push(
                    PairMock::start(spec, slot, &instance_id, node_end, &id, port, watch.clone())
                        .await?,
                );
            }
            mocks.by_pairing.insert(slot.link_id.clone(), started);
        }

        let turned = fixture::turned(descriptor, &model.identity);
        let fixture = fixture::open(turned, &model.identity, &instance_id, port).await?;

        let (params, node) = NodeBuilder::<P>::new()
            .standalone(standalone)
            .with_args(["peppy-harness"])
            .with_runtime_config(None)
            .start()
            .await?;
        clock.watch_node(&node);
        for mock in mocks.by_slot.values().flatten() {
            mock.serve_subject(&node);
        }

        // Barriers: what the node emits reaches the taps from its first
        // message; what it calls answers from its first call; what the
        // test calls finds the node.
        for spec in descriptor.emitted_topics {
            if !mocks::readers_known(&node, spec, BARRIER).await {
                return Err(watch::timed_out(
                    &format!(
                        "the harness's subscription to topic `{}` to reach the node",
                        spec.name
                    ),
                    BARRIER,
                ));
            }
        }
        for producer in mocks.by_slot.values().flatten() {
            let key = describe_key(namespace, MOCK_CORE, producer.instance_id());
            let what = format!(
                "mock `{}` to be reachable from the node",
                producer.instance_id()
            );
            reachable(node.session(), &key, &what).await?;
        }
        // Pairs hold before setup runs: its first publish reaches the peer.
        for slot in model
            .pairings
            .iter()
            .filter(|s| !s.observer && !unpaired_slots.contains(&s.link_id))
        {
            let what = format!("pairing slot `{}` to pair with its mock", slot.link_id);
            let paired =
                tokio::time::timeout(BARRIER, crate::pairing::wait_paired(&node, &slot.link_id));
            match paired.await {
                Ok(Ok(_)) => {}
                Ok(Err(e)) => return Err(e),
                Err(_) => return Err(watch::timed_out(&what, BARRIER)),
            }
        }
        for mock in mocks.by_pairing.values().flatten() {
            mock.taps_reach(&node, BARRIER).await?;
        }
        let key = describe_key(namespace, HARNESS_CORE, &instance_id);
        reachable(
            fixture.session(),
            &key,
            "the node to be reachable from the harness",
        )
        .await?;

        let state = Arc::new(SetupState::default());
        // The flag is set by setup's own task as it returns, so a test that
        // saw what setup's spawned work did sees it set.
        let running = setup(params, node.clone());
        let finished = state.clone();
        let task = tokio::spawn(async move {
            let returned = running.await;
            if returned.is_ok() {
                finished.finished.store(true, Ordering::Release);
            }
            returned
        });
        let (done, failed) = (state.clone(), watch.clone());
        let setup = tokio::spawn(async move {
            let why = match task.await {
                Ok(Ok(())) => return,
                Ok(Err(e)) => {
                    let why = format!("setup failed: {e}");
                    *done.error.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                    why
                }
                Err(e) if e.is_panic() => {
                    let why = format!("setup panicked: {}", panic_message(&*e.into_panic()));
                    *done.error.lock().unwrap_or_else(|p| p.into_inner()) =
                        Some(Error::Testing(why.clone()));
                    why
                }
                // Dropped by the harness's own shutdown.
                Err(_) => return,
            };
            tracing::error!("{why}");
            failed.fail(why);
        });

        Ok((
            Harness {
                node,
                fixture,
                turned,
                setup: Some(setup),
                state,
                watch,
                clock: Arc::new(clock),
                _core: core,
                router,
                _clock_use: clock_use,
            },
            mocks,
        ))
    }

    /// The node under test's runner (its runtime surface, in-process).
    pub fn node_runner(&self) -> &Arc<NodeRunner> {
        &self.node
    }

    /// The harness's own session (the fixture's), which taps and calls use.
    pub fn session(&self) -> &zenoh::Session {
        self.fixture.session()
    }

    /// The node's instance id (`test-<pid>-<n>` unless configured).
    pub fn instance_id(&self) -> &str {
        self.node.instance_id()
    }

    /// The node as its consumers see it.
    pub fn node_producer_ref(&self) -> ProducerRef {
        ProducerRef::new(self.node.core_node(), self.node.instance_id())
    }

    /// Whether `setup` has returned `Ok` (a setup that runs its loop
    /// inline never does: assert on what it emits instead).
    pub fn setup_finished(&self) -> bool {
        self.state.finished.load(Ordering::Acquire)
    }

    /// The clock the harness serves the node.
    pub fn clock(&self) -> &Arc<TestClock> {
        &self.clock
    }

    /// The port of the harness's private router on 127.0.0.1.
    pub fn router_port(&self) -> u16 {
        self.router.port
    }

    /// The harness's tap of emitted topic `spec` (one per topic: taps of
    /// one topic share its queue).
    pub fn tap<M: Decode>(&self, spec: &'static TopicSpec) -> Result<Tap<M>> {
        let consumed = fixture::topic(self.turned, spec)?;
        Ok(Tap::new(self.fixture.clone(), consumed, self.watch.clone()))
    }

    /// Calls exposed service `spec` of the node once, as a consumer would.
    pub async fn poll<Req: Encode + ?Sized, Resp: Decode + Send>(
        &self,
        spec: &'static ServiceSpec,
        request: &Req,
        timeout: Duration,
    ) -> Result<Resp> {
        let consumed = fixture::service(self.turned, spec)?;
        self.watch
            .unbounded(fixture::poll(&self.fixture, consumed, request, timeout))
            .await
    }

    /// Sends a goal to exposed action `spec` of the node and waits up to
    /// `timeout` for its decision.
    pub async fn send_goal<G: Encode + ?Sized, F: Decode, R: Decode>(
        &self,
        spec: &'static ActionSpec,
        goal: &G,
        timeout: Duration,
    ) -> Result<GoalHandle<F, R>> {
        let consumed = fixture::action(self.turned, spec)?;
        let client = self
            .watch
            .unbounded(send_goal(&self.fixture, consumed, timeout, goal))
            .await?;
        Ok(GoalHandle::new(client, self.watch.clone()))
    }

    /// Stops the node as a stop does (its token fires, its shutdown hooks
    /// run within the grace window, its messaging closes), drops a setup
    /// still running, then closes the harness's session, the mocks'
    /// sessions (dropped with the returned mocks) and the router. Returns
    /// setup's error, or its panic as an error.
    pub async fn shutdown(mut self) -> Result<()> {
        self.node.shutdown().await;
        if let Some(mut setup) = self.setup.take()
            && tokio::time::timeout(SETUP_STOP_BOUND, &mut setup)
                .await
                .is_err()
        {
            setup.abort();
        }
        self.fixture.shutdown().await;
        self.router.close().await;
        match self
            .state
            .error
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

impl Drop for Harness {
    fn drop(&mut self) {
        // Not shut down: the node's token still fires, so its tasks end.
        self.node.cancellation_token().cancel();
        if let Some(setup) = self.setup.take() {
            setup.abort();
        }
    }
}

/// The instance ids of a slot's mocks.
fn mock_ids(
    link_id: &str,
    cardinality: Cardinality,
    from_any: bool,
    wanted: &SlotMocks,
) -> Result<Vec<String>> {
    let count = match wanted {
        SlotMocks::Named(ids) => return Ok(ids.clone()),
        SlotMocks::Vacant if cardinality == Cardinality::ZeroOrOne => return Ok(Vec::new()),
        SlotMocks::Vacant => {
            return Err(Error::Testing(format!(
                "slot `{link_id}` cannot be left vacant: its cardinality is `{cardinality}` (only `zero_or_one` slots are)"
            )));
        }
        SlotMocks::Count(n) => *n,
        SlotMocks::Default if from_any => 1,
        SlotMocks::Default => usize::from(cardinality != Cardinality::ZeroOrMore),
    };
    let fits = match cardinality {
        Cardinality::One => count == 1,
        Cardinality::ZeroOrOne => count <= 1,
        Cardinality::OneOrMore => count >= 1,
        Cardinality::ZeroOrMore => true,
    };
    if !fits {
        return Err(Error::Testing(format!(
            "slot `{link_id}` takes `{cardinality}` producers, not {count} mocks"
        )));
    }
    Ok(match (count, cardinality.is_scalar()) {
        (1, true) => vec![mock_instance_id(link_id, None)],
        _ => (0..count)
            .map(|n| mock_instance_id(link_id, Some(n)))
            .collect(),
    })
}
