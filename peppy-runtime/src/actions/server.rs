//! The exposed side of an action: the goal registry (accept or reject,
//! feedback, parked results, cancel, abandon, retention), the goal
//! queryable's intake, and what the node's code holds while serving.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use tracing::{debug, warn};
use zenoh::Wait;
use zenoh::query::Query;

use crate::acks::{Acker, Held};
use crate::error::{Error, Result};
use crate::intake;
use crate::node::NodeRunner;
use crate::services::Caller;
use crate::spec::ActionSpec;
use crate::stop;
use crate::wire::attachment::{self, QueryHeader, ReplyStatus};
use crate::wire::codec::{Decode, Decoder, Encode, from_bytes, to_bytes};
use crate::wire::keys::{ActionPart, Channel, action_part_key, entry_key, feedback_key};

use super::CancelState;

/// How many expired goal ids are remembered (to answer `Expired`, not unknown).
const EXPIRED_MEMORY: usize = 4096;

/// How a goal ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Terminal {
    Completed = 0,
    Cancelled = 1,
    Abandoned = 2,
    Expired = 3,
}

enum GoalState {
    Active {
        cancel: CancellationToken,
        waiters: Vec<Held>,
    },
    Done {
        how: Terminal,
        body: Vec<u8>,
        at: Instant,
    },
}

/// The goals of one exposed action.
pub(crate) struct Registry {
    spec: &'static ActionSpec,
    goals: Mutex<HashMap<String, GoalState>>,
    expired: Mutex<VecDeque<String>>,
    retention: Duration,
    base_key: String,
    session: zenoh::Session,
    acker: Acker,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn reply_result(query: &Query, key: &str, how: Terminal, body: &[u8], fingerprint: u64) {
    let mut payload = vec![how as u8];
    payload.extend_from_slice(body);
    if let Err(e) = query
        .reply(key, payload)
        .attachment(attachment::reply(ReplyStatus::Ok, fingerprint))
        .wait()
    {
        debug!(error = %e, "result reply failed");
    }
}

impl Registry {
    pub(crate) fn new(
        spec: &'static ActionSpec,
        base_key: String,
        session: zenoh::Session,
        retention: Duration,
        acker: Acker,
    ) -> Arc<Registry> {
        Arc::new(Registry {
            spec,
            goals: Mutex::new(HashMap::new()),
            expired: Mutex::new(VecDeque::new()),
            retention,
            base_key,
            session,
            acker,
        })
    }

    fn key(&self, part: ActionPart) -> String {
        action_part_key(&self.base_key, part)
    }

    fn feedback_key(&self, goal_id: &str) -> String {
        feedback_key(&self.base_key, goal_id)
    }

    /// Moves a goal to a terminal state (first call wins), answers parked
    /// result queries and closes the feedback stream.
    fn finish(&self, goal_id: &str, how: Terminal, body: Vec<u8>) -> bool {
        let waiters = {
            let mut goals = lock(&self.goals);
            match goals.get_mut(goal_id) {
                Some(state @ GoalState::Active { .. }) => {
                    let GoalState::Active { waiters, .. } = std::mem::replace(
                        state,
                        GoalState::Done {
                            how,
                            body: body.clone(),
                            at: Instant::now(),
                        },
                    ) else {
                        unreachable!("matched Active")
                    };
                    waiters
                }
                _ => return false,
            }
        };
        let key = self.key(ActionPart::Result);
        for q in waiters {
            reply_result(&q, &key, how, &body, self.spec.result.fingerprint);
        }
        if let Err(e) = self
            .session
            .put(self.feedback_key(goal_id), Vec::<u8>::new())
            .attachment(attachment::END_OF_FEEDBACK.to_vec())
            .wait()
        {
            debug!(error = %e, "end-of-feedback publish failed");
        }
        true
    }

    /// Drops results older than the retention period, remembering their ids.
    pub(crate) fn sweep(&self) {
        let now = Instant::now();
        let mut expired_now = Vec::new();
        lock(&self.goals).retain(|id, state| match state {
            GoalState::Done { at, .. } if now.duration_since(*at) > self.retention => {
                expired_now.push(id.clone());
                false
            }
            _ => true,
        });
        let mut expired = lock(&self.expired);
        for id in expired_now {
            expired.push_back(id);
            if expired.len() > EXPIRED_MEMORY {
                expired.pop_front();
            }
        }
    }

