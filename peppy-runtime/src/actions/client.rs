//! The consumed side of an action: sending a goal through a slot and the
//! goal a caller holds (feedback, result, cancel).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};

use crate::error::{Error, Result};
use crate::node::NodeRunner;
use crate::request::{Request, RequestKeys};
use crate::spec::ConsumedActionSpec;
use crate::stop;
use crate::target;
use crate::wire::attachment::{self, QueryHeader, QueryKind};
use crate::wire::codec::{Decode, Decoder, Encode, from_bytes, to_bytes};
use crate::wire::keys::{ActionPart, Channel, action_part_key, entry_key, feedback_key};

use super::{CancelState, Outcome};

/// A goal sent to an action server, seen from the caller.
pub struct GoalClient {
    session: zenoh::Session,
    base_key: String,
    action: String,
    goal_id: String,
    /// The result format's fingerprint and canonical text.
    result_format: (u64, String),
    feedback: flume::Receiver<Feedback>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    /// Follows the server's liveliness token: its withdrawal (the server's
    /// process died, its host was lost) ends the feedback stream.
    _server_watch: Option<zenoh::pubsub::Subscriber<()>>,
    /// Whether the server went away without finishing the goal.
    gone: std::sync::Arc<std::sync::atomic::AtomicBool>,
    stop: CancellationToken,
    /// Fires when the node's messaging closes, after its shutdown hooks:
    /// asking for the result or a cancel works until then.
    messaging: CancellationToken,
    /// Whether the server accepted the goal.
    pub accepted: bool,
    /// The server's reason when it rejected the goal.
    pub error_message: Option<String>,
    /// The action's declared goal response as the server encoded it with
    /// its decision (empty when it sent none).
    pub response: Vec<u8>,
    /// The server's instance id.
    pub instance_id: String,
    /// The server's core node.
    pub core_node: String,
    /// The server runs in another session (see `Request::remote`).
    remote: bool,
}

impl std::fmt::Debug for GoalClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalClient")
            .field("goal_id", &self.goal_id)
            .field("accepted", &self.accepted)
            .field("server", &self.instance_id)
            .finish_non_exhaustive()
    }
}

/// What the feedback stream of a goal carries to its caller.
enum Feedback {
    /// One feedback message, encoded.
    Message(Vec<u8>),
    /// The server closed the stream: the goal is terminal.
    End,
    /// The server's liveliness token went away first.
    Gone,
}

static GOAL_COUNTER: AtomicU64 = AtomicU64::new(0);

fn new_goal_id() -> String {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(GOAL_COUNTER.fetch_add(1, Ordering::Relaxed));
    h.write_u32(std::process::id());
    format!("{:016x}", h.finish())
}

/// Sends a goal through the action's slot and waits for the server's
/// decision (accepted or rejected). The feedback stream is subscribed
/// before the goal is sent, so no feedback is missed. On an already stopped
/// node it returns [`Error::ShuttingDown`] after a short pause.
pub fn send_goal<'a, G: Encode + ?Sized>(
    runner: &'a NodeRunner,
    spec: &'static ConsumedActionSpec,
    timeout: Duration,
    goal: &G,
) -> impl Future<Output = Result<GoalClient>> + Send + use<'a, G> {
    let body = to_bytes(goal);
    goal_through(runner, spec, None, timeout, body)
}

/// [`send_goal`] to one producer bound to the action's slot, as the
/// peppylib API does (`fire_goal(&runner, target, ...)`): a target the slot is not bound
/// to fails with [`Error::TargetNotBound`] before anything is sent.
pub fn send_goal_to<'a, G: Encode + ?Sized>(
    runner: &'a NodeRunner,
    spec: &'static ConsumedActionSpec,
    target: &crate::ProducerRef,
    timeout: Duration,
    goal: &G,
) -> impl Future<Output = Result<GoalClient>> + Send + use<'a, G> {
    let body = to_bytes(goal);
    let checked = crate::slots::check_target(runner, spec.link_id, target)
        .map(|()| target.instance_id.clone());
    async move { goal_through(runner, spec, Some(checked?), timeout, body).await }
}

