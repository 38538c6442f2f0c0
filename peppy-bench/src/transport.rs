//! The groups that run both systems side by side: each case starts a fresh
//! source process and measuring process(es) for each system in turn, on
//! their own port and namespace. A run is a [`Mode`]: the system, whether
//! shared memory is on (peppy's pool and Zenoh's SHM transport) or off
//! (everything over TCP on loopback, as between two hosts), whether
//! Zenoh runs on its default threads or on a node's, and whether round-trip
//! messages are decoded into owned data or read where they arrived.

use std::time::Duration;

use serde_json::Value;

use crate::children::System;
use crate::floor;
use crate::peers::{self, DoraNode, DoraRun};
use crate::procs::{Proc, free_port};
use crate::roles::{Qos, Res};
use crate::stats::{Figure, Row, Spread, size};

const BOUND: Duration = Duration::from_secs(300);

/// One system with shared memory on or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Mode {
    system: System,
    shm: bool,
    /// On Zenoh's default threads (else on a node's layout).
    zenoh_defaults: bool,
    /// Round-trip messages read where they arrived, not decoded into owned
    /// data (`--in-place`).
    in_place: bool,
    /// The link between the two processes.
    link: Link,
    /// A peer measured instead of `system` (which it then ignores).
    peer: Option<Peer>,
    /// Raw Zenoh on its low-latency transport (`--lowlatency`).
    lowlatency: bool,
    /// peppy over a Unix socket with direct links between the nodes too
    /// (`--direct`), as `up` runs the instances of one launch.
    direct: bool,
}

/// The Zenoh link between a source and its sinks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Link {
    /// Loopback TCP, as between two hosts.
    Tcp,
    /// A Unix socket (`unixsock-stream`): one host only.
    Unix,
}

/// A framework or floor measured beside peppy and raw Zenoh
/// (`peers.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Peer {
    /// dora-rs: the source and sink as dora nodes of one `dora run`.
    Dora,
    /// The hand-off floor: an iceoryx2 ping-pong with event wake-ups.
    Floor,
    /// The source as a Python node on peppy's Python runtime, pinged by
    /// the Rust sink over a Unix socket.
    Python,
}

const RAW_TCP: Mode = Mode {
    system: System::Zenoh,
    shm: false,
    zenoh_defaults: false,
    in_place: false,
    link: Link::Tcp,
    peer: None,
    lowlatency: false,
    direct: false,
};
const PEPPY_TCP: Mode = Mode {
    system: System::Peppy,
    shm: false,
    zenoh_defaults: false,
    in_place: false,
    link: Link::Tcp,
    peer: None,
    lowlatency: false,
    direct: false,
};
const RAW_SHM: Mode = Mode {
    system: System::Zenoh,
    shm: true,
    zenoh_defaults: false,
    in_place: false,
    link: Link::Tcp,
    peer: None,
    lowlatency: false,
    direct: false,
};
const PEPPY_SHM: Mode = Mode {
    system: System::Peppy,
    shm: true,
    zenoh_defaults: false,
    in_place: false,
    link: Link::Tcp,
    peer: None,
    lowlatency: false,
    direct: false,
};

/// With shared memory, reading in place: a camera consumer's way.
const RAW_SHM_IN_PLACE: Mode = Mode {
    in_place: true,
    ..RAW_SHM
};
const PEPPY_SHM_IN_PLACE: Mode = Mode {
    in_place: true,
    ..PEPPY_SHM
};

/// Raw Zenoh as most programs run it, on its default threads. Not like
/// for like: what a node's thread layout buys, next to peppy over TCP.
const RAW_TCP_DEFAULTS: Mode = Mode {
    system: System::Zenoh,
    shm: false,
    zenoh_defaults: true,
    in_place: false,
    link: Link::Tcp,
    peer: None,
    lowlatency: false,
    direct: false,
};

/// Over a Unix socket, shared memory on: the link `peppy-launch up`
/// gives the instances of one launch on one host.
const RAW_UNIX: Mode = Mode {
    link: Link::Unix,
    ..RAW_SHM
};
const PEPPY_UNIX: Mode = Mode {
    link: Link::Unix,
    ..PEPPY_SHM
};

/// peppy as `up` runs the instances of one launch on one host: a Unix
/// socket, and direct links beside it.
const PEPPY_DIRECT: Mode = Mode {
    direct: true,
    ..PEPPY_UNIX
};

/// Raw Zenoh over a Unix socket on its low-latency transport.
const RAW_UNIX_LOWLATENCY: Mode = Mode {
    lowlatency: true,
    ..RAW_UNIX
};

/// dora-rs as it runs on one host: its nodes on Zenoh over loopback TCP,
/// with its shared memory from 4 KiB (`peers.rs`).
const DORA: Mode = Mode {
    peer: Some(Peer::Dora),
    ..RAW_SHM
};

/// The source as a Python node, over a Unix socket with shared memory on
/// as `up` runs a launch's instances (a Python node has no direct links).
const PYTHON_UNIX: Mode = Mode {
    peer: Some(Peer::Python),
    ..PEPPY_UNIX
};

/// The hand-off floor (iceoryx2).
const FLOOR: Mode = Mode {
    peer: Some(Peer::Floor),
    ..RAW_SHM
};

/// Like for like (raw first in the pair, first to run in every other
/// round): both over TCP, then both with shared memory.
const PAIRS: [(Mode, Mode); 2] = [(RAW_TCP, PEPPY_TCP), (RAW_SHM, PEPPY_SHM)];

