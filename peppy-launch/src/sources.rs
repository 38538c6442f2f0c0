//! Remote launcher sources (SPEC 6.2): `{ repo, path, ref }` from git and
//! `{ url, sha256 }` archives, fetched into a cache under the user's cache
//! directory, so a second launch (and one without a network) uses the copy.
//!
//! - git: one mirror per repository (`git clone --mirror`), one unpacked
//!   tree per commit. A full commit id is used as is (fetched only when the
//!   mirror lacks it); a branch or tag is fetched fresh when the remote
//!   answers, else read from the mirror, and the commit it names is
//!   printed.
//! - archives: copied (`file://`) or downloaded (`http(s)://`, by `ureq` in
//!   this process: redirects followed, timeouts on connecting, on a silent
//!   server and on the whole download) into a file in the cache, hashed as
//!   they are written and bounded in size; refused unless they hash to the
//!   launcher's sha256; then unpacked from that file (`.tar`, `.tar.gz`)
//!   entry by entry: no absolute path, no `..`, no links, nothing but files
//!   and directories. HTTPS trusts the system's certificates (a proxy's CA
//!   the system trusts too, as curl did), else Mozilla's built in.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Component, Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use peppy_schema::Source;
use peppy_schema::{FetchError, FetchSource, GitRepository, ListedBy, sha256_hex};
use sha2::{Digest, Sha256};

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

