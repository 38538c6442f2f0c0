//! Command-line interface.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Validate, check and (soon) run stacks of peppy nodes.
#[derive(Debug, Parser)]
#[command(name = "peppy-launch", version, about, long_about = None)]
pub(crate) struct Cli {
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