fn transport(shm: bool) -> &'static str {
    if shm { "shared memory" } else { "TCP, SHM off" }
}

/// A running source process and where to reach it.
struct Source {
    /// The source process (the floor's pong for the floor; none for
    /// dora-rs, whose nodes `dora` runs).
    proc: Option<Proc>,
    /// dora's run, whose nodes are the source and the sinks.
    dora: Option<DoraRun>,
    ns: String,
    endpoint: String,
    mode: Mode,
}

/// Where a run's Unix sockets go (removed when the benchmark ends).
fn socket_dir() -> Res<&'static std::path::Path> {
    static DIR: std::sync::OnceLock<Option<tempfile::TempDir>> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        tempfile::Builder::new()
            .prefix("peppy-bench-")
            .tempdir()
            .ok()
    })
    .as_ref()
    .map(tempfile::TempDir::path)
    .ok_or_else(|| "cannot make a directory for the Unix sockets".into())
}

impl Source {
    fn start(mode: Mode, case: &str) -> Res<Source> {
        let port = free_port()?;
        let ns = format!("{case}-{}-{port}", std::process::id());
        let endpoint = match mode.link {
            Link::Tcp => format!("tcp/127.0.0.1:{port}"),
            Link::Unix => format!(
                "unixsock-stream/{}",
                socket_dir()?.join(format!("{ns}.sock")).display()
            ),
        };
        let proc = match mode.peer {
            Some(Peer::Dora) => None,
            Some(Peer::Floor) => {
                let bin = peers::peers()
                    .floor
                    .as_ref()
                    .ok_or("the hand-off floor is not built")?;
                let mut command = std::process::Command::new(bin);
                command.args(["pong", "--name", &ns]);
                let mut proc = Proc::spawn(command, "the floor's pong")?;
                proc.next_with("ready", Duration::from_secs(30))?;
                Some(proc)
            }
            Some(Peer::Python) => {
                let python = peers::peers()
                    .python
                    .as_ref()
                    .ok_or("the Python source is not set up")?;
                let plan = socket_dir()?.join(format!("{ns}.plan.json"));
                let text = serde_json::json!({
                    "instance_id": "source",
                    "core_node": "bench",
                    "namespace": ns,
                    "zenoh": {
                        "mode": "peer",
                        "listen": [endpoint],
                        "multicast_scouting": false,
                    },
                    // The sink's pings, pinned to it as in the Rust source.
                    "slots": [{
                        "link_id": "sink",
                        "kind": "node",
                        "target": { "name": "bench_sink", "tag": "v1" },
                        "binding": { "kind": "pinned", "producer": "sink" },
                        "filter": { "kind": "pin", "producers": "sink" },
                    }],
                });
                std::fs::write(&plan, text.to_string())?;
                let mut proc = Proc::spawn(python.command(&plan), "the Python source")?;
                proc.next_with("ready", Duration::from_secs(120))?;
                Some(proc)
            }
            None => {
                let mut proc = Proc::child(&place_args("source", mode, &ns, &endpoint))?;
                proc.next_with("ready", Duration::from_secs(30))?;
                Some(proc)
            }
        };
        Ok(Source {
            proc,
            dora: None,
            ns,
            endpoint,
            mode,
        })
    }

    /// Starts a source and its sink, given the sink's arguments (a
    /// benchmark child's: a peer's sink reads the same flags).
    fn with_sink(
        mode: Mode,
        case: &str,
        sink_args: impl FnOnce(&Source) -> Vec<String>,
    ) -> Res<(Source, Proc)> {
        let mut source = Source::start(mode, case)?;
        let args = sink_args(&source);
        let sink = match mode.peer {
            None | Some(Peer::Python) => Proc::child(&args)?,
            Some(Peer::Floor) => {
                let bin = peers::peers()
                    .floor
                    .as_ref()
                    .ok_or("the hand-off floor is not built")?;
                let mut command = std::process::Command::new(bin);
                command
                    .args(["ping", "--name", &source.ns])
                    .args(&args[1..]);
                Proc::spawn(command, "the floor's ping")?
            }
            Some(Peer::Dora) => {
                let dora = peers::peers()
                    .dora
                    .as_ref()
                    .ok_or("dora-rs is not set up")?;
                let nodes = [
                    DoraNode {
                        id: "source".into(),
                        sink: false,
                        inputs: vec![
                            ("ping".into(), "sink/ping".into(), None),
                            ("flood".into(), "sink/flood".into(), None),
                        ],
                        outputs: vec!["pong".into(), "stream".into()],
                        args: Some(Vec::new()),
                    },
                    DoraNode {
                        id: "sink".into(),
                        sink: true,
                        // A flood's messages queue as peppy's keep-all
                        // reader would hold them (dora's default keeps 10).
                        inputs: vec![
                            ("pong".into(), "source/pong".into(), None),
                            ("stream".into(), "source/stream".into(), Some(STREAM_QUEUE)),
                        ],
                        outputs: vec!["ping".into(), "flood".into()],
                        args: Some(args),
                    },
                ];
                let mut run = dora.run(&nodes)?;
                let sink = run.nodes.remove("sink").ok_or("dora's sink never linked")?;
                source.dora = Some(run);
                sink
            }
        };
        Ok((source, sink))
    }

    /// Stops the source (and a peer's run).
    fn stop(self) {
        if let Some(proc) = self.proc {
            proc.stop();
        }
        if let Some(run) = self.dora {
            run.stop();
        }
    }

