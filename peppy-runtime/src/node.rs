//! The node entry point ([`NodeBuilder`]) and the handle node code works
//! with ([`NodeRunner`]).

use std::collections::HashMap;
use std::future::Future;
use std::marker::PhantomData;
use std::panic::Location;
use std::path::PathBuf;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppy_schema::{Identity, NodeModel, SlotBinding, SlotKind, SlotPlan};
use tokio_util::sync::CancellationToken;
use tracing::{debug, error, info, warn};
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::query::Queryable;

use crate::acks::Acker;
use crate::actions::{self, DEFAULT_RESULT_RETENTION, PendingGoal, Registry};
use crate::describe::{
    self, ConsumedTopic, EmittedTopic, InstanceInfo, OwnerInfo, ServedAction, ServedService,
    SlotInfo,
};
use crate::error::{Error, Result};
use crate::members::Members;
use crate::pairing::{self, Pairings};
use crate::producer_ref::ProducerRef;
use crate::producers::Declarer;
use crate::qos;
use crate::request::RequestKeys;
use crate::services::{self, ServiceInbox};
use crate::shm::{SharedMemory, Shm};
use crate::spec::{
    ActionSpec, ConsumedTopicSpec, NodeDescriptor, NodeParameters, OwnerSpec, ServiceSpec,
    TopicSpec,
};
use crate::startup::{self, RUNTIME_CONFIG_ENV, StandaloneConfig, StartupConfig};
use crate::topics::{self, Inbox, Intake};
use crate::wire::attachment;
use crate::wire::keys::{
    ActionPart, Channel, action_part_key, describe_key, entry_key, entry_selector, format_key,
    liveliness_key,
};

/// How long [`NodeBuilder::run`] waits, once the node has shut down, for
/// its tasks that do not yield and its blocking tasks before it returns.
const TASKS_STOP_BOUND: std::time::Duration = std::time::Duration::from_millis(250);

/// Builds and runs a node: reads its start-up inputs, opens one Zenoh
/// session, declares every subscription and service, runs your setup code,
/// then keeps the node up until Ctrl-C, SIGTERM or
/// [`NodeRunner::cancellation_token`] fires.
pub struct NodeBuilder<P> {
    standalone: StandaloneConfig,
    args: Option<Vec<String>>,
    runtime_config: Option<Option<PathBuf>>,
    retention: std::time::Duration,
    shared_memory: SharedMemory,
    shutdown_grace: Option<Duration>,
    _parameters: PhantomData<fn() -> P>,
}

impl<P: NodeParameters> Default for NodeBuilder<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P: NodeParameters> NodeBuilder<P> {
    /// A builder reading the process's command line and environment.
    pub fn new() -> Self {
        NodeBuilder {
            standalone: StandaloneConfig::default(),
            args: None,
            runtime_config: None,
            retention: DEFAULT_RESULT_RETENTION,
            shared_memory: SharedMemory::default(),
            shutdown_grace: None,
            _parameters: PhantomData,
        }
    }

    /// Fallbacks for a plain `cargo run` without a launcher.
    pub fn standalone(mut self, config: StandaloneConfig) -> Self {
        self.standalone = config;
        self
    }

    /// Uses these arguments instead of the process's (the first is the program name).
    pub fn with_args<I: IntoIterator<Item = S>, S: Into<String>>(mut self, args: I) -> Self {
        self.args = Some(args.into_iter().map(Into::into).collect());
        self
    }

    /// Uses this runtime-config file (or none) instead of `PEPPY_RUNTIME_CONFIG`.
    pub fn with_runtime_config(mut self, path: Option<PathBuf>) -> Self {
        self.runtime_config = Some(path);
        self
    }

    /// How long exposed actions keep a finished goal's result for its
    /// caller (default 30 s); after that the caller gets `Expired`.
    pub fn action_result_retention(mut self, retention: std::time::Duration) -> Self {
        self.retention = retention;
        self
    }

    /// How emitted messages use shared memory (default: from 4 KiB, to
    /// readers on this host). `PEPPY_SHM` in the environment overrides it,
    /// so an operator can turn it off without a rebuild.
    pub fn shared_memory(mut self, settings: SharedMemory) -> Self {
        self.shared_memory = settings;
        self
    }

    /// How long the node's shutdown hooks ([`NodeRunner::on_shutdown`]) may
    /// take, all together (default 5 s). The launcher's runtime config
    /// (`shutdown_grace_secs`) takes precedence when it sets one, and
    /// `PEPPY_SHUTDOWN_GRACE_SECS` in the environment over both. The window
    /// must be longer than zero.
    pub fn shutdown_grace(mut self, grace: Duration) -> Self {
        self.shutdown_grace = Some(grace);
        self
    }

    /// Runs the node to completion on its own multi-threaded tokio runtime.
    /// `setup` runs once; spawn long-running work from it. Call it first
    /// thing in `main`, before the program starts threads of its own: then
    /// it sets Zenoh's thread layout for the process
    /// ([`threads::share_zenoh_threads`](crate::threads::share_zenoh_threads));
    /// with other threads already running, Zenoh keeps its default one.
    ///
    /// Every stop (Ctrl-C, SIGTERM, the cancellation token, `setup`
    /// returning an error) goes the same way: a `setup` still running is
    /// dropped; the cancellation token fires; the shutdown hooks run, last
    /// registered first, within one grace window, with messaging still up
    /// ([`NodeRunner::shutdown`]); messaging closes; then the spawned tasks
    /// are dropped at their next `.await`, and tasks that do not yield and
    /// blocking tasks are waited for at most 250 ms before `run` returns.
    /// A second SIGINT or SIGTERM while the hooks run ends the process at
    /// once, with exit status 128 + the signal's number.
    ///
    /// Returns `Ok(())` after a stop by signal or token (so `main` exits
    /// 0), and the error when start-up or `setup` failed (`main` then
    /// exits 1).
    pub fn run<F, Fut>(self, setup: F) -> Result<()>
    where
        F: FnOnce(P, Arc<NodeRunner>) -> Fut,
        Fut: Future<Output = Result<()>>,
    {
        // Before anything else: only while this is the process's one
        // thread may the environment be written.
        let sharing = crate::threads::share_zenoh_threads();
        init_logging();
        if sharing == crate::threads::Sharing::OtherThreads {
            tracing::debug!(
                "other threads run in this process: Zenoh keeps its default threads (docs/RUNNING.md)"
            );
        }
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .map_err(|e| Error::Startup(format!("cannot start the tokio runtime: {e}")))?;
        let result = runtime.block_on(async move {
            let (params, runner) = self.start().await?;
            // Listened to from here on: a signal is never lost between
            // setup and the wait, and a second one is seen during the hooks.
            let mut signals = Signals::listen();
            let outcome = {
                let stop = wait_for_stop(&runner, &mut signals);
                tokio::pin!(stop);
                tokio::select! {
                    r = setup(params, runner.clone()) => match r {
                        Ok(()) => {
                            stop.await;
                            Ok(())
                        }
                        Err(e) => {
                            // The error itself is logged once `run` ends.
                            info!("setup failed; shutting down");
                            Err(e)
                        }
                    },
                    () = &mut stop => Ok(()),
                }
            };
            tokio::select! {
                () = runner.shutdown() => {}
                signo = signals.second() => {
                    tracing::error!("signal {signo} again while stopping: exiting at once");
                    std::process::exit(128 + signo);
                }
            }
            outcome
        });
        // Dropping the runtime would wait for every task, forever for one
        // that never yields; the launcher would then SIGKILL the node.
        runtime.shutdown_timeout(TASKS_STOP_BOUND);
        if let Err(e) = &result {
            tracing::error!("{e}");
        }
        result
    }

