//! `peppy-launch repo index DIR [--check]`: write a repository's
//! `peppy_repository.json5`, or check the committed one. What goes in the
//! index and how drift is found is peppy-schema's ([`declared_in`],
//! [`check_index`]); this prints it and writes the file.

use std::io::Write as _;
use std::path::Path;

use peppy_schema::{
    Composition, DeclaredIndex, Diagnostics, IndexSection, REPOSITORY_INDEX_FILE, check_index,
    declared_in,
};

use crate::cli::{RepoCommand, RepoIndexArgs};
use crate::error::{LaunchError, Result, SetupError};
use crate::report;

pub(crate) fn run(cmd: &RepoCommand) -> Result {
    match cmd {
        RepoCommand::Index(args) => index(args),
        RepoCommand::List(args) => crate::repositories::list(args),
        RepoCommand::Add(args) => crate::repositories::add(args),
        RepoCommand::Remove(args) => crate::repositories::remove(args),
        RepoCommand::Refresh(args) => crate::repositories::refresh(args),
    }
}

fn index(args: &RepoIndexArgs) -> Result {
    if args.check {
        check(&args.dir)
    } else {
        write(&args.dir)
    }
}

/// Prints the findings and turns errors into the command's failure.
fn invalid(diags: Diagnostics) -> LaunchError {
    report::print_human(&diags);
    LaunchError::Invalid {
        errors: diags.error_count(),
    }
}

fn write(dir: &Path) -> Result {
    let (declared, warnings) = declared_in(dir).map_err(invalid)?;
    if !warnings.is_empty() {
        report::print_human(&warnings);
    }
    let path = dir.join(REPOSITORY_INDEX_FILE);
    let text = declared.render();
    // Unchanged content is not rewritten, so the file's time stays.
    if std::fs::read(&path).is_ok_and(|old| old == text.as_bytes()) {
        println!("{}: up to date ({})", path.display(), counts(&declared));
        return Ok(());
    }
    write_atomically(&path, &text).map_err(|source| SetupError::Write {
        path: path.clone(),
        source,
    })?;
    println!("wrote {} ({})", path.display(), counts(&declared));
    Ok(())
}

/// Writes `text` to a temporary file beside `path` and renames it over
/// `path`, so a reader sees the old index or the new one, never half.
fn write_atomically(path: &Path, text: &str) -> std::io::Result<()> {
    let tmp = path.with_file_name(format!(
        ".{REPOSITORY_INDEX_FILE}.{}.tmp",
        std::process::id()
    ));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn check(dir: &Path) -> Result {
    let (found, warnings) = check_index(dir).map_err(invalid)?;
    if !warnings.is_empty() {
        report::print_human(&warnings);
    }
    let path = dir.join(REPOSITORY_INDEX_FILE);
    composition_checks(dir, &found.declared)?;
    if found.is_current() {
        println!(
            "{}: up to date ({})",
            path.display(),
            counts(&found.declared)
        );
        return Ok(());
    }
    let mut out = String::new();
    if found.index.is_none() {
        out.push_str(&format!("{} does not exist\n", path.display()));
    } else {
        out.push_str(&format!(
            "{} is out of date: {}\n",
            path.display(),
            report::count(found.drifts.len(), "drift")
        ));
    }
    for drift in &found.drifts {
        out.push_str(&format!("  {drift}\n"));
    }
    out.push_str(&format!(
        "Run `peppy-launch repo index {}` and commit the result.\n",
        dir.display()
    ));
    let _ = std::io::stderr().write_all(out.as_bytes());
    Err(LaunchError::Invalid {
        errors: found.drifts.len().max(1),
    })
}

/// Holds every composed launcher the repository declares to the checks of
/// [`Composition::check`]: fragments load, the default selection is legal,
/// every legal selection composes, every constraint refuses something,
/// every option is reachable, at most 512 selections.
fn composition_checks(dir: &Path, declared: &DeclaredIndex) -> Result {
    let mut problems = Diagnostics::new();
    let (mut composed, mut selections, mut refused) = (0, 0, 0);
    for (key, path) in &declared.entries {
        if key.section != IndexSection::Launchers {
            continue;
        }
        // Only composed launchers: a flat one's own validity is `validate`'s
        // and `check`'s business, not the index's.
        let file = dir.join(path);
        let has_keys = peppy_schema::SourceFile::read(&file)
            .ok()
            .and_then(|(f, _)| peppy_schema::json::parse(&f).ok())
            .is_some_and(|(root, _)| {
                ["components", "adjustments", "constraints"]
                    .iter()
                    .any(|k| root.get(k).is_some())
            });
        if !has_keys {
            continue;
        }
        match Composition::load(&file) {
            Ok(c) if c.is_composed() => {
                let found = c.check();
                composed += 1;
                selections += found.selections;
                refused += found.refused;
                problems.extend(found.problems);
            }
            Ok(_) => {}
            Err(e) => problems.extend(e),
        }
    }
    if problems.has_errors() {
        return Err(invalid(problems));
    }
    if composed > 0 {
        println!(
            "composed launchers: {composed}, {selections} selections ({refused} refused by their constraints), each checked"
        );
    }
    Ok(())
}

/// `21 nodes, 1 launcher`, or `nothing listed`.
fn counts(declared: &DeclaredIndex) -> String {
    let parts: Vec<String> = IndexSection::ALL
        .iter()
        .map(|&s| (s, declared.count(s)))
        .filter(|(_, n)| *n > 0)
        .map(|(s, n)| report::count(n, s.noun()))
        .collect();
    if parts.is_empty() {
        "nothing listed".to_string()
    } else {
        parts.join(", ")
    }
}
