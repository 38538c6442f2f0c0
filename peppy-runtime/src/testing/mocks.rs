//! Mock producers: each plays one producer of one of the node's slots over
//! the real wire. A mock is a node of its own (its own session, liveliness
//! token, publishers, queryables and action engine), built from the
//! slot's consumed entries turned around: what the slot consumes, the mock
//! emits; what the slot calls, the mock serves, under the same keys a real
//! producer uses.

use std::collections::VecDeque;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppy_schema::{Identity, NodeModel, ParameterSchema, Spelling};
use tokio::task::JoinHandle;
use tracing::warn;

use super::turned;
use super::watch::Watch;
use crate::actions::{DEFAULT_RESULT_RETENTION, GoalContext, GoalServer, IncomingGoal};
use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::producer_ref::ProducerRef;
use crate::services::{Answer, take_request};
use crate::spec::{
    ActionSpec, ConsumedActionSpec, ConsumedServiceSpec, ConsumedTopicSpec, NodeDescriptor,
    OwnerSpec, ServiceSpec, TopicSpec,
};
use crate::startup::{self, StandaloneConfig};
use crate::wire::codec::{Decode, Encode, from_bytes, to_bytes};
use crate::wire::struct_codec::MessageData;

/// How long a mock's first publish waits for the node's subscription.
pub const SUBSCRIBER_WAIT: Duration = Duration::from_secs(10);

/// The identity of the mock that publishes the node's external consumed
/// topics (those of no slot, heard from any producer).
pub(crate) const EXTERNAL_NAME: &str = "mock_external";
/// Its tag.
pub(crate) const EXTERNAL_TAG: &str = "v1";
/// Its instance id, and its key in [`super::MockSet`].
pub const EXTERNAL_INSTANCE: &str = "mock-external";

/// One slot of the node under test as generated code describes it: its
/// consumed entries, which its mocks serve.
#[derive(Debug)]
pub struct SlotSpec {
    /// The slot's link_id.
    pub link_id: &'static str,
    /// The topics the node consumes through it.
    pub topics: &'static [&'static ConsumedTopicSpec],
    /// The services the node calls through it.
    pub services: &'static [&'static ConsumedServiceSpec],
    /// The actions the node calls through it.
    pub actions: &'static [&'static ConsumedActionSpec],
}

/// A mock's node description: the slot's entries turned around.
type Turned = turned::Turned<TopicSpec, ServiceSpec, ActionSpec>;

static TURNED: Mutex<Vec<(usize, &'static Turned)>> = Mutex::new(Vec::new());

fn turned(slot: &'static SlotSpec) -> &'static Turned {
    turned::once(&TURNED, turned::address(slot), || {
        let topics = turned::Side::of(slot.topics, |c| TopicSpec {
            // An external topic is anyone's: the mock emits it as itself.
            owner: match c.owner {
                OwnerSpec::Any => OwnerSpec::Node {
                    name: EXTERNAL_NAME,
                    tag: EXTERNAL_TAG,
                },
                owner => owner,
            },
            name: c.name,
            qos: c.qos,
            format: c.format,
        });
        let services = turned::Side::of(slot.services, |c| ServiceSpec {
            owner: c.owner,
            name: c.name,
            request: c.request,
            response: c.response,
        });
        let actions = turned::Side::of(slot.actions, |c| ActionSpec {
            owner: c.owner,
            name: c.name,
            goal: c.goal,
            feedback: c.feedback,
            result: c.result,
        });
        Turned {
            descriptor: Box::leak(Box::new(NodeDescriptor {
                model: "",
                document_path: "(a test mock)",
                emitted_topics: topics.list,
                consumed_topics: &[],
                exposed_services: services.list,
                exposed_actions: actions.list,
            })),
            topics,
            services,
            actions,
        }
    })
}

/// One mock producer of one slot: a node of its own on the harness's
/// router. Its typed members come from [`MockProducer::topic`],
/// [`MockProducer::service`] and [`MockProducer::action`].
pub struct MockProducer {
    runner: Arc<NodeRunner>,
    slot: &'static SlotSpec,
    turned: &'static Turned,
    watch: Watch,
    pumps: Mutex<Vec<JoinHandle<()>>>,
    /// The node under test, once the harness started it: a topic's first
    /// publish waits until the node's code reads the topic.
    subject: std::sync::OnceLock<Arc<NodeRunner>>,
}

impl std::fmt::Debug for MockProducer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MockProducer")
            .field("slot", &self.slot.link_id)
            .field("instance_id", &self.runner.instance_id())
            .finish_non_exhaustive()
    }
}

