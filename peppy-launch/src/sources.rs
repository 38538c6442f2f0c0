//! Remote launcher sources (SPEC 6.2): `{ repo, path, ref }` from git and
//! `{ url, sha256 }` archives, fetched into a cache under the user's cache
//! directory, so a second launch (and one without a network) uses the copy.
//!
//! - git: one mirror per repository (`git clone --mirror`), one unpacked
//!   tree per commit. A full commit id is used as is (fetched only when the
//!   mirror lacks it); a branch or tag is fetched fresh when the remote
//!   answers, else read from the mirror, and the commit it names is
//!   printed.
//! - archives: downloaded (`file://` read directly, `http(s)://` by
//!   `curl`), refused unless the bytes have the launcher's sha256, then
//!   unpacked (`.tar`, `.tar.gz`) entry by entry: no absolute path, no `..`,
//!   no links, nothing but files and directories.

use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::process::Command;

use peppy_schema::Source;
use peppy_schema::{FetchSource, sha256_hex};

/// Overrides where fetched sources are cached (tests, shared caches).
pub(crate) const CACHE_ENV: &str = "PEPPY_CACHE_DIR";

/// peppy's directory under the user's cache directory: `PEPPY_CACHE_DIR`,
/// else `$XDG_CACHE_HOME/peppy`, else `~/.cache/peppy`.
pub(crate) fn cache_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(CACHE_ENV) {
        return PathBuf::from(dir);
    }
    std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir)
        .join("peppy")
}

/// Fetches remote sources into [`cache_dir`].
#[derive(Debug)]
pub(crate) struct Fetcher {
    cache: PathBuf,
    /// Repositories already asked for their refs by this fetcher: several
    /// deployments from one repository fetch it once per check.
    refreshed: std::sync::Mutex<std::collections::HashSet<String>>,
}

impl Fetcher {
    pub(crate) fn new() -> Fetcher {
        Fetcher {
            cache: cache_dir(),
            refreshed: Default::default(),
        }
    }

    /// `git fetch` of `repo`'s mirror, tried once per fetcher (a failure is
    /// reported to the first caller only).
    fn refresh(&self, repo: &str, mirror: &Path) -> Result<(), String> {
        if !self.first_time(repo) {
            return Ok(());
        }
        git(Some(mirror), &["fetch", "--quiet", "--prune", "origin"])
    }

    /// Whether `repo` is new to this fetcher (and now known).
    fn first_time(&self, repo: &str) -> bool {
        let mut done = self.refreshed.lock().unwrap_or_else(|p| p.into_inner());
        done.insert(repo.to_string())
    }
}

impl FetchSource for Fetcher {
    fn fetch(&self, source: &Source) -> Result<PathBuf, String> {
        match source {
            Source::Git {
                repo,
                path,
                reference,
            } => self.git(repo, path, reference),
            Source::Archive { url, sha256 } => self.archive(url, sha256),
            other => Err(format!("not a remote source: {other:?}")),
        }
    }
}

impl Fetcher {
    fn git(&self, repo: &str, sub: &str, reference: &str) -> Result<PathBuf, String> {
        let sub = relative(sub).ok_or_else(|| {
            format!("`path` `{sub}` must be relative to the repository, without `..`")
        })?;
        let mirror = self
            .cache
            .join("git")
            .join(format!("{}.git", &sha256_hex(repo.as_bytes())[..16]));
        if !mirror.join("HEAD").is_file() {
            let tmp = fresh(&mirror)?;
            git(
                None,
                &["clone", "--quiet", "--mirror", repo, &path_arg(&tmp)],
            )
            .map_err(|e| format!("cannot clone {repo}: {e}"))?;
            publish(&tmp, &mirror)?;
            // Just cloned: as fresh as a fetch would make it.
            self.first_time(repo);
        }
        let commit = if is_commit_id(reference) {
            if resolve(&mirror, reference).is_none() {
                // A commit the mirror has not seen yet: the remote may have it.
                let _ = self.refresh(repo, &mirror);
            }
            resolve(&mirror, reference)
                .ok_or_else(|| format!("commit {reference} is not in {repo}"))?
        } else {
            // A branch or tag moves: ask the remote, else use the mirror.
            if let Err(e) = self.refresh(repo, &mirror) {
                eprintln!(
                    "peppy-launch: cannot reach {repo} ({}); using its cached copy",
                    e.trim()
                );
            }
            let commit = resolve(&mirror, reference).ok_or_else(|| {
                format!(
                    "`{reference}` is not a branch, tag or commit of {repo} (it has: {})",
                    refs_of(&mirror)
                )
            })?;
            eprintln!("peppy-launch: {repo} `{reference}` is commit {commit}");
            commit
        };
        let tree = self.cache.join("git-trees").join(&commit);
        if !tree.is_dir() {
            let tar = git_output(Some(&mirror), &["archive", "--format=tar", &commit])
                .map_err(|e| format!("cannot read commit {commit} of {repo}: {e}"))?;
            let tmp = fresh(&tree)?;
            unpack(&tar, &tmp).map_err(|e| format!("commit {commit} of {repo}: {e}"))?;
            publish(&tmp, &tree)?;
        }
        let dir = tree.join(&sub);
        if !dir.exists() {
            return Err(format!("{repo} at {commit} has no `{}`", sub.display()));
        }
        Ok(dir)
    }

