//! The producers a consumer hears from, each known once.
//!
//! A topic message arrives under its producer's full key
//! (`peppy/<ns>/topic/<owner>/<entry>/<core>/<instance>`). Two costs would
//! otherwise be paid for every message:
//!
//! - peppy parsing that key into the producer's core node and instance;
//! - Zenoh routing it. A consumer subscribes with a wildcard selector, so
//!   no resource of the receiving session has the producer's exact key,
//!   and Zenoh then computes the message's route (matching the key against
//!   every subscription of the session) for each message instead of
//!   reading it from the resource's route cache. Measured at 8 bytes
//!   between two processes: a route computed per message, and a consumer
//!   taking a tenth of raw Zenoh's message rate.
//!
//! So the first message under a key is parsed into a shared [`Producer`],
//! and the key is declared to the node's session ([`Declarer`]), which
//! makes it a resource with a route cache; later messages find both.

use std::collections::HashMap;
use std::sync::{Arc, RwLock};

use tokio_util::sync::CancellationToken;
use tracing::debug;
use zenoh::Session;

use crate::wire::keys::{parse_entry_key, parse_pairing_topic_key};

/// How many producer keys one consumed topic remembers. Past it, a key is
/// parsed per message and not declared: a flood of made-up keys costs
/// time, never unbounded memory.
const REMEMBERED: usize = 1024;

/// A producer of a consumed topic, as its key names it.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct Producer {
    /// The launch (core node) that started it.
    pub(crate) core: Box<str>,
    /// Its instance id.
    pub(crate) instance: Box<str>,
}

impl Producer {
    fn parse(key: &str) -> Option<Producer> {
        if let Some(sender) = parse_entry_key(key) {
            return Some(Producer {
                core: sender.core.into(),
                instance: sender.instance.into(),
            });
        }
        // A pairing's topic: the sender's slot is pinned by the
        // subscription, so the instance is all a reader needs.
        let sender = parse_pairing_topic_key(key)?;
        Some(Producer {
            core: sender.core.into(),
            instance: sender.instance.into(),
        })
    }
}

/// The producers one consumed topic has heard from, by key.
#[derive(Debug)]
pub(crate) struct Producers {
    known: RwLock<HashMap<Box<str>, Arc<Producer>, foldhash::fast::FixedState>>,
    declarer: Declarer,
}

impl Producers {
    pub(crate) fn new(declarer: Declarer) -> Self {
        Producers {
            known: RwLock::new(HashMap::default()),
            declarer,
        }
    }

    /// The producer publishing under `key`; `None` for a key that does not
    /// name one.
    pub(crate) fn of(&self, key: &str) -> Option<Arc<Producer>> {
        if let Some(p) = self.known.read().ok()?.get(key) {
            return Some(p.clone());
        }
        let producer = Arc::new(Producer::parse(key)?);
        let mut known = self.known.write().ok()?;
        if known.len() < REMEMBERED {
            let entry = known.entry(key.into()).or_insert_with(|| {
                self.declarer.declare(key);
                producer
            });
            return Some(entry.clone());
        }
        Some(producer)
    }
}

/// Declares keys to a node's session, off Zenoh's delivery thread (which
/// holds the routing tables a declaration needs), and keeps them declared
/// until the node stops.
#[derive(Debug, Clone)]
pub(crate) struct Declarer {
    tx: Option<flume::Sender<String>>,
}

impl Declarer {
    /// Starts the declaring task of `session`, ending with `token`.
    pub(crate) fn start(session: Session, token: CancellationToken) -> Self {
        let (tx, rx) = flume::unbounded::<String>();
        tokio::spawn(async move {
            let mut declared = Vec::new();
            loop {
                tokio::select! {
                    key = rx.recv_async() => match key {
                        Ok(key) => match session.declare_keyexpr(key).await {
                            Ok(k) => declared.push(k),
                            Err(e) => debug!(error = %e, "could not declare a producer's key"),
                        },
                        Err(_) => break,
                    },
                    () = token.cancelled() => break,
                }
            }
        });
        Declarer { tx: Some(tx) }
    }

    /// A declarer that declares nothing (for tests without a session).
    #[cfg(test)]
    pub(crate) fn none() -> Self {
        Declarer { tx: None }
    }

    fn declare(&self, key: &str) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(key.to_string());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::keys::{Channel, Owner, entry_key};

    #[test]
    fn a_key_is_parsed_once_and_remembered_up_to_a_bound() {
        let producers = Producers::new(Declarer::none());
        let cam = Owner::Node {
            name: "cam",
            tag: "v1",
        };
        let key = &entry_key("lab", Channel::Topic, &cam, "frames", "c1", "cam_a");
        let first = producers.of(key).unwrap();
        assert_eq!(&*first.core, "c1");
        assert_eq!(&*first.instance, "cam_a");
        assert!(Arc::ptr_eq(&first, &producers.of(key).unwrap()));
        // Not an entry key: no owner kind.
        assert!(producers.of("peppy/lab/topic/other/x/v1/t/c/i").is_none());
        for n in 0..REMEMBERED + 10 {
            let instance = format!("cam_{n}");
            let key = entry_key("lab", Channel::Topic, &cam, "frames", "c1", &instance);
            let p = producers.of(&key).unwrap();
            assert_eq!(&*p.instance, format!("cam_{n}"));
        }
        assert_eq!(producers.known.read().unwrap().len(), REMEMBERED);
    }
}
