//! Round-trip latency of peppy topics next to raw Zenoh, in the same run,
//! over the same in-process router on loopback. Run in release:
//!
//! ```sh
//! cargo bench -p peppy-runtime --bench latency
//! ```
//!
//! Each side sends a ping carrying a sequence number and a 64-byte payload;
//! the other side answers with a pong; the time until the matching pong
//! arrives is one sample. Reported: p50, p90 and mean per side, and the
//! peppy / raw ratio.
//!
//! Across a link between two machines, stood in for by two network
//! namespaces joined by a veth pair (needs root and `ip`):
//!
//! ```sh
//! cargo bench -p peppy-runtime --bench latency -- --veth
//! ```
//!
//! What security costs (docs/SECURITY.md): peppy round trips through a
//! router enforcing logins and an access policy of the shape a secured
//! launch derives, both nodes its clients, next to the unsecured default
//! (peers) and to clients of an open router:
//!
//! ```sh
//! cargo bench -p peppy-runtime --bench latency -- --secured
//! ```

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use peppy_runtime::codegen::{
    ConsumedTopicSpec, Decode, DecodeError, Decoder, Encode, FormatSpec, NodeDescriptor,
    NodeParameters, OwnerSpec, QosProfile, TopicSpec, Writer, emit, next_message,
};
use peppy_runtime::wire::keys::{
    Channel, Owner, Space, describe_key, entry_key, entry_selector, format_selector,
    instance_liveliness_selector, namespace_selector, space_selector,
};
use peppy_runtime::{NodeBuilder, NodeRunner};

const WARMUP: usize = 200;
/// Measured round trips per run, after `WARMUP` unmeasured ones; the short
/// run `cargo test` makes (`main`) sets fewer.
static SAMPLES: AtomicUsize = AtomicUsize::new(2_000);
/// `cargo test`'s short run: its samples per run, and how long it may take
/// before the test fails.
const SHORT_RUN_SAMPLES: usize = 100;
const SHORT_RUN_BOUND: Duration = Duration::from_secs(60);

fn samples_per_run() -> usize {
    SAMPLES.load(Ordering::Relaxed)
}

const FORMAT: FormatSpec = FormatSpec {
    fingerprint: 0xbe7c,
    canonical: "{seq:u64,pad:[u8]}",
};

static PING_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "ping",
    qos: QosProfile::Reliable,
    format: FORMAT,
};
static PONG_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "pong",
    qos: QosProfile::Reliable,
    format: FORMAT,
};
static PING_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("pinger"),
    owner: OwnerSpec::Node {
        name: "pinger",
        tag: "v1",
    },
    name: "ping",
    qos: QosProfile::Reliable,
    format: FORMAT,
};
static PONG_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("ponger"),
    owner: OwnerSpec::Node {
        name: "ponger",
        tag: "v1",
    },
    name: "pong",
    qos: QosProfile::Reliable,
    format: FORMAT,
};

#[derive(serde::Deserialize)]
struct Pinger {}
impl NodeParameters for Pinger {
    fn descriptor() -> &'static NodeDescriptor {
        static D: NodeDescriptor = NodeDescriptor {
            model: r#"{"identity":{"name":"pinger","tag":"v1"},"dependencies":[{"kind":"node","target":{"name":"ponger","tag":"v1"},"link_id":"ponger","from_any":false,"sha256":null}],"parameters":{"fields":[]}}"#,
            document_path: "pinger.json5",
            emitted_topics: &[&PING_OUT],
            consumed_topics: &[&PONG_IN],
            exposed_services: &[],
            exposed_actions: &[],
        };
        &D
    }
}

#[derive(serde::Deserialize)]
struct Ponger {}
impl NodeParameters for Ponger {
    fn descriptor() -> &'static NodeDescriptor {
        static D: NodeDescriptor = NodeDescriptor {
            model: r#"{"identity":{"name":"ponger","tag":"v1"},"dependencies":[{"kind":"node","target":{"name":"pinger","tag":"v1"},"link_id":"pinger","from_any":false,"sha256":null}],"parameters":{"fields":[]}}"#,
            document_path: "ponger.json5",
            emitted_topics: &[&PONG_OUT],
            consumed_topics: &[&PING_IN],
            exposed_services: &[],
            exposed_actions: &[],
        };
        &D
    }
}