impl MockProducer {
    /// Starts a mock of `slot` as instance `instance_id`, a node of
    /// identity `identity`, connected to the router on `port`.
    pub(crate) async fn start(
        slot: &'static SlotSpec,
        identity: Identity,
        instance_id: &str,
        port: u16,
        watch: Watch,
    ) -> Result<MockProducer> {
        let turned = turned(slot);
        let doc = NodeModel {
            spelling: Spelling::UnderscoreIds,
            api: Spelling::UnderscoreIds.node_api(),
            identity,
            dependencies: Vec::new(),
            parameters: ParameterSchema::default(),
            pairings: Vec::new(),
        };
        let standalone = StandaloneConfig::new()
            .with_instance_id(instance_id)
            .with_messaging("127.0.0.1", port)
            .with_core_node(super::MOCK_CORE);
        let config = startup::load(&doc, vec!["peppy-mock".into()], None, &standalone)?;
        let runner = NodeRunner::open(
            &doc,
            turned.descriptor,
            config,
            DEFAULT_RESULT_RETENTION,
            crate::shm::usable(crate::SharedMemory::default()),
            crate::DEFAULT_SHUTDOWN_GRACE,
        )
        .await?;
        Ok(MockProducer {
            runner,
            slot,
            turned,
            watch,
            pumps: Mutex::new(Vec::new()),
            subject: std::sync::OnceLock::new(),
        })
    }

    /// Names the node under test (the harness does, once it started it).
    pub(crate) fn serve_subject(&self, node: &Arc<NodeRunner>) {
        let _ = self.subject.set(node.clone());
    }

    /// The slot this mock fills.
    pub fn link_id(&self) -> &'static str {
        self.slot.link_id
    }

    /// The mock's instance id (`mock-<link_id>`, `mock-<link_id>-<n>`).
    pub fn instance_id(&self) -> &str {
        self.runner.instance_id()
    }

    /// The mock as the node sees it among its slot's bound producers.
    pub fn producer_ref(&self) -> ProducerRef {
        ProducerRef::new(self.runner.core_node(), self.runner.instance_id())
    }

    /// The mock's own runner (its session, its identity).
    pub fn runner(&self) -> &Arc<NodeRunner> {
        &self.runner
    }

    /// The publisher of consumed topic `spec` of this slot.
    ///
    /// # Panics
    ///
    /// When `spec` is not a topic of this slot: generated code asks only
    /// for the slot's own entries.
    pub fn topic<M: Encode + ?Sized>(&self, spec: &'static ConsumedTopicSpec) -> TopicMock<M> {
        let served = self.turned.topics.get(spec).expect("a topic of this slot");
        TopicMock {
            runner: self.runner.clone(),
            spec: served,
            subject: self.subject.get().map(|node| (node.clone(), spec)),
            matched: AtomicBool::new(false),
            watch: self.watch.clone(),
            _message: PhantomData,
        }
    }

    /// The server of consumed service `spec` of this slot. Requests are
    /// taken off the wire from now on: each is kept for
    /// [`ServiceMock::captured`], answered with the next scripted response
    /// ([`ServiceMock::enqueue_response`]) or parked for
    /// [`ServiceMock::next_request`].
    ///
    /// # Panics
    ///
    /// When `spec` is not a service of this slot.
    pub fn service<Req, Resp>(&self, spec: &'static ConsumedServiceSpec) -> ServiceMock<Req, Resp> {
        let served = self
            .turned
            .services
            .get(spec)
            .expect("a service of this slot");
        let state = Arc::new(ServiceState::default());
        let (tx, parked) = flume::unbounded();
        let pump = tokio::spawn(pump(self.runner.clone(), served, state.clone(), tx));
        self.pumps
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(pump);
        ServiceMock {
            name: served.name,
            state,
            parked,
            watch: self.watch.clone(),
            _types: PhantomData,
        }
    }

    /// The server of consumed action `spec` of this slot.
    ///
    /// # Panics
    ///
    /// When `spec` is not an action of this slot.
    pub fn action<G: Decode, GR, F, R>(
        &self,
        spec: &'static ConsumedActionSpec,
    ) -> ActionMock<G, GR, F, R> {
        let served = self
            .turned
            .actions
            .get(spec)
            .expect("an action of this slot");
        let server =
            GoalServer::new(&self.runner, served).expect("a mock serves every action of its slot");
        ActionMock {
            name: served.name,
            server,
            watch: self.watch.clone(),
            _types: PhantomData,
            _sends: PhantomData,
        }
    }

    /// Stops the mock as a producer process dying would: its session
    /// closes with every declaration and its liveliness token, so the node
    /// sees the producer gone. A stopped mock stays stopped.
    ///
    /// The stop begins when this returns: `mock.stop();` (PeppyOS's
    /// spelling) stops the mock, and `mock.stop().await` also waits until
    /// its session is closed.
    pub fn stop(&self) -> Stopping {
        for p in self
            .pumps
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .drain(..)
        {
            p.abort();
        }
        Stopping::begin(&self.runner)
    }
}

