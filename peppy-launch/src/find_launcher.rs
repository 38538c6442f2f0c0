//! A launcher named on the command line: a path, or a bare name (its file
//! stem) found through the repositories, the way `run` finds a node by
//! `name:tag`: `--repo` directories first, then `PEPPY_REPOSITORIES`, then
//! the nearest `peppy_repositories.json5` above the working directory. A
//! repository with a `peppy_repository.json5` is read through its
//! `launchers` section, one without by its files.

use std::path::{Path, PathBuf};

use peppy_schema::{Diagnostics, LauncherLookup};

/// Why a LAUNCHER argument names no launcher.
#[derive(Debug, thiserror::Error)]
pub enum LauncherLookupError {
    /// The repositories list cannot be read.
    #[error("cannot look launcher `{name}` up: the repositories list is invalid")]
    Repositories {
        /// The name given.
        name: String,
        /// What is wrong with the list.
        diagnostics: Diagnostics,
    },
    /// No single launcher answers to the name.
    #[error(transparent)]
    Lookup(#[from] LauncherLookup),
    /// `peppy-launch WORD` where WORD is neither a command nor a launcher.
    #[error("`{word}` is no command, and {lookup}{}", match nearest {
        Some(c) => format!("; did you mean `peppy-launch {c}`?"),
        None => " (`peppy-launch --help` lists the commands)".to_string(),
    })]
    NotACommand {
        /// The word given.
        word: String,
        /// The command closest to it, if one is close.
        nearest: Option<String>,
        /// Why no launcher answers to it.
        lookup: Box<LauncherLookup>,
    },
}

/// `error` of a word written where a command goes (`peppy-launch WORD`):
/// when no launcher has that name either, it says so, with the nearest of
/// `commands`.
pub(crate) fn maybe_a_command(
    error: LauncherLookupError,
    commands: &[String],
) -> LauncherLookupError {
    match error {
        LauncherLookupError::Lookup(LauncherLookup::NotFound {
            name,
            suggestion,
            searched,
        }) => LauncherLookupError::NotACommand {
            nearest: peppy_schema::did_you_mean(&name, commands.iter().map(String::as_str))
                .map(str::to_string),
            word: name.clone(),
            lookup: Box::new(LauncherLookup::NotFound {
                name,
                suggestion,
                searched,
            }),
        },
        other => other,
    }
}

/// Whether `arg` is a launcher's name rather than a path: it is no file or
/// directory, and it is a bare name (no `/`, no `.json5`).
pub(crate) fn is_name(arg: &Path) -> bool {
    !arg.exists()
        && arg
            .to_str()
            .is_some_and(|s| peppy_schema::names::check_name(s).is_ok())
}

/// The launcher file `arg` means: `arg` itself when it is a path (a
/// missing file is its reader's to report), else the one launcher of that
/// name in the repositories.
pub(crate) fn locate(arg: &Path, repos: &[PathBuf]) -> Result<PathBuf, LauncherLookupError> {
    let mut repos = repos.to_vec();
    locate_searching(arg, &mut repos)
}

/// [`locate`], for a command that goes on to read the launcher's nodes: a
/// launcher found by name has them looked up where it was found, so every
/// repository searched (git repositories' trees among them) is added to
/// `repos`, after the ones given.
pub(crate) fn locate_searching(
    arg: &Path,
    repos: &mut Vec<PathBuf>,
) -> Result<PathBuf, LauncherLookupError> {
    if !is_name(arg) {
        return Ok(arg.to_path_buf());
    }
    let name = arg.to_string_lossy().into_owned();
    let cwd = std::env::current_dir().unwrap_or_default();
    let index = crate::repositories::index(repos, &cwd).map_err(|diagnostics| {
        crate::report::print_human(&diagnostics);
        LauncherLookupError::Repositories {
            name: name.clone(),
            diagnostics,
        }
    })?;
    let found = index.find_launcher(&name).map(Path::to_path_buf)?;
    for searched in index.repositories() {
        if !repos.contains(searched) {
            repos.push(searched.clone());
        }
    }
    Ok(found)
}