#[derive(Clone)]
struct Msg {
    seq: u64,
    pad: Vec<u8>,
}

impl Encode for Msg {
    fn encode(&self, out: &mut Writer<'_>) {
        self.seq.encode(out);
        self.pad.encode(out);
    }
}

impl Decode for Msg {
    const MIN_SIZE: usize = 12;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(Msg {
            seq: Decode::decode(d)?,
            pad: Decode::decode(d)?,
        })
    }
}

struct Stats {
    p50: Duration,
    p90: Duration,
    mean: Duration,
}

fn stats(mut samples: Vec<Duration>) -> Stats {
    samples.sort();
    let at = |q: f64| samples[((samples.len() as f64 * q).ceil() as usize).saturating_sub(1)];
    let mean = samples.iter().sum::<Duration>() / samples.len() as u32;
    Stats {
        p50: at(0.5),
        p90: at(0.9),
        mean,
    }
}

fn node_args(endpoint: &str, id: &str, bind: &str) -> Vec<String> {
    vec![
        "bench".to_string(),
        "--instance-id".into(),
        id.into(),
        "--namespace".into(),
        "bench".into(),
        "--connect".into(),
        endpoint.into(),
        "--bind".into(),
        bind.into(),
    ]
}

/// How a bench node joins: by flags (a peer connecting to the router, as
/// an unsecured launch starts it), or by the runtime-config file a secured
/// launch writes (`<dir>/<instance>.json`: a client with its login).
#[derive(Clone)]
enum Join {
    Flags(String),
    Config(std::path::PathBuf),
}

impl Join {
    fn builder<P: NodeParameters>(&self, id: &str, bind: &str) -> NodeBuilder<P> {
        match self {
            Join::Flags(endpoint) => NodeBuilder::<P>::new()
                .with_runtime_config(None)
                .with_args(node_args(endpoint, id, bind)),
            Join::Config(dir) => NodeBuilder::<P>::new()
                .with_runtime_config(Some(dir.join(format!("{id}.json"))))
                .with_args(["bench"]),
        }
    }
}

/// The answering side: a ponger node echoing every ping, until aborted.
async fn peppy_ponger(join: &Join) -> (Arc<NodeRunner>, tokio::task::JoinHandle<()>) {
    let (_, ponger): (_, Arc<NodeRunner>) = join
        .builder::<Ponger>("ponger", "pinger@pinger")
        .start()
        .await
        .unwrap();
    let echo = tokio::spawn({
        let ponger = ponger.clone();
        async move {
            while let Ok((_, m)) = next_message::<Msg>(&ponger, &PING_IN, None).await {
                let _ = emit(&ponger, &PONG_OUT, &m).await;
            }
        }
    });
    (ponger, echo)
}

/// The asking side: round trips to a ponger reached through `endpoint`.
async fn peppy_pings(join: &Join) -> Vec<Duration> {
    let (_, pinger): (_, Arc<NodeRunner>) = join
        .builder::<Pinger>("pinger", "ponger@ponger")
        .start()
        .await
        .unwrap();
    let pad = vec![7u8; 64];
    // Wait until both directions are matched.
    loop {
        emit(
            &pinger,
            &PING_OUT,
            &Msg {
                seq: u64::MAX,
                pad: pad.clone(),
            },
        )
        .await
        .unwrap();
        if tokio::time::timeout(
            Duration::from_millis(100),
            next_message::<Msg>(&pinger, &PONG_IN, None),
        )
        .await
        .is_ok()
        {
            break;
        }
    }
    let mut samples = Vec::with_capacity(samples_per_run());
    for seq in 0..(WARMUP + samples_per_run()) as u64 {
        let start = Instant::now();
        emit(
            &pinger,
            &PING_OUT,
            &Msg {
                seq,
                pad: pad.clone(),
            },
        )
        .await
        .unwrap();
        loop {
            let (_, got) = next_message::<Msg>(&pinger, &PONG_IN, None).await.unwrap();
            if got.seq == seq {
                break;
            }
        }
        if seq as usize >= WARMUP {
            samples.push(start.elapsed());
        }
    }
    pinger.shutdown().await;
    samples
}

