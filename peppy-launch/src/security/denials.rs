//! What the router refused, said once per (instance, action, key).
//!
//! Zenoh's access control decides in the router and reports each decision
//! only as a trace event. The launch listens to exactly those events (a
//! per-layer filter on their target, so no other trace event is ever
//! built) and turns each first refusal into one line:
//!
//! When a key expression is first declared on a link, Zenoh also works out
//! in advance, for its cache, the decision for each of the nine kinds of
//! message on it, tracing each the same way. Those are not refusals of
//! anything sent: the nine decisions after a "caching permissions" event
//! on the same thread only teach which user a session is.
//!
//! ```text
//! peppy-launch: denied: `impostor` may not publish on peppy/lab/topic/interface/depth_camera/v1/video_stream/robot/rs_left
//! ```

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::sync::{Arc, Mutex};

use tracing::field::{Field, Visit};
use tracing_subscriber::Layer;
use tracing_subscriber::filter::filter_fn;
use tracing_subscriber::layer::SubscriberExt as _;

/// Where Zenoh's access-control decisions are traced from.
const ACL_TARGET: &str = "zenoh::net::routing::interceptor::access_control";

/// One decision (a refusal, once it is reported), parsed from Zenoh's
/// trace line.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Denial {
    /// The Zenoh user (an instance id) when known, else the session id.
    pub(crate) who: String,
    /// What it tried, in Zenoh's words (`Put (ingress)`).
    pub(crate) action: String,
    /// The key expression.
    pub(crate) key: String,
}

impl Denial {
    /// The line the launch prints.
    pub(crate) fn message(&self) -> String {
        if self.action == TOO_MANY {
            return format!(
                "denied: more than {MAX_SAID} different refusals (the last by `{}`); no more are reported",
                self.who
            );
        }
        if self.action == NO_SUBJECT {
            return format!(
                "denied: session {} is no one the access policy knows: everything it sends is refused",
                self.who
            );
        }
        let (verb, flow) = self
            .action
            .split_once(" (")
            .map_or((self.action.as_str(), ""), |(v, f)| {
                (v, f.trim_end_matches(')'))
            });
        let what = match (verb, flow) {
            ("Put", "ingress") => "may not publish on",
            ("Put", _) => "may not receive",
            ("Query", "ingress") => "may not call",
            ("Query", _) => "may not be asked on",
            ("Reply", "ingress") => "may not answer on",
            ("Reply", _) => "may not receive the answer from",
            ("Declare Subscriber", "ingress") => "may not subscribe to",
            ("Declare Queryable", "ingress") => "may not serve",
            ("Liveliness Token", "ingress") | ("Declare/Undeclare Liveliness Token", "ingress") => {
                "may not announce"
            }
            _ => "",
        };
        if what.is_empty() {
            format!("denied: `{}`: {} on {}", self.who, self.action, self.key)
        } else {
            format!("denied: `{}` {what} {}", self.who, self.key)
        }
    }
}

/// Parses one of Zenoh's access-control trace messages, learning which
/// user a session id belongs to from the lines that name both.
fn parse(message: &str, users: &mut HashMap<String, String>) -> Option<Denial> {
    let message = message
        .strip_prefix("Using cached result: ")
        .unwrap_or(message);
    let (subject, rest) = message
        .split_once(" is unauthorized to ")
        .or_else(|| message.split_once(" is authorized to "))?;
    let (action, key) = rest.rsplit_once(" on ")?;
    // `<zid> on <Interface(lo)+Username(rs_left)+...>` or just `<zid>`.
    let who = match subject.split_once(" on ") {
        Some((zid, names)) => {
            let user = names
                .split('+')
                .find_map(|n| n.strip_prefix("Username(")?.strip_suffix(')'))
                .map(str::to_string);
            if let Some(user) = &user {
                users.insert(zid.to_string(), user.clone());
            }
            user.unwrap_or_else(|| zid.to_string())
        }
        None => users
            .get(subject)
            .cloned()
            .unwrap_or_else(|| subject.to_string()),
    };
    Some(Denial {
        who,
        action: action.to_string(),
        // Undeclarations print `Some(ke`peppy/...`)`.
        key: key
            .strip_prefix("Some(")
            .and_then(|k| k.strip_suffix(')'))
            .unwrap_or(key)
            .trim_start_matches("ke`")
            .trim_end_matches('`')
            .to_string(),
    })
}

#[derive(Default)]
struct Seen {
    users: HashMap<String, String>,
    said: HashSet<Denial>,
}

/// How many distinct refusals are reported: past that, an instance
/// spraying keys would only grow the log and the launch's memory.
const MAX_SAID: usize = 1000;

impl Seen {
    /// Whether `d` is to be said: the first time, and while under
    /// [`MAX_SAID`] (the one past it says that no more will be).
    fn first(&mut self, d: &Denial) -> bool {
        self.said.len() <= MAX_SAID && !self.said.contains(d) && self.said.insert(d.clone())
    }
}

/// The layer: reports each first denial to `say`.
struct Denials {
    seen: Mutex<Seen>,
    say: Arc<dyn Fn(&Denial) + Send + Sync>,
}

struct Message<'a>(&'a mut String);

impl Visit for Message<'_> {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        }
    }
}

/// The action of a session that matches no subject of the policy.
const NO_SUBJECT: &str = "(any)";
/// The action of the line that ends the reports.
const TOO_MANY: &str = "(too many)";

/// How many decisions Zenoh traces when it fills the cache of one key
/// expression: one per kind of message.
const CACHED_KINDS: usize = 9;