impl Drop for MockProducer {
    fn drop(&mut self) {
        for p in self
            .pumps
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .drain(..)
        {
            p.abort();
        }
    }
}

/// A mock on its way down: [`MockProducer::stop`]'s answer. The mock stops
/// whether or not this is awaited; awaiting it waits for the end.
#[derive(Debug)]
pub struct Stopping(JoinHandle<()>);

impl Stopping {
    pub(crate) fn begin(runner: &Arc<NodeRunner>) -> Stopping {
        let runner = runner.clone();
        Stopping(tokio::spawn(async move { runner.shutdown().await }))
    }
}

impl std::future::Future for Stopping {
    type Output = ();

    fn poll(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<()> {
        std::pin::Pin::new(&mut self.0).poll(cx).map(|_| ())
    }
}

/// A mock's publisher of one topic the node consumes.
pub struct TopicMock<M: ?Sized> {
    runner: Arc<NodeRunner>,
    spec: &'static TopicSpec,
    /// The node under test and its side of the topic, when a harness runs it.
    subject: Option<(Arc<NodeRunner>, &'static ConsumedTopicSpec)>,
    matched: AtomicBool,
    watch: Watch,
    _message: PhantomData<fn(&M)>,
}

impl<M: ?Sized> std::fmt::Debug for TopicMock<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TopicMock")
            .field("topic", &self.spec.name)
            .finish_non_exhaustive()
    }
}

impl<M: Encode + ?Sized> TopicMock<M> {
    /// Publishes one message to the node. The first call waits (up to
    /// 10 s) until the node's subscription is known and its code reads the
    /// topic (`subscribe`, or a first `next`), so the first message is
    /// never lost to a start-up race and a returned publish means the
    /// node's code got that far; a node that never subscribes is an error
    /// naming the topic.
    pub async fn publish(&self, message: &M) -> Result<()> {
        if !self.matched.load(Ordering::Acquire)
            && !self.wait_for_subscriber(SUBSCRIBER_WAIT).await?
        {
            return Err(Error::Testing(format!(
                "topic `{}`: the node under test has no subscription to it after {} s (does it consume the topic through this slot?)",
                self.spec.name,
                SUBSCRIBER_WAIT.as_secs()
            )));
        }
        crate::topics::emit(&self.runner, self.spec, message).await
    }

    /// Waits up to `timeout` until the node's subscription to the topic is
    /// known here and, under a harness, the node's code reads the topic;
    /// whether it is so.
    pub async fn wait_for_subscriber(&self, timeout: Duration) -> Result<bool> {
        let deadline = tokio::time::Instant::now() + timeout;
        let read = || {
            self.subject
                .as_ref()
                .is_none_or(|(node, spec)| node.inbox(spec).is_ok_and(|i| i.is_read()))
        };
        let known = self.watch.unbounded(async {
            if !readers_known(&self.runner, self.spec, timeout).await {
                return Ok(false);
            }
            loop {
                if read() {
                    return Ok(true);
                }
                if tokio::time::Instant::now() >= deadline {
                    return Ok(false);
                }
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        });
        let known = known.await?;
        if known {
            self.matched.store(true, Ordering::Release);
        }
        Ok(known)
    }

    /// The topic's name.
    pub fn topic(&self) -> &'static str {
        self.spec.name
    }
}

