//! What a person sees while `up` builds a node: how many of its build units
//! cargo has compiled out of how many, what it is compiling, and the time
//! taken. A bar redrawn in place on a terminal; when stderr is piped (a
//! log, CI), a plain line now and then, so a long build is never minutes of
//! silence either way.
//!
//! The counts are cargo's own: asked to draw its progress bar even into a
//! pipe (`CARGO_TERM_PROGRESS_WHEN=always`), cargo writes
//! `Building [===>  ] 57/257: zenoh-transport, …` lines to stderr, which
//! the build reader hands to [`BuildProgress::units`].

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The environment that makes cargo report its progress into a pipe.
pub(crate) const CARGO_PROGRESS_ENV: [(&str, &str); 2] = [
    ("CARGO_TERM_PROGRESS_WHEN", "always"),
    // Wide enough that the unit names are rarely cut short.
    ("CARGO_TERM_PROGRESS_WIDTH", "400"),
];

/// How often a piped build prints a line while it progresses.
const PLAIN_EVERY: Duration = Duration::from_secs(20);

/// The progress display of one node's build.
pub(crate) struct BuildProgress {
    /// The node, as the build line names it (`realsense_d405:v1 (1/3)`).
    label: String,
    started: Instant,
    /// The bar, on a terminal only.
    bar: Option<ProgressBar>,
    /// When the last plain line went out (piped output).
    last_line: Mutex<Instant>,
}

impl BuildProgress {
    /// Starts showing the build of `label`: a bar when stderr is a
    /// terminal, else plain lines.
    pub(crate) fn start(label: String) -> BuildProgress {
        let terminal = std::io::stderr().is_terminal();
        Self::with_terminal(label, terminal)
    }

    fn with_terminal(label: String, terminal: bool) -> BuildProgress {
        let bar = terminal.then(|| {
            let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
            bar.set_style(spinner_style());
            bar.set_prefix(label.clone());
            bar.enable_steady_tick(Duration::from_millis(200));
            bar
        });
        let started = Instant::now();
        BuildProgress {
            label,
            started,
            bar,
            last_line: Mutex::new(started),
        }
    }

    /// Cargo has finished `done` of `total` units and is compiling `current`.
    pub(crate) fn units(&self, done: u64, total: u64, current: &str) {
        match &self.bar {
            Some(bar) => {
                if bar.length() != Some(total) {
                    bar.set_style(bar_style());
                    bar.set_length(total);
                }
                bar.set_position(done);
                bar.set_message(current.to_string());
            }
            None => {
                let mut last = self.last_line.lock().unwrap_or_else(|p| p.into_inner());
                if last.elapsed() >= PLAIN_EVERY {
                    *last = Instant::now();
                    eprintln!(
                        "peppy-launch: building {}: {done}/{total} units compiled, {} ({current})",
                        self.label,
                        clock(self.started.elapsed())
                    );
                }
            }
        }
    }

    /// The build ended (`ok` or not): clears the bar and says how long it
    /// took.
    pub(crate) fn finish(self, ok: bool) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        let took = clock(self.started.elapsed());
        if ok {
            eprintln!("peppy-launch: built {} in {took}", self.label);
        } else {
            eprintln!(
                "peppy-launch: the build of {} failed after {took}",
                self.label
            );
        }
    }
}

fn spinner_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} building {prefix} · {elapsed}")
        .expect("a valid template")
}

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template(
        "building {prefix} [{bar:24}] {pos}/{len} units · {elapsed} · {wide_msg}",
    )
    .expect("a valid template")
    .progress_chars("=> ")
}

/// `1m05s`, `42s`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 60 {
        format!("{}m{:02}s", s / 60, s % 60)
    } else {
        format!("{s}s")
    }
}

/// Reads one of cargo's progress lines, `Building [==> ] 57/257: a, b`:
/// `(57, 257, "a, b")`. Any other line is `None`.
pub(crate) fn parse_cargo_progress(line: &str) -> Option<(u64, u64, &str)> {
    let rest = line.trim_start().strip_prefix("Building [")?;
    let (_, counts) = rest.split_once("] ")?;
    let (counts, current) = counts.split_once(':').unwrap_or((counts, ""));
    let (done, total) = counts.trim().split_once('/')?;
    Some((done.parse().ok()?, total.parse().ok()?, current.trim()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cargo_progress_lines_give_counts_and_what_is_compiling() {
        assert_eq!(
            parse_cargo_progress(
                "    Building [=============>               ] 57/257: zenoh-transport, peppy(build)   "
            ),
            Some((57, 257, "zenoh-transport, peppy(build)"))
        );
        assert_eq!(
            parse_cargo_progress("    Building [     ] 0/2"),
            Some((0, 2, ""))
        );
        for other in [
            "   Compiling itoa v1.0.19",
            "    Building [==] many/2: x",
            "    Finished `dev` profile",
            "",
        ] {
            assert_eq!(parse_cargo_progress(other), None, "{other:?}");
        }
    }

    #[test]
    fn durations_read_like_a_clock() {
        assert_eq!(clock(Duration::from_secs(42)), "42s");
        assert_eq!(clock(Duration::from_secs(65)), "1m05s");
    }

    #[test]
    fn a_piped_build_draws_no_bar() {
        let p = BuildProgress::with_terminal("x:v1 (1/1)".into(), false);
        assert!(p.bar.is_none());
        p.units(1, 2, "x");
        p.finish(true);
    }
}
