//! `peppy-launch resolve LAUNCHER [--with ...] [--list]`: the flat launcher
//! a selection of a composed launcher gives, and what composing it did.

use std::io::Write as _;

use peppy_schema::{Composition, Diagnostics, stack_rules};

use crate::cli::ResolveArgs;
use crate::error::{LaunchError, Result};
use crate::report;

fn invalid(diags: Diagnostics) -> LaunchError {
    report::print_human(&diags);
    LaunchError::Invalid {
        errors: diags.error_count(),
    }
}

pub(crate) fn run(args: &ResolveArgs) -> Result {
    let composition = Composition::load(&args.launcher).map_err(invalid)?;
    if args.list {
        return list(&composition);
    }
    let selection = composition.select(&args.with).map_err(invalid)?;
    let resolved = composition.resolve(&selection).map_err(invalid)?;
    // The flat launcher must stand on its own: the rules of a whole stack
    // (unique instance ids, link targets that exist) hold on it too.
    let mut problems = resolved.warnings.clone();
    problems.extend(stack_rules(&resolved.launcher));
    if problems.has_errors() {
        return Err(invalid(problems));
    }
    if !problems.is_empty() {
        report::print_human(&problems);
    }
    let mut err = std::io::stderr().lock();
    for line in resolved.report.lines() {
        let _ = writeln!(err, "{line}");
    }
    print!("{}", resolved.text);
    Ok(())
}

/// Every selection, one per line as `--with` words; refused ones say which
/// constraint refuses them and why.
fn list(composition: &Composition) -> Result {
    let verdicts = composition.selections().map_err(invalid)?;
    let refused = verdicts.iter().filter(|v| v.refused_by.is_some()).count();
    for v in &verdicts {
        let words = if composition.is_composed() {
            v.selection.with_words()
        } else {
            "(flat launcher)".to_string()
        };
        match &v.refused_by {
            Some((i, reason)) => println!("{words}  refused by constraint {}: {reason}", i + 1),
            None => println!("{words}"),
        }
    }
    eprintln!(
        "{}, {refused} refused by constraints",
        report::count(verdicts.len(), "selection")
    );
    Ok(())
}