async fn peppy_round_trips(join: &Join) -> Vec<Duration> {
    let (ponger, echo) = peppy_ponger(join).await;
    let samples = peppy_pings(join).await;
    echo.abort();
    ponger.shutdown().await;
    samples
}

fn raw_config(endpoint: &str) -> zenoh::Config {
    let mut c = zenoh::Config::default();
    c.insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    c
}

/// The answering side in raw Zenoh: echoes pings while the session lives.
async fn raw_echo(endpoint: &str) -> (zenoh::Session, zenoh::pubsub::Subscriber<()>) {
    let b = zenoh::open(raw_config(endpoint)).await.unwrap();
    let pong_pub = b
        .declare_publisher("bench/raw/pong")
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .await
        .unwrap();
    let echo = b
        .declare_subscriber("bench/raw/ping")
        .callback(move |s| {
            let _ = zenoh::Wait::wait(pong_pub.put(s.payload().clone()));
        })
        .await
        .unwrap();
    (b, echo)
}

/// The asking side in raw Zenoh.
async fn raw_pings(endpoint: &str) -> Vec<Duration> {
    let a = zenoh::open(raw_config(endpoint)).await.unwrap();
    let ping_pub = a
        .declare_publisher("bench/raw/ping")
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .await
        .unwrap();
    let pongs = a
        .declare_subscriber("bench/raw/pong")
        .with(flume::bounded(256))
        .await
        .unwrap();
    let message = |seq: u64| {
        let mut m = seq.to_le_bytes().to_vec();
        m.extend_from_slice(&[7u8; 64]);
        m
    };
    loop {
        ping_pub.put(message(u64::MAX)).await.unwrap();
        if tokio::time::timeout(Duration::from_millis(100), pongs.recv_async())
            .await
            .is_ok()
        {
            break;
        }
    }
    let mut samples = Vec::with_capacity(samples_per_run());
    for seq in 0..(WARMUP + samples_per_run()) as u64 {
        let start = Instant::now();
        ping_pub.put(message(seq)).await.unwrap();
        loop {
            let s = pongs.recv_async().await.unwrap();
            let bytes = s.payload().to_bytes();
            if bytes[..8] == seq.to_le_bytes() {
                break;
            }
        }
        if seq as usize >= WARMUP {
            samples.push(start.elapsed());
        }
    }
    samples
}

async fn raw_round_trips(endpoint: &str) -> Vec<Duration> {
    let _echo = raw_echo(endpoint).await;
    raw_pings(endpoint).await
}

async fn router(endpoint: &str) -> zenoh::Session {
    router_with(endpoint, &[]).await
}

/// A router on `endpoint` with more settings (JSON5 values by key).
async fn router_with(endpoint: &str, settings: &[(&str, String)]) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", "\"router\"").unwrap();
    c.insert_json5("listen/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    for (key, value) in settings {
        c.insert_json5(key, value).unwrap();
    }
    zenoh::open(c).await.unwrap()
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// Both sides in this process, alternating raw and peppy runs to spread
/// machine noise over both.
async fn report(
    what: &str,
    raw: impl AsyncFn() -> Vec<Duration>,
    peppy: impl AsyncFn() -> Vec<Duration>,
) {
    let raw1 = stats(raw().await);
    let peppy1 = stats(peppy().await);
    let raw2 = stats(raw().await);
    let peppy2 = stats(peppy().await);
    println!(
        "round trip, {} samples per run, 64-byte payload, reliable, {what}",
        samples_per_run()
    );
    println!("{:<12} {:>10} {:>10} {:>10}", "run", "p50", "p90", "mean");
    for (name, s) in [
        ("raw zenoh 1", &raw1),
        ("peppy 1", &peppy1),
        ("raw zenoh 2", &raw2),
        ("peppy 2", &peppy2),
    ] {
        println!(
            "{name:<12} {:>10.1?} {:>10.1?} {:>10.1?}",
            s.p50, s.p90, s.mean
        );
    }
    let ratio = |p: Duration, r: Duration| p.as_secs_f64() / r.as_secs_f64();
    let p50 = (ratio(peppy1.p50, raw1.p50) + ratio(peppy2.p50, raw2.p50)) / 2.0;
    let p90 = (ratio(peppy1.p90, raw1.p90) + ratio(peppy2.p90, raw2.p90)) / 2.0;
    println!("peppy / raw: p50 x{p50:.2}, p90 x{p90:.2}");
}

