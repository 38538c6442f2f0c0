//! Core nodes seeing each other. Each launch of a stack placed over several
//! machines holds a liveliness token for its core node on its router; every
//! launch follows the others' tokens and says once when another machine
//! joins, is lost (its link is down or it stopped) and comes back, so a
//! dropped link shows in the logs of both sides.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};

use peppy_runtime::wire::keys::{core_key, core_selector, parse_core_key};
use zenoh::sample::SampleKind;

use crate::output::Output;

/// The token and the watcher; both end with the launch.
pub(crate) struct Presence {
    _token: zenoh::liveliness::LivelinessToken,
    _watch: zenoh::pubsub::Subscriber<()>,
}

/// The core nodes seen so far: the launches (router ids) announcing each.
#[derive(Debug, Default)]
struct Seen {
    live: HashMap<String, HashSet<String>>,
    warned: HashSet<String>,
}

impl Seen {
    /// What a token's change means, if anything: a machine that joins, is
    /// lost, comes back, or is claimed by a second launch. Duplicate
    /// announcements and repeated losses say nothing.
    fn change(&mut self, me: &str, core: &str, launch: &str, kind: SampleKind) -> Option<String> {
        if core == me {
            return (kind == SampleKind::Put && self.warned.insert(launch.to_string())).then(|| {
                format!("another launch ({launch}) also runs core node {me}: start each core node once")
            });
        }
        let ever = self.live.contains_key(core);
        let launches = self.live.entry(core.to_string()).or_default();
        match kind {
            SampleKind::Put => {
                let was_empty = launches.is_empty();
                launches.insert(launch.to_string());
                match (was_empty, ever) {
                    (true, false) => Some(format!("core node {core} joined")),
                    (true, true) => Some(format!("core node {core} is back")),
                    (false, _) => None,
                }
            }
            SampleKind::Delete => (launches.remove(launch) && launches.is_empty())
                .then(|| format!("lost core node {core} (its link is down or it stopped)")),
        }
    }
}

/// Why a core node could not take part in the others' presence (said in a
/// note: the launch runs all the same).
#[derive(Debug, thiserror::Error)]
pub(crate) enum PresenceError {
    /// The other core nodes' tokens cannot be followed.
    #[error("cannot follow the other core nodes: {0}")]
    Follow(#[source] zenoh::Error),
    /// This core node's token cannot be declared.
    #[error("cannot announce core node {core}: {source}")]
    Announce {
        /// This core node.
        core: String,
        /// Zenoh's error.
        source: zenoh::Error,
    },
}

/// Announces `me` in `ns` on `router` and reports the other core nodes.
pub(crate) async fn announce(
    router: &zenoh::Session,
    ns: &str,
    me: &str,
    out: Arc<Output>,
) -> Result<Presence, PresenceError> {
    let own = router.zid().to_string();
    let seen = Mutex::new(Seen::default());
    let me_name = me.to_string();
    let watch = router
        .liveliness()
        .declare_subscriber(core_selector(ns))
        .history(true)
        .callback(move |sample| {
            let Some((core, launch)) = parse_core_key(sample.key_expr().as_str()) else {
                return;
            };
            if launch == own {
                return;
            }
            if let Ok(mut seen) = seen.lock()
                && let Some(news) = seen.change(&me_name, core, launch, sample.kind())
            {
                out.note(&news);
            }
        })
        .await
        .map_err(PresenceError::Follow)?;
    let token = router
        .liveliness()
        .declare_token(core_key(ns, me, &router.zid().to_string()))
        .await
        .map_err(|source| PresenceError::Announce {
            core: me.to_string(),
            source,
        })?;
    Ok(Presence {
        _token: token,
        _watch: watch,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joins_losses_and_returns_are_said_once() {
        let mut s = Seen::default();
        let put = SampleKind::Put;
        let del = SampleKind::Delete;
        assert_eq!(
            s.change("ws", "robot", "z1", put).as_deref(),
            Some("core node robot joined")
        );
        assert_eq!(
            s.change("ws", "robot", "z1", put),
            None,
            "a repeated token is not news"
        );
        assert!(
            s.change("ws", "robot", "z1", del)
                .unwrap()
                .starts_with("lost core node robot")
        );
        assert_eq!(
            s.change("ws", "robot", "z1", del),
            None,
            "nor a repeated loss"
        );
        assert_eq!(
            s.change("ws", "robot", "z2", put).as_deref(),
            Some("core node robot is back")
        );
        assert_eq!(
            s.change("ws", "lab", "z3", del),
            None,
            "never seen, never lost"
        );
        assert!(
            s.change("ws", "ws", "z4", put)
                .unwrap()
                .contains("also runs core node ws")
        );
        assert_eq!(s.change("ws", "ws", "z4", put), None);
    }
}
