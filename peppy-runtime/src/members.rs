//! Which instances run a given node, learned from their liveliness tokens.
//!
//! A node slot that consumes an entry its producer inherited from an
//! interface receives on the interface's key, which every conforming node
//! shares (WIRE.md): the key alone cannot tell a `realsense_d405` from a
//! `zed_2i`. Each node announces `peppy/<ns>/live/<core>/<instance>/<node>/<tag>`,
//! so the consumer follows those tokens for the slot's node and keeps only
//! samples and servers whose sender is one of them.

use std::collections::HashMap;
use std::sync::{Arc, RwLock};
use std::time::Duration;

use tracing::debug;
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;

use crate::error::Result;
use crate::wire::keys::{liveliness_selector, parse_liveliness_key};

/// How long start-up waits for the instances already running.
const INITIAL_QUERY: Duration = Duration::from_secs(2);

/// Instances as `instance id -> core nodes`, so a sample's sender is looked
/// up by `&str` without allocating on the receive path.
#[derive(Debug, Default)]
pub(crate) struct Live(HashMap<String, Vec<String>>);

impl Live {
    fn insert(&mut self, (core, instance): (String, String)) {
        let cores = self.0.entry(instance).or_default();
        if !cores.contains(&core) {
            cores.push(core);
        }
    }

    fn remove(&mut self, (core, instance): &(String, String)) {
        if let Some(cores) = self.0.get_mut(instance) {
            cores.retain(|c| c != core);
            if cores.is_empty() {
                self.0.remove(instance);
            }
        }
    }

    /// Whether `(core, instance)` is up.
    pub(crate) fn contains(&self, core: &str, instance: &str) -> bool {
        self.0
            .get(instance)
            .is_some_and(|cores| cores.iter().any(|c| c == core))
    }
}

/// The live instances of one node, followed for the node's life.
pub(crate) struct Members {
    live: Arc<RwLock<Live>>,
    _subscriber: Subscriber<()>,
}

impl std::fmt::Debug for Members {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Members").finish_non_exhaustive()
    }
}

impl Members {
    /// Follows the instances of node `name:tag` in namespace `ns`. The
    /// instances already running are known when this returns, so the first
    /// samples of a stream are not dropped for want of a token.
    pub(crate) async fn track(
        session: &zenoh::Session,
        ns: &str,
        name: &str,
        tag: &str,
    ) -> Result<Members> {
        let key = liveliness_selector(ns, name, tag);
        let live: Arc<RwLock<Live>> = Arc::default();
        let set = live.clone();
        let subscriber = session
            .liveliness()
            .declare_subscriber(key.as_str())
            .callback(move |sample| {
                let Some(who) = parse_liveliness_key(sample.key_expr().as_str()) else {
                    return;
                };
                if let Ok(mut set) = set.write() {
                    match sample.kind() {
                        SampleKind::Put => set.insert(who),
                        SampleKind::Delete => set.remove(&who),
                    }
                }
            })
            .await?;
        let running = live_instances(session, ns, name, tag, INITIAL_QUERY).await?;
        if let Ok(mut set) = live.write() {
            for who in running.0.into_iter().flat_map(|(instance, cores)| {
                cores.into_iter().map(move |core| (core, instance.clone()))
            }) {
                set.insert(who);
            }
        }
        Ok(Members {
            live,
            _subscriber: subscriber,
        })
    }

    /// Whether `(core, instance)` runs the tracked node.
    pub(crate) fn contains(&self, core: &str, instance: &str) -> bool {
        let known = self.live.read().is_ok_and(|s| s.contains(core, instance));
        if !known {
            debug!(core, instance, "not an instance of this slot's node");
        }
        known
    }
}

/// The instances of node `name:tag` in `ns` that are up now, asked once
/// (service and action discovery through a node slot).
pub(crate) async fn live_instances(
    session: &zenoh::Session,
    ns: &str,
    name: &str,
    tag: &str,
    timeout: Duration,
) -> Result<Live> {
    let replies = session
        .liveliness()
        .get(liveliness_selector(ns, name, tag))
        .timeout(timeout.max(Duration::from_millis(1)))
        .await?;
    let mut out = Live::default();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && let Some(who) = parse_liveliness_key(sample.key_expr().as_str())
        {
            out.insert(who);
        }
    }
    Ok(out)
}