    /// Starts the node inside an existing tokio runtime and returns its
    /// parameters and runner without waiting for a stop (tests, embedding).
    /// Call [`NodeRunner::shutdown`] when done.
    pub async fn start(self) -> Result<(P, Arc<NodeRunner>)> {
        let descriptor = P::descriptor();
        let doc = NodeModel::from_json(descriptor.model).map_err(|e| {
            Error::Startup(format!(
                "the model of `{}` compiled into this binary is unreadable (rebuild it): {e}",
                descriptor.document_path
            ))
        })?;
        let args = self.args.unwrap_or_else(|| std::env::args().collect());
        let config_file = self
            .runtime_config
            .unwrap_or_else(|| std::env::var_os(RUNTIME_CONFIG_ENV).map(PathBuf::from));
        let startup = startup::load(&doc, args, config_file, &self.standalone)?;
        let params: P = serde_json::from_value(startup.parameters.clone()).map_err(|e| {
            Error::Startup(format!(
                "parameters do not fit this node's Parameters type: {e}"
            ))
        })?;
        let shared_memory = crate::shm::usable(
            SharedMemory::from_env()
                .map_err(Error::Startup)?
                .unwrap_or(self.shared_memory),
        );
        let grace = startup::shutdown_grace(&startup, self.shutdown_grace)?;
        let runner = NodeRunner::open(
            &doc,
            descriptor,
            startup,
            self.retention,
            shared_memory,
            grace,
        )
        .await?;
        Ok((params, runner))
    }
}

fn init_logging() {
    // Zenoh's Unix-socket link warns on every link it opens from a client
    // socket, which has no path by nature (a launch's instances link over
    // them): not a fault anyone can act on.
    let filter = tracing_subscriber::EnvFilter::try_from_env("RUST_LOG").unwrap_or_else(|_| {
        tracing_subscriber::EnvFilter::new("info,zenoh=warn,zenoh_link_unixsock_stream=error")
    });
    // Colour only for a person at a terminal: the launcher pipes output.
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr())
        && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty());
    let _ = tracing_subscriber::fmt()
        .with_ansi(ansi)
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}

/// SIGINT and SIGTERM, and how many have arrived.
struct Signals {
    #[cfg(unix)]
    interrupt: Option<tokio::signal::unix::Signal>,
    #[cfg(unix)]
    terminate: Option<tokio::signal::unix::Signal>,
    seen: u32,
}

impl Signals {
    fn listen() -> Signals {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{SignalKind, signal};
            Signals {
                interrupt: signal(SignalKind::interrupt()).ok(),
                terminate: signal(SignalKind::terminate()).ok(),
                seen: 0,
            }
        }
        #[cfg(not(unix))]
        Signals { seen: 0 }
    }

    /// The next SIGINT or SIGTERM: its number.
    async fn next(&mut self) -> i32 {
        #[cfg(unix)]
        {
            async fn recv(s: Option<&mut tokio::signal::unix::Signal>) {
                match s {
                    Some(s) => {
                        s.recv().await;
                    }
                    None => std::future::pending().await,
                }
            }
            let signo = tokio::select! {
                () = recv(self.interrupt.as_mut()) => 2,
                () = recv(self.terminate.as_mut()) => 15,
            };
            self.seen += 1;
            signo
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
            self.seen += 1;
            2
        }
    }

    /// A signal that asks again: the second one overall (a stop by token
    /// or by a failed setup takes two, the first only confirming it).
    async fn second(&mut self) -> i32 {
        loop {
            let signo = self.next().await;
            if self.seen >= 2 {
                return signo;
            }
            info!("signal {signo} while stopping: send it again to exit at once");
        }
    }
}

async fn wait_for_stop(runner: &NodeRunner, signals: &mut Signals) {
    tokio::select! {
        signo = signals.next() => if signo == 2 {
            info!("interrupted; shutting down");
        } else {
            info!("terminated; shutting down");
        },
        () = runner.cancellation_token().cancelled() => info!("cancelled; shutting down"),
    }
}

/// What a node keeps per entry, keyed by the address of the entry's
/// generated spec (looked up on every message, so not with SipHash).
type ByAddress<V> = HashMap<usize, V, foldhash::fast::FixedState>;

fn address<T>(spec: &'static T) -> usize {
    spec as *const T as usize
}

