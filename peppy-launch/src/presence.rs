//! Core nodes seeing each other. Each launch of a stack placed over several
//! machines holds a liveliness token for its core node on its router; every
//! launch follows the others' tokens and says once when another machine
//! joins, is lost (its link is down or it stopped) and comes back, so a
//! dropped link shows in the logs of both sides.

use std::collections::HashSet;
use std::sync::{Arc, Mutex};

use peppy_runtime::wire::keys::{core_key, core_selector};
use zenoh::sample::SampleKind;

use crate::output::Output;

/// The token and the watcher; both end with the launch.
pub(crate) struct Presence {
    _token: zenoh::liveliness::LivelinessToken,
    _watch: zenoh::pubsub::Subscriber<()>,
}

/// What a token's change means for one core node, given which were seen.
fn change(seen: &mut HashSet<String>, core: &str, kind: SampleKind) -> String {
    match kind {
        SampleKind::Put if seen.insert(core.to_string()) => format!("core node {core} joined"),
        SampleKind::Put => format!("core node {core} is back"),
        SampleKind::Delete => format!("lost core node {core} (its link is down or it stopped)"),
    }
}

/// Announces `me` in `ns` on `router` and reports the other core nodes.
pub(crate) async fn announce(
    router: &zenoh::Session,
    ns: &str,
    me: &str,
    out: Arc<Output>,
) -> Result<Presence, String> {
    let seen = Mutex::new(HashSet::new());
    let own = core_key(ns, me);
    let watch = router
        .liveliness()
        .declare_subscriber(core_selector(ns))
        .history(true)
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            if key == own {
                return;
            }
            let core = key.rsplit('/').next().unwrap_or(key);
            if let Ok(mut seen) = seen.lock() {
                out.note(&change(&mut seen, core, sample.kind()));
            }
        })
        .await
        .map_err(|e| format!("cannot follow the other core nodes: {e}"))?;
    let token = router
        .liveliness()
        .declare_token(core_key(ns, me))
        .await
        .map_err(|e| format!("cannot announce core node {me}: {e}"))?;
    Ok(Presence {
        _token: token,
        _watch: watch,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joins_losses_and_returns_read_apart() {
        let mut seen = HashSet::new();
        assert_eq!(
            change(&mut seen, "robot", SampleKind::Put),
            "core node robot joined"
        );
        assert!(change(&mut seen, "robot", SampleKind::Delete).starts_with("lost core node robot"));
        assert_eq!(
            change(&mut seen, "robot", SampleKind::Put),
            "core node robot is back"
        );
    }
}
