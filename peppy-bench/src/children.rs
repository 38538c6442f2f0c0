//! The benchmark's child processes: `peppy-bench child ROLE`. Each prints
//! `{"ready":true}` once set up, then one JSON line per result.

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::time::{Duration, Instant};

use clap::{Args, Subcommand, ValueEnum};
use peppy::runtime::wire::keys::{Space, space_selector, split_entry_key};
use serde::Serialize;
use serde_json::json;
use tokio::io::AsyncReadExt as _;
use zenoh::Wait as _;

use crate::peppy_side::{self, PeppySink};
use crate::raw_side::{self, RawSink};
use crate::roles::{self, Pace, Qos, Res, Sink, cpu_ms, report};

/// Which system a child runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum System {
    /// Raw Zenoh sessions.
    Zenoh,
    /// peppy nodes.
    Peppy,
}

/// Where a child's session goes.
#[derive(Debug, Args)]
pub(crate) struct Place {
    #[arg(long, value_enum)]
    system: System,
    /// The namespace (peppy) or key prefix (raw) of this run.
    #[arg(long)]
    ns: String,
    /// The source's endpoint.
    #[arg(long)]
    endpoint: String,
    /// Shared memory on: peppy's pool and Zenoh's SHM transport (off:
    /// everything over TCP on loopback, as between two hosts).
    #[arg(long)]
    shm: bool,
    /// Zenoh's default threads, as most Zenoh programs run (default: the
    /// threads a peppy node runs Zenoh on, `peppy::runtime::threads`).
    #[arg(long)]
    zenoh_defaults: bool,
    /// Read messages where they arrived, as a camera consumer does, not
    /// decoded into owned data: the source answers a ping from its bytes
    /// in place, the sink reads a pong's sequence number and length only.
    #[arg(long)]
    in_place: bool,
    /// Raw Zenoh only: Zenoh's low-latency transport
    /// (`transport/unicast/lowlatency`, which needs QoS off and cannot
    /// fragment: messages up to a batch, 64 KiB).
    #[arg(long)]
    lowlatency: bool,
    /// peppy over a Unix socket only: direct links between the two nodes
    /// too, in a directory beside the socket (what `up` gives the
    /// instances of one launch).
    #[arg(long)]
    direct: bool,
}

/// Whether this child runs with shared memory (set once from its [`Place`]).
static SHM: AtomicBool = AtomicBool::new(false);

/// Whether this child's sessions use shared memory.
pub(crate) fn shared_memory() -> bool {
    SHM.load(Relaxed)
}

/// Whether this child's raw sessions use Zenoh's low-latency transport
/// (set once from its [`Place`]).
static LOWLATENCY: AtomicBool = AtomicBool::new(false);

/// Whether this child's raw sessions use Zenoh's low-latency transport.
pub(crate) fn lowlatency() -> bool {
    LOWLATENCY.load(Relaxed)
}

/// The directory of this child's direct links (set once from its
/// [`Place`]).
static DIRECT: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();

/// The directory of this child's direct links, if it uses them.
pub(crate) fn direct_links() -> Option<&'static std::path::Path> {
    DIRECT.get().map(std::path::PathBuf::as_path)
}

/// Whether this child reads round-trip messages in place (set once from
/// its [`Place`]).
static IN_PLACE: AtomicBool = AtomicBool::new(false);

/// Whether this child reads round-trip messages in place.
pub(crate) fn in_place() -> bool {
    IN_PLACE.load(Relaxed)
}

impl Child {
    fn place(&self) -> Option<&Place> {
        match self {
            Child::Source(place)
            | Child::RoundTrip { place, .. }
            | Child::Throughput { place, .. }
            | Child::FanOut { place, .. }
            | Child::Service { place, .. } => Some(place),
            Child::Watch { .. } => None,
        }
    }
}

