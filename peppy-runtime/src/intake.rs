//! The server side of a request, one way for every queryable (services and
//! action goals): read the caller's header, answer a probe and a request in
//! another format, and queue without ever blocking Zenoh's delivery thread
//! (a full queue answers busy; [`Acker`] acks what stays unanswered).

use std::sync::Arc;

use tracing::{debug, warn};
use zenoh::Wait;
use zenoh::query::Query;

use crate::acks::{Acker, Held};
use crate::spec::FormatSpec;
use crate::wire::attachment::{self, QueryHeader, QueryKind, ReplyStatus};

/// Replies to `query` on `key` with a status. A reply that cannot be sent
/// (the caller gave up) is logged, never an error.
pub(crate) fn reply(
    query: &Query,
    key: &str,
    status: ReplyStatus,
    fingerprint: u64,
    payload: Vec<u8>,
    entry: &str,
) {
    if let Err(e) = query
        .reply(key, payload)
        .attachment(attachment::reply(status, fingerprint))
        .wait()
    {
        debug!(entry, error = %e, "reply failed");
    }
}

/// Admits a query to `entry` served on `key`: a query without a valid
/// header is dropped, a probe is answered `Present`, a request in another
/// format than `request` is answered `FormatMismatch` with this server's
/// format. Returns the header of a request to handle.
/// Status replies carry `fingerprint`.
pub(crate) fn admit(
    query: &Query,
    key: &str,
    entry: &str,
    request: FormatSpec,
    fingerprint: u64,
) -> Option<QueryHeader> {
    let Some(header) = query
        .attachment()
        .and_then(|a| QueryHeader::decode(&a.to_bytes()))
    else {
        debug!(entry, "dropping a query without a valid peppy attachment");
        return None;
    };
    let answer = |status, payload| reply(query, key, status, fingerprint, payload, entry);
    match header.kind {
        QueryKind::Probe => {
            answer(ReplyStatus::Present, Vec::new());
            None
        }
        QueryKind::Request if header.fingerprint != request.fingerprint => {
            warn!(entry, caller = %header.instance, "refusing a request whose format differs from this server's");
            answer(
                ReplyStatus::FormatMismatch,
                request.canonical.as_bytes().to_vec(),
            );
            None
        }
        QueryKind::Request => Some(header),
    }
}

/// Queues a request for the node's handler and has `acker` ack it if it is
/// still unanswered after the grace. A full queue answers busy (`queued`
/// names what is queued, e.g. `requests`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn enqueue<T>(
    tx: &flume::Sender<T>,
    item: T,
    query_of: fn(&T) -> &Held,
    acker: &Acker,
    key: &Arc<str>,
    fingerprint: u64,
    entry: &'static str,
    queued: &str,
) {
    let held = query_of(&item).clone();
    match tx.try_send(item) {
        Ok(()) => acker.watch(&held, key, fingerprint, entry),
        Err(flume::TrySendError::Full(_)) => {
            warn!(entry, "{queued} queue full; answering busy");
            reply(
                &held,
                key,
                ReplyStatus::HandlerError,
                fingerprint,
                format!("server busy: too many queued {queued}").into_bytes(),
                entry,
            );
        }
        Err(flume::TrySendError::Disconnected(_)) => debug!(entry, "inbox closed"),
    }
}