async fn goal_through(
    runner: &NodeRunner,
    spec: &'static ConsumedActionSpec,
    server: Option<String>,
    timeout: Duration,
    body: Vec<u8>,
) -> Result<GoalClient> {
    // Outgoing: allowed until messaging closes, so a shutdown hook can
    // still send a goal.
    if runner.messaging_stop().is_cancelled() {
        return Err(stop::refused().await);
    }
    let deadline = Instant::now() + timeout;
    let owner = spec.owner.resolve(runner.node_name(), runner.node_tag());
    let entry = target::Entry {
        link_id: spec.link_id,
        owner: spec.owner,
        channel: Channel::Action,
        name: spec.name,
        part: Some(ActionPart::Goal),
        fingerprint: spec.goal.fingerprint,
        describe: format!("{} (action goal)", spec.name).into(),
    };
    let target = match server {
        Some(server) => server,
        None => target::choose(runner, &entry, deadline).await?,
    };
    let base = entry.base(runner, Some(&target));
    let opened = open_goal(GoalOpening {
        session: runner.session(),
        stop: runner.cancellation_token(),
        messaging: runner.messaging_stop(),
        action: spec.name,
        describe: &entry.describe,
        selector: entry.selector(runner, Some(&target)),
        keys: Some(runner.request_keys()),
        feedback_base: base,
        header: target::header(runner, QueryKind::Request, spec.goal.fingerprint),
        server: &target,
        remote: target != runner.instance_id(),
        goal: (spec.goal.fingerprint, spec.goal.canonical),
        feedback_fingerprint: spec.feedback.fingerprint,
        result: (spec.result.fingerprint, spec.result.canonical),
        body,
        deadline,
    })
    .await?;
    let base_key = entry_key(
        runner.namespace(),
        Channel::Action,
        &owner.expect("consumed actions have an owner"),
        spec.name,
        &opened.core_node,
        &opened.instance_id,
    );
    Ok(GoalClient { base_key, ..opened })
}

