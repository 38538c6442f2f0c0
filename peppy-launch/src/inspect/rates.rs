//! `topic hz` and `topic bw`: rate, period spread and bandwidth per
//! producer over a sliding window of the last messages.

use std::collections::{BTreeMap, VecDeque};
use std::io::IsTerminal as _;

use serde_json::json;
use tokio::time::Instant;

use super::Observer;
use super::nodes::table;
use super::print_json;
use super::stream::{Limits, Selection, Tap};
use crate::cli::{Format, RateArgs};
use crate::error::Result;
use crate::runs::now_ms;

/// What a report leads with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Measure {
    /// Messages per second and the spread of the period.
    Rate,
    /// Bytes per second and message sizes.
    Bandwidth,
}

/// The last messages of one producer: arrival times and sizes.
#[derive(Debug, Default)]
pub(crate) struct Window {
    samples: VecDeque<(Instant, usize)>,
    total: u64,
}

/// Statistics of one window.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Stats {
    /// Messages in the window.
    pub(crate) messages: usize,
    /// Messages per second.
    pub(crate) rate_hz: f64,
    /// Period min / mean / max / standard deviation, seconds.
    pub(crate) period: [f64; 4],
    /// Bytes per second.
    pub(crate) bytes_per_s: f64,
    /// Message size min / mean / max, bytes.
    pub(crate) size: [f64; 3],
}

impl Window {
    pub(crate) fn push(&mut self, at: Instant, bytes: usize, limit: usize) {
        self.samples.push_back((at, bytes));
        self.total += 1;
        while self.samples.len() > limit.max(2) {
            self.samples.pop_front();
        }
    }

    /// `None` until two messages arrived.
    pub(crate) fn stats(&self) -> Option<Stats> {
        let n = self.samples.len();
        if n < 2 {
            return None;
        }
        let first = self.samples.front()?.0;
        let last = self.samples.back()?.0;
        let span = last.duration_since(first).as_secs_f64();
        let periods: Vec<f64> = self
            .samples
            .iter()
            .zip(self.samples.iter().skip(1))
            .map(|(a, b)| b.0.duration_since(a.0).as_secs_f64())
            .collect();
        let mean = span / periods.len() as f64;
        let var = periods.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / periods.len() as f64;
        let (pmin, pmax) = min_max(periods.iter().copied());
        let sizes = self.samples.iter().map(|s| s.1 as f64);
        let (smin, smax) = min_max(sizes.clone());
        let bytes: f64 = sizes.sum();
        // The first message's bytes arrived before the span started.
        let carried = bytes - self.samples.front()?.1 as f64;
        Some(Stats {
            messages: n,
            rate_hz: if span > 0.0 {
                periods.len() as f64 / span
            } else {
                0.0
            },
            period: [pmin, mean, pmax, var.sqrt()],
            bytes_per_s: if span > 0.0 { carried / span } else { 0.0 },
            size: [smin, bytes / n as f64, smax],
        })
    }
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

/// `199.8 Hz`, `1.52 kHz`.
pub(crate) fn hz(rate: f64) -> String {
    if rate >= 1000.0 {
        format!("{:.2} kHz", rate / 1000.0)
    } else {
        format!("{rate:.1} Hz")
    }
}

/// `3.2 ms`, `850 µs`, `1.20 s`.
pub(crate) fn seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 1e-3 {
        format!("{:.1} ms", s * 1e3)
    } else {
        format!("{:.0} µs", s * 1e6)
    }
}

/// `921.6 kB`, `27.65 MB`, in SI units (per second when `per_s`).
pub(crate) fn bytes(b: f64, per_s: bool) -> String {
    let unit = if per_s { "/s" } else { "" };
    match b {
        b if b >= 1e9 => format!("{:.2} GB{unit}", b / 1e9),
        b if b >= 1e6 => format!("{:.2} MB{unit}", b / 1e6),
        b if b >= 1e3 => format!("{:.1} kB{unit}", b / 1e3),
        b => format!("{b:.0} B{unit}"),
    }
}

fn report_rows(measure: Measure, windows: &BTreeMap<String, Window>) -> Vec<Vec<String>> {
    windows
        .iter()
        .map(|(producer, w)| {
            let mut row = vec![producer.clone()];
            match (w.stats(), measure) {
                (None, _) => row.push(format!("waiting ({} message so far)", w.total)),
                (Some(s), Measure::Rate) => row.extend([
                    hz(s.rate_hz),
                    seconds(s.period[0]),
                    seconds(s.period[2]),
                    seconds(s.period[3]),
                    s.messages.to_string(),
                ]),
                (Some(s), Measure::Bandwidth) => row.extend([
                    bytes(s.bytes_per_s, true),
                    bytes(s.size[1], false),
                    bytes(s.size[0], false),
                    bytes(s.size[2], false),
                    s.messages.to_string(),
                ]),
            }
            row
        })
        .collect()
}

