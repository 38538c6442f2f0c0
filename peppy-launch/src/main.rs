//! `peppy-launch`: validate peppy documents, check a launcher end to end and
//! print its binding plan. See `peppy-launch --help`.

mod check;
mod cli;
mod report;
mod validate;

use std::process::ExitCode;

use clap::Parser;

/// Exit codes (SPEC 6.4): 0 valid / clean, 1 a run failed, 2 usage or
/// document errors.
pub(crate) mod exit {
    /// Everything valid.
    pub(crate) const OK: u8 = 0;
    /// A document, binding or command line is invalid.
    pub(crate) const INVALID: u8 = 2;
}

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    let code = match cli.command {
        cli::Command::Validate(args) => validate::run(&args),
        cli::Command::Check(args) => check::run(&args),
    };
    ExitCode::from(code)
}
