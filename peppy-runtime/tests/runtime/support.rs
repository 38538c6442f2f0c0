use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use peppy_runtime::codegen::{Decode, DecodeError, Decoder, Encode, NodeParameters, Writer};
use peppy_runtime::{NodeBuilder, NodeRunner};

/// Every wait in these tests is bounded by this.
pub(crate) const WAIT: Duration = Duration::from_secs(20);

/// A Zenoh router on a free loopback port, standing in for the launcher's.
pub(crate) struct Hub {
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
    // Configured as peppy configures the routers it starts.
    let config = peppy_runtime::Endpoints {
        mode: Some("router".into()),
        listen: vec![endpoint.clone()],
        ..Default::default()
    }
    .zenoh_config()
    .unwrap();
    let session = zenoh::open(config).await.unwrap();
    Hub { session, endpoint }
}

impl Hub {
    /// Waits (bounded) until a liveliness token of namespace `ns` is seen
    /// through this router: a node started elsewhere is on the network.
    pub(crate) async fn sees_a_node(&self, ns: &str) {
        let live =
            peppy_runtime::wire::keys::space_selector(ns, peppy_runtime::wire::keys::Space::Live);
        tokio::time::timeout(WAIT, async {
            loop {
                let replies = self
                    .session
                    .liveliness()
                    .get(&live)
                    .timeout(Duration::from_secs(1))
                    .await
                    .unwrap();
                if replies.recv_async().await.is_ok() {
                    break;
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
        .await
        .expect("the child's liveliness token appears");
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

/// The flags that start `instance` in `ns` against the hub.
fn node_args<'a>(hub: &'a Hub, ns: &'a str, instance: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
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
    args
}

/// Starts a node of type `P` as `instance` with extra flags.
pub(crate) async fn start<P: NodeParameters>(
    hub: &Hub,
    ns: &str,
    instance: &str,
    extra: &[&str],
) -> (P, Arc<NodeRunner>) {
    start_configured(hub, ns, instance, extra, |b| b).await
}

/// Like [`start`], with builder settings (shared memory, say).
pub(crate) async fn start_configured<P: NodeParameters>(
    hub: &Hub,
    ns: &str,
    instance: &str,
    extra: &[&str],
    configure: impl FnOnce(NodeBuilder<P>) -> NodeBuilder<P>,
) -> (P, Arc<NodeRunner>) {
    let builder = NodeBuilder::<P>::new()
        .with_runtime_config(None)
        .with_args(node_args(hub, ns, instance, extra));
    tokio::time::timeout(WAIT, configure(builder).start())
        .await
        .expect("node start timed out")
        .expect("node starts")
}

/// Like [`start`], returning the error.
pub(crate) async fn try_start<P: NodeParameters>(
    hub: &Hub,
    ns: &str,
    instance: &str,
    extra: &[&str],
) -> peppy_runtime::Result<(P, Arc<NodeRunner>)> {
    NodeBuilder::<P>::new()
        .with_runtime_config(None)
        .with_args(node_args(hub, ns, instance, extra))
        .start()
        .await
}

/// A frame: what the camera tests send.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Frame {
    pub(crate) seq: u32,
    pub(crate) data: Vec<u8>,
}

impl Encode for Frame {
    fn encode(&self, out: &mut Writer<'_>) {
        self.seq.encode(out);
        self.data.encode(out);
    }
}

impl Decode for Frame {
    const MIN_SIZE: usize = 8;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(Frame {
            seq: Decode::decode(d)?,
            data: Decode::decode(d)?,
        })
    }
}

/// The run-time model of a test node's document, as the build embeds it.
pub(crate) fn model_json(document: &str) -> &'static str {
    let (doc, _) = peppy_schema::NodeDoc::parse("test.json5", document).expect("valid test node");
    Box::leak(peppy_schema::NodeModel::of(&doc).to_json().into_boxed_str())
}

/// Defines a parameters type whose node is described by `$doc` and the given specs.
macro_rules! test_node {
    ($ty:ident, $doc:expr, emits: [$($e:expr),*], consumes: [$($c:expr),*], serves: [$($s:expr),*], actions: [$($a:expr),*]) => {
        #[derive(Debug, serde::Deserialize)]
        pub(crate) struct $ty {}
        impl peppy_runtime::codegen::NodeParameters for $ty {
            fn descriptor() -> &'static peppy_runtime::codegen::NodeDescriptor {
                use peppy_runtime::codegen as cg;
                static EMITS: &[&cg::TopicSpec] = &[$(&$e),*];
                static CONSUMES: &[&cg::ConsumedTopicSpec] = &[$(&$c),*];
                static SERVES: &[&cg::ServiceSpec] = &[$(&$s),*];
                static ACTIONS: &[&cg::ActionSpec] = &[$(&$a),*];
                // What the build does: the document's run-time model, embedded as JSON.
                static D: std::sync::LazyLock<cg::NodeDescriptor> =
                    std::sync::LazyLock::new(|| cg::NodeDescriptor {
                        model: crate::support::model_json($doc),
                        document_path: concat!(stringify!($ty), ".json5"),
                        emitted_topics: EMITS,
                        consumed_topics: CONSUMES,
                        exposed_services: SERVES,
                        exposed_actions: ACTIONS,
                    });
                &D
            }
        }
    };
}
pub(crate) use test_node;

/// Emits `make(seq)` on `spec` every `period` until the runner stops.
pub(crate) fn keep_emitting<M: Encode + Send + 'static>(
    runner: Arc<NodeRunner>,
    spec: &'static peppy_runtime::codegen::TopicSpec,
    period: Duration,
    make: impl Fn(u32) -> M + Send + 'static,
) {
    tokio::spawn(async move {
        let mut seq = 0;
        while !runner.cancellation_token().is_cancelled() {
            let _ = peppy_runtime::codegen::emit(&runner, spec, &make(seq)).await;
            seq += 1;
            tokio::time::sleep(period).await;
        }
    });
}

