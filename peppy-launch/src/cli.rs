//! Command-line interface.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Validate, check and run stacks of peppy nodes.
#[derive(Debug, Parser)]
#[command(name = "peppy-launch", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Debug, Subcommand)]
pub(crate) enum Command {
    /// Validate peppy documents (nodes, interfaces, launchers, repository
    /// lists). A directory means every document in it, recursively.
    ///
    /// Exit code 0 when every document is valid, 2 otherwise.
    Validate(ValidateArgs),
    /// Check a launcher end to end: resolve every deployment's node through
    /// its source and the repositories, resolve every node, check every
    /// binding rule and parameter, and print the binding plan.
    ///
    /// Exit code 0 when the stack is valid, 2 otherwise.
    Check(CheckArgs),
    /// Run a launcher: check everything (start nothing if anything is
    /// wrong), build each node once, start every instance with its
    /// bindings, parameters, namespace and Zenoh endpoints, multiplex their
    /// output, supervise, and stop cleanly on Ctrl-C.
    ///
    /// `peppy-launch LAUNCHER` is the same. Exit codes: 0 clean stop,
    /// 1 an instance failed (or its restart budget ran out), 2 invalid.
    Up(UpArgs),
    /// Run one node (a `name:tag` from the repositories, or a path) with
    /// the same checks of its bindings and parameters as a launcher, e.g.
    /// `peppy-launch run video_reconstruction:v1 --instance-id rec_1 --bind rear_camera@cam_1`.
    /// Without `--connect` it joins (or hosts) the local hub on
    /// tcp/127.0.0.1:7447, so several `run`s find each other.
    Run(RunArgs),
    /// Print the stack as Graphviz DOT: instances, bindings, dashed `(any)`
    /// edges for unbound from_any slots, dotted edges for external topics.
    Graph(GraphArgs),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Format {
    /// Rendered diagnostics with source snippets.
    Human,
    /// One JSON object on stdout.
    Json,
}

#[derive(Debug, Args)]
pub(crate) struct ValidateArgs {
    /// Files or directories to validate.
    #[arg(required = true, value_name = "PATH")]
    pub(crate) paths: Vec<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct CheckArgs {
    /// The launcher file.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// An extra repository directory, searched before PEPPY_REPOSITORIES and
    /// the nearest peppy_repositories.json5 (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct UpArgs {
    /// The launcher file.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Skip the nodes' build commands.
    #[arg(long)]
    pub(crate) no_build: bool,
    /// The namespace to run in (default: derived from the launcher path).
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    /// Where the launch's Zenoh router listens (repeatable; default a free
    /// loopback port). Listen on a LAN address to let other hosts join.
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) listen: Vec<String>,
    /// Another router or peer to connect to, e.g. a zenohd or another
    /// host's launch (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
    /// Seconds between SIGINT and SIGTERM when stopping.
    #[arg(long, value_name = "SECONDS", default_value = "5", value_parser = parse_grace)]
    pub(crate) grace: Duration,
}

#[derive(Debug, Args)]
pub(crate) struct GraphArgs {
    /// The launcher file.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct RunArgs {
    /// The node: `name:tag` from the repositories, or a path.
    #[arg(value_name = "NODE")]
    pub(crate) node: String,
    /// The instance id (default: a readable random id).
    #[arg(long, value_name = "ID")]
    pub(crate) instance_id: Option<String>,
    /// Bind a slot: `--bind left_cam@rs_left` (repeatable).
    #[arg(long = "bind", value_name = "KEY@INSTANCE")]
    pub(crate) bind: Vec<String>,
    /// Parameter values, `key=value` (dot-paths for groups).
    #[arg(value_name = "KEY=VALUE")]
    pub(crate) overrides: Vec<String>,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// The namespace to join (default: `default`).
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    /// Endpoints to connect to (e.g. a launch's router).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
    /// Endpoints for the node to listen on.
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) listen: Vec<String>,
    /// Skip the node's build command.
    #[arg(long)]
    pub(crate) no_build: bool,
    /// Seconds between SIGINT and SIGTERM when stopping.
    #[arg(long, value_name = "SECONDS", default_value = "5", value_parser = parse_grace)]
    pub(crate) grace: Duration,
}

/// The longest grace period accepted: an hour is already longer than any
/// node should need to stop.
const MAX_GRACE_SECONDS: f64 = 3600.0;

/// `--grace`: a finite number of seconds from 0 to an hour.
fn parse_grace(s: &str) -> Result<Duration, String> {
    let seconds: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if !seconds.is_finite() || !(0.0..=MAX_GRACE_SECONDS).contains(&seconds) {
        return Err(format!(
            "`{s}` is out of range: give seconds from 0 to {MAX_GRACE_SECONDS}"
        ));
    }
    Ok(Duration::from_secs_f64(seconds))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grace_takes_finite_seconds_in_range() {
        assert_eq!(parse_grace("1.5"), Ok(Duration::from_millis(1500)));
        assert_eq!(parse_grace("0"), Ok(Duration::ZERO));
        for bad in ["-1", "NaN", "inf", "-inf", "1e300", "soon", ""] {
            assert!(parse_grace(bad).is_err(), "{bad}");
        }
    }
}