/// A running node: its identity, its Zenoh session, and what generated code
/// uses to publish, receive and call.
pub struct NodeRunner {
    session: zenoh::Session,
    node_name: String,
    node_tag: String,
    instance_id: String,
    core_node: String,
    namespace: String,
    token: CancellationToken,
    slots: Vec<SlotPlan>,
    publishers: ByAddress<Outlet>,
    inboxes: ByAddress<Inbox>,
    service_inboxes: ByAddress<(ServiceInbox, KeyExpr<'static>)>,
    action_servers: ByAddress<(flume::Receiver<PendingGoal>, Arc<Registry>)>,
    entities: Mutex<Entities>,
    shm: Shm,
    /// Started with the first exposed service or action.
    acker: Option<Acker>,
    request_keys: RequestKeys,
    /// Each slot's bound producers as the peppylib API hands them out.
    bound: HashMap<String, Vec<ProducerRef>>,
    /// This runner, for what the peppylib API hands out that outlives a
    /// borrow of it (a declared publisher, a held subscription).
    me: std::sync::OnceLock<std::sync::Weak<NodeRunner>>,
    /// Fires when messaging closes, after the shutdown hooks: outgoing
    /// calls keep working until then.
    messaging: CancellationToken,
    hooks: Mutex<Hooks>,
    grace: Duration,
    use_sim_time: bool,
    /// Held by the one stop sequence; `true` once it has run.
    stopped: tokio::sync::Mutex<bool>,
    /// The pairing slots and their pairs.
    pairings: Pairings,
    /// The launch's directory of direct links (same host), if it gave one.
    direct_dir: Option<PathBuf>,
    /// This node's socket for direct links, while it is up.
    direct_listener: Option<crate::direct::outlet::Listener>,
    /// The topics that socket serves.
    direct_outlets: Arc<crate::direct::outlet::Outlets>,
}

/// A shutdown hook and where it was registered (its name in the logs).
struct Hook {
    /// `file:line`.
    at: String,
    run: Pin<Box<dyn Future<Output = ()> + Send>>,
}

#[derive(Default)]
struct Hooks {
    registered: Vec<Hook>,
    /// Set when the hooks start running: a hook registered later is too late.
    closed: bool,
}

#[derive(Default)]
struct Entities {
    subscribers: Vec<Subscriber<()>>,
    /// Pinned entries' subscriptions, which sole links move.
    #[cfg(unix)]
    feeds: Vec<Arc<crate::direct::feed::Feed>>,
    queryables: Vec<Queryable<()>>,
    /// Declared key expressions: dropping one undeclares it.
    keys: Vec<KeyExpr<'static>>,
    liveliness: Option<zenoh::liveliness::LivelinessToken>,
}

impl std::fmt::Debug for NodeRunner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NodeRunner")
            .field(
                "node",
                &format_args!("{}:{}", self.node_name, self.node_tag),
            )
            .field("instance_id", &self.instance_id)
            .field("namespace", &self.namespace)
            .finish_non_exhaustive()
    }
}

/// Opens the node's session. With shared memory on, Zenoh makes a segment
/// of its own in /dev/shm as it opens; a /dev/shm that is full, tiny or
/// read-only fails that, and the node would not start at all. It starts
/// with shared memory off instead (said once): large messages then go as
/// ordinary buffers, as the pool's own fallbacks send them.
async fn open_session(
    config: zenoh::Config,
    shared_memory: SharedMemory,
) -> Result<(zenoh::Session, SharedMemory)> {
    if !shared_memory.enabled() {
        return Ok((zenoh::open(config).await?, shared_memory));
    }
    let mut without = config.clone();
    match zenoh::open(config).await {
        Ok(session) => Ok((session, shared_memory)),
        Err(e) if e.to_string().to_lowercase().contains("shm") => {
            warn!(
                error = %e,
                "cannot set up shared memory (is /dev/shm full or read-only?); large messages are sent as ordinary buffers"
            );
            without
                .insert_json5("transport/shared_memory/enabled", "false")
                .map_err(|e| Error::Startup(format!("cannot turn shared memory off: {e}")))?;
            Ok((zenoh::open(without).await?, SharedMemory::off()))
        }
        Err(e) => Err(e.into()),
    }
}

impl NodeRunner {
    pub(crate) async fn open(
        doc: &NodeModel,
        descriptor: &'static NodeDescriptor,
        mut startup: StartupConfig,
        retention: std::time::Duration,
        shared_memory: SharedMemory,
        grace: Duration,
    ) -> Result<Arc<NodeRunner>> {
        // Zenoh's own copying of large payloads into a second pool is off
        // in every session peppy opens (`Endpoints::zenoh_config`): with
        // shared memory on, the node's threshold decides.
        let mut config = startup.zenoh.zenoh_config()?;
        if !shared_memory.enabled() {
            // No shared memory at all, as on another host.
            let key = "transport/shared_memory/enabled";
            config.insert_json5(key, "false").map_err(|e| {
                Error::Startup(format!("invalid shared-memory setting `{key}`: {e}"))
            })?;
        }
        let (session, shared_memory) = open_session(config, shared_memory).await?;
        let pair_plans = std::mem::take(&mut startup.pairs);
        let mut runner = NodeRunner {
            session,
            node_name: doc.identity.name.clone(),
            node_tag: doc.identity.tag.clone(),
            instance_id: startup.instance_id.clone(),
            core_node: startup.core_node.clone(),
            namespace: startup.namespace.clone(),
            token: CancellationToken::new(),
            bound: bound_refs(&startup.slots, &startup.core_node, &startup.producer_cores),
            slots: startup.slots,
            publishers: ByAddress::default(),
            inboxes: ByAddress::default(),
            service_inboxes: ByAddress::default(),
            action_servers: ByAddress::default(),
            entities: Mutex::new(Entities::default()),
            shm: Shm::new(shared_memory),
            acker: None,
            request_keys: RequestKeys::default(),
            me: std::sync::OnceLock::new(),
            messaging: CancellationToken::new(),
            hooks: Mutex::new(Hooks::default()),
            grace,
            use_sim_time: startup.use_sim_time,
            stopped: tokio::sync::Mutex::new(false),
            pairings: Pairings::default(),
            direct_dir: startup.direct_links.take(),
            direct_listener: None,
            direct_outlets: Arc::default(),
        };
        let mut entities = Entities::default();
        let started_at_ms = describe::now_ms();
        runner.declare_publishers(descriptor, &mut entities).await?;
        // A participant's pairing topics are served once their publishers
        // are declared, so its socket is up from the start too.
        runner.serve_direct_links(doc.pairings.iter().any(|p| !p.observer));
        runner.serve_formats(descriptor, &mut entities).await?;
        let direct = runner
            .direct_consumer(!descriptor.consumed_topics.is_empty() || !doc.pairings.is_empty());
        let consumes = runner
            .subscribe(descriptor, direct.as_ref(), &mut entities)
            .await?;
        runner.serve_services(descriptor, &mut entities).await?;
        runner
            .serve_actions(descriptor, retention, &mut entities)
            .await?;
        // Presence: withdrawn when the node shuts down or dies.
        let live = liveliness_key(
            &runner.namespace,
            &runner.core_node,
            &runner.instance_id,
            &runner.node_name,
            &runner.node_tag,
        );
        entities.liveliness = Some(runner.session.liveliness().declare_token(live).await?);
        // Claims are out as soon as the node is up: a peer started
        // earlier pairs with it at once.
        let tools = pairing::Tools {
            declarer: Declarer::start(runner.session.clone(), runner.token.clone()),
            mismatch: mismatch_reporter(runner.session.clone(), runner.namespace.clone()),
            direct,
        };
        let own = pairing::Own {
            session: &runner.session,
            ns: &runner.namespace,
            core: &runner.core_node,
            instance: &runner.instance_id,
        };
        let pairings =
            Pairings::start(own, &doc.pairings, &pair_plans, tools, &runner.token).await?;
        runner.pairings = pairings;
        let info = runner.describe(descriptor, consumes, started_at_ms);
        runner.serve_description(info, &mut entities).await?;
        runner.entities = Mutex::new(entities);
        info!(
            node = %format_args!("{}:{}", runner.node_name, runner.node_tag),
            instance = %runner.instance_id,
            namespace = %runner.namespace,
            "node up"
        );
        let runner = Arc::new(runner);
        let _ = runner.me.set(Arc::downgrade(&runner));
        Ok(runner)
    }