    /// `peppy-bench child ROLE` flags that reach this source.
    fn args(&self, role: &str) -> Vec<String> {
        place_args(role, self.mode, &self.ns, &self.endpoint)
    }
}

fn place_args(role: &str, mode: Mode, ns: &str, endpoint: &str) -> Vec<String> {
    let system = match mode.system {
        System::Zenoh => "zenoh",
        System::Peppy => "peppy",
    };
    let mut args = [role, "--system", system, "--ns", ns, "--endpoint", endpoint]
        .map(String::from)
        .to_vec();
    if mode.shm {
        args.push("--shm".into());
    }
    if mode.zenoh_defaults {
        args.push("--zenoh-defaults".into());
    }
    if mode.in_place {
        args.push("--in-place".into());
    }
    if mode.lowlatency {
        args.push("--lowlatency".into());
    }
    if mode.direct {
        args.push("--direct".into());
    }
    args
}

fn spread(v: &Value) -> Option<Spread> {
    serde_json::from_value(v.clone()).ok()
}

/// The rounds' spreads of one figure taken as one ([`Spread::median_of`]).
fn median_spread<'a>(rounds: impl IntoIterator<Item = &'a Value>) -> Option<Spread> {
    let spreads: Vec<Spread> = rounds.into_iter().filter_map(spread).collect();
    Spread::median_of(&spreads)
}

/// Topic round trips at 64 B to 4 MiB, for both profiles: like for like
/// over TCP and with shared memory (decoded into owned data, and read in
/// place), then peppy with shared memory against raw Zenoh over TCP (what
/// zero-copy buys between processes on one host).
pub(crate) fn round_trips(quick: bool) -> Res<Vec<Row>> {
    let sizes = [64usize, 4 << 10, 64 << 10, 1 << 20, 4 << 20];
    // Round trips per size in all rounds: a small one takes a fifth of a
    // millisecond, so fewer would leave a round's median to whatever the
    // machine did in that tenth of a second. Sizes above 64 KiB take a
    // 25th of it (the child divides).
    let count = if quick { 100 } else { 5000 };
    let mut rows = Vec::new();
    for qos in [Qos::Reliable, Qos::Sensor] {
        // Beside this profile's round trips, as a profile's turns run
        // seconds after the other's and the machine moves meanwhile.
        let mut floor_samples = Vec::new();
        let mut modes = vec![
            RAW_TCP,
            PEPPY_TCP,
            RAW_SHM,
            PEPPY_SHM,
            RAW_TCP_DEFAULTS,
            RAW_SHM_IN_PLACE,
            PEPPY_SHM_IN_PLACE,
            RAW_UNIX,
            PEPPY_UNIX,
            PEPPY_DIRECT,
        ];
        if peers::peers().dora.is_some() {
            modes.push(DORA);
        }
        if peers::peers().floor.is_some() {
            modes.push(FLOOR);
        }
        let sizes_arg: Vec<String> = sizes.iter().map(ToString::to_string).collect();
        let got = in_turns(
            &modes,
            rounds(quick),
            sizes.len(),
            |source| {
                let mut args = source.args("round-trip");
                args.extend([
                    "--qos".into(),
                    qos.name().replace("_data", ""),
                    "--sizes".into(),
                    sizes_arg.join(","),
                    "--count".into(),
                    (count / rounds(quick)).to_string(),
                ]);
                args
            },
            |case| {
                if sizes[case] == FLOOR_SIZE {
                    floor_samples.extend(floor::four_copies(FLOOR_SIZE, 5));
                }
            },
            |_, _, sink| Ok(vec![sink.next_with("spread", BOUND)?]),
        )?;
        // Per mode and size: the rounds' median CPU time per round trip in
        // the pinging process, Zenoh's threads and the rest (µs).
        let cpu: Vec<Vec<(f64, f64)>> = got
            .iter()
            .map(|cases| {
                cases
                    .iter()
                    .map(|runs| {
                        let median = |what: &str| {
                            let mut v: Vec<f64> = runs
                                .iter()
                                .filter_map(|r| r["cpu"][what].as_f64())
                                .collect();
                            v.sort_by(f64::total_cmp);
                            v.get(v.len() / 2).copied().unwrap_or(0.0)
                        };
                        (median("zenoh_us"), median("other_us"))
                    })
                    .collect()
            })
            .collect();
        // Per mode and size: the rounds' spreads, and their unanswered pings.
        let got: Vec<Vec<(Option<Spread>, u64, usize)>> = got
            .iter()
            .map(|cases| {
                cases
                    .iter()
                    .map(|runs| {
                        let spread = median_spread(runs.iter().map(|v| &v["spread"]));
                        let lost = runs.iter().map(|v| v["lost"].as_u64().unwrap_or(0)).sum();
                        let bytes = runs[0]["size"].as_u64().unwrap_or(0) as usize;
                        (spread, lost, bytes)
                    })
                    .collect()
            })
            .collect();
        // (group, the base mode and its name, peppy's mode)
        let cases = [
            (RT_DORA_DIRECT, DORA, DORA_NAME, PEPPY_DIRECT),
            (RT_DORA_TCP, DORA, DORA_NAME, PEPPY_SHM),
            (RT_DORA_UNIX, DORA, DORA_NAME, PEPPY_UNIX),
            (RT_FLOOR_DIRECT, FLOOR, FLOOR_NAME, PEPPY_DIRECT),
            (RT_FLOOR, FLOOR, FLOOR_NAME, PEPPY_UNIX),
            (RT_DIRECT_VS_TCP, PEPPY_SHM, "peppy over TCP", PEPPY_DIRECT),
            (
                "topic round trip, TCP (SHM off both sides)",
                RAW_TCP,
                RAW,
                PEPPY_TCP,
            ),
            (
                "topic round trip, shared memory both sides",
                RAW_SHM,
                RAW,
                PEPPY_SHM,
            ),
            (
                "topic round trip, shared memory, read in place (a camera consumer's way)",
                RAW_SHM_IN_PLACE,
                RAW,
                PEPPY_SHM_IN_PLACE,
            ),
            (RT_UNIX, RAW_UNIX, RAW, PEPPY_UNIX),
            (RT_UNIX_VS_TCP, PEPPY_SHM, "peppy over TCP", PEPPY_UNIX),
            (
                "topic round trip, peppy with SHM vs raw over TCP",
                RAW_TCP,
                RAW,
                PEPPY_SHM,
            ),
            (
                "topic round trip, raw Zenoh on its default threads vs peppy (TCP)",
                RAW_TCP_DEFAULTS,
                RAW,
                PEPPY_TCP,
            ),
        ];
        let at = |m: Mode| modes.iter().position(|&x| x == m);
        for (group, base, name, peppy) in cases {
            let (Some(z), Some(p)) = (at(base), at(peppy)) else {
                continue;
            };
            for ((zs, zlost, bytes), (ps, plost, _)) in got[z].iter().zip(&got[p]) {
                let mut row = Row::new(
                    group,
                    format!("{} {}", qos.name(), size(*bytes)),
                    zs.map(Figure::Latency),
                    ps.map(Figure::Latency),
                );
                if name != RAW {
                    row = row.against(name);
                }
                if zlost + plost > 0 {
                    row =
                        row.with_note(format!("unanswered in 2 s: {name} {zlost}, peppy {plost}"));
                }
                rows.push(row);
            }
        }
        // What a round trip costs the pinging process in CPU, where links
        // carry the message and Zenoh still carries its copy.
        if let (Qos::Reliable, Some(z), Some(p)) = (qos, at(RAW_UNIX), at(PEPPY_DIRECT)) {
            for (case, bytes) in got[p].iter().map(|g| g.2).enumerate() {
                let us = |value: f64| Figure::Value {
                    value,
                    unit: "µs".into(),
                };
                let ((zz, zo), (pz, po)) = (cpu[z][case], cpu[p][case]);
                for (threads, raw, peppy) in [("Zenoh's threads", zz, pz), ("the rest", zo, po)] {
                    rows.push(Row::new(
                        RT_CPU,
                        format!("{} {}, {threads}", qos.name(), size(bytes)),
                        Some(us(raw)),
                        Some(us(peppy)),
                    ));
                }
            }
        }
        rows.push(Row::new(
            MACHINE,
            format!("{}: four 1 MiB copies between two threads", qos.name()),
            None,
            Spread::of(&mut floor_samples).map(Figure::Latency),
        ));
    }
    rows.sort_by_key(|r| {
        [
            RT_DORA_DIRECT,
            RT_DORA_TCP,
            RT_DORA_UNIX,
            RT_FLOOR_DIRECT,
            RT_FLOOR,
            RT_DIRECT_VS_TCP,
            "topic round trip, TCP",
            "topic round trip, shared memory both",
            "topic round trip, shared memory, read",
            RT_UNIX,
            RT_UNIX_VS_TCP,
            RT_CPU,
            MACHINE,
            "topic round trip, peppy",
            "topic round trip, raw",
        ]
        .iter()
        .position(|g| r.group.starts_with(g))
    });
    Ok(rows)
}