    fn archive(&self, url: &str, sha256: &str) -> Result<PathBuf, String> {
        let expected = sha256.to_ascii_lowercase();
        let dir = self.cache.join("archives").join(&expected);
        if !dir.is_dir() {
            let bytes = download(url)?;
            let actual = sha256_hex(&bytes);
            if actual != expected {
                return Err(format!(
                    "{url} has sha256 {actual}, but the launcher expects {expected}; refusing to unpack it"
                ));
            }
            let tmp = fresh(&dir)?;
            unpack(&bytes, &tmp).map_err(|e| format!("{url}: {e}"))?;
            publish(&tmp, &dir)?;
        }
        Ok(node_root(&dir))
    }
}

/// The archive's node: its root, or the one directory it holds (archives
/// usually wrap their files in `name-version/`).
fn node_root(dir: &Path) -> PathBuf {
    if dir.join("peppy.json5").is_file() {
        return dir.to_path_buf();
    }
    let entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    match entries.as_slice() {
        [only] if only.is_dir() => only.clone(),
        _ => dir.to_path_buf(),
    }
}

/// The archive's bytes: `file://` (and plain paths) read here, `http(s)://`
/// through `curl`.
fn download(url: &str) -> Result<Vec<u8>, String> {
    if let Some(path) = url.strip_prefix("file://") {
        return std::fs::read(path).map_err(|e| format!("cannot read {url}: {e}"));
    }
    if url.starts_with("http://") || url.starts_with("https://") {
        let out = Command::new("curl")
            .args(["--fail", "--silent", "--show-error", "--location", url])
            .output()
            .map_err(|e| format!("cannot run curl to download {url}: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "cannot download {url}: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        return Ok(out.stdout);
    }
    Err(format!(
        "`{url}`: only file://, http:// and https:// URLs can be fetched"
    ))
}

/// Unpacks a `.tar` or `.tar.gz` into `dst`, refusing anything that could
/// land outside it or is not a plain file or directory.
fn unpack(bytes: &[u8], dst: &Path) -> Result<(), String> {
    let reader: Box<dyn Read + '_> = if bytes.starts_with(&[0x1f, 0x8b]) {
        Box::new(flate2::read::GzDecoder::new(bytes))
    } else {
        Box::new(bytes)
    };
    let mut archive = tar::Archive::new(reader);
    let entries = archive
        .entries()
        .map_err(|e| format!("not a tar archive: {e}"))?;
    for entry in entries {
        let mut entry = entry.map_err(|e| format!("a damaged archive entry: {e}"))?;
        let raw = entry
            .path()
            .map_err(|e| format!("an entry with an unreadable path: {e}"))?
            .into_owned();
        let kind = entry.header().entry_type();
        if kind.is_pax_global_extensions() || kind.is_pax_local_extensions() {
            continue;
        }
        let path = relative(&raw.to_string_lossy()).ok_or_else(|| {
            format!(
                "the entry `{}` would land outside the directory it is unpacked into; refusing the archive",
                raw.display()
            )
        })?;
        if path.as_os_str().is_empty() {
            continue;
        }
        let target = dst.join(&path);
        if kind.is_dir() {
            std::fs::create_dir_all(&target)
                .map_err(|e| format!("cannot create {}: {e}", target.display()))?;
        } else if kind.is_file() {
            if let Some(parent) = target.parent() {
                std::fs::create_dir_all(parent)
                    .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
            }
            let mode = entry.header().mode().unwrap_or(0o644);
            let mut data = Vec::new();
            entry
                .read_to_end(&mut data)
                .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?;
            std::fs::write(&target, &data)
                .map_err(|e| format!("cannot write {}: {e}", target.display()))?;
            set_mode(&target, mode & 0o755)?;
        } else {
            return Err(format!(
                "the entry `{}` is a link or a special file; refusing the archive",
                path.display()
            ));
        }
    }
    Ok(())
}

#[cfg(unix)]
fn set_mode(path: &Path, mode: u32) -> Result<(), String> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode | 0o600))
        .map_err(|e| format!("cannot set the mode of {}: {e}", path.display()))
}