    /// One publisher per emitted topic, declared up front, and the key
    /// declared to every peer.
    async fn declare_publishers(
        &mut self,
        descriptor: &'static NodeDescriptor,
        entities: &mut Entities,
    ) -> Result<()> {
        for spec in descriptor.emitted_topics {
            let owner = spec
                .owner
                .resolve(&self.node_name, &self.node_tag)
                .expect("emitted topics have an owner");
            let key = entry_key(
                &self.namespace,
                Channel::Topic,
                &owner,
                spec.name,
                &self.core_node,
                &self.instance_id,
            );
            // A consumer subscribes with a wildcard (a slot does not know
            // its producer's launch), and Zenoh names a message by the
            // longest part of its key a peer has declared: without this,
            // every message carries the rest of its key after the
            // subscription's wildcard-free prefix as text, for the consumer
            // to resolve. A queryable is the declaration Zenoh passes on to
            // every peer; it answers nothing (WIRE.md §1).
            let declares_key = self
                .session
                .declare_queryable(key.clone())
                .callback(|_query| {})
                .await?;
            entities.queryables.push(declares_key);
            let publisher = self
                .session
                .declare_publisher(key)
                .congestion_control(qos::congestion(spec.qos))
                .priority(qos::priority(spec.qos))
                .express(qos::express(spec.qos))
                .await?;
            // Until a session has heard which subscriptions a new peer
            // holds, Zenoh sends it every message in case it wants them;
            // one in shared memory would make that peer map and lock the
            // producer's whole pool for nothing (each of 50 cameras mapped
            // every other camera's pool). Frames go through shared memory
            // only while a subscriber is known.
            let known = Arc::new(AtomicBool::new(
                publisher
                    .matching_status()
                    .await
                    .map_or(true, |s| s.matching()),
            ));
            let flag = known.clone();
            publisher
                .matching_listener()
                .callback(move |status| flag.store(status.matching(), Ordering::Relaxed))
                .background()
                .await?;
            self.publishers.insert(
                address(*spec),
                Outlet {
                    direct: self.direct_dir.as_ref().map(|_| {
                        Arc::new(crate::direct::outlet::DirectOutlet::new(
                            &self.session,
                            &publisher,
                            known.clone(),
                            spec.qos,
                            spec.format.fingerprint,
                        ))
                    }),
                    publisher,
                    readers_known: known,
                    attachment: ZBytes::from(attachment::topic(spec.format.fingerprint)),
                },
            );
        }
        Ok(())
    }

    /// Listens for consumers on this host that read the node's topics over
    /// direct links (docs/WIRE.md, "Direct links"): its emitted topics, and
    /// its pairing topics when it `pairs`.
    fn serve_direct_links(&mut self, pairs: bool) {
        let Some(dir) = &self.direct_dir else {
            return;
        };
        let mut served = pairs;
        for outlet in self.publishers.values().filter_map(|o| o.direct.as_ref()) {
            self.direct_outlets.add(outlet);
            served = true;
        }
        if !served {
            return;
        }
        let path = crate::direct::socket_path(dir, &self.core_node, &self.instance_id);
        self.direct_listener = crate::direct::outlet::serve(
            &path,
            self.direct_outlets.clone(),
            self.shm.settings().enabled(),
            self.token.clone(),
        );
    }

    /// Where the node reads producers on this host over direct links, when
    /// the launch gives it a directory for them and it `consumes` topics.
    fn direct_consumer(&self, consumes: bool) -> Option<Arc<crate::direct::inlet::Consumer>> {
        let dir = self.direct_dir.as_ref().filter(|_| consumes)?;
        Some(crate::direct::inlet::Consumer::new(
            dir.clone(),
            format!("{}/{}", self.core_node, self.instance_id),
            self.shm.settings().enabled(),
            tokio::runtime::Handle::current(),
            self.token.clone(),
        ))
    }

    /// The direct links of a pairing topic published by `publisher`, served
    /// by the node's socket while the publisher lives (none when the node
    /// has no socket).
    pub(crate) fn paired_outlet(
        &self,
        publisher: &zenoh::pubsub::Publisher<'static>,
        readers: &Arc<AtomicBool>,
        spec: &'static TopicSpec,
    ) -> Option<Arc<crate::direct::outlet::DirectOutlet>> {
        self.direct_listener.as_ref()?;
        let outlet = Arc::new(crate::direct::outlet::DirectOutlet::new(
            &self.session,
            publisher,
            readers.clone(),
            spec.qos,
            spec.format.fingerprint,
        ));
        self.direct_outlets.add(&outlet);
        Some(outlet)
    }

    /// The format queryables of emitted topics.
    async fn serve_formats(
        &self,
        descriptor: &'static NodeDescriptor,
        entities: &mut Entities,
    ) -> Result<()> {
        // Other nodes ask this node for the text of a format whose
        // fingerprint they do not know, to name both sides of a mismatch.
        let mut served = std::collections::HashSet::new();
        for spec in descriptor.emitted_topics {
            if !served.insert(spec.format.fingerprint) {
                continue;
            }
            let key = format_key(&self.namespace, spec.format.fingerprint, &self.instance_id);
            let canonical = spec.format.canonical;
            let reply_key = key.clone();
            let q = self
                .session
                .declare_queryable(key)
                .callback(move |q| {
                    let _ = zenoh::Wait::wait(
                        q.reply(reply_key.as_str(), canonical.as_bytes().to_vec()),
                    );
                })
                .await?;
            entities.queryables.push(q);
        }
        Ok(())
    }