/// The base column's name for raw Zenoh (the default).
const RAW: &str = "raw zenoh";
/// The base column's name for dora-rs.
pub(crate) const DORA_NAME: &str = "dora-rs";
/// The base column's name for the hand-off floor.
const FLOOR_NAME: &str = "floor";

const RT_DORA_DIRECT: &str = "topic round trip, dora-rs vs peppy as `up` links one launch's instances (Unix socket and direct links)";
const RT_FLOOR_DIRECT: &str =
    "topic round trip, the hand-off floor (iceoryx2, event wake-ups) vs peppy with direct links";
const RT_DIRECT_VS_TCP: &str =
    "topic round trip, peppy with direct links vs over loopback TCP (shared memory)";
const RT_DORA_TCP: &str =
    "topic round trip, dora-rs vs peppy (each with its shared memory, loopback TCP)";
const RT_DORA_UNIX: &str =
    "topic round trip, dora-rs vs peppy over a Unix socket (each with its shared memory)";
const RT_FLOOR: &str =
    "topic round trip, the hand-off floor (iceoryx2, event wake-ups) vs peppy over a Unix socket";
const RT_UNIX: &str = "topic round trip, Unix socket, shared memory both sides";
const RT_CPU: &str = "CPU time per round trip in the pinging process, raw Zenoh vs peppy with direct links (Unix socket)";
const RT_UNIX_VS_TCP: &str =
    "topic round trip, peppy over a Unix socket vs over loopback TCP (shared memory)";

/// How many messages a dora sink's flood input holds (dora's default is
/// 10, and it drops the oldest beyond): a flood is read as it comes, as
/// peppy's keep-all reader holds what it has not read.
const STREAM_QUEUE: usize = 100_000;

