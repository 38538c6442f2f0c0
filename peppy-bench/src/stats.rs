//! Figures: percentiles of a sample, the results table and its JSON.

use serde::{Deserialize, Serialize};

/// p50, p99 and max of a latency sample, in microseconds.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub(crate) struct Spread {
    pub(crate) p50: f64,
    pub(crate) p99: f64,
    pub(crate) max: f64,
    /// How many samples.
    pub(crate) n: usize,
}

impl Spread {
    /// The spread of `samples` (µs); `None` for an empty sample.
    pub(crate) fn of(samples: &mut [f64]) -> Option<Spread> {
        if samples.is_empty() {
            return None;
        }
        samples.sort_by(f64::total_cmp);
        let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize];
        Some(Spread {
            p50: at(0.50),
            p99: at(0.99),
            max: samples[samples.len() - 1],
            n: samples.len(),
        })
    }

    /// Rounds of one measurement taken as one: the median round's p50 and
    /// p99 (each taken separately), the largest max, every sample counted.
    pub(crate) fn median_of(rounds: &[Spread]) -> Option<Spread> {
        let median = |pick: fn(&Spread) -> f64| {
            let mut v: Vec<f64> = rounds.iter().map(pick).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        (!rounds.is_empty()).then(|| Spread {
            p50: median(|s| s.p50),
            p99: median(|s| s.p99),
            max: rounds.iter().map(|s| s.max).fold(0.0, f64::max),
            n: rounds.iter().map(|s| s.n).sum(),
        })
    }
}

/// One measured figure of one system.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub(crate) enum Figure {
    /// A latency spread (µs).
    Latency(Spread),
    /// A rate: messages per second and bytes per second.
    Rate { msgs_per_s: f64, bytes_per_s: f64 },
    /// A single quantity with its unit.
    Value { value: f64, unit: String },
}

impl Figure {
    /// The number a ratio compares: p50, the message rate, or the value.
    fn headline(&self) -> f64 {
        match self {
            Figure::Latency(s) => s.p50,
            Figure::Rate { msgs_per_s, .. } => *msgs_per_s,
            Figure::Value { value, .. } => *value,
        }
    }

    /// The unit of the headline, for a figure without a raw side.
    fn unit(&self) -> Option<&str> {
        match self {
            Figure::Latency(_) => Some("µs"),
            Figure::Rate { .. } => Some("msg/s"),
            Figure::Value { unit, .. } => Some(unit),
        }
    }

    fn text(&self) -> String {
        match self {
            Figure::Latency(s) => {
                format!("{} / {} / {}", micros(s.p50), micros(s.p99), micros(s.max))
            }
            Figure::Rate {
                msgs_per_s,
                bytes_per_s,
            } => format!(
                "{} msg/s, {:.2} GB/s",
                count(*msgs_per_s),
                bytes_per_s / 1e9
            ),
            Figure::Value { value, unit } => format!("{value:.1} {unit}"),
        }
    }
}

/// One row: a case measured on raw Zenoh and on peppy (either may be
/// missing: launch and build figures are peppy's alone).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Row {
    pub(crate) group: String,
    pub(crate) case: String,
    pub(crate) zenoh: Option<Figure>,
    pub(crate) peppy: Option<Figure>,
    /// peppy / raw Zenoh on the headline figure (p50, or message rate).
    pub(crate) ratio: Option<f64>,
    /// peppy / raw Zenoh at p99, for latencies.
    pub(crate) ratio_p99: Option<f64>,
    /// Anything the figures do not say (messages lost, a comparison base).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) note: Option<String>,
    /// Over several runs ([`median_run`]): how many, and the lowest and
    /// highest ratio (or peppy's figure, where there is no raw side).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) over_runs: Option<OverRuns>,
    /// What the left-hand figure (`zenoh`) measures when it is not raw
    /// Zenoh: a peer (`dora-rs`), the hand-off floor, or peppy itself
    /// another way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) base: Option<String>,
    /// What the right-hand figure (`peppy`) measures when it is not peppy
    /// as the record runs it (another link of peppy's, or raw Zenoh's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) subject: Option<String>,
}

/// How one figure moved over the runs of the whole table.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub(crate) struct OverRuns {
    pub(crate) runs: usize,
    pub(crate) lowest: f64,
    pub(crate) highest: f64,
}

