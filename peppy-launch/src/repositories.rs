//! The repositories a command searches, and `repo add/list/remove/refresh`.
//!
//! After a command line's `--repo` folders, `PEPPY_REPOSITORIES` and the
//! nearest `peppy_repositories.json5`, every command searches the user's
//! own list (`repositories.json5` in peppy's configuration directory). A
//! user without one gets the default list, PeppyOS's public hubs. Git
//! repositories are read from the cache the git sources of launchers use
//! (one mirror per repository, one tree per commit); the user's and the
//! default list are fetched by `repo add` and `repo refresh` only, so no
//! other command reaches the network for them.

use std::path::{Path, PathBuf};

use peppy_schema::{
    DocumentKind, GitRepository, ListedBy, ListedRepository, RepoIndex, RepoOptions,
    RepositoryEntry, RepositoryList, SourceFile,
};

use crate::cli::{RepoAddArgs, RepoListArgs, RepoRefreshArgs, RepoRemoveArgs};
use crate::error::{LaunchError, Result, SetupError, UsageError};
use crate::sources::{Fetcher, RepoFetch};

/// Overrides peppy's configuration directory (tests, shared machines).
pub(crate) const CONFIG_ENV: &str = "PEPPY_CONFIG_DIR";

/// The default list, used while the user has none of their own.
const DEFAULTS: &str = include_str!("../assets/default_repositories.json5");

/// What the default list is called where it is shown.
const DEFAULTS_NAME: &str = "<default repositories>";

/// peppy's configuration directory: `PEPPY_CONFIG_DIR`, else
/// `$XDG_CONFIG_HOME/peppy`, else `~/.config/peppy`.
pub(crate) fn config_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(CONFIG_ENV).filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    std::env::var_os("XDG_CONFIG_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))
        .unwrap_or_else(std::env::temp_dir)
        .join("peppy")
}

/// The user's repository list.
pub(crate) fn user_list_path() -> PathBuf {
    config_dir().join("repositories.json5")
}

