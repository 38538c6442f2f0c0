use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use peppy::NodeRunner;
use peppy::codegen::NodeParameters;

/// Every wait in these tests is bounded by this.
pub(crate) const WAIT: Duration = Duration::from_secs(20);

/// A Zenoh router on a free loopback port, standing in for the launcher's.
pub(crate) struct Hub {
    _session: zenoh::Session,
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
    Hub {
        _session: session,
        endpoint,
    }
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

/// Starts the node whose generated parameters are `P` as `instance`, with
/// extra command-line flags, through the generated `NodeBuilder` alias's
/// target type.
pub(crate) async fn start<P: NodeParameters>(
    hub: &Hub,
    ns: &str,
    instance: &str,
    extra: &[&str],
) -> (P, Arc<NodeRunner>) {
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
    tokio::time::timeout(
        WAIT,
        peppy::NodeBuilder::<P>::new()
            .with_runtime_config(None)
            .with_args(args)
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
