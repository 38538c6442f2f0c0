//! The one request/reply client. A request goes to one server; the client
//! follows the server's status replies (WIRE.md: ack, ok, handler error,
//! format mismatch) until the deadline, the node's stop, or an answer, and
//! tells an unreachable server from one that accepted and went quiet.
//! Service calls, action goals and a goal's result and cancel queries all
//! go through here, so they fail the same way with the same words.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, RwLock};
use std::time::Duration;

use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::Locality;
use zenoh::sample::Sample;

use crate::error::{Error, Result};
use crate::stop;
use crate::wire::attachment::{self, ReplyStatus};
use crate::wire::keys::split_entry_key;

/// How many request keys a node declares; calls to further keys send the
/// key as text (as before the first call to any key).
const DECLARED_KEYS: usize = 1024;

/// The keys a node sends requests to, each declared to its session on first
/// use. A request key names one server but holds a wildcard (the server's
/// core node, unknown to a pinned slot), so no resource of the session has
/// it and Zenoh computed the request's route, matching the key against
/// every queryable, on each call; a declared key carries the route cache
/// (the same cause and cure as a consumer's producer keys, see
/// `producers.rs`).
///
/// Once a server has answered, its calls go to the key it answered on,
/// which names its core node. Zenoh matches each request's key against
/// each queryable of the server's session (a node holds a dozen: its
/// services, actions, formats, description and topic keys); a key without
/// a wildcard is compared as text where one with a wildcard is walked chunk
/// by chunk, and it can be asked with target `AllComplete` ([`target_of`]),
/// which leaves the node's other queryables out before matching
/// (docs/PERFORMANCE_HISTORY.md has the instruction counts). A call that finds
/// nobody at that key (the instance runs under another launch now) forgets
/// it and asks again with the wildcard, in what is left of its budget.
#[derive(Default)]
pub(crate) struct RequestKeys {
    known: RwLock<HashMap<Box<str>, Keys>>,
}

/// The declared keys of one request key.
struct Keys {
    /// The request key, wildcard and all.
    asked: KeyExpr<'static>,
    /// The key its server answered on, once one has.
    answered: Option<KeyExpr<'static>>,
}

impl RequestKeys {
    /// `key` declared to `session`, and the key its server answered on if
    /// one has; `None` when `key` could not be declared (or more than
    /// [`DECLARED_KEYS`] already are).
    async fn for_call(
        &self,
        session: &zenoh::Session,
        key: &str,
    ) -> Option<(KeyExpr<'static>, Option<KeyExpr<'static>>)> {
        {
            let known = self.known.read().ok()?;
            if let Some(k) = known.get(key) {
                return Some((k.asked.clone(), k.answered.clone()));
            }
            if known.len() >= DECLARED_KEYS {
                return None;
            }
        }
        let asked = session.declare_keyexpr(key.to_string()).await.ok()?;
        let mut known = self.known.write().ok()?;
        let keys = known.entry(key.into()).or_insert(Keys {
            asked,
            answered: None,
        });
        Some((keys.asked.clone(), None))
    }

    /// Notes that a server answered a request for `key` on `answered`, to
    /// send the next ones there (a key without wildcards only).
    async fn answered(&self, session: &zenoh::Session, key: &str, answered: &KeyExpr<'_>) {
        // Only for a request key of the table (not one past its bound),
        // whose server is not known yet.
        let unknown = self
            .known
            .read()
            .is_ok_and(|known| known.get(key).is_some_and(|k| k.answered.is_none()));
        if !unknown || answered.is_wild() {
            return;
        }
        let Ok(answered) = session.declare_keyexpr(answered.clone().into_owned()).await else {
            return;
        };
        if let Ok(mut known) = self.known.write()
            && let Some(keys) = known.get_mut(key)
        {
            keys.answered = Some(answered);
        }
    }

    /// Forgets the server key of `key`: no server answered there.
    fn unanswered(&self, key: &str) {
        if let Ok(mut known) = self.known.write()
            && let Some(keys) = known.get_mut(key)
        {
            keys.answered = None;
        }
    }
}