/// Waits up to `timeout` until `runner`'s publisher of `spec` knows a
/// subscriber. Zenoh reports matching as a status flag; a short poll of it
/// is the barrier.
pub(crate) async fn readers_known(
    runner: &NodeRunner,
    spec: &'static TopicSpec,
    timeout: Duration,
) -> bool {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if runner.outlet(spec).is_some_and(|o| o.readers_known()) {
            return true;
        }
        if tokio::time::Instant::now() >= deadline {
            return false;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[derive(Default)]
struct ServiceState {
    captured: Mutex<Vec<Vec<u8>>>,
    scripted: Mutex<VecDeque<Vec<u8>>>,
}

/// Takes every request of one mocked service off the wire: kept, then
/// answered from the script or parked.
async fn pump(
    runner: Arc<NodeRunner>,
    spec: &'static ServiceSpec,
    state: Arc<ServiceState>,
    parked: flume::Sender<(Vec<u8>, Answer)>,
) {
    loop {
        let (_caller, body, answer) = match take_request(&runner, spec).await {
            Ok(taken) => taken,
            Err(_) => return,
        };
        state
            .captured
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(body.clone());
        let scripted = state
            .scripted
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .pop_front();
        match scripted {
            Some(response) => {
                if let Err(e) = answer.respond(response).await {
                    warn!(
                        service = spec.name,
                        "a scripted mock response was not sent: {e}"
                    );
                }
            }
            None => {
                if parked.send((body, answer)).is_err() {
                    return;
                }
            }
        }
    }
}

/// A mock's server of one service the node calls.
pub struct ServiceMock<Req, Resp> {
    name: &'static str,
    state: Arc<ServiceState>,
    parked: flume::Receiver<(Vec<u8>, Answer)>,
    watch: Watch,
    _types: PhantomData<fn(Resp) -> Req>,
}

impl<Req, Resp> std::fmt::Debug for ServiceMock<Req, Resp> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServiceMock")
            .field("service", &self.name)
            .finish_non_exhaustive()
    }
}

impl<Req, Resp> ServiceMock<Req, Resp> {
    /// Waits up to `timeout` for the node's next request not answered by
    /// the script.
    async fn next_parked(&self, timeout: Duration) -> Result<(Vec<u8>, Responder<Resp>)> {
        let what = format!("a request of service `{}` from the node", self.name);
        let (body, answer) = self
            .watch
            .bound(&what, timeout, async {
                self.parked
                    .recv_async()
                    .await
                    .map_err(|_| Error::ShuttingDown)
            })
            .await?;
        Ok((
            body,
            Responder {
                answer,
                _response: PhantomData,
            },
        ))
    }

    fn script(&self, body: Vec<u8>) {
        self.state
            .scripted
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push_back(body);
    }

    /// How many requests the node made so far, scripted and parked alike.
    pub fn captured_count(&self) -> usize {
        self.state
            .captured
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .len()
    }

    /// The service's name.
    pub fn service(&self) -> &'static str {
        self.name
    }
}

impl<Req: MessageData, Resp> ServiceMock<Req, Resp> {
    /// Waits up to `timeout` for the node's next request not answered by
    /// the script, and returns it with the responder that answers it.
    pub async fn next_request(&self, timeout: Duration) -> Result<(Req, Responder<Resp>)> {
        let (body, responder) = self.next_parked(timeout).await?;
        let request = from_bytes::<Req>(&body).map_err(|source| Error::Decode {
            what: format!("request of `{}`", self.name),
            source,
        })?;
        Ok((request, responder))
    }

    /// Every request received so far, scripted and parked alike, in
    /// arrival order.
    pub fn captured(&self) -> Result<Vec<Req>> {
        self.state
            .captured
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .map(|b| {
                from_bytes::<Req>(b).map_err(|source| Error::Decode {
                    what: format!("request of `{}`", self.name),
                    source,
                })
            })
            .collect()
    }
}

/// A service without request data: a request is only a call.
impl<Resp> ServiceMock<(), Resp> {
    /// Waits up to `timeout` for the node's next call not answered by the
    /// script, and returns the responder that answers it.
    pub async fn next_request(&self, timeout: Duration) -> Result<Responder<Resp>> {
        Ok(self.next_parked(timeout).await?.1)
    }
}

