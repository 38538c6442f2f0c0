use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use peppy::NodeRunner;
use peppy::codegen::NodeParameters;
use peppy::runtime::describe::InstanceInfo;
use peppy::runtime::tool::ToolCaller;

/// Every wait in these tests is bounded by this.
pub(crate) const WAIT: Duration = Duration::from_secs(20);

/// A Zenoh router on a free loopback port, standing in for the launcher's.
pub(crate) struct Hub {
    /// The router's own session: what it subscribes to or asks is in place
    /// before any node connects, so a node's first message is not raced.
    pub(crate) session: zenoh::Session,
    pub(crate) endpoint: String,
}

pub(crate) async fn hub() -> Hub {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"router\"").unwrap();
    config
        .insert_json5("listen/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    let session = zenoh::open(config).await.unwrap();
    Hub { session, endpoint }
}

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A namespace no other test uses.
pub(crate) fn namespace(test: &str) -> String {
    format!(
        "{test}-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// The flags that start `instance` in `ns` against the hub.
pub(crate) fn node_args(hub: &Hub, ns: &str, instance: &str, extra: &[&str]) -> Vec<String> {
    let mut args = vec![
        "node",
        "--instance-id",
        instance,
        "--namespace",
        ns,
        "--connect",
        &hub.endpoint,
    ];
    args.extend_from_slice(extra);
    args.into_iter().map(String::from).collect()
}

/// Starts the node whose generated parameters are `P` as `instance`, with
/// extra command-line flags, through the generated `NodeBuilder` alias's
/// target type.
pub(crate) async fn start<P: NodeParameters>(
    hub: &Hub,
    ns: &str,
    instance: &str,
    extra: &[&str],
) -> (P, Arc<NodeRunner>) {
    tokio::time::timeout(
        WAIT,
        peppy::NodeBuilder::<P>::new()
            .with_runtime_config(None)
            .with_args(node_args(hub, ns, instance, extra))
            .start(),
    )
    .await
    .expect("node start timed out")
    .expect("node starts")
}

/// Runs `f` until it returns `Some`, within [`WAIT`].
pub(crate) async fn eventually<T>(what: &str, mut f: impl AsyncFnMut() -> Option<T>) -> T {
    tokio::time::timeout(WAIT, async {
        loop {
            if let Some(v) = f().await {
                return v;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    })
    .await
    .unwrap_or_else(|_| panic!("timed out: {what}"))
}

/// Polls until the server is up (`ServiceUnreachable` until then).
pub(crate) async fn until_up<T>(f: impl AsyncFn() -> peppy::Result<T>) -> peppy::Result<T> {
    eventually("the server to answer", async || match f().await {
        Err(peppy::Error::ServiceUnreachable { .. }) => None,
        other => Some(other),
    })
    .await
}

/// What the standalone instance `instance` of `ns` says about itself,
/// asked from the hub (within [`WAIT`]).
pub(crate) async fn describe(hub: &Hub, ns: &str, instance: &str) -> InstanceInfo {
    let key =
        peppy::runtime::wire::keys::describe_key(ns, peppy::runtime::STANDALONE_CORE, instance);
    eventually(&format!("{instance} to describe itself"), async || {
        let replies = hub
            .session
            .get(&key)
            .timeout(Duration::from_secs(1))
            .await
            .ok()?;
        let reply = replies.recv_async().await.ok()?;
        InstanceInfo::from_json(&reply.result().ok()?.payload().to_bytes()).ok()
    })
    .await
}

/// A tool on the hub's session: calls services and sends goals with the
/// formats an instance describes, so a test can play the other side of a
/// node without generated code of its own.
pub(crate) fn tool(hub: &Hub) -> ToolCaller {
    ToolCaller::new(hub.session.clone(), "test", "tool")
}

/// Topic messages of one namespace as the hub hears them, kept by key.
pub(crate) struct Heard {
    subscriber:
        zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    first: std::collections::BTreeMap<String, Vec<u8>>,
}

/// Starts hearing every topic of `ns` on the hub. Call it before the
/// producers start: the router then has the subscription when they connect.
pub(crate) async fn hear_topics(hub: &Hub, ns: &str) -> Heard {
    let subscriber = hub
        .session
        .declare_subscriber(peppy_runtime::wire::keys::space_selector(
            ns,
            peppy_runtime::wire::keys::Space::Topic,
        ))
        .await
        .unwrap();
    Heard {
        subscriber,
        first: Default::default(),
    }
}

impl Heard {
    /// The first message published on `key` (within [`WAIT`]).
    pub(crate) async fn first(&mut self, key: &str) -> Vec<u8> {
        tokio::time::timeout(WAIT, async {
            while !self.first.contains_key(key) {
                let sample = self.subscriber.recv_async().await.unwrap();
                self.first
                    .entry(sample.key_expr().to_string())
                    .or_insert_with(|| sample.payload().to_bytes().into_owned());
            }
        })
        .await
        .unwrap_or_else(|_| panic!("timed out: a message on {key}"));
        self.first[key].clone()
    }
}