/// One request to one server.
pub(crate) struct Request<'a> {
    /// The session to send on.
    pub(crate) session: &'a zenoh::Session,
    /// The node's stop: a waiting request returns `ShuttingDown` at once.
    pub(crate) stop: &'a CancellationToken,
    /// The server's key (one instance).
    pub(crate) key: String,
    /// The node's declared request keys (`None`: send the key as text).
    pub(crate) keys: Option<&'a RequestKeys>,
    /// The query header (`QueryHeader::encode`).
    pub(crate) header: Vec<u8>,
    /// The request body.
    pub(crate) payload: Vec<u8>,
    /// When to give up.
    pub(crate) deadline: Instant,
    /// How the entry reads in errors (`move_arm (action goal)`).
    pub(crate) describe: &'a str,
    /// The server instance, for errors.
    pub(crate) instance: &'a str,
    /// The server runs in another session than `session` (another node's;
    /// a tool's session serves nothing): the query skips the session's own
    /// queryables, which Zenoh would otherwise match the key against one by
    /// one on every call.
    pub(crate) remote: bool,
    /// This node's request format, named when the server expects another.
    pub(crate) request_format: &'a str,
    /// The response format an `Ok` must carry, as fingerprint and
    /// canonical text (`None`: status replies without a format, as a goal's
    /// decision).
    pub(crate) response: Option<(u64, &'a str)>,
}

/// A server's `Ok` reply.
#[derive(Debug)]
pub(crate) struct Answer {
    /// The server's core node.
    pub(crate) core: String,
    /// The server's instance id.
    pub(crate) instance: String,
    /// The response body as it arrived, not yet decoded.
    pub(crate) body: ZBytes,
}