/// Why a remote source (git or archive) could not be had.
#[derive(Debug, thiserror::Error)]
pub(crate) enum SourceError {
    /// A local source was handed to the fetcher.
    #[error("not a remote source: {0:?}")]
    NotRemote(Source),
    /// The git source's `path` leaves the repository.
    #[error("`path` `{path}` must be relative to the repository, without `..`")]
    PathOutside {
        /// The `path` given.
        path: String,
    },
    /// The repository could not be cloned.
    #[error("cannot clone {repo}: {source}")]
    Clone {
        /// The repository.
        repo: String,
        /// Git's complaint.
        source: GitError,
    },
    /// A full commit id the repository does not have.
    #[error("commit {commit} is not in {repo}")]
    NoCommit {
        /// The commit id.
        commit: String,
        /// The repository.
        repo: String,
    },
    /// A `ref` that names no branch, tag or commit.
    #[error(
        "`{reference}` is not a branch, tag or commit of {repo} (it has: {})",
        refs_text(refs)
    )]
    NoRef {
        /// The `ref` given.
        reference: String,
        /// The repository.
        repo: String,
        /// The branches and tags the repository has.
        refs: Vec<String>,
    },
    /// The commit's files could not be read from the mirror.
    #[error("cannot read commit {commit} of {repo}: {source}")]
    ReadCommit {
        /// The commit id.
        commit: String,
        /// The repository.
        repo: String,
        /// Git's complaint.
        source: GitError,
    },
    /// The commit's files could not be unpacked into the cache.
    #[error("commit {commit} of {repo}: {source}")]
    UnpackCommit {
        /// The commit id.
        commit: String,
        /// The repository.
        repo: String,
        /// What went wrong unpacking.
        source: UnpackError,
    },
    /// The commit has no `path`.
    #[error("{repo} at {commit} has no `{}`", path.display())]
    NoPath {
        /// The repository.
        repo: String,
        /// The commit id.
        commit: String,
        /// The `path` asked for.
        path: PathBuf,
    },
    /// The archive could not be fetched or does not match its sha256.
    #[error(transparent)]
    Archive(#[from] ArchiveError),
    /// The downloaded archive could not be read back.
    #[error("cannot read {}: {source}", path.display())]
    ReadDownload {
        /// The downloaded file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The archive could not be unpacked.
    #[error("{url}: {source}")]
    UnpackArchive {
        /// The archive's URL.
        url: String,
        /// What went wrong unpacking.
        source: UnpackError,
    },
    /// A directory of the cache could not be created.
    #[error("cannot create {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A filled cache entry could not be moved into place.
    #[error("cannot write the cache entry {}", path.display())]
    Publish {
        /// The cache entry.
        path: PathBuf,
    },
}

/// A repository's branches and tags, for a message.
fn refs_text(refs: &[String]) -> String {
    if refs.is_empty() {
        "no branches or tags".into()
    } else {
        refs.iter()
            .map(|r| format!("`{r}`"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A git command that failed.
#[derive(Debug, thiserror::Error)]
pub(crate) enum GitError {
    /// Git could not be started.
    #[error("cannot run git: {0}")]
    Spawn(#[source] std::io::Error),
    /// Git ran and failed.
    #[error("{stderr}")]
    Failed {
        /// What git printed on stderr, trimmed.
        stderr: String,
    },
}

/// Why an archive (or a commit's tar) could not be unpacked.
#[derive(Debug, thiserror::Error)]
pub(crate) enum UnpackError {
    /// Its first bytes could not be read.
    #[error("cannot read the archive: {0}")]
    Read(#[source] std::io::Error),
    /// It is not a tar archive.
    #[error("not a tar archive: {0}")]
    NotTar(#[source] std::io::Error),
    /// An entry could not be read.
    #[error("a damaged archive entry: {0}")]
    Damaged(#[source] std::io::Error),
    /// An entry's path could not be read.
    #[error("an entry with an unreadable path: {0}")]
    UnreadablePath(#[source] std::io::Error),
    /// An entry would land outside the directory it is unpacked into.
    #[error(
        "the entry `{}` would land outside the directory it is unpacked into; refusing the archive",
        entry.display()
    )]
    Outside {
        /// The entry's path.
        entry: PathBuf,
    },
    /// An entry is a link or a special file.
    #[error(
        "the entry `{}` is a link or a special file; refusing the archive",
        entry.display()
    )]
    Special {
        /// The entry's path.
        entry: PathBuf,
    },
    /// A directory could not be created.
    #[error("cannot create {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file could not be created.
    #[error("cannot write {}: {source}", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// An entry's contents could not be copied out.
    #[error("cannot unpack `{}`: {source}", entry.display())]
    Copy {
        /// The entry's path.
        entry: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file's mode could not be set.
    #[error("cannot set the mode of {}: {source}", path.display())]
    Mode {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
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
    fn refresh(&self, repo: &str, mirror: &Path) -> Result<(), GitError> {
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
    fn fetch(&self, source: &Source) -> Result<PathBuf, FetchError> {
        Ok(self.fetch_source(source)?)
    }

    /// A project's list (a `peppy_repositories.json5`) fetches a git
    /// repository the first time it is needed; the user's list and the
    /// default one are read from the cache only (`repo add` and `repo
    /// refresh` fetch them), so no command reaches the network for them.
    fn repository(
        &self,
        repository: &GitRepository,
        by: &ListedBy,
    ) -> Result<Option<PathBuf>, FetchError> {
        let how = match by {
            ListedBy::Defaults => RepoFetch::CachedOnly,
            ListedBy::File(list) if *list == crate::repositories::user_list_path() => {
                RepoFetch::CachedOnly
            }
            _ => RepoFetch::FirstUse,
        };
        Ok(self.git_repository(repository, how)?.map(|f| f.tree))
    }
}

/// How [`Fetcher::git_repository`] may use the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RepoFetch {
    /// Never: the cached copy or nothing.
    CachedOnly,
    /// To clone it (or fetch a ref the cache lacks); a cached ref is used
    /// as it is.
    FirstUse,
    /// Ask the remote for its branches and tags first.
    Refresh,
}

/// A git repository brought to a local tree.
#[derive(Debug)]
pub(crate) struct FetchedRepository {
    /// The commit's files.
    pub(crate) tree: PathBuf,
    /// The commit.
    pub(crate) commit: String,
    /// Why a refresh failed (the cached commit is used).
    pub(crate) stale: Option<String>,
}

impl Fetcher {
    /// The directory holding a remote source's node.
    pub(crate) fn fetch_source(&self, source: &Source) -> Result<PathBuf, SourceError> {
        match source {
            Source::Git {
                repo,
                path,
                reference,
            } => self.git(repo, path, reference),
            Source::Archive { url, sha256 } => self.archive(url, sha256),
            other => Err(SourceError::NotRemote(other.clone())),
        }
    }

    fn git(&self, repo: &str, sub: &str, reference: &str) -> Result<PathBuf, SourceError> {
        let sub = relative(sub).ok_or_else(|| SourceError::PathOutside {
            path: sub.to_string(),
        })?;
        let mirror = self.mirror(repo)?;
        let commit = if is_commit_id(reference) {
            if resolve(&mirror, reference).is_none() {
                // A commit the mirror has not seen yet: the remote may have it.
                let _ = self.refresh(repo, &mirror);
            }
            resolve(&mirror, reference).ok_or_else(|| SourceError::NoCommit {
                commit: reference.to_string(),
                repo: repo.to_string(),
            })?
        } else {
            // A branch or tag moves: ask the remote, else use the mirror.
            if let Err(e) = self.refresh(repo, &mirror) {
                eprintln!(
                    "peppy-launch: cannot reach {repo} ({}); using its cached copy",
                    e.to_string().trim()
                );
            }
            let commit = resolve(&mirror, reference).ok_or_else(|| SourceError::NoRef {
                reference: reference.to_string(),
                repo: repo.to_string(),
                refs: refs_of(&mirror),
            })?;
            eprintln!("peppy-launch: {repo} `{reference}` is commit {commit}");
            commit
        };
        let tree = self.tree(repo, &commit)?;
        let dir = tree.join(&sub);
        if !dir.exists() {
            return Err(SourceError::NoPath {
                repo: repo.to_string(),
                commit,
                path: sub,
            });
        }
        Ok(dir)
    }

    /// Where `repo`'s mirror is kept (whether or not it is there yet).
    fn mirror_path(&self, repo: &str) -> PathBuf {
        self.cache
            .join("git")
            .join(format!("{}.git", &sha256_hex(repo.as_bytes())[..16]))
    }

    /// `repo`'s mirror, cloned first if it is not cached yet.
    fn mirror(&self, repo: &str) -> Result<PathBuf, SourceError> {
        let mirror = self.mirror_path(repo);
        if !mirror.join("HEAD").is_file() {
            let tmp = fresh(&mirror)?;
            git(
                None,
                &["clone", "--quiet", "--mirror", "--", repo, &path_arg(&tmp)],
            )
            .map_err(|source| SourceError::Clone {
                repo: repo.to_string(),
                source,
            })?;
            publish(&tmp, &mirror)?;
            // Just cloned: as fresh as a fetch would make it.
            self.first_time(repo);
        }
        Ok(mirror)
    }

    /// The files of `commit` of `repo`, unpacked once into the cache.
    fn tree(&self, repo: &str, commit: &str) -> Result<PathBuf, SourceError> {
        let mirror = self.mirror_path(repo);
        let tree = self.cache.join("git-trees").join(commit);
        if !tree.is_dir() {
            let tar = git_output(Some(&mirror), &["archive", "--format=tar", commit]).map_err(
                |source| SourceError::ReadCommit {
                    commit: commit.to_string(),
                    repo: repo.to_string(),
                    source,
                },
            )?;
            let tmp = fresh(&tree)?;
            unpack(tar.as_slice(), &tmp).map_err(|source| SourceError::UnpackCommit {
                commit: commit.to_string(),
                repo: repo.to_string(),
                source,
            })?;
            publish(&tmp, &tree)?;
        }
        Ok(tree)
    }

    /// A git repository of a repository list, as `how` says: its tree and
    /// commit, or `None` when `how` is [`RepoFetch::CachedOnly`] and it is
    /// not cached. A branch or tag is read from the cached mirror, asked
    /// of the remote only when refreshing or when the mirror lacks it;
    /// a refresh that fails keeps the cached commit and says why.
    pub(crate) fn git_repository(
        &self,
        repository: &GitRepository,
        how: RepoFetch,
    ) -> Result<Option<FetchedRepository>, SourceError> {
        let url = repository.url.as_str();
        if how == RepoFetch::CachedOnly && !self.mirror_path(url).join("HEAD").is_file() {
            return Ok(None);
        }
        let mirror = self.mirror(url)?;
        let reference = repository.reference.as_deref().unwrap_or("HEAD");
        let mut stale = None;
        if how == RepoFetch::Refresh
            && let Err(e) = self.refresh(url, &mirror)
        {
            stale = Some(e.to_string().trim().to_string());
        }
        let mut commit = resolve(&mirror, reference);
        if commit.is_none() && how != RepoFetch::CachedOnly {
            // A commit or branch the mirror has not seen yet.
            let _ = self.refresh(url, &mirror);
            commit = resolve(&mirror, reference);
        }
        let Some(commit) = commit else {
            return Err(if is_commit_id(reference) {
                SourceError::NoCommit {
                    commit: reference.to_string(),
                    repo: url.to_string(),
                }
            } else {
                SourceError::NoRef {
                    reference: reference.to_string(),
                    repo: url.to_string(),
                    refs: refs_of(&mirror),
                }
            });
        };
        let tree = self.tree(url, &commit)?;
        Ok(Some(FetchedRepository {
            tree,
            commit,
            stale,
        }))
    }

    fn archive(&self, url: &str, sha256: &str) -> Result<PathBuf, SourceError> {
        let expected = sha256.to_ascii_lowercase();
        let dir = self.cache.join("archives").join(&expected);
        if !dir.is_dir() {
            let download = Scratch::beside(&dir)?;
            fetch_archive(url, &expected, &download.0)?;
            // Unpacked from this process's own copy, the one that was hashed:
            // the source cannot change between the check and the unpacking.
            let file =
                std::fs::File::open(&download.0).map_err(|source| SourceError::ReadDownload {
                    path: download.0.clone(),
                    source,
                })?;
            let tmp = fresh(&dir)?;
            if let Err(source) = unpack(BufReader::new(file), &tmp) {
                let _ = std::fs::remove_dir_all(&tmp);
                return Err(SourceError::UnpackArchive {
                    url: url.to_string(),
                    source,
                });
            }
            publish(&tmp, &dir)?;
        }
        Ok(node_root(&dir))
    }
}

/// The most bytes an archive source may have: a node's sources, not a
/// data set. Counted as they arrive, whatever the server announced.
const MAX_ARCHIVE_BYTES: u64 = 1 << 30;

/// Connecting to the server (each redirect's too).
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);

/// How long the server may stay silent: before its response, or between
/// two reads of the body.
const SILENCE_TIMEOUT: Duration = Duration::from_secs(60);

/// The whole download, redirects included.
const DOWNLOAD_TIMEOUT: Duration = Duration::from_secs(15 * 60);

/// How many redirects a download follows.
const MAX_REDIRECTS: u32 = 10;

/// Why an archive source was not fetched.
#[derive(Debug, thiserror::Error)]
pub(crate) enum ArchiveError {
    /// The URL's scheme is not one peppy fetches.
    #[error("`{url}`: only file://, http:// and https:// URLs can be fetched")]
    Scheme {
        /// The URL.
        url: String,
    },
    /// The download failed (connection, status, timeout).
    #[error("cannot download {url}: {source}")]
    Request {
        /// The URL.
        url: String,
        /// The HTTP client's error.
        #[source]
        source: Box<ureq::Error>,
    },
    /// The archive could not be read.
    #[error("cannot read {url}: {source}")]
    Read {
        /// The URL.
        url: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The copy in the cache could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file in the cache.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The archive is larger than an archive source may be.
    #[error("{url} is larger than {max} bytes, the most an archive source may have")]
    TooLarge {
        /// The URL.
        url: String,
        /// The bound, in bytes.
        max: u64,
    },
    /// The archive does not hash to the launcher's sha256.
    #[error("{url} has sha256 {got}, but the launcher expects {expected}; refusing to unpack it")]
    Mismatch {
        /// The URL.
        url: String,
        /// The launcher's sha256.
        expected: String,
        /// The archive's.
        got: String,
    },
}

/// Writes the archive at `url` into the file `to` and checks it hashes to
/// `expected` (lowercase hex).
fn fetch_archive(url: &str, expected: &str, to: &Path) -> Result<(), ArchiveError> {
    let (body, announced): (Box<dyn Read>, Option<u64>) =
        if let Some(path) = url.strip_prefix("file://") {
            let file = std::fs::File::open(path).map_err(|source| ArchiveError::Read {
                url: url.to_string(),
                source,
            })?;
            (Box::new(file), None)
        } else if url.starts_with("http://") || url.starts_with("https://") {
            let response = agent()
                .get(url)
                .call()
                .map_err(|source| ArchiveError::Request {
                    url: url.to_string(),
                    source: Box::new(source),
                })?;
            let announced = response.body().content_length();
            (Box::new(response.into_body().into_reader()), announced)
        } else {
            return Err(ArchiveError::Scheme {
                url: url.to_string(),
            });
        };
    if announced.is_some_and(|n| n > MAX_ARCHIVE_BYTES) {
        return Err(ArchiveError::TooLarge {
            url: url.to_string(),
            max: MAX_ARCHIVE_BYTES,
        });
    }
    let got = copy_hashed(body, url, to, MAX_ARCHIVE_BYTES)?;
    if got != expected {
        return Err(ArchiveError::Mismatch {
            url: url.to_string(),
            expected: expected.to_string(),
            got,
        });
    }
    Ok(())
}

/// Copies at most `max` bytes of `body` into a new file `to` and returns
/// their sha256 (lowercase hex), computed as they are written.
fn copy_hashed(
    mut body: impl Read,
    url: &str,
    to: &Path,
    max: u64,
) -> Result<String, ArchiveError> {
    let write_error = |source| ArchiveError::Write {
        path: to.to_path_buf(),
        source,
    };
    let mut out = std::fs::File::create_new(to).map_err(write_error)?;
    let mut hash = Sha256::new();
    let mut buffer = vec![0; 64 * 1024];
    let mut total = 0u64;
    loop {
        let n = match body.read(&mut buffer) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(source) => {
                return Err(ArchiveError::Read {
                    url: url.to_string(),
                    source,
                });
            }
        };
        total += n as u64;
        if total > max {
            return Err(ArchiveError::TooLarge {
                url: url.to_string(),
                max,
            });
        }
        hash.update(&buffer[..n]);
        out.write_all(&buffer[..n]).map_err(write_error)?;
    }
    out.flush().map_err(write_error)?;
    Ok(format!("{:x}", hash.finalize()))
}

/// The HTTP client of archive downloads: bounded in time, following
/// redirects, an error for any status but success.
fn agent() -> ureq::Agent {
    let tls = ureq::tls::TlsConfig::builder()
        .root_certs(root_certs())
        .build();
    ureq::Agent::config_builder()
        .timeout_connect(Some(CONNECT_TIMEOUT))
        .timeout_recv_response(Some(SILENCE_TIMEOUT))
        .timeout_per_read(Some(SILENCE_TIMEOUT))
        .timeout_global(Some(DOWNLOAD_TIMEOUT))
        .max_redirects(MAX_REDIRECTS)
        .http_status_as_error(true)
        .user_agent(concat!("peppy-launch/", env!("CARGO_PKG_VERSION")))
        .tls_config(tls)
        .build()
        .into()
}

/// Where Linux distributions (and the BSDs and macOS) keep the system's
/// trusted certificates as one PEM file.
const SYSTEM_BUNDLES: [&str; 5] = [
    "/etc/ssl/certs/ca-certificates.crt",
    "/etc/pki/tls/certs/ca-bundle.crt",
    "/etc/pki/ca-trust/extracted/pem/tls-ca-bundle.pem",
    "/etc/ssl/ca-bundle.pem",
    "/etc/ssl/cert.pem",
];

/// The certificates HTTPS downloads trust: `SSL_CERT_FILE`, else the
/// system's bundle, as curl trusted (so a company proxy's CA the system
/// trusts still works); Mozilla's roots, built in, where there is neither.
fn root_certs() -> ureq::tls::RootCerts {
    let given = std::env::var_os("SSL_CERT_FILE").map(PathBuf::from);
    let files = given
        .into_iter()
        .chain(SYSTEM_BUNDLES.iter().map(PathBuf::from));
    for file in files {
        let Ok(pem) = std::fs::read(&file) else {
            continue;
        };
        let certificates: Vec<ureq::tls::Certificate<'static>> = ureq::tls::parse_pem(&pem)
            .filter_map(|item| match item {
                Ok(ureq::tls::PemItem::Certificate(c)) => Some(c),
                _ => None,
            })
            .collect();
        if !certificates.is_empty() {
            return ureq::tls::RootCerts::new_with_certs(&certificates);
        }
    }
    ureq::tls::RootCerts::WebPki
}

/// A file beside a cache entry that is removed when dropped: the
/// downloaded archive, kept only until it is unpacked.
struct Scratch(PathBuf);

impl Scratch {
    /// A new path beside `final_dir`, unique to this process and call.
    fn beside(final_dir: &Path) -> Result<Scratch, SourceError> {
        static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let parent = final_dir.parent().unwrap_or(Path::new("."));
        std::fs::create_dir_all(parent).map_err(|source| SourceError::CreateDir {
            path: parent.to_path_buf(),
            source,
        })?;
        let name = final_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let path = parent.join(format!(
            ".{name}.{}.{}.download",
            std::process::id(),
            NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        let _ = std::fs::remove_file(&path);
        Ok(Scratch(path))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
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

/// Unpacks a `.tar` or `.tar.gz` into `dst`, refusing anything that could
/// land outside it or is not a plain file or directory.
fn unpack(mut input: impl BufRead, dst: &Path) -> Result<(), UnpackError> {
    let gzip = input
        .fill_buf()
        .map_err(UnpackError::Read)?
        .starts_with(&[0x1f, 0x8b]);
    let reader: Box<dyn Read + '_> = if gzip {
        Box::new(flate2::bufread::GzDecoder::new(input))
    } else {
        Box::new(input)
    };
    let mut archive = tar::Archive::new(reader);
    let entries = archive.entries().map_err(UnpackError::NotTar)?;
    for entry in entries {
        let mut entry = entry.map_err(UnpackError::Damaged)?;
        let raw = entry
            .path()
            .map_err(UnpackError::UnreadablePath)?
            .into_owned();
        let kind = entry.header().entry_type();
        if kind.is_pax_global_extensions() || kind.is_pax_local_extensions() {
            continue;
        }
        let path = relative(&raw.to_string_lossy())
            .ok_or_else(|| UnpackError::Outside { entry: raw.clone() })?;
        if path.as_os_str().is_empty() {
            continue;
        }
        let target = dst.join(&path);
        let create_dir = |dir: &Path| {
            std::fs::create_dir_all(dir).map_err(|source| UnpackError::CreateDir {
                path: dir.to_path_buf(),
                source,
            })
        };
        if kind.is_dir() {
            create_dir(&target)?;
        } else if kind.is_file() {
            if let Some(parent) = target.parent() {
                create_dir(parent)?;
            }
            let mode = entry.header().mode().unwrap_or(0o644);
            let mut file =
                std::fs::File::create(&target).map_err(|source| UnpackError::Create {
                    path: target.clone(),
                    source,
                })?;
            std::io::copy(&mut entry, &mut file).map_err(|source| UnpackError::Copy {
                entry: path.clone(),
                source,
            })?;
            set_mode(&target, mode & 0o755)?;
        } else {
            return Err(UnpackError::Special { entry: path });
        }
    }
    Ok(())
}

#[cfg(unix)]
fn set_mode(path: &Path, mode: u32) -> Result<(), UnpackError> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode | 0o600)).map_err(
        |source| UnpackError::Mode {
            path: path.to_path_buf(),
            source,
        },
    )
}

#[cfg(not(unix))]
fn set_mode(_path: &Path, _mode: u32) -> Result<(), UnpackError> {
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
fn refs_of(mirror: &Path) -> Vec<String> {
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
    String::from_utf8_lossy(&out)
        .lines()
        .map(str::to_string)
        .collect()
}

fn git(dir: Option<&Path>, args: &[&str]) -> Result<(), GitError> {
    git_output(dir, args).map(drop)
}

/// Runs git (in `dir` as its git directory), returning its stdout.
fn git_output(dir: Option<&Path>, args: &[&str]) -> Result<Vec<u8>, GitError> {
    let mut cmd = Command::new("git");
    if let Some(dir) = dir {
        cmd.arg("--git-dir").arg(dir);
    }
    // Never wait for a password prompt: a launch has no one to answer it.
    cmd.args(args)
        .env("GIT_TERMINAL_PROMPT", "0")
        .stdin(std::process::Stdio::null());
    let out = cmd.output().map_err(GitError::Spawn)?;
    if out.status.success() {
        Ok(out.stdout)
    } else {
        Err(GitError::Failed {
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        })
    }
}

/// A new empty directory beside `final_dir`, to fill and then publish.
fn fresh(final_dir: &Path) -> Result<PathBuf, SourceError> {
    let create = |dir: &Path| {
        std::fs::create_dir_all(dir).map_err(|source| SourceError::CreateDir {
            path: dir.to_path_buf(),
            source,
        })
    };
    let parent = final_dir.parent().unwrap_or(Path::new("."));
    create(parent)?;
    let name = final_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = parent.join(format!(".{name}.{}.partial", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    create(&tmp)?;
    Ok(tmp)
}

/// Moves a filled directory into place in one step, so an interrupted
/// fetch never leaves a half-written cache entry (a concurrent launch that
/// published first wins).
fn publish(tmp: &Path, final_dir: &Path) -> Result<(), SourceError> {
    if std::fs::rename(tmp, final_dir).is_err() {
        let _ = std::fs::remove_dir_all(tmp);
        if !final_dir.exists() {
            return Err(SourceError::Publish {
                path: final_dir.to_path_buf(),
            });
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
    fn a_copy_is_hashed_as_written_and_bounded() {
        let dir = tempfile::tempdir().unwrap();
        let to = dir.path().join("a");
        let got = copy_hashed(&b"abc"[..], "mem://abc", &to, 3).unwrap();
        assert_eq!(got, sha256_hex(b"abc"));
        assert_eq!(std::fs::read(&to).unwrap(), b"abc");
        let err = copy_hashed(&b"abcd"[..], "mem://abcd", &dir.path().join("b"), 3).unwrap_err();
        assert!(
            matches!(err, ArchiveError::TooLarge { max: 3, .. }),
            "{err}"
        );
    }

    #[test]
    fn bytes_with_another_hash_are_refused_naming_both() {
        let dir = tempfile::tempdir().unwrap();
        let source = dir.path().join("src.tar");
        std::fs::write(&source, b"not the archive").unwrap();
        let url = format!("file://{}", source.display());
        let expected = "0".repeat(64);
        let err = fetch_archive(&url, &expected, &dir.path().join("copy")).unwrap_err();
        let got = sha256_hex(b"not the archive");
        assert_eq!(
            err.to_string(),
            format!(
                "{url} has sha256 {got}, but the launcher expects {expected}; refusing to unpack it"
            )
        );
        let err = fetch_archive("ftp://x/y.tar", &expected, &dir.path().join("ftp")).unwrap_err();
        assert!(matches!(err, ArchiveError::Scheme { .. }), "{err}");
    }

    /// A tar holding one entry of `kind` at `path`, written raw so that
    /// paths tar's builder refuses (`..`) can be tried.
    fn tar_with(path: &str, kind: tar::EntryType) -> Vec<u8> {
        let mut header = tar::Header::new_old();
        header.as_old_mut().name[..path.len()].copy_from_slice(path.as_bytes());
        header.set_entry_type(kind);
        header.set_size(0);
        header.set_mode(0o644);
        header.set_cksum();
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(&[0; 1024]);
        bytes
    }

    #[test]
    fn unpacking_refuses_what_leaves_the_directory_or_is_no_plain_file() {
        let dir = tempfile::tempdir().unwrap();
        let err = unpack(
            &tar_with("../evil", tar::EntryType::Regular)[..],
            dir.path(),
        )
        .unwrap_err();
        assert!(
            matches!(&err, UnpackError::Outside { entry } if entry == Path::new("../evil")),
            "{err}"
        );
        assert_eq!(
            err.to_string(),
            "the entry `../evil` would land outside the directory it is unpacked into; refusing the archive"
        );
        let err = unpack(&tar_with("link", tar::EntryType::Symlink)[..], dir.path()).unwrap_err();
        assert!(matches!(err, UnpackError::Special { .. }), "{err}");
        unpack(&tar_with("ok.txt", tar::EntryType::Regular)[..], dir.path()).unwrap();
        assert!(dir.path().join("ok.txt").is_file());
    }

    #[test]
    fn a_missing_ref_names_what_the_repository_has() {
        let e = SourceError::NoRef {
            reference: "v9".into(),
            repo: "https://example.org/r.git".into(),
            refs: vec!["main".into(), "v1".into()],
        };
        assert_eq!(
            e.to_string(),
            "`v9` is not a branch, tag or commit of https://example.org/r.git (it has: `main`, `v1`)"
        );
        let none = SourceError::NoRef {
            reference: "main".into(),
            repo: "r".into(),
            refs: Vec::new(),
        };
        assert!(none.to_string().ends_with("(it has: no branches or tags)"));
        let fetched = Fetcher::new().fetch(&Source::Local { path: "x".into() });
        assert!(
            fetched
                .unwrap_err()
                .to_string()
                .starts_with("not a remote source: Local")
        );
    }

    #[test]
    fn commit_ids_are_forty_hex_digits() {
        assert!(is_commit_id("0123456789abcdef0123456789abcdef01234567"));
        assert!(!is_commit_id("main"));
        assert!(!is_commit_id("0123456"));
    }
}