impl<Req, Resp: MessageData> ServiceMock<Req, Resp> {
    /// Queues a response: the node's next request not yet answered gets
    /// it, in order (scripted answers go before parking).
    pub fn enqueue_response(&self, response: Resp) -> Result<()> {
        self.script(to_bytes(&response));
        Ok(())
    }
}

/// A service without response data: an answer is only a reply.
impl<Req> ServiceMock<Req, ()> {
    /// Queues an answer: the node's next request not yet answered gets it,
    /// in order (scripted answers go before parking).
    pub fn enqueue_response(&self) -> Result<()> {
        self.script(Vec::new());
        Ok(())
    }
}

impl<Req, Resp> Drop for ServiceMock<Req, Resp> {
    fn drop(&mut self) {
        // A request the test never answered, or a script the node never
        // used, is a test that checked less than it reads.
        let parked = self.parked.len();
        let unused = self
            .state
            .scripted
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .len();
        if parked > 0 || unused > 0 {
            warn!(
                service = self.name,
                unanswered_requests = parked,
                unused_scripted_responses = unused,
                "mock service torn down with requests nobody answered or responses nobody asked for"
            );
        }
    }
}

/// Answers one request a [`ServiceMock`] handed out.
pub struct Responder<Resp> {
    answer: Answer,
    _response: PhantomData<fn(Resp)>,
}

impl<Resp> std::fmt::Debug for Responder<Resp> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Responder").finish_non_exhaustive()
    }
}

impl<Resp> Responder<Resp> {
    /// Answers with an error: the node's call fails with
    /// [`Error::ServiceError`] carrying `reason`.
    pub async fn respond_error(self, reason: impl AsRef<str>) -> Result<()> {
        self.answer.fail(reason.as_ref()).await
    }
}

impl<Resp: MessageData> Responder<Resp> {
    /// Answers with `response`.
    pub async fn respond(self, response: Resp) -> Result<()> {
        self.answer.respond(to_bytes(&response)).await
    }
}

/// A service without response data.
impl Responder<()> {
    /// Answers the call.
    pub async fn respond(self) -> Result<()> {
        self.answer.respond(Vec::new()).await
    }
}

/// A goal's rejection reason: a text, or `Some(text)` / `None` as
/// PeppyOS's mocks take it.
pub trait RejectReason {
    /// The reason, if any.
    fn into_reason(self) -> Option<String>;
}

impl RejectReason for &str {
    fn into_reason(self) -> Option<String> {
        Some(self.to_string())
    }
}

impl RejectReason for String {
    fn into_reason(self) -> Option<String> {
        Some(self)
    }
}

impl RejectReason for &String {
    fn into_reason(self) -> Option<String> {
        Some(self.clone())
    }
}

impl RejectReason for Option<&str> {
    fn into_reason(self) -> Option<String> {
        self.map(str::to_string)
    }
}

/// What a goal's server sends: goal response `GR`, feedback `F` and
/// result `R` (each `()` where the action declares none).
type Sends<GR, F, R> = PhantomData<(fn(&GR), fn(&F), fn(&R))>;

/// A mock's server of one action the node calls: goals `G`, declared goal
/// response `GR`, feedback `F`, result `R` (`()` where the action has
/// none).
pub struct ActionMock<G, GR, F, R> {
    name: &'static str,
    server: GoalServer,
    watch: Watch,
    _types: PhantomData<fn() -> G>,
    _sends: Sends<GR, F, R>,
}

impl<G, GR, F, R> std::fmt::Debug for ActionMock<G, GR, F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ActionMock")
            .field("action", &self.name)
            .finish_non_exhaustive()
    }
}

impl<G: Decode, GR, F, R> ActionMock<G, GR, F, R> {
    /// Waits up to `timeout` for the node's next goal.
    pub async fn next_goal(&self, timeout: Duration) -> Result<PendingGoal<G, GR, F, R>> {
        let what = format!("a goal of action `{}` from the node", self.name);
        let incoming: IncomingGoal<G> = self
            .watch
            .bound(&what, timeout, self.server.next::<G>())
            .await?;
        let (incoming, request) = incoming.into_parts();
        Ok(PendingGoal {
            request,
            incoming,
            _types: PhantomData,
        })
    }

    /// The action's name.
    pub fn action(&self) -> &'static str {
        self.name
    }
}

