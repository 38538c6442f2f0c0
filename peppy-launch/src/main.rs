//! `peppy-launch`: validate peppy documents, check a launcher end to end,
//! and run its stack. See `peppy-launch --help`.

use std::process::ExitCode;

use clap::Parser;
use peppy_launch::{Cli, run, with_default_command};

fn main() -> ExitCode {
    let cli = Cli::parse_from(with_default_command(std::env::args_os().collect()));
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if !e.already_reported() {
                eprintln!("peppy-launch: {e}");
            }
            ExitCode::from(e.exit_code())
        }
    }
}