/// What each link on one host buys small messages: round trips of 64 B
/// and 4 KiB over loopback TCP and over a Unix socket, peppy and raw
/// Zenoh (shared memory on, as `up` runs nodes; it does not apply at
/// these sizes), and raw Zenoh's low-latency transport, all in turns.
pub(crate) fn links(quick: bool) -> Res<Vec<Row>> {
    let sizes = [64usize, 4 << 10];
    let count = if quick { 100 } else { 5000 };
    let mut modes = vec![
        RAW_SHM,
        PEPPY_SHM,
        RAW_UNIX,
        PEPPY_UNIX,
        RAW_UNIX_LOWLATENCY,
        PEPPY_DIRECT,
    ];
    if peers::peers().floor.is_some() {
        modes.push(FLOOR);
    }
    if peers::peers().python.is_some() {
        modes.push(PYTHON_UNIX);
    }
    let sizes_arg: Vec<String> = sizes.iter().map(ToString::to_string).collect();
    let got = in_turns(
        &modes,
        rounds(quick),
        sizes.len(),
        |source| {
            let mut args = source.args("round-trip");
            args.extend([
                "--qos".into(),
                "reliable".into(),
                "--sizes".into(),
                sizes_arg.join(","),
                "--count".into(),
                (count / rounds(quick)).to_string(),
            ]);
            args
        },
        |_| {},
        |_, _, sink| Ok(vec![sink.next_with("spread", BOUND)?]),
    )?;
    let spreads: Vec<Vec<Option<Spread>>> = got
        .iter()
        .map(|cases| {
            cases
                .iter()
                .map(|runs| median_spread(runs.iter().map(|v| &v["spread"])))
                .collect()
        })
        .collect();
    let at = |mode| modes.iter().position(|m| *m == mode).unwrap_or(usize::MAX);
    let cases = [
        (LINKS_DIRECT, 1, 5, "TCP", "direct"),
        (LINKS_DIRECT_UNIX, 3, 5, "Unix", "direct"),
        (LINKS_DIRECT_FLOOR, at(FLOOR), 5, "floor", "direct"),
        (LINKS_PYTHON, 5, at(PYTHON_UNIX), "Rust", "Python"),
        (LINKS_PYTHON_UNIX, 3, at(PYTHON_UNIX), "Rust", "Python"),
        (LINKS_PEPPY, 1, 3, "TCP", "Unix"),
        (LINKS_RAW, 0, 2, "TCP", "Unix"),
        (LINKS_LOWLATENCY, 2, 4, "default", "low-latency"),
        (LINKS_PEPPY_UNIX_RAW_TCP, 0, 3, "raw, TCP", "peppy, Unix"),
    ];
    let mut rows = Vec::new();
    for (group, base, subject, base_name, subject_name) in cases {
        if base >= modes.len() || subject >= modes.len() {
            continue;
        }
        for (i, &bytes) in sizes.iter().enumerate() {
            rows.push(
                Row::new(
                    group,
                    format!("reliable {}", size(bytes)),
                    spreads[base][i].map(Figure::Latency),
                    spreads[subject][i].map(Figure::Latency),
                )
                .against(base_name)
                .of(subject_name),
            );
        }
    }
    Ok(rows)
}

const LINKS_DIRECT: &str = "links on one host, peppy: direct links vs loopback TCP";
const LINKS_DIRECT_UNIX: &str = "links on one host, peppy: direct links vs a Unix socket";
const LINKS_DIRECT_FLOOR: &str =
    "links on one host: the hand-off floor (iceoryx2) vs peppy with direct links";
const LINKS_PEPPY: &str = "links on one host, peppy: Unix socket vs loopback TCP";
const LINKS_PYTHON: &str = "links on one host: a Python consumer of a Rust producer (its answer back over a Unix socket) vs a Rust one with direct links";
const LINKS_PYTHON_UNIX: &str = "links on one host: a Python consumer of a Rust producer vs a Rust one, both over a Unix socket alone";
const LINKS_RAW: &str = "links on one host, raw Zenoh: Unix socket vs loopback TCP";
const LINKS_LOWLATENCY: &str =
    "links on one host, raw Zenoh over a Unix socket: the low-latency transport vs the default";
const LINKS_PEPPY_UNIX_RAW_TCP: &str =
    "links on one host: peppy over a Unix socket vs raw Zenoh over loopback TCP";

/// The size whose round trips the machine's floor (`floor`) is measured
/// beside, in the same turns.
const FLOOR_SIZE: usize = 1 << 20;

/// The group of figures measuring the machine alone (`stats::render`
/// heads its column "measured").
pub(crate) const MACHINE: &str = "machine: the memory floor under a shared-memory round trip";

