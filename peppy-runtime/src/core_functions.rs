//! What a core node (a launch, or the hub of `peppy-launch run`, or a test
//! harness) answers its nodes, as PeppyOS's core node does: the
//! [`datastore`](crate::datastore), [`info`](crate::info) and the stack
//! listing ([`stack::list`](crate::stack::list)).
//!
//! Each is one queryable of the core node's on
//! `peppy/<ns>/stack/<core>/<function>` (docs/WIRE.md, "Core node
//! functions"); a node asks the core node it was started by
//! ([`NodeRunner::core_node`]).

use std::collections::HashSet;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tracing::debug;
use zenoh::Wait;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::SampleKind;

use crate::datastore::Store;
use crate::error::{Error, Result};
use crate::info::InfoResponse;
use crate::node::NodeRunner;
use crate::stack::{SerializedNodeGraph, StackList};
use crate::wire::keys::{
    CoreFunction, all_liveliness_selector, core_function_key, parse_liveliness_key,
};

/// What a core node knows of itself and its stack, asked at each call of
/// `info` and `stack::list`.
pub trait CoreView: Send + Sync + 'static {
    /// The core node's facts.
    fn info(&self) -> InfoResponse;
    /// Its nodes, their instances and the links between them; `live`
    /// holds the instances whose liveliness token is up (reachable now).
    fn graph(&self, live: &HashSet<String>) -> SerializedNodeGraph;
}

/// The instances of the namespace whose liveliness token is up, as the
/// core node's subscription saw them.
#[derive(Default)]
struct Live(Mutex<HashSet<String>>);

impl Live {
    fn snapshot(&self) -> HashSet<String> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// The stack listing a core node answers: its graph and who it is.
fn stack_list(view: &dyn CoreView, live: &Live) -> StackList {
    let info = view.info();
    StackList {
        graph: view.graph(&live.snapshot()),
        core_node: info.core_node_name,
        instance_id: info.core_node_instance_id,
        host_name: info.host_name,
    }
}

/// A core node's answers, served until dropped.
pub struct CoreFunctions {
    _queryables: Vec<zenoh::query::Queryable<()>>,
    _live: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for CoreFunctions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CoreFunctions").finish_non_exhaustive()
    }
}

/// Serves core node `core`'s functions for namespace `namespace` on
/// `session`: a datastore of its own (empty at start, kept while served)
/// and `info` / `stack::list` from `view`.
pub async fn serve(
    session: &zenoh::Session,
    namespace: &str,
    core: &str,
    view: Arc<dyn CoreView>,
) -> Result<CoreFunctions> {
    let store = Arc::new(Store::default());
    let live = Arc::new(Live::default());
    let seen = live.clone();
    let live_sub = session
        .liveliness()
        .declare_subscriber(all_liveliness_selector(namespace))
        .history(true)
        .callback(move |sample| {
            if let Some((_core, instance)) = parse_liveliness_key(sample.key_expr().as_str()) {
                let mut set = seen.0.lock().unwrap_or_else(|p| p.into_inner());
                match sample.kind() {
                    SampleKind::Put => set.insert(instance),
                    SampleKind::Delete => set.remove(&instance),
                };
            }
        })
        .await?;
    let mut queryables = Vec::new();
    for function in [
        CoreFunction::Datastore,
        CoreFunction::Info,
        CoreFunction::List,
    ] {
        let key = core_function_key(namespace, core, function);
        let (reply_key, store, view, live) =
            (key.clone(), store.clone(), view.clone(), live.clone());
        let queryable = session
            .declare_queryable(key)
            .callback(move |q| {
                let payload = q.payload().map(|p| p.to_bytes()).unwrap_or_default();
                let answer = match function {
                    CoreFunction::Datastore => store.answer(&payload),
                    CoreFunction::Info => serde_json::to_vec(&view.info()).map_err(|e| e.to_string()),
                    CoreFunction::List => {
                        serde_json::to_vec(&stack_list(&*view, &live)).map_err(|e| e.to_string())
                    }
                };
                let sent = match answer {
                    Ok(body) => q.reply(reply_key.as_str(), body).wait(),
                    Err(why) => {
                        debug!(function = function.as_str(), reason = %why, "refusing a core node call");
                        q.reply_err(why).wait()
                    }
                };
                if let Err(e) = sent {
                    debug!(function = function.as_str(), error = %e, "a core node answer was not sent");
                }
            })
            .await?;
        queryables.push(queryable);
    }
    Ok(CoreFunctions {
        _queryables: queryables,
        _live: live_sub,
    })
}

/// How long a call of a core node function waits for its core node by
/// default.
pub const DEFAULT_RESPONSE_TIMEOUT: Duration = Duration::from_secs(10);

/// How long a call waits before asking again when nobody answered (a node
/// just started may not know its core node's queryables yet).
const RETRY: Duration = Duration::from_millis(50);

/// Asks this node's core node `function` for its JSON answer (`info`,
/// `list`); `what` names the answer in a decoding error.
pub(crate) async fn ask_json<T: serde::de::DeserializeOwned>(
    runner: &NodeRunner,
    function: CoreFunction,
    timeout: Option<Duration>,
    what: &str,
) -> Result<T> {
    let body = ask(runner, function, Vec::new(), timeout).await?;
    serde_json::from_slice(&body)
        .map_err(|e| Error::Deserialization(format!("the core node's {what}: {e}")))
}

/// Asks this node's core node `function` with `payload`: the answer's
/// payload. `Error::ServiceUnreachable` when nobody answers within
/// `timeout` (`None`: [`DEFAULT_RESPONSE_TIMEOUT`]), `Error::ServiceError`
/// when the core node refuses.
pub(crate) async fn ask(
    runner: &NodeRunner,
    function: CoreFunction,
    payload: Vec<u8>,
    timeout: Option<Duration>,
) -> Result<Vec<u8>> {
    let timeout = timeout.unwrap_or(DEFAULT_RESPONSE_TIMEOUT);
    if runner.messaging_stop().is_cancelled() {
        return Err(crate::stop::refused().await);
    }
    let key = core_function_key(runner.namespace(), runner.core_node(), function);
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(tokio::time::Instant::now());
        let replies = runner
            .session()
            .get(&key)
            .payload(payload.clone())
            .target(QueryTarget::BestMatching)
            .consolidation(ConsolidationMode::None)
            .timeout(left.max(Duration::from_millis(1)))
            .await?;
        let reply = tokio::select! {
            r = replies.recv_async() => r.ok(),
            () = runner.messaging_stop().cancelled() => return Err(Error::ShuttingDown),
        };
        if let Some(reply) = reply {
            match reply.result() {
                Ok(sample) => return Ok(sample.payload().to_bytes().into_owned()),
                Err(e) => {
                    let why = e.payload().try_to_string().unwrap_or_default().into_owned();
                    // Zenoh ends a query whose time is up with an error
                    // of its own, not the core node's.
                    if why != "Timeout" {
                        return Err(Error::ServiceError {
                            service_name: function.as_str().to_string(),
                            instance_id: Some(runner.core_node().to_string()),
                            reason: why,
                        });
                    }
                }
            }
        }
        let left = deadline.saturating_duration_since(tokio::time::Instant::now());
        if left.is_zero() {
            return Err(Error::ServiceUnreachable {
                service_name: format!(
                    "{} of core node `{}`",
                    function.as_str(),
                    runner.core_node()
                ),
                instance_id: None,
            });
        }
        tokio::select! {
            () = tokio::time::sleep(left.min(RETRY)) => {}
            () = runner.messaging_stop().cancelled() => return Err(Error::ShuttingDown),
        }
    }
}
