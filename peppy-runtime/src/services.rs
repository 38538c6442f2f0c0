//! Services: a queryable per exposed service that lives as long as the
//! node and queues requests, and calls that go straight to a bound
//! producer or discover one.

use std::sync::Arc;
use std::time::Duration;

use tokio::time::Instant;
use tracing::warn;
use zenoh::query::Query;

use crate::acks::{Acker, Held};
use crate::error::{Error, Result};
use crate::intake;
use crate::node::NodeRunner;
use crate::producer_ref::ProducerRef;
use crate::request::Request;
use crate::spec::{ConsumedServiceSpec, ServiceSpec};
use crate::stop;
use crate::target;
use crate::wire::attachment::{self, QueryHeader, QueryKind, ReplyStatus};
use crate::wire::codec::{Decode, Encode, from_bytes, to_bytes};
use crate::wire::keys::{Channel, entry_key};

/// Requests waiting for `handle_next_request`.
pub(crate) struct ServiceInbox {
    pub(crate) rx: flume::Receiver<Pending>,
}

pub(crate) struct Pending {
    query: Held,
    header: QueryHeader,
}

/// The queryable callback: answer probes, check the request format, queue
/// requests (acked by `acker` if not answered promptly).
pub(crate) fn intake(
    spec: &'static ServiceSpec,
    key: String,
    tx: flume::Sender<Pending>,
    acker: Acker,
) -> impl Fn(Query) + Send + Sync + 'static {
    let key: Arc<str> = key.into();
    move |query: Query| {
        let fingerprint = spec.response.fingerprint;
        let Some(header) = intake::admit(&query, &key, spec.name, spec.request, fingerprint) else {
            return;
        };
        intake::enqueue(
            &tx,
            Pending {
                query: Arc::new(query),
                header,
            },
            |p| &p.query,
            &acker,
            &key,
            fingerprint,
            spec.name,
            "requests",
        );
    }
}

/// Who called.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Caller {
    /// The caller's instance id.
    pub instance_id: String,
    /// The caller's core node.
    pub core_node: String,
}

/// Serves the next request of an exposed service with `handler`. A request
/// that does not decode is answered with an error and `Ok(())` is returned,
/// so a serving loop keeps going.
///
/// Once the node stops it returns [`Error::ShuttingDown`]: at once if it was
/// waiting, after a short pause if called on an already stopped node, so a
/// loop that ignores the error parks instead of spinning.
pub async fn handle_next<Req, Resp, F>(
    runner: &NodeRunner,
    spec: &'static ServiceSpec,
    handler: F,
) -> Result<()>
where
    Req: Decode,
    Resp: Encode,
    F: FnOnce(Caller, Req) -> Result<Resp>,
{
    let (inbox, key) = runner.service_inbox(spec)?;
    if runner.cancellation_token().is_cancelled() {
        return Err(stop::refused().await);
    }
    let pending = tokio::select! {
        p = inbox.rx.recv_async() => p.map_err(|_| Error::ShuttingDown)?,
        () = runner.cancellation_token().cancelled() => return Err(Error::ShuttingDown),
    };
    let Pending { query, header } = pending;
    let caller = Caller {
        instance_id: header.instance,
        core_node: header.core,
    };
    let payload = query.payload().map(|p| p.to_bytes()).unwrap_or_default();
    let (status, body) = match from_bytes::<Req>(&payload) {
        Err(e) => {
            warn!(service = spec.name, caller = %caller.instance_id, error = %e, "refusing a request that does not decode");
            (
                ReplyStatus::HandlerError,
                format!("request does not decode: {e}").into_bytes(),
            )
        }
        Ok(req) => match handler(caller, req) {
            Ok(resp) => (ReplyStatus::Ok, to_bytes(&resp)),
            Err(e) => (ReplyStatus::HandlerError, e.to_string().into_bytes()),
        },
    };
    query
        .reply(key.clone(), body)
        .attachment(attachment::reply(status, spec.response.fingerprint))
        .await
        .map_err(Error::from)
}

/// A request taken off an exposed service's queue, to be answered later
/// (the test mocks' pull-style serving): the caller, the request's bytes,
/// and the reply handle.
#[cfg(feature = "testing")]
pub(crate) async fn take_request(
    runner: &NodeRunner,
    spec: &'static ServiceSpec,
) -> Result<(Caller, Vec<u8>, Answer)> {
    let (inbox, key) = runner.service_inbox(spec)?;
    let pending = tokio::select! {
        p = inbox.rx.recv_async() => p.map_err(|_| Error::ShuttingDown)?,
        () = runner.cancellation_token().cancelled() => return Err(Error::ShuttingDown),
    };
    let Pending { query, header } = pending;
    let caller = Caller {
        instance_id: header.instance,
        core_node: header.core,
    };
    let payload = query
        .payload()
        .map(|p| p.to_bytes().into_owned())
        .unwrap_or_default();
    let answer = Answer {
        query,
        key: key.clone(),
        fingerprint: spec.response.fingerprint,
    };
    Ok((caller, payload, answer))
}

/// The reply handle of a request taken with [`take_request`]. Held, the
/// request stays acknowledged, so its caller keeps waiting for the answer.
#[cfg(feature = "testing")]
pub(crate) struct Answer {
    query: Held,
    key: zenoh::key_expr::KeyExpr<'static>,
    fingerprint: u64,
}