/// This test binary run again as a child process, for one `#[ignore]`d
/// entry test (`module::entry`): what a test needs a process of its own
/// for (a signal, a kill, a freeze, a mount namespace, the one stack clock
/// of a process). Its stderr is read line by line as it comes; it is
/// killed when dropped, so a failed test leaves none behind.
pub(crate) struct TestChild {
    process: std::process::Child,
    lines: std::sync::mpsc::Receiver<String>,
    /// The lines read so far.
    pub(crate) seen: Vec<String>,
}

impl TestChild {
    /// Runs `entry` with `env` set, behind `wrapper` (`unshare …`, which
    /// must exec what follows; empty: none).
    pub(crate) fn spawn(entry: &str, env: &[(&str, &str)], wrapper: &[&str]) -> TestChild {
        use std::io::BufRead as _;
        // Linux runs the running binary even once a rebuild has replaced
        // the file under its path (another `cargo test` in the same
        // target); a wrapper needs the path itself.
        let exe = if wrapper.is_empty() && cfg!(target_os = "linux") {
            "/proc/self/exe".into()
        } else {
            std::env::current_exe().unwrap()
        };
        let mut command = match wrapper.split_first() {
            Some((first, rest)) => {
                let mut c = std::process::Command::new(first);
                c.args(rest).arg(exe);
                c
            }
            None => std::process::Command::new(exe),
        };
        command
            .args([
                "--exact",
                entry,
                "--ignored",
                "--nocapture",
                "--test-threads",
                "1",
            ])
            .envs(env.iter().copied())
            .env("NO_COLOR", "1")
            .env_remove("RUST_LOG")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped());
        let mut process = command.spawn().unwrap();
        let stderr = process.stderr.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
            {
                let _ = tx.send(line);
            }
        });
        TestChild {
            process,
            lines,
            seen: Vec::new(),
        }
    }

    /// Reads lines until `wanted` holds for one (which it returns), within
    /// `bound`; `what` names it when it does not come.
    pub(crate) fn until(
        &mut self,
        bound: Duration,
        what: &str,
        mut wanted: impl FnMut(&str) -> bool,
    ) -> String {
        let deadline = std::time::Instant::now() + bound;
        loop {
            let line = self
                .lines
                .recv_timeout(deadline.saturating_duration_since(std::time::Instant::now()))
                .unwrap_or_else(|_| {
                    let exit = self.process.try_wait();
                    let tail = &self.seen[self.seen.len().saturating_sub(30)..];
                    panic!(
                        "no {what} from the child within {bound:?} (exit: {exit:?}); its last lines: {tail:#?}"
                    )
                });
            self.seen.push(line.clone());
            if wanted(&line) {
                return line;
            }
        }
    }

    /// The lines it wrote that have come since they were last read.
    pub(crate) fn read_available(&mut self) {
        self.seen.extend(self.lines.try_iter());
    }

    /// Sends it `signal` (`TERM`, `KILL`, `STOP`, ...).
    pub(crate) fn signal(&self, signal: &str) {
        let status = std::process::Command::new("kill")
            .args([&format!("-{signal}"), &self.process.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success(), "kill -{signal}");
    }

    /// Its exit status, within `bound` (a failure past it), with every line
    /// it wrote read into [`seen`](Self::seen).
    pub(crate) fn exit(&mut self, bound: Duration) -> std::process::ExitStatus {
        let deadline = std::time::Instant::now() + bound;
        loop {
            if let Some(s) = self.process.try_wait().unwrap() {
                // Every line, up to the pipe's end (or the bound, should a
                // grandchild still hold it).
                while let Ok(line) = self
                    .lines
                    .recv_timeout(deadline.saturating_duration_since(std::time::Instant::now()))
                {
                    self.seen.push(line);
                }
                return s;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "the child did not exit within {bound:?}: {:#?}",
                self.seen
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for TestChild {
    fn drop(&mut self) {
        let _ = self.process.kill();
        let _ = self.process.wait();
    }
}