/// One producer to one consumer, as fast as it can, `reliable`.
pub(crate) fn throughput(quick: bool) -> Res<Vec<Row>> {
    // Each round runs about a second per case: shorter ones measured the
    // connection's start and the machine's passing mood more than the rate.
    let scale = if quick { 50 } else { 1 };
    let cases = [
        (8usize, 1_000_000 / scale),
        (64, 1_000_000 / scale),
        (64 << 10, 20_000 / scale),
        (1 << 20, 1_000 / scale),
    ];
    // The median round by message rate.
    let rate = |runs: &[Value]| {
        let mut runs: Vec<&Value> = runs.iter().collect();
        runs.sort_by(|a, b| {
            let r = |v: &Value| v["msgs_per_s"].as_f64().unwrap_or(0.0);
            r(a).total_cmp(&r(b))
        });
        let v = runs[runs.len() / 2];
        Figure::Rate {
            msgs_per_s: v["msgs_per_s"].as_f64().unwrap_or(0.0),
            bytes_per_s: v["bytes_per_s"].as_f64().unwrap_or(0.0),
        }
    };
    let mut rows = Vec::new();
    // The pairs, then peppy as `up` runs one launch's instances (a Unix
    // socket and direct links) against raw Zenoh over the same socket.
    let pairs = PAIRS.into_iter().chain([(RAW_UNIX, PEPPY_DIRECT)]);
    for (raw, peppy) in pairs {
        // dora-rs beside the pair that runs as it does on one host.
        let mut modes = vec![raw, peppy];
        if raw == RAW_SHM && peers::peers().dora.is_some() {
            modes.push(DORA);
        }
        // What direct links change, against peppy on the same socket alone.
        if peppy.direct {
            modes.push(PEPPY_UNIX);
        }
        let got = in_rounds(&modes, rounds(quick), |mode| {
            let (source, mut sink) = Source::with_sink(mode, "tp", |source| {
                let mut args = source.args("throughput");
                // dora-rs moves small messages at a tenth of the others'
                // rate or less here: a tenth of the messages keeps its
                // flood near a second too.
                let tenth = |(s, c): &(usize, u32)| match mode.peer {
                    Some(Peer::Dora) if *s < 1024 => (*s, c / 10),
                    _ => (*s, *c),
                };
                let list: Vec<String> = cases
                    .iter()
                    .map(tenth)
                    .map(|(s, c)| format!("{s}:{c}"))
                    .collect();
                args.extend(["--cases".into(), list.join(",")]);
                args
            })?;
            let mut got = Vec::new();
            for _ in 0..cases.len() {
                got.push(sink.next_with("msgs_per_s", BOUND)?);
            }
            sink.wait_or_kill(Duration::from_secs(10));
            source.stop();
            Ok(got)
        })?;
        let group = if peppy.direct {
            "topic throughput (reliable, one to one), peppy with direct links vs raw Zenoh over a Unix socket".to_string()
        } else {
            format!(
                "topic throughput (reliable, one to one, {})",
                transport(raw.shm)
            )
        };
        let short = |runs: &[Value]| -> u64 {
            runs.iter()
                .map(|v| v["sent"].as_u64().unwrap_or(0) - v["received"].as_u64().unwrap_or(0))
                .sum()
        };
        if peppy.direct {
            let rate_row =
                |group: &str, base: &[Vec<Value>], subject: &[Vec<Value>], name: &str, of: &str| {
                    base.iter()
                        .zip(subject)
                        .map(|(b, p)| {
                            let bytes = b[0]["size"].as_u64().unwrap_or(0) as usize;
                            Row::new(group, size(bytes), Some(rate(b)), Some(rate(p)))
                                .against(name)
                                .of(of)
                        })
                        .collect::<Vec<_>>()
                };
            rows.extend(rate_row(
                "topic throughput (reliable, one to one), peppy with direct links vs over a Unix socket alone",
                &got[2],
                &got[1],
                "Unix",
                "direct",
            ));
            rows.extend(rate_row(
                "topic throughput (reliable, one to one), peppy over a Unix socket vs raw Zenoh over it",
                &got[0],
                &got[2],
                RAW,
                "peppy, Unix",
            ));
        }
        if let Some(dora) = got.get(2).filter(|_| raw == RAW_SHM) {
            rows.extend(dora.iter().zip(&got[1]).map(|(d, p)| {
                let bytes = d[0]["size"].as_u64().unwrap_or(0) as usize;
                let mut row = Row::new(
                    "topic throughput, dora-rs vs peppy (one to one, shared memory)",
                    size(bytes),
                    Some(rate(d)),
                    Some(rate(p)),
                )
                .against(DORA_NAME);
                if bytes < 1024 {
                    row = row.with_note("dora-rs sent a tenth as many messages");
                }
                if short(d) + short(p) > 0 {
                    let note = format!("not received: dora-rs {}, peppy {}", short(d), short(p));
                    row.note = Some(match row.note.take() {
                        Some(n) => format!("{n}; {note}"),
                        None => note,
                    });
                }
                row
            }));
        }
        rows.extend(got[0].iter().zip(&got[1]).map(|(z, p)| {
            let bytes = z[0]["size"].as_u64().unwrap_or(0) as usize;
            let mut row = Row::new(&group, size(bytes), Some(rate(z)), Some(rate(p)));
            if short(z) + short(p) > 0 {
                row = row.with_note(format!(
                    "not received: raw {}, peppy {}",
                    short(z),
                    short(p)
                ));
            }
            row
        }));
    }
    Ok(rows)
}

/// How many rounds a like-for-like group runs: the systems take turns,
/// so a slow spell of the machine falls on both, and each figure is the
/// median of its rounds.
fn rounds(quick: bool) -> usize {
    if quick { 1 } else { 4 }
}

/// Runs `run` for each mode, `rounds` times, the modes taking turns, in
/// reverse order every other round (so no mode always runs first, or
/// always right after another). Returns, per mode and per case, what each
/// round reported.
fn in_rounds(
    modes: &[Mode],
    rounds: usize,
    mut run: impl FnMut(Mode) -> Res<Vec<Value>>,
) -> Res<Vec<Vec<Vec<Value>>>> {
    let mut got: Vec<Vec<Vec<Value>>> = vec![Vec::new(); modes.len()];
    for round in 0..rounds {
        let order: Vec<usize> = if round % 2 == 0 {
            (0..modes.len()).collect()
        } else {
            (0..modes.len()).rev().collect()
        };
        for i in order {
            let cases = run(modes[i])?;
            got[i].resize(cases.len(), Vec::new());
            for (case, v) in cases.into_iter().enumerate() {
                got[i][case].push(v);
            }
        }
    }
    Ok(got)
}