#[cfg(feature = "testing")]
impl Answer {
    /// Answers with an encoded response.
    pub(crate) async fn respond(self, body: Vec<u8>) -> Result<()> {
        self.send(ReplyStatus::Ok, body).await
    }

    /// Answers with an error the caller sees as [`Error::ServiceError`].
    pub(crate) async fn fail(self, reason: &str) -> Result<()> {
        self.send(ReplyStatus::HandlerError, reason.as_bytes().to_vec())
            .await
    }

    async fn send(self, status: ReplyStatus, body: Vec<u8>) -> Result<()> {
        self.query
            .reply(self.key, body)
            .attachment(attachment::reply(status, self.fingerprint))
            .await
            .map_err(Error::from)
    }
}

/// A service response with the server's identity.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply<T> {
    /// The server's instance id.
    pub instance_id: String,
    /// The server's core node.
    pub core_node: String,
    /// The response.
    pub data: T,
}

/// Calls a consumed service through its slot: straight to the bound
/// producer for pinned slots (and from_any slots bound to one producer),
/// else to the first server the slot's filter accepts. The request is
/// encoded before the returned future first runs.
///
/// Calls work until the node's messaging closes, so a shutdown hook
/// ([`NodeRunner::on_shutdown`]) can still make them. A call waiting for
/// its reply when messaging closes returns [`Error::ShuttingDown`] at once;
/// a call made after that returns it after a short pause, so a loop that
/// ignores the error does not spin.
pub fn call<'a, Req, Resp>(
    runner: &'a NodeRunner,
    spec: &'static ConsumedServiceSpec,
    timeout: Duration,
    request: &Req,
) -> impl Future<Output = Result<Reply<Resp>>> + Send + use<'a, Req, Resp>
where
    Req: Encode + ?Sized,
    Resp: Decode + Send + 'a,
{
    let payload = to_bytes(request);
    async move {
        // Messaging, not the token: a shutdown hook may still call.
        if runner.messaging_stop().is_cancelled() {
            return Err(stop::refused().await);
        }
        let deadline = Instant::now() + timeout;
        let entry = entry(spec);
        let target = target::choose(runner, &entry, deadline).await?;
        request_to(runner, spec, &entry, &target, deadline, payload).await
    }
}

/// Calls a consumed service on one producer bound to its slot, as the
/// peppylib API does (`poll(&runner, target, timeout, request)`): a target the slot
/// is not bound to fails with [`Error::TargetNotBound`] before anything is
/// sent.
pub fn call_to<'a, Req, Resp>(
    runner: &'a NodeRunner,
    spec: &'static ConsumedServiceSpec,
    target: &ProducerRef,
    timeout: Duration,
    request: &Req,
) -> impl Future<Output = Result<Reply<Resp>>> + Send + use<'a, Req, Resp>
where
    Req: Encode + ?Sized,
    Resp: Decode + Send + 'a,
{
    let payload = to_bytes(request);
    let checked = crate::slots::check_target(runner, spec.link_id, target)
        .map(|()| target.instance_id.clone());
    async move {
        let instance = checked?;
        if runner.messaging_stop().is_cancelled() {
            return Err(stop::refused().await);
        }
        let deadline = Instant::now() + timeout;
        request_to(runner, spec, &entry(spec), &instance, deadline, payload).await
    }
}

fn entry(spec: &ConsumedServiceSpec) -> target::Entry<'static> {
    target::Entry {
        link_id: spec.link_id,
        owner: spec.owner,
        channel: Channel::Service,
        name: spec.name,
        part: None,
        fingerprint: spec.request.fingerprint,
        describe: spec.name.into(),
    }
}

async fn request_to<Resp: Decode>(
    runner: &NodeRunner,
    spec: &ConsumedServiceSpec,
    entry: &target::Entry<'_>,
    instance: &str,
    deadline: Instant,
    payload: Vec<u8>,
) -> Result<Reply<Resp>> {
    let answer = Request {
        session: runner.session(),
        stop: runner.messaging_stop(),
        key: entry.selector(runner, Some(instance)),
        keys: Some(runner.request_keys()),
        header: target::header(runner, QueryKind::Request, spec.request.fingerprint),
        payload,
        deadline,
        describe: &entry.describe,
        instance,
        remote: instance != runner.instance_id(),
        request_format: spec.request.canonical,
        response: Some((spec.response.fingerprint, spec.response.canonical)),
    }
    .send()
    .await?;
    let data = from_bytes::<Resp>(&answer.body.to_bytes()).map_err(|source| Error::Decode {
        what: format!("response of `{}`", spec.name),
        source,
    })?;
    Ok(Reply {
        instance_id: answer.instance,
        core_node: answer.core,
        data,
    })
}

/// The key a server replies on and serves.
pub(crate) fn server_key(runner: &NodeRunner, spec: &ServiceSpec) -> String {
    let owner = spec
        .owner
        .resolve(runner.node_name(), runner.node_tag())
        .expect("exposed services have an owner");
    entry_key(
        runner.namespace(),
        Channel::Service,
        &owner,
        spec.name,
        runner.core_node(),
        runner.instance_id(),
    )
}