    /// One subscription and inbox per consumed topic, for the node's life.
    /// Returns how each is routed, for the instance's description.
    async fn subscribe(
        &mut self,
        descriptor: &'static NodeDescriptor,
        direct: Option<&Arc<crate::direct::inlet::Consumer>>,
        entities: &mut Entities,
    ) -> Result<Vec<ConsumedTopic>> {
        let own = Identity::new(&self.node_name, &self.node_tag);
        let mut routes = Vec::new();
        let mismatch = mismatch_reporter(self.session.clone(), self.namespace.clone());
        let declarer = Declarer::start(self.session.clone(), self.token.clone());
        let mut trackers = HashMap::new();
        for spec in descriptor.consumed_topics {
            let filter = match spec.link_id {
                Some(link) => self.slot(link)?.filter.clone(),
                None => peppy_schema::RouteFilter::Any,
            };
            let members = match (spec.link_id, spec.owner) {
                (Some(link), OwnerSpec::Interface { .. }) => {
                    self.node_slot_members(link, &mut trackers).await?
                }
                _ => None,
            };
            let selector = topics::subscription_selector(self, spec, &filter);
            routes.push(ConsumedTopic {
                slot: spec.link_id.map(str::to_string),
                owner: describe::owner_info(&spec.owner, &own),
                name: spec.name.to_string(),
                qos: spec.qos,
                format: (&spec.format).into(),
                selector: selector.clone(),
                filter: filter.clone(),
                members_of: members
                    .is_some()
                    .then(|| spec.link_id.and_then(|l| self.slot(l).ok()))
                    .flatten()
                    .map(|s| s.target.clone()),
            });
            #[cfg(unix)]
            let pinned = matches!(filter, peppy_schema::RouteFilter::Pin(_));
            let (intake, inbox) =
                Intake::new(spec, filter, members, declarer.clone(), mismatch.clone());
            let intake = intake.linked(direct);
            let reader = intake.clone();
            let subscriber = self
                .session
                .declare_subscriber(selector.clone())
                .callback(move |s| reader.accept(s))
                .await?;
            #[cfg(unix)]
            if let Some(inlet) = intake.direct().filter(|_| pinned) {
                // Pinned to one producer: a sole link to it moves this
                // subscription to the producer's side key.
                let feed = crate::direct::feed::Feed::new(
                    self.session.clone(),
                    selector,
                    &intake,
                    subscriber,
                );
                inlet.bind_feed(&feed);
                entities.feeds.push(feed);
                self.inboxes.insert(address(*spec), inbox);
                continue;
            }
            entities.subscribers.push(subscriber);
            self.inboxes.insert(address(*spec), inbox);
        }
        Ok(routes)
    }

    /// What this instance is, serves and receives, as inspection tools see it.
    fn describe(
        &self,
        descriptor: &'static NodeDescriptor,
        consumes: Vec<ConsumedTopic>,
        started_at_ms: u64,
    ) -> InstanceInfo {
        let own = |o: &OwnerSpec| {
            describe::owner_info(o, &Identity::new(&self.node_name, &self.node_tag))
                .expect("served entries have an owner")
        };
        let key = |channel, o: &OwnerInfo, name| {
            entry_key(
                &self.namespace,
                channel,
                &o.as_owner(),
                name,
                &self.core_node,
                &self.instance_id,
            )
        };
        let emits = descriptor.emitted_topics.iter().map(|t| {
            let owner = own(&t.owner);
            EmittedTopic {
                key: key(Channel::Topic, &owner, t.name),
                owner,
                name: t.name.to_string(),
                qos: t.qos,
                format: (&t.format).into(),
            }
        });
        let services = descriptor.exposed_services.iter().map(|s| {
            let owner = own(&s.owner);
            ServedService {
                key: key(Channel::Service, &owner, s.name),
                owner,
                name: s.name.to_string(),
                request: (&s.request).into(),
                response: (&s.response).into(),
            }
        });
        let actions = descriptor.exposed_actions.iter().map(|a| {
            let owner = own(&a.owner);
            ServedAction {
                key: key(Channel::Action, &owner, a.name),
                owner,
                name: a.name.to_string(),
                goal: (&a.goal).into(),
                feedback: (&a.feedback).into(),
                result: (&a.result).into(),
            }
        });
        InstanceInfo {
            version: describe::DESCRIBE_VERSION,
            instance_id: self.instance_id.clone(),
            core_node: self.core_node.clone(),
            namespace: self.namespace.clone(),
            node: Identity::new(&self.node_name, &self.node_tag),
            pid: std::process::id(),
            started_at_ms,
            slots: self
                .slots
                .iter()
                .map(|s| SlotInfo {
                    link_id: s.link_id.clone(),
                    kind: s.kind,
                    target: s.target.clone(),
                    binding: s.binding.clone(),
                    filter: s.filter.clone(),
                })
                .collect(),
            emits: emits.collect(),
            consumes,
            services: services.collect(),
            actions: actions.collect(),
            pairings: self.pairings.info(),
        }
    }

    /// Answers `describe` queries for the node's whole life.
    async fn serve_description(&self, info: InstanceInfo, entities: &mut Entities) -> Result<()> {
        let key = describe_key(&self.namespace, &self.core_node, &self.instance_id);
        let (reply_key, body) = (key.clone(), info.to_json());
        // Pairs come and go: a node with pairing slots describes their
        // state as it is when asked.
        let pairings = self.pairings.clone();
        let q = self
            .session
            .declare_queryable(key)
            .callback(move |q| {
                let body = if pairings.is_empty() {
                    body.clone()
                } else {
                    let mut info = info.clone();
                    info.pairings = pairings.info();
                    info.to_json()
                };
                let _ = zenoh::Wait::wait(q.reply(reply_key.as_str(), body.into_bytes()));
            })
            .await?;
        entities.queryables.push(q);
        Ok(())
    }

    /// The node's acker, started on first use.
    fn acker(&mut self) -> Acker {
        let token = &self.token;
        self.acker
            .get_or_insert_with(|| Acker::start(token.clone()))
            .clone()
    }