/// `--veth`: the pinging side and its router in one network namespace, the
/// answering side in another, joined by a veth pair (192.0.2.0/24): every
/// round trip crosses the link twice, for raw Zenoh and peppy alike.
/// Needs root and `ip`.
fn veth() {
    let exe = std::env::current_exe().unwrap();
    let ip = |args: &[&str]| {
        let ok = std::process::Command::new("ip")
            .args(args)
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok, "ip {}", args.join(" "));
    };
    let tag = std::process::id() % 100_000;
    let (a, b) = (
        format!("peppy-bench-{tag}-a"),
        format!("peppy-bench-{tag}-b"),
    );
    let (va, vb) = (format!("pb{tag}a"), format!("pb{tag}b"));
    // Removes the namespaces (and the link) however the run ends.
    struct Cleanup(Vec<String>, String);
    impl Drop for Cleanup {
        fn drop(&mut self) {
            for ns in &self.0 {
                let _ = std::process::Command::new("ip")
                    .args(["netns", "del", ns])
                    .status();
            }
            let _ = std::process::Command::new("ip")
                .args(["link", "del", &self.1])
                .status();
        }
    }
    let _cleanup = Cleanup(vec![a.clone(), b.clone()], va.clone());
    ip(&["netns", "add", &a]);
    ip(&["netns", "add", &b]);
    ip(&["link", "add", &va, "type", "veth", "peer", "name", &vb]);
    ip(&["link", "set", &va, "netns", &a]);
    ip(&["link", "set", &vb, "netns", &b]);
    ip(&["-n", &a, "addr", "add", "192.0.2.1/24", "dev", &va]);
    ip(&["-n", &b, "addr", "add", "192.0.2.2/24", "dev", &vb]);
    for (ns, dev) in [(&a, &va), (&b, &vb)] {
        ip(&["-n", ns, "link", "set", dev, "up"]);
        ip(&["-n", ns, "link", "set", "lo", "up"]);
    }
    let endpoint = "tcp/192.0.2.1:7450";
    let exe = exe.to_str().unwrap();
    let mut pong = std::process::Command::new("ip")
        .args([
            "netns",
            "exec",
            &b,
            exe,
            "--role",
            "pong",
            "--endpoint",
            endpoint,
        ])
        .spawn()
        .unwrap();
    let ping = std::process::Command::new("ip")
        .args([
            "netns",
            "exec",
            &a,
            exe,
            "--role",
            "ping",
            "--endpoint",
            endpoint,
        ])
        .status();
    let _ = pong.kill();
    let _ = pong.wait();
    assert!(ping.is_ok_and(|s| s.success()), "the pinging side failed");
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    if args.iter().any(|a| a == "--veth") {
        return veth();
    }
    if args.iter().any(|a| a == "--secured") {
        return secured();
    }
    let rt = runtime();
    rt.block_on(async {
        match (flag("--role").as_deref(), flag("--endpoint")) {
            (Some("pong"), Some(endpoint)) => {
                // Both echoes at once (different keys); killed when done.
                let _raw = raw_echo(&endpoint).await;
                let _peppy = peppy_ponger(&Join::Flags(endpoint.clone())).await;
                std::future::pending::<()>().await;
            }
            (Some("ping"), Some(endpoint)) => {
                let _router = router(&endpoint).await;
                report(
                    "across a veth link between two network namespaces",
                    async || raw_pings(&endpoint).await,
                    async || peppy_pings(&Join::Flags(endpoint.clone())).await,
                )
                .await;
            }
            _ => {
                let endpoint = free_endpoint();
                let _router = router(&endpoint).await;
                let both = report(
                    "via a router on loopback",
                    async || raw_round_trips(&endpoint).await,
                    async || peppy_round_trips(&Join::Flags(endpoint.clone())).await,
                );
                // `cargo bench` passes `--bench`. `cargo test` runs this
                // target too (`test = true` in Cargo.toml), so the
                // benchmark is built, linted and run with the tests: there
                // a short run, bounded, whose figures mean nothing.
                if args.iter().any(|a| a == "--bench") {
                    both.await;
                } else {
                    SAMPLES.store(SHORT_RUN_SAMPLES, Ordering::Relaxed);
                    tokio::time::timeout(SHORT_RUN_BOUND, both)
                        .await
                        .expect("the benchmark's short run did not finish in time");
                }
            }
        }
    });
}

