//! The harness's outside view of the node under test: a consumer of its
//! own (the *fixture*), a node whose one slot is bound to the node under
//! test and which consumes everything it emits, calls everything it
//! serves. A test's taps, polls and goals go the way a real consumer's do.

use std::marker::PhantomData;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppy_schema::{
    Cardinality, Dependency, Identity, NodeModel, ParameterSchema, SlotKind, Spelling,
};

use super::HARNESS_CORE;
use super::turned;
use super::watch::Watch;
use crate::actions::{CancelState, DEFAULT_RESULT_RETENTION, GoalClient, Outcome};
use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::spec::{
    ActionSpec, ConsumedActionSpec, ConsumedServiceSpec, ConsumedTopicSpec, NodeDescriptor,
    OwnerSpec, ServiceSpec, TopicSpec,
};
use crate::startup::{self, StandaloneConfig};
use crate::wire::codec::{Decode, Encode};

/// The fixture's slot: bound to the node under test.
pub(crate) const SUBJECT: &str = "subject";

/// The fixture's node identity.
const FIXTURE_NAME: &str = "peppy_test_harness";

/// The node under test's served entries turned around.
pub(crate) type Turned = turned::Turned<ConsumedTopicSpec, ConsumedServiceSpec, ConsumedActionSpec>;

