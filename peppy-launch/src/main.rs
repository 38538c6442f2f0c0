//! `peppy-launch`: validate peppy documents, check a launcher end to end and
//! print its binding plan. See `peppy-launch --help`.

mod check;
mod cli;
mod graph;
mod output;
mod report;
mod run_node;
mod supervise;
mod up;
mod validate;

use std::process::ExitCode;

use clap::Parser;

/// Exit codes (SPEC 6.4): 0 valid / clean, 1 a run failed, 2 usage or
/// document errors.
pub(crate) mod exit {
    /// Everything valid, or a clean stop.
    pub(crate) const OK: u8 = 0;
    /// A build or an instance failed, or a restart budget ran out.
    pub(crate) const FAILED: u8 = 1;
    /// A document, binding or command line is invalid.
    pub(crate) const INVALID: u8 = 2;
}

fn main() -> ExitCode {
    let cli = cli::Cli::parse_from(with_default_command(std::env::args_os().collect()));
    let code = match cli.command {
        cli::Command::Validate(args) => validate::run(&args),
        cli::Command::Check(args) => check::run(&args),
        cli::Command::Up(args) => up::run(&args),
        cli::Command::Graph(args) => graph::run(&args),
        cli::Command::Run(args) => run_node::run(&args),
    };
    ExitCode::from(code)
}

/// `peppy-launch LAUNCHER ...` means `peppy-launch up LAUNCHER ...`.
fn with_default_command(mut args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    const COMMANDS: &[&str] = &["validate", "check", "up", "run", "graph", "help"];
    if let Some(first) = args.get(1).and_then(|a| a.to_str())
        && !first.starts_with('-')
        && !COMMANDS.contains(&first)
    {
        args.insert(1, "up".into());
    }
    args
}
