//! Deferred acks. A server acks a request only when it has not answered it
//! within [`ACK_GRACE`]: the ack exists so a caller whose deadline passes can
//! tell a server that holds its request (*ServiceTimeout*) from one that
//! never got it (*ServiceUnreachable*), and a prompt answer says that
//! already. Acking every request at once cost a third Zenoh message per
//! call (measured on two cores: a tenth of each side's CPU time and of its
//! context switches per pinned call).
//!
//! A held request is an `Arc<Query>` owned by whoever answers it; the
//! node's one acker task keeps only a `Weak`. Answering drops the `Arc`, so
//! when the grace ends the acker finds nothing to ack. Requests are held in
//! arrival order and the grace is the same for all, so the acker's queue is
//! already sorted by due time: one sleep at a time, and requests arriving
//! while it sleeps cost no wake-up.

use std::sync::{Arc, Weak};
use std::time::Duration;

use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use zenoh::query::Query;

use crate::intake;
use crate::wire::attachment::ReplyStatus;

/// How long a server may take to answer before it acks. Long enough for a
/// handler that answers at once, short against any useful call timeout
/// (a call whose whole timeout is shorter cannot tell a slow server from an
/// absent one, and reports it unreachable).
pub(crate) const ACK_GRACE: Duration = Duration::from_millis(5);

/// A request a server holds until it answers.
pub(crate) type Held = Arc<Query>;

/// What the acker needs to ack one request.
struct Due {
    at: Instant,
    query: Weak<Query>,
    key: Arc<str>,
    fingerprint: u64,
    entry: &'static str,
}

/// The node's acker: acks the requests still held when their grace ends.
#[derive(Clone)]
pub(crate) struct Acker {
    tx: flume::Sender<Due>,
}

impl Acker {
    /// Starts the acker task, ending with `token` (held requests are then
    /// dropped by their owners, which closes them for their callers).
    pub(crate) fn start(token: CancellationToken) -> Self {
        let (tx, rx) = flume::unbounded::<Due>();
        tokio::spawn(async move {
            loop {
                let due = tokio::select! {
                    due = rx.recv_async() => match due {
                        Ok(due) => due,
                        Err(_) => break,
                    },
                    () = token.cancelled() => break,
                };
                if due.query.strong_count() == 0 {
                    continue;
                }
                tokio::select! {
                    () = tokio::time::sleep_until(due.at) => {}
                    () = token.cancelled() => break,
                }
                if let Some(query) = due.query.upgrade() {
                    intake::reply(
                        &query,
                        &due.key,
                        ReplyStatus::Ack,
                        due.fingerprint,
                        Vec::new(),
                        due.entry,
                    );
                }
            }
        });
        Acker { tx }
    }

    /// Acks `query` after the grace unless it has been answered (its
    /// [`Held`] dropped) by then.
    pub(crate) fn watch(
        &self,
        query: &Held,
        key: &Arc<str>,
        fingerprint: u64,
        entry: &'static str,
    ) {
        let _ = self.tx.send(Due {
            at: Instant::now() + ACK_GRACE,
            query: Arc::downgrade(query),
            key: key.clone(),
            fingerprint,
            entry,
        });
    }
}