/// A goal the node sent, not yet accepted or rejected.
pub struct PendingGoal<G, GR, F, R> {
    /// The goal's request.
    pub request: G,
    incoming: IncomingGoal<()>,
    _types: Sends<GR, F, R>,
}

impl<G: std::fmt::Debug, GR, F, R> std::fmt::Debug for PendingGoal<G, GR, F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PendingGoal")
            .field("goal_id", &self.incoming.goal_id())
            .field("request", &self.request)
            .finish_non_exhaustive()
    }
}

impl<G, GR, F, R> PendingGoal<G, GR, F, R> {
    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        self.incoming.goal_id()
    }

    /// Who sent it (the node under test).
    pub fn caller(&self) -> &crate::Caller {
        &self.incoming.caller
    }

    fn accepted(self, response: Vec<u8>) -> Result<ActiveGoal<F, R>> {
        let context = self.incoming.accept_with(response)?;
        Ok(ActiveGoal {
            context,
            _types: PhantomData,
        })
    }
}

/// An action that declares a goal response: the decision carries one.
impl<G, GR: MessageData, F, R> PendingGoal<G, GR, F, R> {
    /// Accepts the goal with its declared response; the node's `fire_goal`
    /// returns accepted, with `data` holding `response`.
    pub async fn accept(self, response: GR) -> Result<ActiveGoal<F, R>> {
        self.accepted(to_bytes(&response))
    }

    /// Rejects the goal with `reason` (a text, `Some(text)` or `None`) and,
    /// optionally, a response; the node sees both.
    pub async fn reject(self, reason: impl RejectReason, response: Option<GR>) -> Result<()> {
        let body = response.map(|r| to_bytes(&r)).unwrap_or_default();
        self.incoming.reject_with(reason.into_reason(), body)
    }
}

/// An action without a declared goal response.
impl<G, F, R> PendingGoal<G, (), F, R> {
    /// Accepts the goal; the node's `fire_goal` returns accepted.
    pub async fn accept(self) -> Result<ActiveGoal<F, R>> {
        self.accepted(Vec::new())
    }

    /// Rejects the goal with `reason` (a text, `Some(text)` or `None`),
    /// which the node sees.
    pub async fn reject(self, reason: impl RejectReason) -> Result<()> {
        self.incoming.reject_with(reason.into_reason(), Vec::new())
    }
}

/// What an accepted goal's server sends: feedback `F` and result `R`.
type GoalSends<F, R> = PhantomData<(fn(&F), fn(&R))>;

/// An accepted goal the test plays the server of.
pub struct ActiveGoal<F, R> {
    context: GoalContext,
    _types: GoalSends<F, R>,
}

impl<F, R> std::fmt::Debug for ActiveGoal<F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ActiveGoal")
            .field("goal_id", &self.context.goal_id())
            .finish_non_exhaustive()
    }
}

impl<F, R> ActiveGoal<F, R> {
    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        self.context.goal_id()
    }

    /// Resolves when the node asks to cancel the goal.
    pub async fn cancel_signal(&self) {
        self.context.cancel_signal().await;
    }

    /// Whether the node asked to cancel the goal.
    pub fn is_cancelled(&self) -> bool {
        self.context.is_cancelled()
    }
}

impl<F: MessageData, R> ActiveGoal<F, R> {
    /// Sends one feedback message to the node.
    pub async fn publish_feedback(&self, feedback: &F) -> Result<()> {
        self.context.publish_feedback(feedback).await
    }
}

impl<F, R: MessageData> ActiveGoal<F, R> {
    /// Finishes the goal with `result` (only the first finish counts).
    pub async fn complete(&self, result: &R) -> Result<()> {
        self.context.complete(result)
    }

    /// Finishes the goal as cancelled, with a (partial) `result`.
    pub async fn complete_cancelled(&self, result: &R) -> Result<()> {
        self.context.complete_cancelled(result)
    }
}

/// An action without a result.
impl<F> ActiveGoal<F, ()> {
    /// Finishes the goal (only the first finish counts).
    pub async fn complete(&self) -> Result<()> {
        self.context.complete(&())
    }

    /// Finishes the goal as cancelled.
    pub async fn complete_cancelled(&self) -> Result<()> {
        self.context.complete_cancelled(&())
    }
}
