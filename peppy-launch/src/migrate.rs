//! `peppy-launch migrate FILE... [--write]`: each file rewritten in the
//! slashed spelling by peppy-schema's writer ([`peppy_schema::migrate`]),
//! printed or written in place.

use std::path::PathBuf;

use peppy_schema::migrate::{Outcome, migrate_file};

use crate::cli::MigrateArgs;
use crate::error::{LaunchError, Result};

/// `peppy-launch migrate`: every file is migrated from the originals before
/// any is written, so a launcher is planned against its nodes as they were.
pub(crate) fn run(args: &MigrateArgs) -> Result {
    let options = crate::repositories::options(args.repos.clone())?;
    let outcomes: Vec<(PathBuf, Outcome)> = args
        .files
        .iter()
        .map(|p| {
            let file = peppy_schema::node_file(p);
            let o = migrate_file(&file, &options);
            (file, o)
        })
        .collect();
    let mut failed = 0;
    for (path, outcome) in outcomes {
        let shown = path.display();
        match outcome {
            Outcome::AlreadySlashed(kind) => {
                eprintln!("{shown}: already in the slashed spelling ({kind}): left alone")
            }
            Outcome::Unreadable(why) => {
                failed += 1;
                eprintln!("{shown}: not migrated: {why}");
            }
            Outcome::Migrated { text, notes } => {
                for n in &notes {
                    match n.at {
                        Some((l, c)) => eprintln!("{shown}:{l}:{c}: not carried: {}", n.message),
                        None => eprintln!("{shown}: not carried: {}", n.message),
                    }
                }
                if args.write {
                    if let Err(e) = std::fs::write(&path, &text) {
                        failed += 1;
                        eprintln!("{shown}: cannot write: {e}");
                    } else {
                        eprintln!("{shown}: rewritten in the slashed spelling");
                    }
                } else {
                    if args.files.len() > 1 {
                        println!("// {shown}");
                    }
                    print!("{text}");
                    if !text.ends_with('\n') {
                        println!();
                    }
                }
            }
        }
    }
    if failed == 0 {
        Ok(())
    } else {
        Err(LaunchError::Invalid { errors: failed })
    }
}