impl Request<'_> {
    fn failed(&self, instance: String, reason: String) -> Error {
        Error::ServiceError {
            service_name: self.describe.to_string(),
            instance_id: Some(instance),
            reason,
        }
    }

    /// Sends the request and waits for the answer.
    pub(crate) async fn send(mut self) -> Result<Answer> {
        if self.stop.is_cancelled() {
            return Err(stop::refused().await);
        }
        let payload = ZBytes::from(std::mem::take(&mut self.payload));
        let header = ZBytes::from(std::mem::take(&mut self.header));
        let declared = match self.keys {
            Some(keys) => keys.for_call(self.session, &self.key).await,
            None => None,
        };
        let (asked, server) = match declared {
            Some(declared) => declared,
            None => (KeyExpr::try_from(self.key.clone())?, None),
        };
        if let Some(server) = server {
            match self.ask(&server, payload.clone(), header.clone()).await? {
                Asked::Answered(answer, _) => return Ok(answer),
                // The server holds the request: it is there, only slow.
                Asked::Unanswered { acked: true } => return Err(self.unanswered(true)),
                // Nobody is at that key any more (the instance runs under
                // another launch now, say): ask as before it was known.
                Asked::Unanswered { acked: false } => {
                    if let Some(keys) = self.keys {
                        keys.unanswered(&self.key);
                    }
                }
            }
        }
        match self.ask(&asked, payload, header).await? {
            Asked::Answered(answer, on) => {
                if let Some(keys) = self.keys {
                    keys.answered(self.session, &self.key, &on).await;
                }
                Ok(answer)
            }
            Asked::Unanswered { acked } => Err(self.unanswered(acked)),
        }
    }

    /// One query to `key`, followed until an answer, the deadline, the end
    /// of replies or the node's stop.
    async fn ask(&self, key: &KeyExpr<'static>, payload: ZBytes, header: ZBytes) -> Result<Asked> {
        let budget = self
            .deadline
            .saturating_duration_since(Instant::now())
            .max(Duration::from_millis(1));
        // An ack only says the server holds the request: it is noted on
        // Zenoh's thread, and the waiting task is woken once, by the
        // answer (back to back on two cores, a pinned call's median went
        // from about 710 to about 520 µs). Each reply's status is read
        // here, once; a reply without one is not the protocol's and is
        // dropped.
        let acked = Arc::new(AtomicBool::new(false));
        let (tx, replies) = flume::unbounded::<(ReplyStatus, u64, Sample)>();
        let seen = acked.clone();
        self.session
            .get(key)
            .payload(payload)
            .attachment(header)
            .target(target_of(key))
            .allowed_destination(if self.remote {
                Locality::Remote
            } else {
                Locality::Any
            })
            .consolidation(ConsolidationMode::None)
            .timeout(budget)
            .callback(move |reply| {
                let Ok(sample) = reply.into_result() else {
                    return;
                };
                let Some((status, fingerprint)) = sample
                    .attachment()
                    .and_then(|a| attachment::parse_reply(&a.to_bytes()))
                else {
                    return;
                };
                match status {
                    ReplyStatus::Ack | ReplyStatus::Present => seen.store(true, Ordering::Relaxed),
                    _ => {
                        let _ = tx.send((status, fingerprint, sample));
                    }
                }
            })
            .await?;
        // No timer of its own: Zenoh ends the query at `budget` and drops
        // the callback, which closes `replies`. (In tokio's timer code, a
        // new deadline earlier than the driver's next wake-up unparks the
        // driver's thread: a wake-up per call.)
        loop {
            let (status, fingerprint, sample) = tokio::select! {
                r = replies.recv_async() => match r {
                    Ok(r) => r,
                    Err(_) => break,
                },
                () = self.stop.cancelled() => return Err(Error::ShuttingDown),
            };
            let Some(sender) = split_entry_key(sample.key_expr().as_str()) else {
                continue;
            };
            let body = sample.payload();
            match status {
                // Noted by the callback; never queued.
                ReplyStatus::Ack | ReplyStatus::Present => continue,
                ReplyStatus::Ok => match self.response {
                    Some((expected, canonical)) if fingerprint != expected => {
                        return Err(self.failed(
                            sender.instance.to_string(),
                            format!(
                                "the server's response format differs from this node's ({canonical}); rebuild one side",
                            ),
                        ));
                    }
                    _ => {
                        let answer = Answer {
                            core: sender.core.to_string(),
                            instance: sender.instance.to_string(),
                            body: body.clone(),
                        };
                        return Ok(Asked::Answered(answer, sample.key_expr().clone()));
                    }
                },
                ReplyStatus::HandlerError => {
                    let reason = String::from_utf8_lossy(&body.to_bytes()).into_owned();
                    return Err(self.failed(sender.instance.to_string(), reason));
                }
                ReplyStatus::FormatMismatch => {
                    let reason = format!(
                        "the server expects request format {}, this node sends {}; rebuild one side",
                        String::from_utf8_lossy(&body.to_bytes()),
                        self.request_format
                    );
                    return Err(self.failed(sender.instance.to_string(), reason));
                }
            }
        }
        Ok(Asked::Unanswered {
            acked: acked.load(Ordering::Relaxed),
        })
    }

    /// The error of a request no server answered: held by one (`acked`)
    /// but not answered in time, or never reached.
    fn unanswered(&self, acked: bool) -> Error {
        let (service_name, instance_id) =
            (self.describe.to_string(), Some(self.instance.to_string()));
        if acked {
            Error::ServiceTimeout {
                service_name,
                instance_id,
            }
        } else {
            Error::ServiceUnreachable {
                service_name,
                instance_id,
            }
        }
    }
}

/// How one query ended, short of an error.
enum Asked {
    /// A server's `ok`, and the key it answered on.
    Answered(Answer, KeyExpr<'static>),
    /// No answer before the deadline or the end of replies; `acked`: a
    /// server said it held the request.
    Unanswered { acked: bool },
}

/// Which queryables a query to `key` goes to. Every server's service and
/// action queryables are complete (WIRE.md §3), so a key without wildcards
/// (a server's own key) reaches the same one with `AllComplete` as with
/// `All`; but each session that receives a query matches its key against
/// each of its queryables that the target admits, and `AllComplete` leaves
/// out a node's others (its topic keys, formats and description) before
/// matching. A wildcard key needs `All`: Zenoh calls a queryable complete
/// for a query only when the queryable's key includes the query's.
fn target_of(key: &KeyExpr<'_>) -> QueryTarget {
    if key.is_wild() {
        QueryTarget::All
    } else {
        QueryTarget::AllComplete
    }
}