impl Row {
    pub(crate) fn new(
        group: &str,
        case: String,
        zenoh: Option<Figure>,
        peppy: Option<Figure>,
    ) -> Row {
        let ratio = match (&zenoh, &peppy) {
            (Some(z), Some(p)) if z.headline() > 0.0 => Some(p.headline() / z.headline()),
            _ => None,
        };
        let ratio_p99 = match (&zenoh, &peppy) {
            (Some(Figure::Latency(z)), Some(Figure::Latency(p))) if z.p99 > 0.0 => {
                Some(p.p99 / z.p99)
            }
            _ => None,
        };
        Row {
            group: group.to_string(),
            case,
            zenoh,
            peppy,
            ratio,
            ratio_p99,
            note: None,
            over_runs: None,
            base: None,
            subject: None,
        }
    }

    /// The right-hand figure is `subject`'s, not peppy's as the record
    /// runs it.
    pub(crate) fn of(mut self, subject: &str) -> Row {
        self.subject = Some(subject.to_string());
        self
    }

    /// The left-hand figure is `base`'s, not raw Zenoh's.
    pub(crate) fn against(mut self, base: &str) -> Row {
        self.base = Some(base.to_string());
        self
    }

    pub(crate) fn with_note(mut self, note: impl Into<String>) -> Row {
        self.note = Some(note.into());
        self
    }
}

/// Several runs of the whole table taken as one, figure by figure: the run
/// whose ratio (or, without a raw side, whose peppy figure) is the median
/// (the upper middle one for an even count), with the range over the runs.
/// A figure on this machine moves 10 to 20 % from one run to the next,
/// more than some targets leave, so one run cannot say which side of a
/// target a figure is on.
pub(crate) fn median_run(runs: Vec<Vec<Row>>) -> Vec<Row> {
    let mut order: Vec<(String, String)> = Vec::new();
    let mut by_figure: std::collections::HashMap<(String, String), Vec<Row>> =
        std::collections::HashMap::new();
    for row in runs.into_iter().flatten() {
        let key = (row.group.clone(), row.case.clone());
        if !by_figure.contains_key(&key) {
            order.push(key.clone());
        }
        by_figure.entry(key).or_default().push(row);
    }
    let measure = |r: &Row| {
        r.ratio
            .or_else(|| r.peppy.as_ref().map(Figure::headline))
            .unwrap_or(f64::NAN)
    };
    order
        .into_iter()
        .filter_map(|key| {
            let mut rows = by_figure.remove(&key)?;
            if rows.len() < 2 {
                return rows.pop();
            }
            rows.sort_by(|a, b| measure(a).total_cmp(&measure(b)));
            let over = OverRuns {
                runs: rows.len(),
                lowest: measure(&rows[0]),
                highest: measure(&rows[rows.len() - 1]),
            };
            let mut row = rows.swap_remove(rows.len() / 2);
            row.over_runs = Some(over);
            Some(row)
        })
        .collect()
}