    /// Declares the selector callers pinned to this instance ask an entry
    /// on (`part`: an action's goal queryable): the entry's key with any
    /// core node, which a slot does not know. The wildcard meant no
    /// resource of the session had it and Zenoh computed each request's
    /// route here; declared, the route is cached. Failing only costs that.
    async fn declare_pinned(
        &self,
        channel: Channel,
        owner: &OwnerSpec,
        name: &str,
        part: Option<ActionPart>,
        entities: &mut Entities,
    ) {
        let owner = owner.resolve(&self.node_name, &self.node_tag);
        let mut selector = entry_selector(
            &self.namespace,
            channel,
            owner.as_ref(),
            name,
            None,
            Some(&self.instance_id),
        );
        if let Some(part) = part {
            selector = action_part_key(&selector, part);
        }
        match self.session.declare_keyexpr(selector).await {
            Ok(key) => entities.keys.push(key),
            Err(e) => debug!(error = %e, "could not declare a pinned callers' selector"),
        }
    }

    /// One queryable and inbox per exposed service.
    async fn serve_services(
        &mut self,
        descriptor: &'static NodeDescriptor,
        entities: &mut Entities,
    ) -> Result<()> {
        for spec in descriptor.exposed_services {
            let key = services::server_key(self, spec);
            let (tx, rx) = flume::bounded(64);
            let acker = self.acker();
            let queryable = self
                .session
                .declare_queryable(key.clone())
                .complete(true)
                .callback(services::intake(spec, key.clone(), tx, acker))
                .await?;
            // Replies name the key as the queryable holds it, checked once
            // here rather than parsed from text on every reply.
            let reply_key = queryable.key_expr().clone();
            entities.queryables.push(queryable);
            self.declare_pinned(Channel::Service, &spec.owner, spec.name, None, entities)
                .await;
            self.service_inboxes
                .insert(address(*spec), (ServiceInbox { rx }, reply_key));
        }
        Ok(())
    }

    /// Each exposed action's goal, cancel and result queryables, its goal
    /// registry and the sweep that expires kept results.
    async fn serve_actions(
        &mut self,
        descriptor: &'static NodeDescriptor,
        retention: std::time::Duration,
        entities: &mut Entities,
    ) -> Result<()> {
        for spec in descriptor.exposed_actions {
            let base = actions::server_base_key(self, spec);
            let acker = self.acker();
            let registry = Registry::new(
                spec,
                base.clone(),
                self.session.clone(),
                retention,
                acker.clone(),
            );
            let (tx, rx) = flume::bounded(64);
            let goal_key = action_part_key(&base, ActionPart::Goal);
            let goal = self
                .session
                .declare_queryable(goal_key.clone())
                .complete(true)
                .callback(actions::goal_intake(spec, goal_key, tx, acker))
                .await?;
            let r = registry.clone();
            let cancel = self
                .session
                .declare_queryable(action_part_key(&base, ActionPart::Cancel))
                .complete(true)
                .callback(move |q| r.on_cancel(q))
                .await?;
            let r = registry.clone();
            let result = self
                .session
                .declare_queryable(action_part_key(&base, ActionPart::Result))
                .complete(true)
                .callback(move |q| r.on_result(q))
                .await?;
            entities.queryables.extend([goal, cancel, result]);
            let goal = Some(ActionPart::Goal);
            self.declare_pinned(Channel::Action, &spec.owner, spec.name, goal, entities)
                .await;
            let (r, token) = (registry.clone(), self.token.clone());
            tokio::spawn(async move {
                let mut tick = tokio::time::interval((retention / 4).clamp(
                    std::time::Duration::from_millis(10),
                    std::time::Duration::from_secs(1),
                ));
                loop {
                    tokio::select! {
                        _ = tick.tick() => r.sweep(),
                        () = token.cancelled() => break,
                    }
                }
            });
            self.action_servers.insert(address(*spec), (rx, registry));
        }
        Ok(())
    }

    /// This instance's id.
    pub fn instance_id(&self) -> &str {
        &self.instance_id
    }

    /// The launch that started this instance (`standalone` for `cargo run`).
    pub fn core_node(&self) -> &str {
        &self.core_node
    }

    /// The namespace every key of this node lives under.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// This node's name.
    pub fn node_name(&self) -> &str {
        &self.node_name
    }

    /// This node's tag.
    pub fn node_tag(&self) -> &str {
        &self.node_tag
    }

    /// Fires when the node stops; spawned tasks watch it to end cleanly.
    /// Cancelling it stops the node ([`NodeRunner::shutdown`]'s sequence,
    /// run by [`NodeBuilder::run`]).
    pub fn cancellation_token(&self) -> &CancellationToken {
        &self.token
    }

    /// Fires when messaging closes, once the shutdown hooks are done: what
    /// outgoing calls watch, so a hook can still call services.
    pub(crate) fn messaging_stop(&self) -> &CancellationToken {
        &self.messaging
    }

    /// Whether this node follows simulated time (`framework.use_sim_time`,
    /// `--use-sim-time`): see [`crate::clock`].
    pub fn use_sim_time(&self) -> bool {
        self.use_sim_time
    }

    /// How long the shutdown hooks may take, all together.
    pub fn shutdown_grace(&self) -> Duration {
        self.grace
    }

    /// Runs `hook` when the node stops: after the cancellation token fires
    /// and before messaging closes, so the hook can still emit and call
    /// services (to park an arm, flush a log, say goodbye). Hooks run one
    /// at a time, the last registered first, all within one grace window
    /// ([`NodeBuilder::shutdown_grace`], 5 s by default). A hook that
    /// panics is logged and skipped; one still running when the window
    /// ends is cut off (dropped at its next `.await`), and the hooks not
    /// yet run are skipped. The logs name each hook by where it was
    /// registered (`src/main.rs:42`).
    ///
    /// A hook registered once the hooks have started running is not run
    /// (a warning says so).
    #[track_caller]
    pub fn on_shutdown<F>(&self, hook: F)
    where
        F: Future<Output = ()> + Send + 'static,
    {
        let caller = Location::caller();
        let at = format!("{}:{}", caller.file(), caller.line());
        let mut hooks = self.hooks.lock().unwrap_or_else(|p| p.into_inner());
        if hooks.closed {
            warn!(
                "shutdown hook registered at {at} comes too late: the node's hooks have already run; it will not run"
            );
            return;
        }
        hooks.registered.push(Hook {
            at,
            run: Box::pin(hook),
        });
    }