    /// The cancel queryable.
    pub(crate) fn on_cancel(&self, query: Query) {
        let Some(goal_id) = goal_id_of(&query) else {
            return;
        };
        let state = match lock(&self.goals).get(&goal_id) {
            Some(GoalState::Active { cancel, .. }) => {
                cancel.cancel();
                CancelState::Signalled
            }
            Some(GoalState::Done { .. }) => CancelState::AlreadyTerminal,
            None if lock(&self.expired).contains(&goal_id) => CancelState::AlreadyTerminal,
            None => CancelState::Unknown,
        };
        let _ = query
            .reply(self.key(ActionPart::Cancel), vec![state as u8])
            .attachment(attachment::reply(ReplyStatus::Ok, 0))
            .wait();
    }

    /// The result queryable: answer at once when terminal, else park (and
    /// ack, unless the goal ends within the grace).
    pub(crate) fn on_result(&self, query: Query) {
        let Some(goal_id) = goal_id_of(&query) else {
            return;
        };
        let key = self.key(ActionPart::Result);
        let mut goals = lock(&self.goals);
        match goals.get_mut(&goal_id) {
            Some(GoalState::Active { waiters, .. }) => {
                let held = Arc::new(query);
                self.acker
                    .watch(&held, &key.as_str().into(), 0, self.spec.name);
                waiters.push(held);
            }
            Some(GoalState::Done { how, body, .. }) => {
                reply_result(&query, &key, *how, body, self.spec.result.fingerprint)
            }
            None if lock(&self.expired).contains(&goal_id) => reply_result(
                &query,
                &key,
                Terminal::Expired,
                &[],
                self.spec.result.fingerprint,
            ),
            None => {
                let _ = query
                    .reply(
                        key.as_str(),
                        format!("no goal `{goal_id}` on this server").into_bytes(),
                    )
                    .attachment(attachment::reply(ReplyStatus::HandlerError, 0))
                    .wait();
            }
        }
    }
}

/// The goal id a cancel or result query names (its payload).
fn goal_id_of(query: &Query) -> Option<String> {
    let payload = query.payload()?.to_bytes();
    let id = from_bytes::<String>(&payload).ok()?;
    is_goal_id(&id).then_some(id)
}

fn is_goal_id(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// A goal waiting for the server's decision.
pub(crate) struct PendingGoal {
    query: Held,
    header: QueryHeader,
    goal_id: String,
    body: Vec<u8>,
}

/// The goal queryable: check the format, queue for the decider (acked by
/// `acker` if not decided promptly).
pub(crate) fn goal_intake(
    spec: &'static ActionSpec,
    key: String,
    tx: flume::Sender<PendingGoal>,
    acker: Acker,
) -> impl Fn(Query) + Send + Sync + 'static {
    let key: Arc<str> = key.into();
    move |query: Query| {
        // A goal's status replies carry no format of their own.
        let Some(header) = intake::admit(&query, &key, spec.name, spec.goal, 0) else {
            return;
        };
        let payload = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let mut d = Decoder::new(&payload);
        let goal_id = match String::decode(&mut d) {
            Ok(id) if is_goal_id(&id) => id,
            _ => {
                return intake::reply(
                    &query,
                    &key,
                    ReplyStatus::HandlerError,
                    0,
                    b"malformed goal envelope".to_vec(),
                    spec.name,
                );
            }
        };
        let body = payload[payload.len() - d.remaining()..].to_vec();
        let goal = PendingGoal {
            query: Arc::new(query),
            header,
            goal_id,
            body,
        };
        intake::enqueue(&tx, goal, |g| &g.query, &acker, &key, 0, spec.name, "goals");
    }
}

/// A goal request, before the server decides.
pub struct IncomingGoal<G> {
    pending: PendingGoal,
    registry: Arc<Registry>,
    /// Who sent it.
    pub caller: Caller,
    /// The goal's data.
    pub data: G,
}

impl<G> std::fmt::Debug for IncomingGoal<G> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IncomingGoal")
            .field("goal_id", &self.pending.goal_id)
            .field("caller", &self.caller)
            .finish_non_exhaustive()
    }
}