fn free_endpoint() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("tcp/127.0.0.1:{port}")
}

/// Writes `<dir>/<instance>.json` for the pinger and the ponger: clients
/// of `endpoint`, with a login when `passwords` are given.
fn runtime_configs(dir: &std::path::Path, endpoint: &str, passwords: Option<[&str; 2]>) {
    for (i, (id, producer)) in [("pinger", "ponger"), ("ponger", "pinger")]
        .into_iter()
        .enumerate()
    {
        let mut zenoh = serde_json::json!({ "mode": "client", "connect": [endpoint] });
        if let Some(pw) = passwords {
            zenoh["login"] = serde_json::json!({ "user": id, "password": pw[i] });
        }
        let config = serde_json::json!({
            "instance_id": id, "core_node": "standalone", "namespace": "bench",
            "slots": [{
                "link_id": producer, "kind": "node", "target": { "name": producer, "tag": "v1" },
                "binding": { "kind": "pinned", "producer": producer },
                "filter": { "kind": "pin", "producers": producer },
            }],
            "zenoh": zenoh,
        });
        std::fs::write(dir.join(format!("{id}.json")), config.to_string()).unwrap();
    }
}

/// The access policy a secured launch derives for the pinger and the
/// ponger, in its shape: each publishes its own topic and receives the
/// other's; each announces itself, answers its format and description
/// queries, follows liveliness and learns declarations.
fn bench_policy() -> serde_json::Value {
    let ns = "bench";
    fn owner(node: &str) -> Owner<'_> {
        Owner::Node {
            name: node,
            tag: "v1",
        }
    }
    let topic = |node: &str, name: &str| {
        entry_key(ns, Channel::Topic, &owner(node), name, "standalone", node)
    };
    let mut rules = vec![
        serde_json::json!({ "id": "any.declarations", "flows": ["egress"], "permission": "allow",
            "messages": ["declare_subscriber", "declare_queryable", "liveliness_token", "reply"],
            "key_exprs": [namespace_selector(ns)] }),
        serde_json::json!({ "id": "any.live", "flows": ["ingress"], "permission": "allow",
            "messages": ["declare_liveliness_subscriber", "liveliness_query"],
            "key_exprs": [space_selector(ns, Space::Live)] }),
    ];
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for (me, out, other, inp) in [
        ("pinger", "ping", "ponger", "pong"),
        ("ponger", "pong", "pinger", "ping"),
    ] {
        rules.push(serde_json::json!({ "id": format!("{me}.emits"), "flows": ["ingress"], "permission": "allow",
            "messages": ["put"], "key_exprs": [topic(me, out)] }));
        rules.push(serde_json::json!({ "id": format!("{me}.self"), "flows": ["ingress"], "permission": "allow",
            "messages": ["liveliness_token", "declare_queryable", "reply"],
            "key_exprs": [instance_liveliness_selector(ns, "standalone", me), format_selector(ns, Some(me)), describe_key(ns, "standalone", me)] }));
        rules.push(serde_json::json!({ "id": format!("{me}.subscribe"), "flows": ["ingress"], "permission": "allow",
            "messages": ["declare_subscriber"], "key_exprs": [entry_selector(ns, Channel::Topic, Some(&owner(other)), inp, None, None)] }));
        rules.push(serde_json::json!({ "id": format!("{me}.receives"), "flows": ["egress"], "permission": "allow",
            "messages": ["put"], "key_exprs": [topic(other, inp)] }));
        subjects.push(serde_json::json!({ "id": me, "usernames": [me] }));
        policies.push(serde_json::json!({ "id": me, "subjects": [me],
            "rules": ["any.declarations", "any.live", format!("{me}.emits"), format!("{me}.self"), format!("{me}.subscribe"), format!("{me}.receives")] }));
    }
    serde_json::json!({ "enabled": true, "default_permission": "deny",
        "rules": rules, "subjects": subjects, "policies": policies })
}