thread_local! {
    /// The key expression this thread is filling Zenoh's cache for, and
    /// how many of its decisions are still to come.
    static CACHING: std::cell::RefCell<Option<(String, usize)>> = const { std::cell::RefCell::new(None) };
}

/// Whether a decision on `key` is one of those Zenoh works out in advance
/// (see the module's documentation).
fn in_advance(key: &str) -> bool {
    CACHING.with(|c| {
        let mut c = c.borrow_mut();
        match c.as_mut() {
            Some((k, left)) if k == key && *left > 0 => {
                *left -= 1;
                true
            }
            _ => {
                *c = None;
                false
            }
        }
    })
}

impl<S: tracing::Subscriber> Layer<S> for Denials {
    fn on_event(&self, event: &tracing::Event<'_>, _: tracing_subscriber::layer::Context<'_, S>) {
        let mut text = String::new();
        event.record(&mut Message(&mut text));
        let cached = text.starts_with("Using cached result: ");
        let denied = text.contains(" is unauthorized to ");
        // The common case, every routed message: a cached permission.
        if cached && !denied {
            return;
        }
        if let Some((zid, _)) = text.split_once(" did not match any configured ACL subject") {
            let nobody = Denial {
                who: zid.to_string(),
                action: NO_SUBJECT.to_string(),
                key: String::new(),
            };
            if let Ok(mut seen) = self.seen.lock()
                && seen.first(&nobody)
            {
                self.report(&nobody, seen.said.len());
            }
            return;
        }
        if let Some(key) = text
            .split_once("caching permissions for `")
            .and_then(|(_, rest)| rest.split_once('`'))
            .map(|(key, _)| key)
        {
            CACHING.with(|c| *c.borrow_mut() = Some((key.to_string(), CACHED_KINDS)));
            return;
        }
        let Ok(mut seen) = self.seen.lock() else {
            return;
        };
        let Some(decision) = parse(&text, &mut seen.users) else {
            return;
        };
        let ahead = !cached && in_advance(&decision.key);
        if denied && !ahead && seen.first(&decision) {
            self.report(&decision, seen.said.len());
        }
    }
}

impl Denials {
    /// Says the `n`th distinct refusal, or past [`MAX_SAID`] that no more
    /// will be said.
    fn report(&self, d: &Denial, n: usize) {
        if n <= MAX_SAID {
            (self.say)(d);
        } else {
            (self.say)(&Denial {
                who: d.who.clone(),
                action: TOO_MANY.to_string(),
                key: String::new(),
            });
        }
    }
}

/// Installs the listener for this process (the launch, whose router is in
/// process), passing each first denial to `say`. Zenoh's own log reaches
/// stderr when `RUST_LOG` asks for it.
pub(crate) fn listen(say: Arc<dyn Fn(&Denial) + Send + Sync>) {
    let denials = Denials {
        seen: Mutex::default(),
        say,
    }
    .with_filter(filter_fn(|m| m.target() == ACL_TARGET));
    // Zenoh's own log reaches stderr only when asked for, as without
    // security.
    let rest = tracing_subscriber::EnvFilter::try_from_env("RUST_LOG")
        .ok()
        .map(|filter| {
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_filter(filter)
        });
    let subscriber = tracing_subscriber::registry().with(denials).with(rest);
    let _ = tracing::subscriber::set_global_default(subscriber);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_stop_after_a_thousand_distinct_refusals() {
        let mut seen = Seen::default();
        let d = |i: usize| Denial {
            who: "x".into(),
            action: "Put (ingress)".into(),
            key: format!("k/{i}"),
        };
        let said: Vec<bool> = (0..=MAX_SAID + 5).map(|i| seen.first(&d(i))).collect();
        // Each of the first MAX_SAID, plus the one that says "no more".
        assert_eq!(said.iter().filter(|s| **s).count(), MAX_SAID + 1);
        assert!(!seen.first(&d(0)), "a refusal is said once");
        let last = Denial {
            who: "x".into(),
            action: TOO_MANY.into(),
            key: String::new(),
        };
        assert!(last.message().contains("no more are reported"));
    }

    #[test]
    fn zenohs_lines_become_one_denial_each() {
        let mut users = HashMap::new();
        let first = parse(
            "a1b2 on Interface(lo)+Username(impostor)+Transport(Tcp) is unauthorized to Put (ingress) on peppy/lab/topic/interface/depth_camera/v1/video_stream/robot/rs_left",
            &mut users,
        )
        .unwrap();
        assert_eq!(first.who, "impostor");
        assert_eq!(first.action, "Put (ingress)");
        assert_eq!(
            first.message(),
            "denied: `impostor` may not publish on peppy/lab/topic/interface/depth_camera/v1/video_stream/robot/rs_left"
        );
        // A cached decision names the session only.
        let cached = parse(
            "Using cached result: a1b2 is unauthorized to Put (ingress) on peppy/lab/x",
            &mut users,
        )
        .unwrap();
        assert_eq!(cached.who, "impostor");
        assert_eq!(cached.key, "peppy/lab/x");
        let allowed = parse(
            "cdef on Username(x)+Transport(Tcp) is authorized to Put (ingress) on k",
            &mut users,
        )
        .unwrap();
        assert_eq!(allowed.who, "x");
        let undecl = parse(
            "Using cached result: ffee is unauthorized to Declare/Undeclare Subscriber (ingress) on Some(ke`peppy/lab/y`)",
            &mut users,
        )
        .unwrap();
        assert_eq!(undecl.who, "ffee");
        assert_eq!(undecl.key, "peppy/lab/y");
    }
}