/// How many batches each case of `in_turns` is cut into.
const TURNS: usize = 10;

/// Like [`in_rounds`], but within a round every mode's source and sink are
/// up at once and the sinks take turns ([`roles::Pace`]): each of the
/// `cases` a sink measures is cut into [`TURNS`] batches, and the modes
/// run one batch each in turn (the order turning each time), so the
/// machine's drift within a round reaches every mode alike. `sink_args`
/// gives a sink's arguments for its source (`--turns` is added);
/// `between` runs after every mode's batch of a turn, with the case;
/// `collect` reads a sink's results of one case once all its batches ran.
fn in_turns(
    modes: &[Mode],
    rounds: usize,
    cases: usize,
    sink_args: impl Fn(&Source) -> Vec<String>,
    mut between: impl FnMut(usize),
    mut collect: impl FnMut(usize, Mode, &mut Proc) -> Res<Vec<Value>>,
) -> Res<Vec<Vec<Vec<Value>>>> {
    let mut got: Vec<Vec<Vec<Value>>> = vec![Vec::new(); modes.len()];
    for round in 0..rounds {
        let mut sides = Vec::new();
        for &mode in modes {
            sides.push(Source::with_sink(mode, "turns", |source| {
                let mut args = sink_args(source);
                args.extend(["--turns".into(), TURNS.to_string()]);
                args
            })?);
        }
        let mut position = vec![0; modes.len()];
        for case in 0..cases {
            for turn in 0..TURNS {
                let shift = round + case + turn;
                let mut order: Vec<usize> = (0..modes.len())
                    .map(|k| (k + shift) % modes.len())
                    .collect();
                if shift % 2 == 1 {
                    order.reverse();
                }
                for i in order {
                    let sink = &mut sides[i].1;
                    sink.say("go")?;
                    sink.next_with("batch", BOUND)?;
                }
                between(case);
            }
            for (i, (_, sink)) in sides.iter_mut().enumerate() {
                for v in collect(case, modes[i], sink)? {
                    if got[i].len() <= position[i] {
                        got[i].push(Vec::new());
                    }
                    got[i][position[i]].push(v);
                    position[i] += 1;
                }
            }
        }
        for (source, mut sink) in sides {
            sink.wait_or_kill(Duration::from_secs(10));
            source.stop();
        }
    }
    Ok(got)
}

/// One producer, eight consumer processes, 1 MiB frames at 30 Hz, both
/// with shared memory (each system's default on one host); dora-rs too,
/// its producer and consumers nodes of one dataflow.
pub(crate) fn fan_out(quick: bool) -> Res<Vec<Row>> {
    const CONSUMERS: usize = 8;
    const GROUP: &str = "fan-out: 1 producer, 8 consumer processes, 1 MiB at 30 Hz";
    let (warmup, frames) = (30u64, if quick { 60u64 } else { 150 });
    let window = frames as f64 / 30.0;
    // A consumer's arguments (the last one starts the producer).
    let consumer_args = |source_args: Vec<String>, id: usize| {
        let mut args = source_args;
        args.extend(
            [
                "--id",
                &id.to_string(),
                "--size",
                &(1u32 << 20).to_string(),
                "--hz",
                "30",
                "--warmup",
                &warmup.to_string(),
                "--frames",
                &frames.to_string(),
            ]
            .map(String::from),
        );
        if id == CONSUMERS - 1 {
            args.push("--trigger".into());
        }
        args
    };
    let mut figures = Vec::new();
    for mode in [RAW_SHM, PEPPY_SHM] {
        let mut source = Source::start(mode, "fan")?;
        let mut consumers = Vec::new();
        for id in 0..CONSUMERS {
            let mut c = Proc::child(&consumer_args(source.args("fan-out"), id))?;
            c.next_with("ready", Duration::from_secs(30))?;
            consumers.push(c);
        }
        let mut received = Vec::new();
        for mut c in consumers {
            received.push(c.next_with("received", BOUND)?);
            c.wait_or_kill(Duration::from_secs(10));
        }
        let proc = source.proc.as_mut().ok_or("no source process")?;
        let flood = proc.next_with("flood", Duration::from_secs(30))?;
        figures.push(fan_figures(&received, &flood, window));
        source.stop();
    }
    let mut rows = vec![
        Row::new(
            GROUP,
            "latency per consumer".into(),
            figures[0].0.map(Figure::Latency),
            figures[1].0.map(Figure::Latency),
        ),
        Row::new(
            GROUP,
            "CPU, all nine processes".into(),
            Some(cpu_figure(figures[0].1)),
            Some(cpu_figure(figures[1].1)),
        ),
    ];
    if let Some(dora) = &peers::peers().dora {
        let (latency, cpu) = dora_fan_out(dora, CONSUMERS, &consumer_args, window)?;
        let group = "fan-out, dora-rs vs peppy: 1 producer, 8 consumer processes, 1 MiB at 30 Hz";
        rows.push(
            Row::new(
                group,
                "latency per consumer".into(),
                latency.map(Figure::Latency),
                figures[1].0.map(Figure::Latency),
            )
            .against(DORA_NAME),
        );
        rows.push(
            Row::new(
                group,
                "CPU, all nine processes".into(),
                Some(cpu_figure(cpu)),
                Some(cpu_figure(figures[1].1)),
            )
            .against(DORA_NAME)
            .with_note("dora's own process (daemon) not counted"),
        );
    }
    Ok(rows)
}