/// A child process's role (internal: started by the benchmark itself).
#[derive(Debug, Subcommand)]
#[command(hide = true)]
pub(crate) enum Child {
    /// Serve pings, echo, flood and work until stdin closes.
    Source(Place),
    /// Round trips at each size.
    RoundTrip {
        #[command(flatten)]
        place: Place,
        #[arg(long, value_enum)]
        qos: Qos,
        #[arg(long, value_delimiter = ',')]
        sizes: Vec<usize>,
        /// Round trips per size up to 64 KiB (a 25th of it above).
        #[arg(long)]
        count: usize,
        /// Each size's round trips in this many batches, taking turns
        /// with other processes (`roles::Pace`); none: straight through.
        #[arg(long)]
        turns: Option<usize>,
    },
    /// Flood throughput at each size.
    Throughput {
        #[command(flatten)]
        place: Place,
        /// `SIZE:COUNT` pairs.
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
    },
    /// One consumer of a fan-out.
    FanOut {
        #[command(flatten)]
        place: Place,
        #[arg(long)]
        id: usize,
        /// This consumer starts the producer.
        #[arg(long)]
        trigger: bool,
        #[arg(long)]
        size: u32,
        #[arg(long)]
        hz: f64,
        #[arg(long)]
        warmup: u64,
        #[arg(long)]
        frames: u64,
    },
    /// Service round trips (and, on peppy, action goal to result).
    Service {
        #[command(flatten)]
        place: Place,
        #[arg(long)]
        count: usize,
        /// The calls in this many batches, taking turns with other
        /// processes (`roles::Pace`); none: straight through.
        #[arg(long)]
        turns: Option<usize>,
    },
    /// Watch a launch: when the first message comes, and when every
    /// instance has been heard.
    Watch {
        #[arg(long)]
        listen: String,
        #[arg(long)]
        ns: String,
        #[arg(long)]
        expect: usize,
    },
}