/// Follows the liveliness token of server `instance` (in the namespace of
/// `base_key`): when it is withdrawn, the goal's feedback stream ends with
/// [`Feedback::Gone`] after what already arrived, and `gone` is set.
/// `None` when the subscription cannot be declared (the stream then ends
/// only when the server closes it).
async fn watch_server(
    session: &zenoh::Session,
    base_key: &str,
    instance: &str,
    feedback: flume::Sender<Feedback>,
    gone: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> Option<zenoh::pubsub::Subscriber<()>> {
    let ns = base_key.split('/').nth(1)?;
    // Instance ids name instances in a stack: on whichever core node.
    let selector = crate::wire::keys::instance_liveliness_selector(ns, "*", instance);
    session
        .liveliness()
        .declare_subscriber(selector)
        // With the tokens already there: a withdrawal is then always one
        // of a token this subscriber knows.
        .history(true)
        .callback(move |sample| {
            if sample.kind() == zenoh::sample::SampleKind::Delete
                && !gone.swap(true, std::sync::atomic::Ordering::AcqRel)
            {
                let _ = feedback.send(Feedback::Gone);
            }
        })
        .await
        .map_err(|e| debug!(error = %e, "cannot follow a goal's server"))
        .ok()
}

/// Everything needed to send one goal to one server.
pub(crate) struct GoalOpening<'a> {
    pub(crate) session: &'a zenoh::Session,
    pub(crate) stop: &'a CancellationToken,
    /// Ends outgoing requests: the node's messaging closing.
    pub(crate) messaging: &'a CancellationToken,
    /// The action's name, for errors.
    pub(crate) action: &'a str,
    /// How the goal reads in errors.
    pub(crate) describe: &'a str,
    /// The goal queryable's key (or selector) of the server.
    pub(crate) selector: String,
    /// The node's declared request keys (`None`: send the key as text).
    pub(crate) keys: Option<&'a RequestKeys>,
    /// The action's base key (or selector) the feedback key hangs below.
    pub(crate) feedback_base: String,
    /// The query header.
    pub(crate) header: Vec<u8>,
    /// The server instance, for errors.
    pub(crate) server: &'a str,
    /// The server runs in another session (see `Request::remote`).
    pub(crate) remote: bool,
    /// Goal format: fingerprint and canonical text.
    pub(crate) goal: (u64, &'a str),
    /// The feedback format's fingerprint.
    pub(crate) feedback_fingerprint: u64,
    /// Result format: fingerprint and canonical text.
    pub(crate) result: (u64, &'a str),
    /// The encoded goal.
    pub(crate) body: Vec<u8>,
    pub(crate) deadline: Instant,
}

/// Subscribes to the goal's feedback, sends it, and reads the decision.
/// The returned client's `base_key` is the selector given; callers that
/// sent to a selector set the server's exact key.
pub(crate) async fn open_goal(o: GoalOpening<'_>) -> Result<GoalClient> {
    let goal_id = new_goal_id();
    let (tx, rx) = flume::unbounded();
    let fb = tx.clone();
    let feedback_fp = o.feedback_fingerprint;
    let subscriber = o
        .session
        .declare_subscriber(feedback_key(&o.feedback_base, &goal_id))
        .callback(move |sample| {
            let att = sample
                .attachment()
                .map(|a| a.to_bytes().into_owned())
                .unwrap_or_default();
            if att == attachment::END_OF_FEEDBACK {
                let _ = fb.send(Feedback::End);
            } else if attachment::parse_topic(&att) == Some(feedback_fp) {
                let _ = fb.send(Feedback::Message(sample.payload().to_bytes().into_owned()));
            } else {
                debug!("dropping feedback with another format");
            }
        })
        .await?;
    // Followed from before the goal is sent: a server lost at any time
    // after it accepts ends the feedback stream.
    let gone = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let server_watch = watch_server(o.session, &o.feedback_base, o.server, tx, gone.clone()).await;
    let mut payload = to_bytes(goal_id.as_str());
    payload.extend_from_slice(&o.body);
    let answer = Request {
        session: o.session,
        stop: o.messaging,
        key: o.selector,
        keys: o.keys,
        header: o.header,
        payload,
        deadline: o.deadline,
        describe: o.describe,
        instance: o.server,
        remote: o.remote,
        request_format: o.goal.1,
        // The decision is a status reply without a format of its own.
        response: None,
    }
    .send()
    .await?;
    let malformed = |source| Error::Decode {
        what: "goal response".into(),
        source,
    };
    let body = answer.body.to_bytes();
    let mut d = Decoder::new(&body);
    let accepted = bool::decode(&mut d).map_err(malformed)?;
    let error_message = Option::<String>::decode(&mut d).map_err(malformed)?;
    let response = body[body.len() - d.remaining()..].to_vec();
    Ok(GoalClient {
        session: o.session.clone(),
        base_key: o.feedback_base,
        action: o.action.to_string(),
        goal_id,
        result_format: (o.result.0, o.result.1.to_string()),
        feedback: rx,
        _subscriber: subscriber,
        _server_watch: server_watch,
        gone,
        stop: o.stop.clone(),
        messaging: o.messaging.clone(),
        accepted,
        error_message,
        response,
        instance_id: answer.instance,
        core_node: answer.core,
        remote: o.remote,
    })
}

impl GoalClient {
    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        &self.goal_id
    }

    /// The action's declared goal response the server sent with its
    /// decision, decoded; `None` when it sent none.
    pub fn goal_response<T: Decode>(&self) -> Result<Option<T>> {
        if self.response.is_empty() {
            return Ok(None);
        }
        from_bytes::<T>(&self.response)
            .map(Some)
            .map_err(|source| Error::Decode {
                what: format!("goal response of `{}`", self.action),
                source,
            })
    }

    /// The next feedback message; [`Error::ActionFeedbackChannelClosed`]
    /// once the goal is terminal and every feedback message was read. Once this node stops
    /// it returns [`Error::ShuttingDown`]: at once if it was waiting, after
    /// a short pause if called on an already stopped node.
    pub async fn next_feedback<F: Decode>(&mut self) -> Result<F> {
        if self.stop.is_cancelled() {
            return Err(stop::refused().await);
        }
        loop {
            let next = tokio::select! {
                next = self.feedback.recv_async() => next,
                () = self.stop.cancelled() => return Err(Error::ShuttingDown),
            };
            match next {
                Ok(Feedback::Message(bytes)) => match from_bytes::<F>(&bytes) {
                    Ok(f) => return Ok(f),
                    Err(e) => {
                        warn!(action = %self.action, error = %e, "dropping feedback that does not decode")
                    }
                },
                Ok(Feedback::Gone) => {
                    return Err(Error::ActionFeedbackProducerGone {
                        instance_id: Some(self.instance_id.clone()),
                        action_name: self.action.clone(),
                    });
                }
                Ok(Feedback::End) | Err(_) => return Err(Error::ActionFeedbackChannelClosed),
            }
        }
    }

    async fn ask(&self, part: ActionPart, timeout: Duration) -> Result<Vec<u8>> {
        let describe = format!("{} (action {})", self.action, part.as_str());
        let answer = Request {
            session: &self.session,
            stop: &self.messaging,
            key: action_part_key(&self.base_key, part),
            keys: None,
            header: QueryHeader {
                kind: QueryKind::Request,
                fingerprint: 0,
                core: String::new(),
                instance: String::new(),
            }
            .encode(),
            payload: to_bytes(self.goal_id.as_str()),
            deadline: Instant::now() + timeout,
            describe: &describe,
            instance: &self.instance_id,
            remote: self.remote,
            request_format: "a goal id",
            response: (part == ActionPart::Result)
                .then_some((self.result_format.0, self.result_format.1.as_str())),
        }
        .send()
        .await?;
        Ok(answer.body.to_bytes().into_owned())
    }

    /// Waits (up to `timeout`) until the goal is terminal and returns how it
    /// ended. It works until the node's messaging closes (shutdown hooks may
    /// ask), then returns [`Error::ShuttingDown`].
    ///
    /// A wait that runs out of time is [`Error::ActionResultTimeout`] (the
    /// goal may still be running: ask again); a server nobody reaches,
    /// [`Error::ActionResultUnreachable`].
    pub async fn result<R: Decode>(&self, timeout: Duration) -> Result<Outcome<R>> {
        // The server is gone: its goals' results went with it.
        if self.gone.load(std::sync::atomic::Ordering::Acquire) {
            return Ok(Outcome::Abandoned);
        }
        let body = self
            .ask(ActionPart::Result, timeout)
            .await
            .map_err(|e| match e {
                Error::ServiceTimeout { .. } => Error::ActionResultTimeout {
                    instance_id: Some(self.instance_id.clone()),
                    action_name: self.action.clone(),
                },
                Error::ServiceUnreachable { .. } => Error::ActionResultUnreachable {
                    instance_id: Some(self.instance_id.clone()),
                    action_name: self.action.clone(),
                },
                other => other,
            })?;
        let decode = |bytes: &[u8]| {
            from_bytes::<R>(bytes).map_err(|source| Error::Decode {
                what: format!("result of `{}`", self.action),
                source,
            })
        };
        match body.split_first() {
            Some((0, rest)) => Ok(Outcome::Completed(decode(rest)?)),
            Some((1, rest)) => Ok(Outcome::Cancelled(decode(rest)?)),
            Some((2, _)) => Ok(Outcome::Abandoned),
            Some((3, _)) => Ok(Outcome::Expired),
            _ => Err(Error::ServiceError {
                service_name: self.action.clone(),
                instance_id: Some(self.instance_id.clone()),
                reason: "malformed result".into(),
            }),
        }
    }

    /// Asks the server to cancel the goal. It works until the node's
    /// messaging closes (a shutdown hook cancelling what the node started is
    /// the usual case), then returns [`Error::ShuttingDown`].
    pub async fn cancel(&self, timeout: Duration) -> Result<CancelState> {
        let body = self.ask(ActionPart::Cancel, timeout).await?;
        Ok(match body.first() {
            Some(0) => CancelState::Signalled,
            Some(1) => CancelState::AlreadyTerminal,
            _ => CancelState::Unknown,
        })
    }
}