/// Why the user's repository list cannot be used or changed.
#[derive(Debug, thiserror::Error)]
pub enum RepoListError {
    /// The list is not a valid repository list.
    #[error("{} is not a valid repository list", path.display())]
    Invalid {
        /// The list.
        path: PathBuf,
        /// What is wrong with it, located.
        diagnostics: peppy_schema::Diagnostics,
    },
    /// `repo remove` names no repository of the list.
    #[error("no repository of {list} is `{name}` (it has: {})", known.join(", "))]
    NotListed {
        /// What was named.
        name: String,
        /// Which list.
        list: String,
        /// The repositories it has.
        known: Vec<String>,
    },
    /// `repo add` names a repository the list has already.
    #[error("{list} lists `{name}` already")]
    AlreadyListed {
        /// What was named.
        name: String,
        /// Which list.
        list: String,
    },
    /// The list cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The list.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A git repository `repo add` was to fetch cannot be had.
    #[error("cannot fetch `{name}`: {source}")]
    Fetch {
        /// The repository.
        name: String,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// `repo refresh` could fetch some repositories neither now nor
    /// before.
    #[error("{count} git repositories could not be fetched (named above)")]
    Unfetched {
        /// How many.
        count: usize,
    },
}

impl From<RepoListError> for LaunchError {
    fn from(e: RepoListError) -> Self {
        match e {
            RepoListError::Invalid { diagnostics, .. } => {
                crate::report::print_human(&diagnostics);
                LaunchError::Invalid {
                    errors: diagnostics.error_count(),
                }
            }
            RepoListError::Write { .. } => LaunchError::Setup(SetupError::RepoList(e)),
            RepoListError::Fetch { .. } | RepoListError::Unfetched { .. } => {
                LaunchError::Setup(SetupError::RepoList(e))
            }
            other => LaunchError::Usage(UsageError::RepoList(other)),
        }
    }
}

/// The user's list as it stands: its file's entries, or the defaults when
/// there is no file.
fn user_list() -> std::result::Result<(Vec<RepositoryEntry>, ListedBy), RepoListError> {
    let path = user_list_path();
    if path.is_file() {
        let (doc, _) = peppy_schema::RepositoriesDoc::load(&path).map_err(|diagnostics| {
            RepoListError::Invalid {
                path: path.clone(),
                diagnostics,
            }
        })?;
        return Ok((doc.entries, ListedBy::File(path)));
    }
    Ok((defaults(), ListedBy::Defaults))
}

/// The default list's entries.
fn defaults() -> Vec<RepositoryEntry> {
    let file = SourceFile::new(DEFAULTS_NAME, DEFAULTS);
    match peppy_schema::parse_as(&file, "", DocumentKind::Repositories) {
        Ok((peppy_schema::Document::Repositories(doc), _)) => doc.entries,
        // The default list is part of this program and tested below.
        _ => Vec::new(),
    }
}

/// The repository options of a command given `--repo` folders `explicit`:
/// the user's list (or the defaults) searched last.
pub(crate) fn options(explicit: Vec<PathBuf>) -> std::result::Result<RepoOptions, RepoListError> {
    let (entries, by) = user_list()?;
    Ok(RepoOptions {
        explicit,
        env: None,
        last: entries.into_iter().map(|e| (e, by.clone())).collect(),
    })
}

/// The index of every repository a command given `--repo` folders
/// `explicit` searches from `start`: git repositories fetched as their
/// lists allow ([`Fetcher`]), what could not be had printed as warnings.
pub(crate) fn index(
    explicit: &[PathBuf],
    start: &Path,
) -> std::result::Result<RepoIndex, peppy_schema::Diagnostics> {
    let options = options(explicit.to_vec()).map_err(|e| match e {
        RepoListError::Invalid { diagnostics, .. } => diagnostics,
        other => peppy_schema::Diagnostics::from(peppy_schema::Diagnostic::error(
            peppy_schema::Code::InvalidValue,
            other.to_string(),
        )),
    })?;
    let mut list = options.discover(start)?;
    if list.unfetched().next().is_some() {
        let warnings = list.fetch_git(&Fetcher::new());
        if !warnings.is_empty() {
            crate::report::print_human(&warnings);
        }
    }
    Ok(RepoIndex::of(&list))
}

/// Every repository a command run here with `--repo` folders `explicit`
/// searches, not fetched.
fn searched_here(explicit: &[PathBuf]) -> Result<RepositoryList> {
    let cwd = std::env::current_dir().unwrap_or_default();
    options(explicit.to_vec())?.discover(&cwd).map_err(|diags| {
        crate::report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })
}

/// `repo list`: every repository a command run here searches, in order,
/// who listed it and what it holds.
pub(crate) fn list(args: &RepoListArgs) -> Result {
    let mut repositories = searched_here(&args.repos)?;
    let fetcher = Fetcher::new();
    // Listing reads the cache; it never fetches.
    for listed in &mut repositories.listed {
        if let RepositoryEntry::Git(git) = &listed.entry
            && let Ok(Some(f)) = fetcher.git_repository(git, RepoFetch::CachedOnly)
        {
            listed.local = Some(f.tree);
        }
    }
    if repositories.listed.is_empty() {
        println!(
            "no repositories (the user's list {} is empty)",
            user_list_path().display()
        );
        return Ok(());
    }
    for (n, listed) in repositories.listed.iter().enumerate() {
        println!("{}. {}", n + 1, describe(listed));
        println!("   listed by {}", listed.by);
        println!("   {}", contents(listed));
    }
    Ok(())
}

fn describe(listed: &ListedRepository) -> String {
    match &listed.entry {
        RepositoryEntry::Folder(p) => format!("{} (folder)", p.display()),
        RepositoryEntry::Git(g) => format!("{} ({})", g.short_name(), g.describe()),
    }
}

/// What a repository holds, or why it is not there.
fn contents(listed: &ListedRepository) -> String {
    let Some(local) = &listed.local else {
        return "not fetched yet (`peppy-launch repo refresh` fetches it)".to_string();
    };
    if !local.is_dir() {
        return format!("{} is not a folder; skipped", local.display());
    }
    let index = RepoIndex::scan(std::slice::from_ref(local));
    let at = match &listed.entry {
        RepositoryEntry::Git(_) => format!(
            " at commit {}",
            local
                .file_name()
                .map(|c| c.to_string_lossy().chars().take(12).collect::<String>())
                .unwrap_or_default()
        ),
        RepositoryEntry::Folder(_) => String::new(),
    };
    format!(
        "{} nodes, {} contracts, {} launchers{at}",
        index.node_ids().count(),
        index.interface_ids().count(),
        index.launcher_names().count()
    )
}

/// `repo add LOCATION`: a folder, or a git repository (fetched now, so a
/// wrong URL or ref is said at once), appended to the user's list.
pub(crate) fn add(args: &RepoAddArgs) -> Result {
    let (mut entries, _) = user_list()?;
    let folder = Path::new(&args.location);
    let entry = if args.reference.is_none() && folder.is_dir() && !is_git(&args.location) {
        RepositoryEntry::Folder(
            std::fs::canonicalize(folder).unwrap_or_else(|_| folder.to_path_buf()),
        )
    } else {
        let git = GitRepository {
            url: git_url(&args.location),
            reference: args.reference.clone(),
            loc: Default::default(),
        };
        let fetch_error = |source: Box<dyn std::error::Error + Send + Sync>| RepoListError::Fetch {
            name: git.describe(),
            source,
        };
        // A refresh always reaches for the repository: `None` is only
        // what a read of the cache alone gives.
        let fetched = Fetcher::new()
            .git_repository(&git, RepoFetch::Refresh)
            .map_err(|e| fetch_error(e.into()))?
            .ok_or_else(|| fetch_error("nothing was fetched".into()))?;
        println!(
            "peppy-launch: fetched {} ({}): commit {}",
            git.short_name(),
            git.describe(),
            fetched.commit
        );
        RepositoryEntry::Git(git)
    };
    let name = key(&entry);
    if entries.iter().any(|e| key(e) == name) {
        return Err(RepoListError::AlreadyListed {
            name,
            list: user_list_path().display().to_string(),
        }
        .into());
    }
    entries.push(entry);
    write_user_list(&entries)?;
    println!(
        "peppy-launch: added `{name}` to {}",
        user_list_path().display()
    );
    Ok(())
}

/// Whether `repo add LOCATION` means a git repository: a URL, a name
/// ending in `.git`, or a bare repository's folder. Any other folder is a
/// folder repository (a work tree included: its files as they are now).
fn is_git(location: &str) -> bool {
    let path = Path::new(location);
    location.contains("://")
        || location.trim_end_matches('/').ends_with(".git")
        || (path.join("HEAD").is_file() && path.join("objects").is_dir())
}

/// A local path given to `repo add` as a git repository (a bare
/// repository's folder, say) is kept absolute, so the list means the same
/// from any directory.
fn git_url(location: &str) -> String {
    let path = Path::new(location);
    if !location.contains("://") && path.exists() {
        return std::fs::canonicalize(path)
            .unwrap_or_else(|_| path.to_path_buf())
            .display()
            .to_string();
    }
    location.to_string()
}

/// How an entry is named and matched by `repo add` and `repo remove`.
fn key(entry: &RepositoryEntry) -> String {
    match entry {
        RepositoryEntry::Folder(p) => p.display().to_string(),
        RepositoryEntry::Git(g) => g.describe(),
    }
}

/// `repo remove NAME...`: takes repositories off the user's list (a
/// default one too: the list is then the defaults without it). NAME is a
/// git repository's short name (`nodes-hub`) or URL, or a folder.
pub(crate) fn remove(args: &RepoRemoveArgs) -> Result {
    let (mut entries, _) = user_list()?;
    if args.all {
        entries.clear();
    }
    for name in &args.names {
        let folder = std::fs::canonicalize(name).ok();
        let matches = |e: &RepositoryEntry| match e {
            RepositoryEntry::Git(g) => {
                g.short_name() == name || g.url == *name || g.describe() == *name
            }
            RepositoryEntry::Folder(p) => {
                Path::new(name) == p || folder.as_deref() == Some(p.as_path())
            }
        };
        let before = entries.len();
        entries.retain(|e| !matches(e));
        if entries.len() == before {
            return Err(RepoListError::NotListed {
                name: name.clone(),
                list: user_list_path().display().to_string(),
                known: entries.iter().map(short).collect(),
            }
            .into());
        }
    }
    write_user_list(&entries)?;
    println!(
        "peppy-launch: {} now lists {} repositories",
        user_list_path().display(),
        entries.len()
    );
    Ok(())
}

fn short(entry: &RepositoryEntry) -> String {
    match entry {
        RepositoryEntry::Folder(p) => p.display().to_string(),
        RepositoryEntry::Git(g) => g.short_name().to_string(),
    }
}

/// `repo refresh`: asks every git repository a command run here would
/// search for its branches and tags, and says which commit each is now
/// read at. One that cannot be reached keeps its cached copy (and says
/// so); one with no cached copy fails the command, naming it.
pub(crate) fn refresh(args: &RepoRefreshArgs) -> Result {
    let repositories = searched_here(&args.repos)?;
    let fetcher = Fetcher::new();
    let mut failed = 0;
    let mut seen = 0;
    for listed in &repositories.listed {
        let RepositoryEntry::Git(git) = &listed.entry else {
            continue;
        };
        seen += 1;
        let name = git.short_name();
        match fetcher.git_repository(git, RepoFetch::Refresh) {
            Ok(Some(f)) => match f.stale {
                None => println!("{name}: {} is commit {}", reference(git), f.commit),
                Some(why) => println!(
                    "{name}: cannot reach {} ({why}); keeping the cached commit {}",
                    git.url, f.commit
                ),
            },
            Ok(None) => {}
            Err(e) => {
                failed += 1;
                eprintln!(
                    "peppy-launch: cannot fetch {name} ({}): {e}",
                    git.describe()
                );
            }
        }
    }
    if seen == 0 {
        println!("no git repositories to refresh");
    }
    if failed > 0 {
        return Err(RepoListError::Unfetched { count: failed }.into());
    }
    Ok(())
}

fn reference(git: &GitRepository) -> String {
    match &git.reference {
        Some(r) => format!("`{r}`"),
        None => "the default branch".to_string(),
    }
}

/// Writes the user's list (atomically: a half-written list is never read).
fn write_user_list(entries: &[RepositoryEntry]) -> std::result::Result<(), RepoListError> {
    let path = user_list_path();
    let write_error = |source| RepoListError::Write {
        path: path.clone(),
        source,
    };
    let mut text = String::from(
        "// The repositories peppy-launch searches after a project's own\n\
         // peppy_repositories.json5, in order. `peppy-launch repo add` and\n\
         // `repo remove` keep it; `repo list` shows every repository searched.\n[\n",
    );
    for entry in entries {
        match entry {
            RepositoryEntry::Folder(p) => {
                text.push_str(&format!(
                    "  {{ type: \"fs\", path: {} }},\n",
                    quoted(&p.display().to_string())
                ));
            }
            RepositoryEntry::Git(g) => {
                text.push_str(&format!("  {{ type: \"git\", url: {}", quoted(&g.url)));
                if let Some(r) = &g.reference {
                    text.push_str(&format!(", ref: {}", quoted(r)));
                }
                text.push_str(" },\n");
            }
        }
    }
    text.push_str("]\n");
    // What is written must read back as written.
    let check = SourceFile::new(path.clone(), text.clone());
    debug_assert!(peppy_schema::parse_as(&check, "", DocumentKind::Repositories).is_ok());
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(write_error)?;
    }
    let tmp = path.with_extension("json5.tmp");
    std::fs::write(&tmp, text).map_err(write_error)?;
    std::fs::rename(&tmp, &path).map_err(write_error)?;
    Ok(())
}

/// A JSON string literal (JSON5 reads JSON's).
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| format!("{s:?}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_list_reads_and_names_the_public_hubs() {
        let names: Vec<String> = defaults().iter().map(short).collect();
        assert_eq!(
            names,
            [
                "nodes-hub",
                "launchers-hub",
                "openarm-nodes",
                "contracts-hub"
            ]
        );
    }
}