/// Runs a child role; errors are printed, and the exit code says so.
pub(crate) fn run(child: Child) -> std::process::ExitCode {
    // Both systems on the threads a node runs Zenoh on, unless asked for
    // Zenoh's defaults.
    if !child.place().is_some_and(|p| p.zenoh_defaults) {
        use peppy::runtime::threads::{Sharing, share_zenoh_threads};
        // A layout silently not applied would be measured as if it were.
        if share_zenoh_threads() == Sharing::OtherThreads {
            eprintln!(
                "peppy-bench child: other threads run before Zenoh's layout was set; it cannot be"
            );
            return std::process::ExitCode::FAILURE;
        }
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("peppy-bench child: {e}");
            return std::process::ExitCode::FAILURE;
        }
    };
    // The role runs on one of the runtime's workers, as a node's loops do
    // (a node's setup spawns them: every example and PeppyOS node does),
    // not on the thread that waits for it. A message a worker hands on (a
    // direct link's reading task) then wakes the reader on that worker;
    // handed to the waiting thread instead, it wakes another thread first:
    // measured, 64 B round trips over a direct link took 38 to 56 µs that
    // way and 35 to 38 µs this way, 64 KiB 105 to 121 µs and 70 µs.
    let role = async {
        tokio::spawn(role(child))
            .await
            .unwrap_or_else(|e| Err(format!("the role's task failed: {e}").into()))
    };
    let outcome = runtime.block_on(role);
    // Not waiting for a read of stdin still blocked (a source's stop).
    runtime.shutdown_background();
    match outcome {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("peppy-bench child: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Resolves when stdin closes: the parent's way of stopping a source.
async fn stdin_closed() {
    let mut sink = Vec::new();
    let _ = tokio::io::stdin().read_to_end(&mut sink).await;
}

async fn role(child: Child) -> Res<()> {
    SHM.store(child.place().is_some_and(|p| p.shm), Relaxed);
    IN_PLACE.store(child.place().is_some_and(|p| p.in_place), Relaxed);
    LOWLATENCY.store(child.place().is_some_and(|p| p.lowlatency), Relaxed);
    if let Some(place) = child.place().filter(|p| p.direct) {
        // Beside the source's socket, named by the case: the source and
        // its sinks find it without being told.
        let socket = place
            .endpoint
            .strip_prefix("unixsock-stream/")
            .ok_or("direct links are tried over a Unix socket only")?;
        let dir = std::path::Path::new(socket).with_extension("d");
        std::fs::create_dir_all(&dir)?;
        let _ = DIRECT.set(dir);
    }
    match child {
        Child::Source(p) => {
            let ready = async {
                report(&json!({ "ready": true, "cpu_ms": cpu_ms() }));
                stdin_closed().await;
            };
            match p.system {
                System::Zenoh => raw_side::source(&p.ns, &p.endpoint, ready).await,
                System::Peppy => peppy_side::source(&p.ns, &p.endpoint, ready).await,
            }
        }
        Child::RoundTrip {
            place,
            qos,
            sizes,
            count,
            turns,
        } => {
            with_sink(&place, "sink", async |s| {
                let mut pace = turns.map_or_else(Pace::free, Pace::turns);
                for &size in &sizes {
                    let n = if size > 64 << 10 { count / 25 } else { count };
                    let n = n.max(10).max(turns.unwrap_or(0));
                    report(&roles::round_trips(s, qos, size, n, &mut pace).await?);
                }
                Ok(())
            })
            .await
        }
        Child::Throughput { place, cases } => {
            with_sink(&place, "sink", async |s| {
                for case in &cases {
                    let (size, count) = case
                        .split_once(':')
                        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
                        .ok_or_else(|| format!("bad case `{case}`: SIZE:COUNT"))?;
                    report(&roles::throughput(s, size, count).await?);
                }
                Ok(())
            })
            .await
        }
        Child::FanOut {
            place,
            id,
            trigger,
            size,
            hz,
            warmup,
            frames,
        } => {
            let instance = format!("sink_{id}");
            with_sink(&place, &instance, async |s| {
                // Every consumer's subscription is up before the producer starts.
                report(&json!({ "ready": true }));
                let flood = trigger.then_some((size, (warmup + frames) as u32, hz));
                if trigger {
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
                report(&roles::fan_out(s, flood, warmup, frames).await?);
                Ok(())
            })
            .await
        }
        Child::Service {
            place,
            count,
            turns,
        } => {
            let spread = with_sink(&place, "sink", async |s| {
                let mut pace = turns.map_or_else(Pace::free, Pace::turns);
                let count = count.max(turns.unwrap_or(0));
                let spread = roles::service_calls(s, 64, count, &mut pace).await?;
                report(&json!({ "service": spread }));
                Ok(())
            });
            spread.await?;
            if place.system == System::Peppy {
                let sink = PeppySink::connect(&place.ns, &place.endpoint, "sink_action").await?;
                let spread = sink.action_round_trips(count / 2).await;
                sink.stop().await;
                report(&json!({ "action": spread? }));
            }
            Ok(())
        }
        Child::Watch { listen, ns, expect } => watch(&listen, &ns, expect).await,
    }
}

/// Connects a sink of the place's system and runs `work` on it.
async fn with_sink(
    place: &Place,
    instance: &str,
    work: impl AsyncFnOnce(&AnySink) -> Res<()>,
) -> Res<()> {
    let sink = match place.system {
        System::Zenoh => AnySink::Raw(Box::new(
            RawSink::connect(&place.ns, &place.endpoint).await?,
        )),
        System::Peppy => {
            AnySink::Peppy(PeppySink::connect(&place.ns, &place.endpoint, instance).await?)
        }
    };
    let r = work(&sink).await;
    if let AnySink::Peppy(p) = sink {
        p.stop().await;
    }
    r
}

/// Either system's sink, so one measuring loop serves both.
pub(crate) enum AnySink {
    Raw(Box<RawSink>),
    Peppy(PeppySink),
}

impl Sink for AnySink {
    async fn ping(&self, qos: Qos, seq: u64, data: Vec<u8>) -> Res<()> {
        match self {
            AnySink::Raw(s) => s.ping(qos, seq, data).await,
            AnySink::Peppy(s) => s.ping(qos, seq, data).await,
        }
    }

    async fn pong(&self, qos: Qos) -> Res<u64> {
        match self {
            AnySink::Raw(s) => s.pong(qos).await,
            AnySink::Peppy(s) => s.pong(qos).await,
        }
    }

    async fn flood(&self, size: u32, count: u32, hz: f64) -> Res<()> {
        match self {
            AnySink::Raw(s) => s.flood(size, count, hz).await,
            AnySink::Peppy(s) => s.flood(size, count, hz).await,
        }
    }

    async fn stream(&self) -> Res<(u64, u64, usize)> {
        match self {
            AnySink::Raw(s) => s.stream().await,
            AnySink::Peppy(s) => s.stream().await,
        }
    }

    async fn echo(&self, data: Vec<u8>) -> Res<usize> {
        match self {
            AnySink::Raw(s) => s.echo(data).await,
            AnySink::Peppy(s) => s.echo(data).await,
        }
    }
}

/// Subscribes to every topic of namespace `ns` and reports when the first
/// message came and when `expect` distinct instances had been heard.
async fn watch(listen: &str, ns: &str, expect: usize) -> Res<()> {
    let session = raw_side::open(Some(listen), None).await?;
    let topics = session
        .declare_subscriber(space_selector(ns, Space::Topic))
        .await?;
    report(&json!({ "ready": true }));
    let mut heard = std::collections::BTreeSet::new();
    let mut first = None;
    let deadline = Instant::now() + Duration::from_secs(120);
    while heard.len() < expect {
        let left = deadline.saturating_duration_since(Instant::now());
        let Ok(Ok(sample)) = tokio::time::timeout(left, topics.recv_async()).await else {
            break;
        };
        first.get_or_insert_with(roles::now_ns);
        if let Some(sender) = split_entry_key(sample.key_expr().as_str()) {
            heard.insert(sender.instance.to_string());
        }
    }
    report(&json!({
        "first_ns": first,
        "all_ns": (heard.len() >= expect).then(roles::now_ns),
        "heard": heard.len(),
    }));
    let _ = session.close().wait();
    Ok(())
}
