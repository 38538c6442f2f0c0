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
}

const RAW_TCP: Mode = Mode {
    system: System::Zenoh,
    shm: false,
    zenoh_defaults: false,
    in_place: false,
};
const PEPPY_TCP: Mode = Mode {
    system: System::Peppy,
    shm: false,
    zenoh_defaults: false,
    in_place: false,
};
const RAW_SHM: Mode = Mode {
    system: System::Zenoh,
    shm: true,
    zenoh_defaults: false,
    in_place: false,
};
const PEPPY_SHM: Mode = Mode {
    system: System::Peppy,
    shm: true,
    zenoh_defaults: false,
    in_place: false,
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
};

/// Like for like (raw first in the pair, first to run in every other
/// round): both over TCP, then both with shared memory.
const PAIRS: [(Mode, Mode); 2] = [(RAW_TCP, PEPPY_TCP), (RAW_SHM, PEPPY_SHM)];

fn transport(shm: bool) -> &'static str {
    if shm { "shared memory" } else { "TCP, SHM off" }
}

/// A running source process and where to reach it.
struct Source {
    proc: Proc,
    ns: String,
    endpoint: String,
    mode: Mode,
}

impl Source {
    fn start(mode: Mode, case: &str) -> Res<Source> {
        let port = free_port()?;
        let ns = format!("{case}-{}-{port}", std::process::id());
        let endpoint = format!("tcp/127.0.0.1:{port}");
        let mut proc = Proc::child(&place_args("source", mode, &ns, &endpoint))?;
        proc.next_with("ready", Duration::from_secs(30))?;
        Ok(Source {
            proc,
            ns,
            endpoint,
            mode,
        })
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
        let modes = [
            RAW_TCP,
            PEPPY_TCP,
            RAW_SHM,
            PEPPY_SHM,
            RAW_TCP_DEFAULTS,
            RAW_SHM_IN_PLACE,
            PEPPY_SHM_IN_PLACE,
        ];
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
        let cases = [
            ("topic round trip, TCP (SHM off both sides)", 0, 1),
            ("topic round trip, shared memory both sides", 2, 3),
            (
                "topic round trip, shared memory, read in place (a camera consumer's way)",
                5,
                6,
            ),
            ("topic round trip, peppy with SHM vs raw over TCP", 0, 3),
            (
                "topic round trip, raw Zenoh on its default threads vs peppy (TCP)",
                4,
                1,
            ),
        ];
        for (group, z, p) in cases {
            for ((zs, zlost, bytes), (ps, plost, _)) in got[z].iter().zip(&got[p]) {
                let mut row = Row::new(
                    group,
                    format!("{} {}", qos.name(), size(*bytes)),
                    zs.map(Figure::Latency),
                    ps.map(Figure::Latency),
                );
                if zlost + plost > 0 {
                    row = row.with_note(format!("unanswered in 2 s: raw {zlost}, peppy {plost}"));
                }
                rows.push(row);
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
            "topic round trip, TCP",
            "topic round trip, shared memory both",
            "topic round trip, shared memory, read",
            MACHINE,
            "topic round trip, peppy",
            "topic round trip, raw",
        ]
        .iter()
        .position(|g| r.group.starts_with(g))
    });
    Ok(rows)
}

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
    for (raw, peppy) in PAIRS {
        let got = in_rounds(&[raw, peppy], rounds(quick), |mode| {
            let source = Source::start(mode, "tp")?;
            let mut args = source.args("throughput");
            let list: Vec<String> = cases.iter().map(|(s, c)| format!("{s}:{c}")).collect();
            args.extend(["--cases".into(), list.join(",")]);
            let mut sink = Proc::child(&args)?;
            let mut got = Vec::new();
            for _ in 0..cases.len() {
                got.push(sink.next_with("msgs_per_s", BOUND)?);
            }
            sink.wait_or_kill(Duration::from_secs(10));
            source.proc.stop();
            Ok(got)
        })?;
        let group = format!(
            "topic throughput (reliable, one to one, {})",
            transport(raw.shm)
        );
        rows.extend(got[0].iter().zip(&got[1]).map(|(z, p)| {
            let bytes = z[0]["size"].as_u64().unwrap_or(0) as usize;
            let mut row = Row::new(&group, size(bytes), Some(rate(z)), Some(rate(p)));
            let short = |runs: &[Value]| -> u64 {
                runs.iter()
                    .map(|v| v["sent"].as_u64().unwrap_or(0) - v["received"].as_u64().unwrap_or(0))
                    .sum()
            };
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
            let source = Source::start(mode, "turns")?;
            let mut args = sink_args(&source);
            args.extend(["--turns".into(), TURNS.to_string()]);
            let sink = Proc::child(&args)?;
            sides.push((source, sink));
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
            source.proc.stop();
        }
    }
    Ok(got)
}

/// One producer, eight consumer processes, 1 MiB frames at 30 Hz, both
/// with shared memory (each system's default on one host).
pub(crate) fn fan_out(quick: bool) -> Res<Vec<Row>> {
    const CONSUMERS: usize = 8;
    let (warmup, frames) = (30u64, if quick { 60u64 } else { 150 });
    let mut rows = Vec::new();
    let mut latency: [Option<Spread>; 2] = [None, None];
    let mut cpu: [f64; 2] = [0.0; 2];
    for (i, mode) in [RAW_SHM, PEPPY_SHM].into_iter().enumerate() {
        let mut source = Source::start(mode, "fan")?;
        let mut consumers = Vec::new();
        for id in 0..CONSUMERS {
            let mut args = source.args("fan-out");
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
            // The last consumer starts the producer, once all are ready.
            if id == CONSUMERS - 1 {
                args.push("--trigger".into());
            }
            let mut c = Proc::child(&args)?;
            c.next_with("ready", Duration::from_secs(30))?;
            consumers.push(c);
        }
        let mut samples = Vec::new();
        let window = frames as f64 / 30.0;
        let mut cpu_s = 0.0;
        for mut c in consumers {
            let r = c.next_with("received", BOUND)?;
            if let Some(s) = spread(&r["spread"]) {
                // Per-consumer p50s: the spread across consumers.
                samples.push(s.p50);
                latency[i] = Some(match latency[i] {
                    Some(m) if m.max >= s.max => Spread { max: m.max, ..m },
                    _ => s,
                });
            }
            cpu_s += r["cpu_ms"].as_f64().unwrap_or(0.0) / 1e3;
            c.wait_or_kill(Duration::from_secs(10));
        }
        let flood = source.proc.next_with("flood", Duration::from_secs(30))?;
        let (src_cpu, src_secs) = (
            flood["flood"]["cpu_ms"].as_f64().unwrap_or(0.0) / 1e3,
            flood["flood"]["secs"].as_f64().unwrap_or(1.0),
        );
        cpu[i] = 100.0 * (cpu_s / window + src_cpu / src_secs);
        let all = Spread::of(&mut samples);
        if let (Some(l), Some(a)) = (latency[i].as_mut(), all) {
            // Report the median consumer's p50, the worst p99 and max.
            l.p50 = a.p50;
        }
        source.proc.stop();
    }
    rows.push(Row::new(
        "fan-out: 1 producer, 8 consumer processes, 1 MiB at 30 Hz",
        "latency per consumer".into(),
        latency[0].map(Figure::Latency),
        latency[1].map(Figure::Latency),
    ));
    rows.push(Row::new(
        "fan-out: 1 producer, 8 consumer processes, 1 MiB at 30 Hz",
        "CPU, all nine processes".into(),
        Some(Figure::Value {
            value: cpu[0],
            unit: "% of one core".into(),
        }),
        Some(Figure::Value {
            value: cpu[1],
            unit: "% of one core".into(),
        }),
    ));
    Ok(rows)
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