/// A goal's answer: `{ accepted, error_message }`, then the action's
/// declared goal response when one is sent (docs/WIRE.md, "Actions").
fn goal_response(accepted: bool, error: Option<String>, response: &[u8]) -> Vec<u8> {
    let mut out = to_bytes(&(accepted, error));
    out.extend_from_slice(response);
    out
}

impl<G> IncomingGoal<G> {
    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        &self.pending.goal_id
    }

    /// The goal's data apart from the goal: the test mocks hand a goal's
    /// request out as a field and keep the decision for later.
    #[cfg(feature = "testing")]
    pub(crate) fn into_parts(self) -> (IncomingGoal<()>, G) {
        let IncomingGoal {
            pending,
            registry,
            caller,
            data,
        } = self;
        (
            IncomingGoal {
                pending,
                registry,
                caller,
                data: (),
            },
            data,
        )
    }

    /// Accepts the goal: it is registered before the caller hears back, so
    /// an immediate cancel or result request finds it.
    pub fn accept(self) -> Result<GoalContext> {
        self.accept_with(Vec::new())
    }

    /// [`accept`](Self::accept) with the action's declared goal response,
    /// encoded: the caller reads it as its handle's `data`.
    pub fn accept_with(self, response: Vec<u8>) -> Result<GoalContext> {
        let token = CancellationToken::new();
        lock(&self.registry.goals).insert(
            self.pending.goal_id.clone(),
            GoalState::Active {
                cancel: token.clone(),
                waiters: Vec::new(),
            },
        );
        self.pending
            .query
            .reply(
                self.registry.key(ActionPart::Goal),
                goal_response(true, None, &response),
            )
            .attachment(attachment::reply(ReplyStatus::Ok, 0))
            .wait()?;
        Ok(GoalContext {
            goal_id: self.pending.goal_id,
            registry: self.registry,
            cancel: token,
            finished: AtomicBool::new(false),
        })
    }

    /// Rejects the goal with a reason the caller sees.
    pub fn reject(self, reason: impl Into<String>) -> Result<()> {
        self.reject_with(Some(reason.into()), Vec::new())
    }

    /// Rejects the goal, with or without a reason, and with the action's
    /// declared goal response (encoded; empty for none).
    pub fn reject_with(self, reason: Option<String>, response: Vec<u8>) -> Result<()> {
        self.pending
            .query
            .reply(
                self.registry.key(ActionPart::Goal),
                goal_response(false, reason, &response),
            )
            .attachment(attachment::reply(ReplyStatus::Ok, 0))
            .wait()
            .map_err(Error::from)
    }
}

/// The goal queue of one exposed action on this node. It owns what it needs
/// (not the [`NodeRunner`]), so it can move into a spawned task; several
/// servers of one action share its queue, each goal going to one of them.
pub struct GoalServer {
    spec: &'static ActionSpec,
    rx: flume::Receiver<PendingGoal>,
    registry: Arc<Registry>,
    stop: CancellationToken,
}

impl std::fmt::Debug for GoalServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalServer")
            .field("action", &self.spec.name)
            .finish_non_exhaustive()
    }
}

impl GoalServer {
    /// The server of `spec` on this node; [`Error::Undeclared`] if the node
    /// does not expose it.
    pub fn new(runner: &NodeRunner, spec: &'static ActionSpec) -> Result<GoalServer> {
        let (rx, registry) = runner.action_server(spec)?;
        Ok(GoalServer {
            spec,
            rx: rx.clone(),
            registry: registry.clone(),
            stop: runner.cancellation_token().clone(),
        })
    }

    /// Waits for the next goal. A goal whose data does not decode is
    /// rejected and skipped.
    ///
    /// Once the node stops it returns [`Error::ShuttingDown`]: at once if it
    /// was waiting, after a short pause if called on an already stopped
    /// node, so a loop that ignores the error parks instead of spinning.
    pub async fn next<G: Decode>(&self) -> Result<IncomingGoal<G>> {
        if self.stop.is_cancelled() {
            return Err(stop::refused().await);
        }
        loop {
            let pending = tokio::select! {
                p = self.rx.recv_async() => p.map_err(|_| Error::ShuttingDown)?,
                () = self.stop.cancelled() => return Err(Error::ShuttingDown),
            };
            match from_bytes::<G>(&pending.body) {
                Ok(data) => {
                    let caller = Caller {
                        instance_id: pending.header.instance.clone(),
                        core_node: pending.header.core.clone(),
                    };
                    return Ok(IncomingGoal {
                        pending,
                        registry: self.registry.clone(),
                        caller,
                        data,
                    });
                }
                Err(e) => {
                    warn!(action = self.spec.name, caller = %pending.header.instance, error = %e, "rejecting a goal that does not decode");
                    let _ = pending
                        .query
                        .reply(
                            self.registry.key(ActionPart::Goal),
                            goal_response(false, Some(format!("goal does not decode: {e}")), &[]),
                        )
                        .attachment(attachment::reply(ReplyStatus::Ok, 0))
                        .await;
                }
            }
        }
    }
}