    /// Runs the shutdown hooks, last registered first, within one grace
    /// window.
    async fn run_hooks(&self) {
        /// How long the last hook's messages get to leave before messaging
        /// closes: Zenoh holds a batch up to its batching time limit (1 ms by
        /// default) and may send the link's close ahead of it.
        const SETTLE: Duration = Duration::from_millis(10);
        let hooks = {
            let mut hooks = self.hooks.lock().unwrap_or_else(|p| p.into_inner());
            hooks.closed = true;
            std::mem::take(&mut hooks.registered)
        };
        if hooks.is_empty() {
            return;
        }
        let window = self.grace;
        let deadline = tokio::time::Instant::now() + window;
        let mut pending = hooks.into_iter().rev();
        while let Some(hook) = pending.next() {
            // On a task of its own: a panic is caught there, and the
            // window's end drops it wherever it is waiting.
            let task = tokio::spawn(hook.run);
            let abort = task.abort_handle();
            match tokio::time::timeout_at(deadline, task).await {
                Ok(Ok(())) => debug!("shutdown hook registered at {} done", hook.at),
                Ok(Err(e)) if e.is_panic() => {
                    let panic = e.into_panic();
                    let why = panic
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| panic.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "(no message)".into());
                    error!(
                        "shutdown hook registered at {} panicked: {why}; skipped",
                        hook.at
                    );
                }
                Ok(Err(e)) => warn!(
                    "shutdown hook registered at {} did not finish: {e}",
                    hook.at
                ),
                Err(_) => {
                    abort.abort();
                    warn!(
                        "shutdown hook registered at {} overran the {} s grace window; cut off",
                        hook.at,
                        window.as_secs_f64()
                    );
                    for skipped in pending.by_ref() {
                        warn!(
                            "shutdown hook registered at {} skipped: the {} s grace window is spent",
                            skipped.at,
                            window.as_secs_f64()
                        );
                    }
                }
            }
        }
        tokio::time::sleep(SETTLE).await;
    }

    /// The keys this node's requests go to, declared once each.
    pub(crate) fn request_keys(&self) -> &RequestKeys {
        &self.request_keys
    }

    /// The pairing slots of this instance.
    pub(crate) fn pairings(&self) -> &Pairings {
        &self.pairings
    }

    /// The Zenoh session, for anything peppy does not wrap.
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// The slots of this instance with what fills them.
    pub fn slots(&self) -> &[SlotPlan] {
        &self.slots
    }

    /// For a node slot, the tracker of its node's instances (shared by the
    /// slot's entries); `None` for an interface slot, whose key already
    /// names what it accepts.
    async fn node_slot_members(
        &self,
        link_id: &str,
        cache: &mut HashMap<String, Arc<Members>>,
    ) -> Result<Option<Arc<Members>>> {
        let slot = self.slot(link_id)?;
        if slot.kind != SlotKind::Node {
            return Ok(None);
        }
        if let Some(m) = cache.get(link_id) {
            return Ok(Some(m.clone()));
        }
        let m = Arc::new(
            Members::track(
                &self.session,
                &self.namespace,
                &slot.target.name,
                &slot.target.tag,
            )
            .await?,
        );
        cache.insert(link_id.to_string(), m.clone());
        Ok(Some(m))
    }

    /// The producer instances bound to slot `link_id`, in link order: the
    /// pinned producer, a set's producers, a `from_any` slot's explicit
    /// ones. Empty for a vacant or empty slot, an unbound `from_any` slot
    /// (it takes any producer, none named) and a link_id that names no
    /// slot. Fixed for the instance's life.
    pub fn bound_producers(&self, link_id: &str) -> &[String] {
        match self.slot(link_id).map(|s| &s.binding) {
            Ok(SlotBinding::Pinned { producer }) => std::slice::from_ref(producer),
            Ok(SlotBinding::Set { producers, .. } | SlotBinding::FromAnyBound { producers }) => {
                producers
            }
            Ok(SlotBinding::FromAnyUnbound) | Err(_) => &[],
        }
    }

    /// The producers bound to slot `link_id` as [`ProducerRef`]s, in link
    /// order (see [`NodeRunner::bound_producers`]).
    pub fn bound_producer_refs(&self, link_id: &str) -> &[ProducerRef] {
        self.bound.get(link_id).map_or(&[], Vec::as_slice)
    }

    /// This runner as an `Arc`, for what outlives a borrow of it.
    pub(crate) fn arc(&self) -> Result<Arc<NodeRunner>> {
        self.me
            .get()
            .and_then(std::sync::Weak::upgrade)
            .ok_or(Error::ShuttingDown)
    }

    /// The slot named `link_id`.
    pub fn slot(&self, link_id: &str) -> Result<&SlotPlan> {
        self.slots
            .iter()
            .find(|s| s.link_id == link_id)
            .ok_or_else(|| Error::Undeclared(format!("slot `{link_id}`")))
    }

    /// How this node's emitted messages use shared memory.
    pub fn shared_memory(&self) -> SharedMemory {
        self.shm.settings()
    }

    /// Sends messages of `topic` of at least `threshold` bytes through
    /// shared memory (`None`: never), overriding the node's threshold for
    /// that topic. Generated code offers it as
    /// `emitted_topics::<topic>::set_shm_threshold`.
    pub fn set_shm_threshold(&self, topic: &'static TopicSpec, threshold: Option<usize>) {
        self.shm.set_threshold(topic, threshold);
    }

    /// How many messages of `topic` have arrived in shared memory: read
    /// in place from the producer's pages rather than copied off a socket.
    pub fn received_in_shared_memory(&self, topic: &'static ConsumedTopicSpec) -> Result<u64> {
        Ok(self.inbox(topic)?.backlog.shared.load(Ordering::Relaxed))
    }

    /// How many messages of `topic` have arrived over direct links from
    /// producers of this launch on this host (docs/WIRE.md, "Direct
    /// links"), rather than through Zenoh.
    pub fn received_over_direct_links(&self, topic: &'static ConsumedTopicSpec) -> Result<u64> {
        Ok(self.inbox(topic)?.backlog.direct.load(Ordering::Relaxed))
    }

    /// How many consumers of this launch on this host read `topic` from
    /// this instance over a direct link now (one per consumer instance,
    /// however many of its entries read the topic).
    pub fn direct_links_served(&self, topic: &'static TopicSpec) -> usize {
        self.outlet(topic)
            .and_then(|o| o.direct.as_ref())
            .map_or(0, |d| d.links())
    }

    pub(crate) fn shm(&self) -> &Shm {
        &self.shm
    }

    pub(crate) fn outlet(&self, spec: &'static TopicSpec) -> Option<&Outlet> {
        self.publishers.get(&address(spec))
    }

    pub(crate) fn inbox(&self, spec: &'static ConsumedTopicSpec) -> Result<&Inbox> {
        self.inboxes
            .get(&address(spec))
            .ok_or_else(|| Error::Undeclared(format!("consumed topic `{}`", spec.name)))
    }

    /// An exposed service's inbox, and the key its replies carry.
    pub(crate) fn service_inbox(
        &self,
        spec: &'static ServiceSpec,
    ) -> Result<(&ServiceInbox, &KeyExpr<'static>)> {
        self.service_inboxes
            .get(&address(spec))
            .map(|(i, k)| (i, k))
            .ok_or_else(|| Error::Undeclared(format!("exposed service `{}`", spec.name)))
    }

    pub(crate) fn action_server(
        &self,
        spec: &'static ActionSpec,
    ) -> Result<(&flume::Receiver<PendingGoal>, &Arc<Registry>)> {
        self.action_servers
            .get(&address(spec))
            .map(|(rx, r)| (rx, r))
            .ok_or_else(|| Error::Undeclared(format!("exposed action `{}`", spec.name)))
    }

    /// Stops the node: cancels the token, runs the shutdown hooks
    /// ([`NodeRunner::on_shutdown`]) within the grace window, then
    /// undeclares every subscription and service and closes the session.
    /// Idempotent: a second call waits for the first to finish.
    pub async fn shutdown(&self) {
        let mut stopped = self.stopped.lock().await;
        if *stopped {
            return;
        }
        self.token.cancel();
        self.run_hooks().await;
        self.messaging.cancel();
        self.close_messaging().await;
        *stopped = true;
    }

    /// Undeclares every subscription and the liveliness token, and closes
    /// the session (which ends the rest).
    async fn close_messaging(&self) {
        let entities =
            std::mem::take(&mut *self.entities.lock().unwrap_or_else(|p| p.into_inner()));
        for s in entities.subscribers {
            let _ = s.undeclare().await;
        }
        #[cfg(unix)]
        for feed in entities.feeds {
            feed.close().await;
        }
        // The queryables go with the session: one declares each emitted
        // key (WIRE.md §1), and its undeclaration, sent ahead of data,
        // could overtake the last messages the shutdown hooks emitted,
        // which the router could then no longer name.
        let queryables = entities.queryables;
        // Consumers on this host read what the hooks sent over the links
        // (emitted and pairing topics alike), then hear of the end at once
        // rather than when the process exits.
        self.direct_outlets.close_all();
        if let Some(token) = entities.liveliness {
            let _ = token.undeclare().await;
        }
        if let Err(e) = self.session.close().await {
            warn!("closing the zenoh session: {e}");
        }
        drop(queryables);
    }
}