/// `--secured`: the same round trips through a secured router, the
/// unsecured default, and an open router's clients, interleaved twice.
fn secured() {
    let dir = tempfile::tempdir().unwrap();
    let open_dir = dir.path().join("open");
    let secured_dir = dir.path().join("secured");
    std::fs::create_dir_all(&open_dir).unwrap();
    std::fs::create_dir_all(&secured_dir).unwrap();
    let (peers_at, open_at, secured_at) = (free_endpoint(), free_endpoint(), free_endpoint());
    let passwords = [
        "b3f1c0de0a1b2c3d4e5f60718293a4b5",
        "9c8d7e6f5a4b3c2d1e0f9a8b7c6d5e4f",
    ];
    runtime_configs(&open_dir, &open_at, None);
    runtime_configs(&secured_dir, &secured_at, Some(passwords));
    let dictionary = dir.path().join("users");
    std::fs::write(
        &dictionary,
        format!("pinger:{}\nponger:{}\n", passwords[0], passwords[1]),
    )
    .unwrap();
    let rt = runtime();
    rt.block_on(async {
        let _peers_router = router(&peers_at).await;
        let _open_router = router(&open_at).await;
        let _secured_router = router_with(
            &secured_at,
            &[
                (
                    "transport/auth/usrpwd/dictionary_file",
                    format!("{:?}", dictionary.display().to_string()),
                ),
                ("access_control", bench_policy().to_string()),
            ],
        )
        .await;
        let runs = [
            ("peers (unsecured default)", Join::Flags(peers_at.clone())),
            ("clients of an open router", Join::Config(open_dir.clone())),
            ("clients of a secured router", Join::Config(secured_dir.clone())),
        ];
        let mut results: Vec<Vec<Stats>> = vec![Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..2 {
            for (i, (_, join)) in runs.iter().enumerate() {
                let samples = peppy_round_trips(join).await;
                assert!(!samples.is_empty());
                results[i].push(stats(samples));
            }
        }
        println!("peppy round trip, {} samples per run, 64-byte payload, reliable, via a router on loopback", samples_per_run());
        println!("{:<32} {:>10} {:>10} {:>10}", "run", "p50", "p90", "mean");
        for (i, (name, _)) in runs.iter().enumerate() {
            for (n, s) in results[i].iter().enumerate() {
                println!("{:<32} {:>10.1?} {:>10.1?} {:>10.1?}", format!("{name} {}", n + 1), s.p50, s.p90, s.mean);
            }
        }
        let mean_ratio = |a: usize, b: usize, f: fn(&Stats) -> Duration| {
            results[a].iter().zip(&results[b]).map(|(x, y)| f(x).as_secs_f64() / f(y).as_secs_f64()).sum::<f64>() / 2.0
        };
        println!(
            "secured / unsecured default: p50 x{:.2}, p90 x{:.2}",
            mean_ratio(2, 0, |s| s.p50),
            mean_ratio(2, 0, |s| s.p90)
        );
        println!(
            "secured / open router's clients (the policy and logins alone): p50 x{:.2}, p90 x{:.2}",
            mean_ratio(2, 1, |s| s.p50),
            mean_ratio(2, 1, |s| s.p90)
        );
    });
}