#[cfg(not(unix))]
fn set_mode(_path: &Path, _mode: u32) -> Result<(), String> {
    Ok(())
}

/// `path` as a relative path with only normal components (`.` dropped);
/// `None` when absolute or with `..`.
fn relative(path: &str) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in Path::new(path).components() {
        match c {
            Component::Normal(part) => out.push(part),
            Component::CurDir => {}
            Component::ParentDir | Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

fn is_commit_id(s: &str) -> bool {
    s.len() == 40 && s.bytes().all(|b| b.is_ascii_hexdigit())
}

/// The commit `reference` names in `mirror`.
fn resolve(mirror: &Path, reference: &str) -> Option<String> {
    let spec = format!("{reference}^{{commit}}");
    git_output(Some(mirror), &["rev-parse", "--verify", "--quiet", &spec])
        .ok()
        .map(|out| String::from_utf8_lossy(&out).trim().to_string())
        .filter(|c| is_commit_id(c))
}

/// Branches and tags of `mirror`, for an error message.
fn refs_of(mirror: &Path) -> String {
    let out = git_output(
        Some(mirror),
        &[
            "for-each-ref",
            "--format=%(refname:short)",
            "refs/heads",
            "refs/tags",
        ],
    )
    .unwrap_or_default();
    let names: Vec<String> = String::from_utf8_lossy(&out)
        .lines()
        .map(|l| format!("`{l}`"))
        .collect();
    if names.is_empty() {
        "no branches or tags".into()
    } else {
        names.join(", ")
    }
}

fn git(dir: Option<&Path>, args: &[&str]) -> Result<(), String> {
    git_output(dir, args).map(drop)
}

/// Runs git (in `dir` as its git directory), returning its stdout.
fn git_output(dir: Option<&Path>, args: &[&str]) -> Result<Vec<u8>, String> {
    let mut cmd = Command::new("git");
    if let Some(dir) = dir {
        cmd.arg("--git-dir").arg(dir);
    }
    // Never wait for a password prompt: a launch has no one to answer it.
    cmd.args(args)
        .env("GIT_TERMINAL_PROMPT", "0")
        .stdin(std::process::Stdio::null());
    let out = cmd.output().map_err(|e| format!("cannot run git: {e}"))?;
    if out.status.success() {
        Ok(out.stdout)
    } else {
        Err(String::from_utf8_lossy(&out.stderr).trim().to_string())
    }
}

/// A new empty directory beside `final_dir`, to fill and then publish.
fn fresh(final_dir: &Path) -> Result<PathBuf, String> {
    let parent = final_dir.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
    let name = final_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = parent.join(format!(".{name}.{}.partial", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| format!("cannot create {}: {e}", tmp.display()))?;
    Ok(tmp)
}

/// Moves a filled directory into place in one step, so an interrupted
/// fetch never leaves a half-written cache entry (a concurrent launch that
/// published first wins).
fn publish(tmp: &Path, final_dir: &Path) -> Result<(), String> {
    if std::fs::rename(tmp, final_dir).is_err() {
        let _ = std::fs::remove_dir_all(tmp);
        if !final_dir.exists() {
            return Err(format!(
                "cannot write the cache entry {}",
                final_dir.display()
            ));
        }
    }
    Ok(())
}

fn path_arg(p: &Path) -> String {
    p.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_stay_inside() {
        assert_eq!(relative("a/./b"), Some(PathBuf::from("a/b")));
        assert_eq!(relative("../x"), None);
        assert_eq!(relative("a/../../x"), None);
        assert_eq!(relative("/etc/passwd"), None);
        assert_eq!(relative("."), Some(PathBuf::new()));
    }

    #[test]
    fn commit_ids_are_forty_hex_digits() {
        assert!(is_commit_id("0123456789abcdef0123456789abcdef01234567"));
        assert!(!is_commit_id("main"));
        assert!(!is_commit_id("0123456"));
    }
}