/// Waits for the next goal of an exposed action, as [`GoalServer::next`].
pub async fn next_goal<G: Decode>(
    runner: &NodeRunner,
    spec: &'static ActionSpec,
) -> Result<IncomingGoal<G>> {
    GoalServer::new(runner, spec)?.next().await
}

/// An accepted goal on the server. Finish it with [`complete`](Self::complete)
/// or [`complete_cancelled`](Self::complete_cancelled); dropping it
/// unfinished reports `Abandoned` to the caller.
pub struct GoalContext {
    goal_id: String,
    registry: Arc<Registry>,
    cancel: CancellationToken,
    finished: AtomicBool,
}

impl std::fmt::Debug for GoalContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalContext")
            .field("goal_id", &self.goal_id)
            .finish_non_exhaustive()
    }
}

impl GoalContext {
    /// The goal's id.
    pub fn goal_id(&self) -> &str {
        &self.goal_id
    }

    /// Resolves when the caller asks to cancel.
    pub async fn cancel_signal(&self) {
        self.cancel.cancelled().await;
    }

    /// Whether the caller asked to cancel.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }

    /// Publishes one feedback message on this goal's stream. Once the
    /// node's session is closed it returns [`Error::ShuttingDown`] after a
    /// short pause.
    pub async fn publish_feedback<F: Encode + ?Sized>(&self, feedback: &F) -> Result<()> {
        if self.registry.session.is_closed() {
            return Err(stop::refused().await);
        }
        let payload = to_bytes(feedback);
        self.registry
            .session
            .put(self.registry.feedback_key(&self.goal_id), payload)
            .attachment(attachment::topic(self.registry.spec.feedback.fingerprint))
            .await
            .map_err(Error::from)
    }

    /// Finishes the goal successfully with its result. The first finish of
    /// a goal counts; a later `complete` or `complete_cancelled` does
    /// nothing (as PeppyOS's, it is idempotent, so a worker holding the
    /// context by reference may race its cancel path safely).
    pub fn complete<R: Encode + ?Sized>(&self, result: &R) -> Result<()> {
        self.finish(Terminal::Completed, result);
        Ok(())
    }

    /// Finishes the goal as cancelled, with a (partial) result. As
    /// [`complete`](Self::complete), only the first finish counts.
    pub fn complete_cancelled<R: Encode + ?Sized>(&self, result: &R) -> Result<()> {
        self.finish(Terminal::Cancelled, result);
        Ok(())
    }

    fn finish<R: Encode + ?Sized>(&self, how: Terminal, result: &R) {
        if !self.finished.swap(true, AtomicOrdering::AcqRel) {
            self.registry.finish(&self.goal_id, how, to_bytes(result));
        }
    }
}

impl Drop for GoalContext {
    fn drop(&mut self) {
        if !self.finished.load(AtomicOrdering::Acquire)
            && self
                .registry
                .finish(&self.goal_id, Terminal::Abandoned, Vec::new())
        {
            warn!(action = self.registry.spec.name, goal = %self.goal_id, "goal dropped without a result: reported as abandoned");
        }
    }
}

/// The base key of an exposed action on this node.
pub(crate) fn server_base_key(runner: &NodeRunner, spec: &ActionSpec) -> String {
    let owner = spec
        .owner
        .resolve(runner.node_name(), runner.node_tag())
        .expect("exposed actions have an owner");
    entry_key(
        runner.namespace(),
        Channel::Action,
        &owner,
        spec.name,
        runner.core_node(),
        runner.instance_id(),
    )
}
