//! What peppy-bench's dora-rs nodes share: the connection to the benchmark
//! (the dora daemon owns a node's stdin and stdout, so the nodes talk to
//! peppy-bench over a loopback socket it names in `PEPPY_BENCH_CONTROL`),
//! the message header, and percentiles computed as peppy-bench's own
//! (`peppy-bench/src/stats.rs`).

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::sync::mpsc::{Receiver, channel};
use std::time::{SystemTime, UNIX_EPOCH};

/// Errors of a benchmark node: reported, never recovered from.
pub type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// A node's line-based link to peppy-bench: JSON lines out, words in.
pub struct Control {
    out: TcpStream,
    lines: Receiver<String>,
}

impl Control {
    /// Connects to `PEPPY_BENCH_CONTROL` and says which node this is; the
    /// first line back is the node's arguments (a JSON array of strings).
    pub fn connect(node: &str) -> Res<(Control, Vec<String>)> {
        let addr = std::env::var("PEPPY_BENCH_CONTROL")
            .map_err(|_| "PEPPY_BENCH_CONTROL is not set: peppy-bench starts this node")?;
        let out = TcpStream::connect(&addr)?;
        out.set_nodelay(true)?;
        let input = out.try_clone()?;
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(input).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let mut control = Control { out, lines };
        control.say(&serde_json::json!({ "hello": node }));
        let args = control
            .word()
            .ok_or("peppy-bench closed the control link")?;
        let args: Vec<String> = serde_json::from_str(&args)?;
        Ok((control, args))
    }

    /// Sends one JSON line (a closed link is not this node's problem: the
    /// benchmark has gone, and dora stops the dataflow).
    pub fn say(&mut self, value: &serde_json::Value) {
        let _ = writeln!(self.out, "{value}").and_then(|()| self.out.flush());
    }

    /// The next line from peppy-bench; `None` once it closed the link.
    pub fn word(&mut self) -> Option<String> {
        self.lines.recv().ok()
    }
}

/// `--name VALUE` in `args`.
pub fn arg<'a>(args: &'a [String], name: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
}

/// Whether flag `name` is in `args`.
pub fn flag(args: &[String], name: &str) -> bool {
    args.iter().any(|a| a == name)
}

/// Nanoseconds since the epoch: comparable across processes of one host.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// CPU time this process has used (user + system), in milliseconds.
pub fn cpu_ms() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) * 10.0
}

/// Every message starts with its sequence number and its send time, as
/// peppy-bench's messages carry them (`seq`, `sent_ns`).
pub const HEADER: usize = 16;

/// Writes the header into the start of `buf`.
pub fn put_header(buf: &mut [u8], seq: u64, sent_ns: u64) {
    buf[..8].copy_from_slice(&seq.to_le_bytes());
    buf[8..16].copy_from_slice(&sent_ns.to_le_bytes());
}

/// Reads the header back; `None` if the message is too short.
pub fn header(buf: &[u8]) -> Option<(u64, u64)> {
    let seq = u64::from_le_bytes(buf.get(..8)?.try_into().ok()?);
    let sent = u64::from_le_bytes(buf.get(8..16)?.try_into().ok()?);
    Some((seq, sent))
}

/// p50, p99 and max of `samples` (µs) as peppy-bench's `Spread::of`
/// computes them, as the JSON it reads.
pub fn spread(samples: &mut [f64]) -> serde_json::Value {
    if samples.is_empty() {
        return serde_json::Value::Null;
    }
    samples.sort_by(f64::total_cmp);
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize];
    serde_json::json!({
        "p50": at(0.50),
        "p99": at(0.99),
        "max": samples[samples.len() - 1],
        "n": samples.len(),
    })
}