static TURNED: Mutex<Vec<(usize, &'static Turned)>> = Mutex::new(Vec::new());

/// `Own` names the node under test: the fixture must name it outright.
fn owner_of(owner: OwnerSpec, node: &'static Identity) -> OwnerSpec {
    match owner {
        OwnerSpec::Own => OwnerSpec::Node {
            name: &node.name,
            tag: &node.tag,
        },
        other => other,
    }
}

/// The fixture's description for `node` (of identity `identity`).
pub(crate) fn turned(node: &'static NodeDescriptor, identity: &Identity) -> &'static Turned {
    turned::once(&TURNED, turned::address(node), || {
        let identity: &'static Identity = Box::leak(Box::new(identity.clone()));
        let topics = turned::Side::of(node.emitted_topics, |t: &TopicSpec| ConsumedTopicSpec {
            link_id: Some(SUBJECT),
            owner: owner_of(t.owner, identity),
            name: t.name,
            qos: t.qos,
            format: t.format,
        });
        let services = turned::Side::of(node.exposed_services, |s: &ServiceSpec| {
            ConsumedServiceSpec {
                link_id: SUBJECT,
                owner: owner_of(s.owner, identity),
                name: s.name,
                request: s.request,
                response: s.response,
            }
        });
        let actions = turned::Side::of(node.exposed_actions, |a: &ActionSpec| ConsumedActionSpec {
            link_id: SUBJECT,
            owner: owner_of(a.owner, identity),
            name: a.name,
            goal: a.goal,
            feedback: a.feedback,
            result: a.result,
        });
        Turned {
            descriptor: Box::leak(Box::new(NodeDescriptor {
                model: "",
                document_path: "(the test harness)",
                emitted_topics: &[],
                consumed_topics: topics.list,
                exposed_services: &[],
                exposed_actions: &[],
            })),
            topics,
            services,
            actions,
        }
    })
}

/// Opens the fixture: a node consuming `turned`'s topics from instance
/// `subject` of node `identity`, on the router at `port`.
pub(crate) async fn open(
    turned: &'static Turned,
    identity: &Identity,
    subject: &str,
    port: u16,
) -> Result<Arc<NodeRunner>> {
    let doc = NodeModel {
        spelling: Spelling::SlashIds,
        api: Spelling::SlashIds.node_api(),
        identity: Identity::new(FIXTURE_NAME, "v1"),
        dependencies: vec![Dependency {
            kind: SlotKind::Node,
            target: identity.clone(),
            link_id: SUBJECT.into(),
            from_any: false,
            cardinality: Cardinality::One,
            sha256: None,
            loc: Default::default(),
        }],
        parameters: ParameterSchema::default(),
        pairings: Vec::new(),
    };
    let standalone = StandaloneConfig::new()
        .with_instance_id(super::FIXTURE_INSTANCE_ID)
        .with_messaging("127.0.0.1", port)
        .with_core_node(super::FIXTURE_CORE)
        .with_bound_producer(SUBJECT, HARNESS_CORE, subject);
    let config = startup::load(&doc, vec!["peppy-harness".into()], None, &standalone)?;
    NodeRunner::open(
        &doc,
        turned.descriptor,
        config,
        DEFAULT_RESULT_RETENTION,
        crate::shm::usable(crate::SharedMemory::default()),
        crate::DEFAULT_SHUTDOWN_GRACE,
    )
    .await
}

/// What the node serves, as the fixture calls it.
pub(crate) fn topic(t: &Turned, spec: &'static TopicSpec) -> Result<&'static ConsumedTopicSpec> {
    t.topics
        .get(spec)
        .ok_or_else(|| Error::Undeclared(format!("emitted topic `{}`", spec.name)))
}

pub(crate) fn service(
    t: &Turned,
    spec: &'static ServiceSpec,
) -> Result<&'static ConsumedServiceSpec> {
    t.services
        .get(spec)
        .ok_or_else(|| Error::Undeclared(format!("exposed service `{}`", spec.name)))
}

pub(crate) fn action(t: &Turned, spec: &'static ActionSpec) -> Result<&'static ConsumedActionSpec> {
    t.actions
        .get(spec)
        .ok_or_else(|| Error::Undeclared(format!("exposed action `{}`", spec.name)))
}

/// The harness's subscription to one topic the node emits, open since
/// before the node started: `next` yields every message, in order.
pub struct Tap<M> {
    fixture: Arc<NodeRunner>,
    spec: &'static ConsumedTopicSpec,
    watch: Watch,
    _message: PhantomData<fn() -> M>,
}

impl<M> std::fmt::Debug for Tap<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tap")
            .field("topic", &self.spec.name)
            .finish_non_exhaustive()
    }
}

impl<M: Decode> Tap<M> {
    pub(crate) fn new(
        fixture: Arc<NodeRunner>,
        spec: &'static ConsumedTopicSpec,
        watch: Watch,
    ) -> Self {
        Tap {
            fixture,
            spec,
            watch,
            _message: PhantomData,
        }
    }

    /// The node's next message on the topic; `Ok(None)` once the harness
    /// is shut down. A node whose setup failed ends the wait with that
    /// failure. Bound it with `tokio::time::timeout`, or use
    /// [`Tap::next_within`].
    #[allow(clippy::should_implement_trait)]
    pub async fn next(&mut self) -> Result<Option<M>> {
        let next = crate::topics::next_message::<M>(&self.fixture, self.spec, None);
        match self.watch.unbounded(next).await {
            Ok((_, m)) => Ok(Some(m)),
            Err(Error::ShuttingDown) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// [`Tap::next`], failing with an error that names the topic when
    /// nothing arrives within `timeout`.
    pub async fn next_within(&mut self, timeout: Duration) -> Result<Option<M>> {
        let what = format!("a message of topic `{}` from the node", self.spec.name);
        let next = crate::topics::next_message::<M>(&self.fixture, self.spec, None);
        match self.watch.bound(&what, timeout, next).await {
            Ok((_, m)) => Ok(Some(m)),
            Err(Error::ShuttingDown) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// The topic's name.
    pub fn topic(&self) -> &'static str {
        self.spec.name
    }
}

/// A goal the harness sent to one of the node's exposed actions.
pub struct GoalHandle<F, R> {
    /// Whether the node accepted the goal.
    pub accepted: bool,
    /// The node's reason when it rejected the goal.
    pub reason: Option<String>,
    client: GoalClient,
    watch: Watch,
    _types: PhantomData<fn() -> (F, R)>,
}

impl<F, R> std::fmt::Debug for GoalHandle<F, R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalHandle")
            .field("goal_id", &self.client.goal_id())
            .field("accepted", &self.accepted)
            .field("reason", &self.reason)
            .finish_non_exhaustive()
    }
}

impl<F: Decode, R: Decode> GoalHandle<F, R> {
    pub(crate) fn new(client: GoalClient, watch: Watch) -> Self {
        GoalHandle {
            accepted: client.accepted,
            reason: client.error_message.clone(),
            client,
            watch,
            _types: PhantomData,
        }
    }

    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        self.client.goal_id()
    }

    /// The server (the node under test): its instance id and core node.
    pub fn server(&self) -> (&str, &str) {
        (&self.client.instance_id, &self.client.core_node)
    }

    /// The declared goal response the node sent with its decision,
    /// decoded; `None` when it sent none.
    pub fn goal_response<T: crate::wire::codec::Decode>(&self) -> Result<Option<T>> {
        self.client.goal_response()
    }

    /// The node's next feedback message on this goal;
    /// [`Error::ActionFeedbackChannelClosed`] once the goal is over and every feedback
    /// message was read.
    pub async fn on_next_feedback(&mut self) -> Result<F> {
        let watch = self.watch.clone();
        watch.unbounded(self.client.next_feedback::<F>()).await
    }

    /// Waits up to `timeout` for the goal to end and returns how.
    pub async fn get_result(&self, timeout: Duration) -> Result<Outcome<R>> {
        self.watch.unbounded(self.client.result::<R>(timeout)).await
    }

    /// Asks the node to cancel the goal.
    pub async fn cancel_goal(&self, timeout: Duration) -> Result<CancelState> {
        self.watch.unbounded(self.client.cancel(timeout)).await
    }
}

/// Calls exposed service `spec` of the node from the fixture.
pub(crate) async fn poll<Req: Encode + ?Sized, Resp: Decode + Send>(
    fixture: &NodeRunner,
    spec: &'static ConsumedServiceSpec,
    request: &Req,
    timeout: Duration,
) -> Result<Resp> {
    crate::services::call(fixture, spec, timeout, request)
        .await
        .map(|r| r.data)
}