/// Every slot's bound producers as [`ProducerRef`]s. The plan names
/// producers by instance id, unique in a stack; they are placed on this
/// launch's core node unless `cores` says otherwise.
fn bound_refs(
    slots: &[SlotPlan],
    core_node: &str,
    cores: &std::collections::BTreeMap<String, String>,
) -> HashMap<String, Vec<ProducerRef>> {
    slots
        .iter()
        .map(|slot| {
            let producers = match &slot.binding {
                SlotBinding::Pinned { producer } => std::slice::from_ref(producer),
                SlotBinding::Set { producers, .. } | SlotBinding::FromAnyBound { producers } => {
                    producers.as_slice()
                }
                SlotBinding::FromAnyUnbound => &[],
            };
            let refs = producers
                .iter()
                .map(|p| {
                    let core = cores.get(p).map_or(core_node, String::as_str);
                    ProducerRef::new(core, p.as_str())
                })
                .collect();
            (slot.link_id.clone(), refs)
        })
        .collect()
}

/// An emitted topic's publisher, and whether Zenoh knows a subscriber
/// for it: only then does a large message go through shared memory.
pub(crate) struct Outlet {
    pub(crate) publisher: Publisher<'static>,
    /// Its direct links to consumers on this host, when the launch gives
    /// the node a directory for them.
    pub(crate) direct: Option<Arc<crate::direct::outlet::DirectOutlet>>,
    readers_known: Arc<AtomicBool>,
    /// The topic's attachment (its format's fingerprint), made once: each
    /// message shares it.
    pub(crate) attachment: ZBytes,
}

impl Outlet {
    /// Whether Zenoh knows a subscriber of this topic, or a consumer
    /// reads it through a sole link's side key.
    pub(crate) fn readers_known(&self) -> bool {
        self.readers_known.load(Ordering::Relaxed)
            || self.direct.as_ref().is_some_and(|d| d.sole_readers())
    }
}

/// Logs a fingerprint mismatch once per producer, naming both formats: the
/// producer's text is asked from the producer itself.
fn mismatch_reporter(
    session: zenoh::Session,
    ns: String,
) -> Arc<dyn Fn(&'static ConsumedTopicSpec, String, u64) + Send + Sync> {
    let handle = tokio::runtime::Handle::current();
    Arc::new(
        move |spec: &'static ConsumedTopicSpec, producer: String, theirs: u64| {
            let (session, ns) = (session.clone(), ns.clone());
            handle.spawn(
                async move { report_mismatch(&session, &ns, spec, &producer, theirs).await },
            );
        },
    )
}

async fn report_mismatch(
    session: &zenoh::Session,
    ns: &str,
    spec: &ConsumedTopicSpec,
    producer: &str,
    theirs: u64,
) {
    let wait = std::time::Duration::from_secs(2);
    let their_text = match crate::describe::ask_format(session, ns, theirs, producer, wait).await {
        Some(text) => format!("{text} (fingerprint {theirs:016x})"),
        None => format!("(fingerprint {theirs:016x})"),
    };
    warn!(
        "dropping topic `{}` from `{producer}`: it sends {their_text}, this node expects {} (fingerprint {:016x}); rebuild the two nodes against the same format",
        spec.name, spec.format.canonical, spec.format.fingerprint
    );
}