fn cpu_figure(value: f64) -> Figure {
    Figure::Value {
        value,
        unit: "% of one core".into(),
    }
}

/// A fan-out's figures from its consumers' reports and its producer's:
/// the median consumer's p50 with the worst p99 and max, and the CPU of
/// all the processes over the window (% of one core).
fn fan_figures(received: &[Value], flood: &Value, window: f64) -> (Option<Spread>, f64) {
    let (mut latency, mut samples, mut cpu_s) = (None::<Spread>, Vec::new(), 0.0);
    for r in received {
        if let Some(s) = spread(&r["spread"]) {
            samples.push(s.p50);
            latency = Some(match latency {
                Some(m) if m.max >= s.max => Spread { max: m.max, ..m },
                _ => s,
            });
        }
        cpu_s += r["cpu_ms"].as_f64().unwrap_or(0.0) / 1e3;
    }
    let (src_cpu, src_secs) = (
        flood["flood"]["cpu_ms"].as_f64().unwrap_or(0.0) / 1e3,
        flood["flood"]["secs"].as_f64().unwrap_or(1.0),
    );
    let cpu = 100.0 * (cpu_s / window + src_cpu / src_secs);
    if let (Some(l), Some(a)) = (latency.as_mut(), Spread::of(&mut samples)) {
        l.p50 = a.p50;
    }
    (latency, cpu)
}

/// The fan-out as a dora dataflow: a source node and `consumers` sink
/// nodes, each told the same flags as the benchmark's consumers.
fn dora_fan_out(
    dora: &peers::Dora,
    consumers: usize,
    consumer_args: &dyn Fn(Vec<String>, usize) -> Vec<String>,
    window: f64,
) -> Res<(Option<Spread>, f64)> {
    let mut nodes = vec![DoraNode {
        id: "source".into(),
        sink: false,
        inputs: vec![(
            "flood".into(),
            format!("sink_{}/flood", consumers - 1),
            None,
        )],
        outputs: vec!["pong".into(), "stream".into()],
        args: Some(Vec::new()),
    }];
    for id in 0..consumers {
        nodes.push(DoraNode {
            id: format!("sink_{id}"),
            sink: true,
            inputs: vec![("stream".into(), "source/stream".into(), None)],
            outputs: if id == consumers - 1 {
                vec!["flood".into()]
            } else {
                Vec::new()
            },
            args: Some(consumer_args(vec!["fan-out".into()], id)),
        });
    }
    let mut run = dora.run(&nodes)?;
    let mut take = |id: &str| {
        run.nodes
            .remove(id)
            .ok_or_else(|| format!("dora node {id} never linked"))
    };
    let mut source = take("source")?;
    let mut sinks = Vec::new();
    for id in 0..consumers {
        let mut c = take(&format!("sink_{id}"))?;
        c.next_with("ready", Duration::from_secs(30))?;
        sinks.push(c);
    }
    // As the benchmark's trigger does: a second for every subscription to
    // be matched, then the producer starts.
    std::thread::sleep(Duration::from_secs(1));
    sinks[consumers - 1].say("go")?;
    let mut received = Vec::new();
    for c in &mut sinks {
        received.push(c.next_with("received", BOUND)?);
    }
    let flood = source.next_with("flood", Duration::from_secs(30))?;
    run.nodes.insert("source".into(), source);
    for (id, c) in sinks.into_iter().enumerate() {
        run.nodes.insert(format!("sink_{id}"), c);
    }
    run.stop();
    Ok(fan_figures(&received, &flood, window))
}

/// A pinned service call against a raw query and queryable; an action's
/// goal to result against the same raw query.
pub(crate) fn services(quick: bool) -> Res<Vec<Row>> {
    // A call takes a quarter of a millisecond: eight rounds of 500 calls,
    // the two systems taking turns every 50 (`in_turns`).
    let (count, rounds) = if quick { (100, 1) } else { (4000, 8) };
    let got = in_turns(
        &[RAW_SHM, PEPPY_SHM],
        rounds,
        1,
        |source| {
            let mut args = source.args("service");
            args.extend(["--count".into(), (count / rounds).to_string()]);
            args
        },
        |_| {},
        |_, mode, sink| {
            let mut got = vec![sink.next_with("service", BOUND)?["service"].clone()];
            if mode.system == System::Peppy {
                got.push(sink.next_with("action", BOUND)?["action"].clone());
            }
            Ok(got)
        },
    )?;
    let median = |runs: Option<&Vec<Value>>| median_spread(runs.into_iter().flatten());
    let service = [median(got[0].first()), median(got[1].first())];
    let action = median(got[1].get(1));
    Ok(vec![
        Row::new(
            "services and actions (64 B)",
            "pinned service call vs raw get".into(),
            service[0].map(Figure::Latency),
            service[1].map(Figure::Latency),
        ),
        Row::new(
            "services and actions (64 B)",
            "action goal to result vs raw get".into(),
            service[0].map(Figure::Latency),
            action.map(Figure::Latency),
        )
        .with_note("a goal is two requests: the goal, then its result"),
    ])
}