/// The table as people read it: one block per group.
pub(crate) fn render(rows: &[Row]) -> String {
    let mut out = String::new();
    let mut group = "";
    let cell = |f: &Option<Figure>| f.as_ref().map_or("-".to_string(), Figure::text);
    let width = rows.iter().map(|r| r.case.len()).max().unwrap_or(0).max(4);
    for r in rows {
        if r.group != group {
            group = &r.group;
            let latency = matches!(
                r.zenoh.as_ref().or(r.peppy.as_ref()),
                Some(Figure::Latency(_))
            );
            let what = if latency { "p50 / p99 / max" } else { "figure" };
            // The machine's own figures sit in the right-hand column.
            let who = if group == crate::transport::MACHINE {
                "measured"
            } else {
                r.subject.as_deref().unwrap_or("peppy")
            };
            let base = r.base.as_deref().unwrap_or("raw zenoh");
            let short = if base == "raw zenoh" { "raw" } else { base };
            out.push_str(&format!(
                "\n{group}\n  {:width$}  {:>30}  {:>30}  {:>13}\n",
                "case",
                format!("{base} {what}"),
                format!("{who} {what}"),
                format!("{} / {short}", r.subject.as_deref().unwrap_or("peppy"))
            ));
        }
        let ratio = match (r.ratio, r.ratio_p99) {
            (Some(a), Some(b)) => format!("×{a:.2} / ×{b:.2}"),
            (Some(a), None) => format!("×{a:.2}"),
            _ => "-".to_string(),
        };
        out.push_str(&format!(
            "  {:width$}  {:>30}  {:>30}  {:>13}",
            r.case,
            cell(&r.zenoh),
            cell(&r.peppy),
            ratio
        ));
        let over = r.over_runs.map(|o| {
            let unit = r.peppy.as_ref().and_then(Figure::unit);
            match (r.ratio, unit) {
                (Some(_), _) => format!("{} runs: ×{:.2} to ×{:.2}", o.runs, o.lowest, o.highest),
                (None, Some(unit)) => {
                    format!(
                        "{} runs: {:.1} to {:.1} {unit}",
                        o.runs, o.lowest, o.highest
                    )
                }
                (None, None) => format!("{} runs: {:.1} to {:.1}", o.runs, o.lowest, o.highest),
            }
        });
        let notes: Vec<&str> = [over.as_deref(), r.note.as_deref()]
            .into_iter()
            .flatten()
            .collect();
        if !notes.is_empty() {
            out.push_str(&format!("  ({})", notes.join("; ")));
        }
        out.push('\n');
    }
    out
}

/// `412 µs`, `3.41 ms`, `1.20 s`.
fn micros(us: f64) -> String {
    if us >= 1e6 {
        format!("{:.2} s", us / 1e6)
    } else if us >= 1e3 {
        format!("{:.2} ms", us / 1e3)
    } else {
        format!("{us:.0} µs")
    }
}

/// `1.23 M`, `45.6 k`, `812`.
fn count(n: f64) -> String {
    if n >= 1e6 {
        format!("{:.2} M", n / 1e6)
    } else if n >= 1e3 {
        format!("{:.1} k", n / 1e3)
    } else {
        format!("{n:.0}")
    }
}

/// `64 B`, `4 KiB`, `1 MiB`.
pub(crate) fn size(bytes: usize) -> String {
    if bytes >= 1 << 20 {
        format!("{} MiB", bytes >> 20)
    } else if bytes >= 1 << 10 {
        format!("{} KiB", bytes >> 10)
    } else {
        format!("{bytes} B")
    }
}

// Not in `cargo test --workspace` (the benchmark builds no test binary
// there, to keep CI's zenoh links few); `cargo test -p peppy-bench --bin
// peppy-bench` runs it.
#[cfg(test)]
mod tests {
    use super::*;

    fn latency(p50: f64) -> Option<Figure> {
        Some(Figure::Latency(Spread {
            p50,
            p99: p50 * 2.0,
            max: p50 * 3.0,
            n: 100,
        }))
    }

    fn value(v: f64) -> Option<Figure> {
        Some(Figure::Value {
            value: v,
            unit: "ms".into(),
        })
    }

    #[test]
    fn several_runs_give_each_figure_its_median_run_and_range() {
        let run = |raw: f64, peppy: f64, launch: f64| {
            vec![
                Row::new("rt", "64 B".into(), latency(raw), latency(peppy)),
                Row::new("launch", "first".into(), None, value(launch)),
            ]
        };
        let rows = median_run(vec![
            run(200.0, 260.0, 600.0),
            run(200.0, 200.0, 500.0),
            run(200.0, 220.0, 700.0),
        ]);
        assert_eq!(rows.len(), 2, "one row per figure, in the table's order");
        assert_eq!(
            (rows[0].group.as_str(), rows[1].group.as_str()),
            ("rt", "launch")
        );
        assert_eq!(rows[0].ratio, Some(1.1), "the median run's ratio");
        assert_eq!(
            rows[0].over_runs,
            Some(OverRuns {
                runs: 3,
                lowest: 1.0,
                highest: 1.3
            })
        );
        assert_eq!(rows[1].peppy, value(600.0));
        let table = render(&rows);
        assert!(table.contains("3 runs: ×1.00 to ×1.30"), "{table}");
        assert!(table.contains("3 runs: 500.0 to 700.0 ms"), "{table}");
        let one = median_run(vec![run(200.0, 260.0, 600.0)]);
        assert_eq!(one[0].over_runs, None, "a single run is shown as it is");
    }
}
