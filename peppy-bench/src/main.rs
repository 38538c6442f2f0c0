//! `peppy-bench`: peppy next to raw Zenoh and its peers (dora-rs, and the
//! hand-off floor on iceoryx2: `peers.rs`) doing the same work between
//! real processes on this machine, in one run, reported as ratios (peppy /
//! the other) with p50, p99 and max; then what a person waits for:
//! launching a stack and building a node. The table is printed and
//! written as JSON.
//!
//! Run it in release: `cargo run --release -p peppy-bench`
//! (docs/PERFORMANCE.md explains every figure).

#[peppy::node("nodes/source/peppy.json5")]
mod source_node {}

#[peppy::node("nodes/sink/peppy.json5")]
mod sink_node {}

mod build_times;
mod children;
mod floor;
mod launch;
mod peers;
mod peppy_side;
mod procs;
mod raw_side;
mod recording;
mod roles;
mod stats;
mod transport;

use std::path::{Path, PathBuf};

use clap::{Parser, ValueEnum};

use crate::stats::Row;

/// Measure peppy against raw Zenoh between processes, and what launching
/// and building cost.
#[derive(Debug, Parser)]
#[command(name = "peppy-bench", version)]
struct Cli {
    /// Only these groups (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    only: Vec<Group>,
    /// Fewer samples: a quick look, not a figure to record.
    #[arg(long)]
    quick: bool,
    /// Which peers to set up and measure beside peppy and raw Zenoh
    /// (default: all; `none` for peppy's own figures on a machine where
    /// the peers are not built yet).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [peers::Peer::Dora, peers::Peer::Floor, peers::Peer::Python])]
    peers: Vec<peers::Peer>,
    /// Run the whole table this many times, the groups taking turns, and
    /// report each figure's median run with its range over the runs (on a
    /// small shared machine one run moves 10 to 20 %).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=99))]
    runs: u32,
    /// Where the JSON results go (default: target/peppy-bench.json in the
    /// workspace).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// One of the benchmark's own processes (started by it, not by hand).
    #[command(hide = true)]
    Child {
        #[command(subcommand)]
        role: children::Child,
    },
}

/// A group of figures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Group {
    /// Topic round trips, 64 B to 4 MiB, `reliable` and `sensor_data`.
    Roundtrip,
    /// Small round trips over each link on one host: loopback TCP, a
    /// Unix socket, Zenoh's low-latency transport.
    Links,
    /// One producer to one consumer, as fast as it goes.
    Throughput,
    /// One producer, eight consumer processes, 1 MiB at 30 Hz.
    Fanout,
    /// A pinned service call against a raw query; an action's goal to
    /// result.
    Service,
    /// `up --no-build` to the first message; an idle node's memory.
    Launch,
    /// Code generation and cargo builds of an example node.
    Build,
    /// `peppy-launch record` on three 1 MiB cameras at 30 Hz.
    Record,
}

/// Measures one group (`true`: quickly).
type Measure = fn(bool) -> roles::Res<Vec<Row>>;

/// The cargo to build examples with: the one running this benchmark
/// (`cargo run` says which, with the toolchain rustup chose for it), else
/// rustup's on `PATH`. Not the path of the cargo this binary was compiled
/// by: run without rustup's word on the toolchain, it leaves `rustc` to
/// rustup's proxy, which then follows a dependency's own
/// `rust-toolchain.toml` (one pins a release that may not be installed).
pub(crate) fn cargo() -> std::ffi::OsString {
    std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into())
}

/// The workspace root (the benchmark builds and launches its examples).
pub(crate) fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace root")
        .to_path_buf()
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    peers::choose(&cli.peers);
    if let Some(Command::Child { role }) = cli.command {
        return children::run(role);
    }
    if cfg!(debug_assertions) {
        eprintln!(
            "peppy-bench: this is a debug build; figures are only meaningful from `cargo run --release -p peppy-bench`"
        );
    }
    let wanted = |g| cli.only.is_empty() || cli.only.contains(&g);
    let mut runs: Vec<Vec<Row>> = Vec::new();
    let mut failures = Vec::new();
    let groups: [(Group, Measure); 8] = [
        (Group::Roundtrip, transport::round_trips),
        (Group::Links, transport::links),
        (Group::Throughput, transport::throughput),
        (Group::Fanout, transport::fan_out),
        (Group::Service, transport::services),
        (Group::Launch, launch::launch),
        (Group::Build, build_times::build),
        (Group::Record, recording::record),
    ];
    for run in 1..=cli.runs {
        let mut rows = Vec::new();
        for (group, measure) in groups {
            if !wanted(group) {
                continue;
            }
            if cli.runs > 1 {
                eprintln!(
                    "peppy-bench: run {run} of {}: measuring {group:?}…",
                    cli.runs
                );
            } else {
                eprintln!("peppy-bench: measuring {group:?}…");
            }
            match measure(cli.quick) {
                Ok(mut r) => {
                    eprint!("{}", stats::render(&r));
                    rows.append(&mut r);
                }
                Err(e) => {
                    eprintln!("peppy-bench: {group:?} failed: {e}");
                    failures.push(format!("run {run}, {group:?}: {e}"));
                }
            }
        }
        runs.push(rows);
    }
    let rows = stats::median_run(runs);
    println!("{}", machine_line());
    print!("{}", stats::render(&rows));
    let out = cli
        .out
        .unwrap_or_else(|| workspace().join("target").join("peppy-bench.json"));
    let json = serde_json::json!({
        "machine": machine_line(),
        "quick": cli.quick,
        "runs": cli.runs,
        "release": !cfg!(debug_assertions),
        "rows": rows,
        "failures": failures,
    });
    let written = out
        .parent()
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| std::fs::write(&out, serde_json::to_string_pretty(&json).expect("json")));
    match written {
        Ok(()) => println!("\nresults: {}", out.display()),
        Err(e) => eprintln!("peppy-bench: cannot write {}: {e}", out.display()),
    }
    if failures.is_empty() {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}

/// The machine, in one line: CPU model, cores, kernel.
fn machine_line() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find_map(|l| l.strip_prefix("model name"))
        .map(|m| m.trim_start_matches([' ', '\t', ':']).to_string())
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
    format!("machine: {model}, {cores} cores, Linux {}", kernel.trim())
}