fn header(measure: Measure) -> [&'static str; 6] {
    match measure {
        Measure::Rate => [
            "PRODUCER",
            "RATE",
            "MIN PERIOD",
            "MAX PERIOD",
            "STD",
            "WINDOW",
        ],
        Measure::Bandwidth => ["PRODUCER", "BANDWIDTH", "MEAN SIZE", "MIN", "MAX", "WINDOW"],
    }
}

fn report_json(topic: &str, windows: &BTreeMap<String, Window>) -> serde_json::Value {
    let producers: Vec<_> = windows
        .iter()
        .map(|(producer, w)| match w.stats() {
            None => json!({ "instance": producer, "messages": w.total }),
            Some(s) => json!({
                "instance": producer,
                "window": s.messages,
                "rate_hz": s.rate_hz,
                "period_s": { "min": s.period[0], "mean": s.period[1], "max": s.period[2], "std": s.period[3] },
                "bytes_per_s": s.bytes_per_s,
                "size_bytes": { "min": s.size[0], "mean": s.size[1], "max": s.size[2] },
            }),
        })
        .collect();
    json!({ "topic": topic, "at_ms": now_ms(), "producers": producers })
}

pub(crate) async fn run(args: RateArgs, measure: Measure) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_some().await?;
    let mut selection = Selection::new(&args.select, &observer.reach.namespace, &all)?;
    let tap = Tap::of(&observer, &selection, false).await?;
    let limits = Limits::new(&args.stream);
    let live = args.format == Format::Human && std::io::stdout().is_terminal();
    let mut windows: BTreeMap<String, Window> = BTreeMap::new();
    let mut tick = tokio::time::interval_at(Instant::now() + args.interval, args.interval);
    let (mut reports, mut drawn_lines) = (0u64, 0usize);
    while !limits.reached(reports) {
        tokio::select! {
            r = tap.next(&limits) => match r {
                Some(r) => {
                    selection.learn(&observer, &r.sender).await;
                    if selection.keeps(&r.sender, r.fingerprint) {
                        windows
                            .entry(r.sender.instance.clone())
                            .or_default()
                            .push(r.at, r.size, args.window);
                    }
                }
                None => break,
            },
            _ = tick.tick() => {
                reports += 1;
                if args.format == Format::Json {
                    print_json(&report_json(&selection.topic, &windows));
                    continue;
                }
                let text = if windows.is_empty() {
                    format!("no message on `{}` yet\n", selection.topic)
                } else {
                    table(&header(measure), &report_rows(measure, &windows))
                };
                if live && drawn_lines > 0 {
                    // Redraw in place: up over the last report, clear below.
                    print!("\x1b[{drawn_lines}A\x1b[J");
                }
                print!("{text}");
                if !live {
                    println!();
                }
                drawn_lines = text.lines().count();
            }
        }
    }
    limits.outcome(reports, "reports")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_steady_stream_reports_its_rate_and_bandwidth() {
        let start = Instant::now();
        let mut w = Window::default();
        for i in 0..11u64 {
            w.push(start + Duration::from_millis(100 * i), 1000, 1000);
        }
        let s = w.stats().unwrap();
        assert_eq!(s.messages, 11);
        assert!((s.rate_hz - 10.0).abs() < 1e-9, "{s:?}");
        assert!((s.period[1] - 0.1).abs() < 1e-9 && s.period[3] < 1e-9);
        assert!((s.bytes_per_s - 10_000.0).abs() < 1e-6);
        assert_eq!(hz(s.rate_hz), "10.0 Hz");
    }

    #[test]
    fn the_window_keeps_the_last_messages() {
        let start = Instant::now();
        let mut w = Window::default();
        w.push(start, 1, 3);
        assert!(w.stats().is_none());
        for i in 1..10u64 {
            w.push(start + Duration::from_millis(10 * i), 1, 3);
        }
        assert_eq!(w.stats().unwrap().messages, 3);
        assert_eq!(w.total, 10);
    }

    #[test]
    fn units_read_naturally() {
        assert_eq!(hz(199.84), "199.8 Hz");
        assert_eq!(hz(1520.0), "1.52 kHz");
        assert_eq!(seconds(0.0032), "3.2 ms");
        assert_eq!(seconds(0.00085), "850 µs");
        assert_eq!(bytes(921_600.0, false), "921.6 kB");
        assert_eq!(bytes(27_648_000.0, true), "27.65 MB/s");
    }
}
