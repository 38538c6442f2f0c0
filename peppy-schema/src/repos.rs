//! Repositories: where nodes, interfaces and launchers are found by
//! `name:tag`, and the index built by scanning them: through a
//! repository's `peppy_repository.json5` when it has one, else by walking
//! it.

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::diag::{Code, Diagnostic, Diagnostics, Severity};
use crate::document::{
    Document, DocumentKind, GitRepository, REPOSITORIES_FILE, RepositoriesDoc, RepositoryEntry,
    detect_kind, parse_tree,
};
use crate::interface::InterfaceDoc;
use crate::node::{Identity, NodeDoc};
use crate::pairing::PairingDoc;
use crate::repository_index::{
    IndexKey, IndexSection, Listed, REPOSITORY_INDEX_FILE, RepositoryIndexDoc, mismatch,
    peek_identity,
};
use crate::source::SourceFile;
use crate::stack::FetchSource;

/// The environment variable listing extra repositories (separated like `PATH`).
pub const REPOSITORIES_ENV: &str = "PEPPY_REPOSITORIES";

/// Directories never scanned.
pub const SKIPPED_DIRS: &[&str] = &[
    ".git",
    ".peppy",
    "target",
    "node_modules",
    ".venv",
    "__pycache__",
];

/// Where repositories come from, in priority order, and what was read to
/// find them (for rebuild tracking).
#[derive(Debug, Clone, Default)]
pub struct RepositoryList {
    /// Repository directories, highest priority first, without duplicates:
    /// the folders listed and, once [`fetch_git`](Self::fetch_git) ran, the
    /// git repositories' trees in their places.
    pub paths: Vec<PathBuf>,
    /// Every repository listed, highest priority first, as listed.
    pub listed: Vec<ListedRepository>,
    /// `peppy_repositories.json5` files that were read.
    pub files_read: Vec<PathBuf>,
}

/// One repository of a [`RepositoryList`] and who listed it.
#[derive(Debug, Clone)]
pub struct ListedRepository {
    /// The repository.
    pub entry: RepositoryEntry,
    /// Who listed it.
    pub by: ListedBy,
    /// A git repository's tree once fetched; a folder's path.
    pub local: Option<PathBuf>,
}

/// Who put a repository on the list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ListedBy {
    /// A `--repo` argument.
    CommandLine,
    /// `PEPPY_REPOSITORIES`.
    Environment,
    /// A repository list file: the nearest `peppy_repositories.json5`, a
    /// node's own, or the user's list.
    File(PathBuf),
    /// The built-in default list, used while the user has no list of
    /// their own.
    Defaults,
}

impl std::fmt::Display for ListedBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ListedBy::CommandLine => f.write_str("--repo"),
            ListedBy::Environment => f.write_str(REPOSITORIES_ENV),
            ListedBy::File(p) => write!(f, "{}", p.display()),
            ListedBy::Defaults => f.write_str("the default list"),
        }
    }
}

impl RepositoryList {
    /// Builds the list from, in order: `explicit` paths, the value of
    /// `PEPPY_REPOSITORIES` (`env`), and the nearest
    /// `peppy_repositories.json5` in `start_dir` or an ancestor.
    pub fn discover(
        explicit: &[PathBuf],
        env: Option<&OsStr>,
        start_dir: &Path,
    ) -> Result<RepositoryList, Diagnostics> {
        let mut list = RepositoryList::default();
        for p in explicit {
            list.add(RepositoryEntry::Folder(p.clone()), ListedBy::CommandLine);
        }
        if let Some(value) = env {
            for p in std::env::split_paths(value).filter(|p| !p.as_os_str().is_empty()) {
                list.add(RepositoryEntry::Folder(p), ListedBy::Environment);
            }
        }
        list.add_nearest_file(start_dir)?;
        Ok(list)
    }

    /// Appends the repositories of the nearest `peppy_repositories.json5`
    /// in `dir` or an ancestor (nothing if there is none).
    pub fn add_nearest_file(&mut self, dir: &Path) -> Result<(), Diagnostics> {
        let dir = absolute(dir);
        for ancestor in dir.ancestors() {
            let candidate = ancestor.join(REPOSITORIES_FILE);
            if candidate.is_file() {
                return self.add_file(&candidate);
            }
        }
        Ok(())
    }

    /// Appends the repositories of the list file `path` (once).
    pub fn add_file(&mut self, path: &Path) -> Result<(), Diagnostics> {
        if self.files_read.iter().any(|f| f == path) {
            return Ok(());
        }
        let (doc, _) = RepositoriesDoc::load(path)?;
        self.files_read.push(path.to_path_buf());
        for entry in doc.entries {
            self.add(entry, ListedBy::File(path.to_path_buf()));
        }
        Ok(())
    }

    /// Appends `entry`, listed by `by`, unless it is listed already.
    pub fn add(&mut self, entry: RepositoryEntry, by: ListedBy) {
        let entry = match entry {
            RepositoryEntry::Folder(p) => RepositoryEntry::Folder(absolute(&p)),
            git => git,
        };
        let same = |l: &ListedRepository| match (&l.entry, &entry) {
            (RepositoryEntry::Folder(a), RepositoryEntry::Folder(b)) => a == b,
            (RepositoryEntry::Git(a), RepositoryEntry::Git(b)) => {
                a.url == b.url && a.reference == b.reference
            }
            _ => false,
        };
        if self.listed.iter().any(same) {
            return;
        }
        let local = match &entry {
            RepositoryEntry::Folder(p) => Some(p.clone()),
            RepositoryEntry::Git(_) => None,
        };
        self.listed.push(ListedRepository { entry, by, local });
        self.update_paths();
    }

    /// The git repositories listed and not fetched yet.
    pub fn unfetched(&self) -> impl Iterator<Item = &GitRepository> {
        self.listed.iter().filter_map(|l| match &l.entry {
            RepositoryEntry::Git(g) if l.local.is_none() => Some(g),
            _ => None,
        })
    }

    /// Brings every listed git repository to a local tree with `fetcher`,
    /// each in its place in [`paths`](Self::paths). One that cannot be
    /// had is skipped with a warning at its entry, naming it and why.
    pub fn fetch_git(&mut self, fetcher: &dyn FetchSource) -> Diagnostics {
        let mut warnings = Diagnostics::new();
        for listed in &mut self.listed {
            let RepositoryEntry::Git(git) = &listed.entry else {
                continue;
            };
            if listed.local.is_some() {
                continue;
            }
            match fetcher.repository(git, &listed.by) {
                Ok(tree) => listed.local = tree,
                Err(why) => warnings.push(
                    git.loc
                        .warning(
                            Code::DependencyNotFound,
                            format!(
                                "git repository `{}` cannot be had: {why}; skipped",
                                git.describe()
                            ),
                        )
                        .with_help(
                            "`peppy-launch repo refresh` fetches every git repository again",
                        ),
                ),
            }
        }
        self.update_paths();
        warnings
    }

    fn update_paths(&mut self) {
        self.paths.clear();
        for listed in &self.listed {
            if let Some(p) = &listed.local
                && !self.paths.contains(p)
            {
                self.paths.push(p.clone());
            }
        }
    }
}

/// An absolute, normalised form of `p` (symlinks resolved when it exists).
pub(crate) fn absolute(p: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    let joined = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Every `*.json5` file under `dir`, in name order, skipping build, VCS and
/// hidden directories ([`SKIPPED_DIRS`]). Walk errors are returned in place.
pub fn json5_files(dir: &Path) -> impl Iterator<Item = Result<PathBuf, walkdir::Error>> {
    walkdir::WalkDir::new(dir)
        .sort_by_file_name()
        .into_iter()
        .filter_entry(|e| {
            e.depth() == 0
                || !(e.file_type().is_dir()
                    && e.file_name()
                        .to_str()
                        .is_some_and(|n| SKIPPED_DIRS.contains(&n) || n.starts_with('.')))
        })
        .filter_map(|entry| match entry {
            Ok(e)
                if e.file_type().is_file() && e.path().extension() == Some(OsStr::new("json5")) =>
            {
                Some(Ok(e.into_path()))
            }
            Ok(_) => None,
            Err(e) => Some(Err(e)),
        })
}

/// One indexed document.
#[derive(Debug, Clone)]
pub struct Entry<T> {
    /// The parsed document.
    pub doc: Arc<T>,
    /// Its file.
    pub path: PathBuf,
    /// The repository it was found in.
    pub repository: PathBuf,
}

/// A document with a recognisable `name:tag` that failed validation.
#[derive(Debug, Clone)]
pub struct Broken {
    /// Its file.
    pub path: PathBuf,
    /// Why it is invalid.
    pub diagnostics: Diagnostics,
}

/// Nodes, interfaces and launchers of a list of repositories, by identity.
#[derive(Debug, Clone, Default)]
pub struct RepoIndex {
    repositories: Vec<PathBuf>,
    nodes: BTreeMap<Identity, Vec<Entry<NodeDoc>>>,
    interfaces: BTreeMap<Identity, Vec<Entry<InterfaceDoc>>>,
    pairings: BTreeMap<Identity, Vec<Entry<PairingDoc>>>,
    launchers: BTreeMap<String, Vec<PathBuf>>,
    /// Launchers an index lists at a path that is no file.
    missing_launchers: BTreeMap<String, Vec<PathBuf>>,
    broken: BTreeMap<(DocumentKind, Identity), Broken>,
    findings: Diagnostics,
    /// Git repositories listed but not fetched: named where a lookup
    /// finds nothing.
    unfetched: Vec<String>,
}

impl RepoIndex {
    /// Scans the local repositories of `list` ([`scan`](Self::scan)),
    /// remembering the git repositories it names that are not fetched.
    pub fn of(list: &RepositoryList) -> RepoIndex {
        let mut index = RepoIndex::scan(&list.paths);
        index.unfetched = list
            .unfetched()
            .map(|g| g.short_name().to_string())
            .collect();
        index
    }

    /// Scans `repositories` in order. Problems that do not stop the scan
    /// (duplicates, missing directories, unreadable files) become warnings
    /// in [`findings`](Self::findings).
    ///
    /// A repository with a `peppy_repository.json5` is read through it:
    /// only the files it lists are read, each of which must declare the
    /// kind and identity it is listed under (else an `UnmatchedIndexEntry`
    /// warning at the entry). A listed file that does not parse (a kind
    /// peppy does not read yet, say) is kept as [`broken`](Self::broken)
    /// under its listed identity, so what depends on it says why. An
    /// invalid index skips its repository (its errors become warnings).
    /// Without an index the repository is walked ([`json5_files`]).
    pub fn scan(repositories: &[PathBuf]) -> RepoIndex {
        let mut index = RepoIndex {
            repositories: repositories.to_vec(),
            ..RepoIndex::default()
        };
        for repo in repositories {
            if !repo.is_dir() {
                index.findings.push(
                    Diagnostic::warning(
                        Code::DependencyNotFound,
                        format!(
                            "repository `{}` is not a directory; skipped",
                            repo.display()
                        ),
                    )
                    .with_file_path(repo),
                );
                continue;
            }
            let index_file = repo.join(REPOSITORY_INDEX_FILE);
            if index_file.is_file() {
                index.scan_indexed(repo, &index_file);
                continue;
            }
            for entry in json5_files(repo) {
                let path = match entry {
                    Ok(p) => p,
                    Err(e) => {
                        index.findings.push(Diagnostic::warning(
                            Code::CannotRead,
                            format!("while scanning `{}`: {e}", repo.display()),
                        ));
                        continue;
                    }
                };
                let path = path.as_path();
                index.add_file(path, repo);
            }
        }
        index
    }

    /// Reads the files `index_file` lists.
    fn scan_indexed(&mut self, repo: &Path, index_file: &Path) {
        let doc = match RepositoryIndexDoc::load(index_file) {
            Ok((doc, warnings)) => {
                self.findings.extend(warnings);
                doc
            }
            Err(errors) => {
                for mut d in errors {
                    d.severity = Severity::Warning;
                    self.findings.push(d);
                }
                self.findings.push(
                    Diagnostic::warning(
                        Code::DependencyNotFound,
                        format!(
                            "repository `{}` is skipped: its `{REPOSITORY_INDEX_FILE}` is invalid",
                            repo.display()
                        ),
                    )
                    .with_file_path(index_file)
                    .with_help(format!(
                        "fix it, or write it again with `peppy-launch repo index {}`",
                        repo.display()
                    )),
                );
                return;
            }
        };
        for (key, listed) in &doc.entries {
            self.add_listed(repo, key, listed);
        }
    }

    /// Reads one listed file, which must declare what it is listed as.
    fn add_listed(&mut self, repo: &Path, key: &IndexKey, listed: &Listed) {
        let path = repo.join(&listed.path);
        let unmatched = |why: &str| {
            listed
                .loc
                .warning(
                    Code::UnmatchedIndexEntry,
                    format!("{key} is listed at `{}`, {why}", listed.path),
                )
                .with_help(format!(
                    "the index is out of date: write it again with `peppy-launch repo index {}`",
                    repo.display()
                ))
        };
        if !path.is_file() {
            let why = if path.exists() {
                "which is not a file"
            } else {
                "which does not exist"
            };
            self.findings.push(unmatched(why));
            if key.section == IndexSection::Launchers {
                self.missing_launchers
                    .entry(key.name.clone())
                    .or_default()
                    .push(path);
            }
            return;
        }
        let (file, sha) = match SourceFile::read(&path) {
            Ok(v) => v,
            Err(d) => {
                self.findings
                    .push(unmatched(&format!("which cannot be read: {}", d.message)));
                return;
            }
        };
        let (root, read) = match crate::json::parse(&file) {
            Ok(parsed) => parsed,
            // Not JSON5: what it was meant to be cannot be checked, so it
            // is taken as listed; whoever reads it says what is wrong.
            Err(diagnostics) => {
                if key.section == IndexSection::Launchers {
                    self.launchers
                        .entry(key.name.clone())
                        .or_default()
                        .push(path);
                } else {
                    self.add_broken(key, &path, diagnostics);
                }
                return;
            }
        };
        let stem = path.file_stem().and_then(OsStr::to_str);
        if let Some(why) = mismatch(key, &root, stem) {
            self.findings.push(unmatched(&why));
            return;
        }
        match key.section {
            // The path is what a launcher is looked up for; reading it is
            // its caller's (which reports a kind peppy does not read yet).
            IndexSection::Launchers => {
                self.launchers
                    .entry(key.name.clone())
                    .or_default()
                    .push(path);
                return;
            }
            // Nothing in peppy reads these yet.
            IndexSection::McpExposures => return,
            IndexSection::Nodes | IndexSection::Contracts | IndexSection::Pairings => {}
        }
        match parse_tree(&file, &sha, &root, read) {
            Ok((Document::Node(n), _)) if key.section == IndexSection::Nodes => {
                let entry = Entry {
                    doc: Arc::new(n),
                    path,
                    repository: repo.to_path_buf(),
                };
                self.insert_node(entry.doc.identity(), entry);
            }
            Ok((Document::Interface(i), _)) if key.section == IndexSection::Contracts => {
                let entry = Entry {
                    doc: Arc::new(i),
                    path,
                    repository: repo.to_path_buf(),
                };
                self.insert_interface(entry.doc.identity.clone(), entry);
            }
            Ok((Document::Pairing(p), _)) if key.section == IndexSection::Pairings => {
                let entry = Entry {
                    doc: Arc::new(p),
                    path,
                    repository: repo.to_path_buf(),
                };
                self.insert_pairing(entry);
            }
            // `mismatch` matched the section to the kind already.
            Ok((other, _)) => self.findings.push(unmatched(&format!(
                "which peppy reads as a `{}` document",
                other.kind().as_str()
            ))),
            Err(diagnostics) => self.add_broken(key, &path, diagnostics),
        }
    }

    /// Adds a pairing document; a second one of the same identity is a
    /// finding, the first found wins.
    fn insert_pairing(&mut self, entry: Entry<PairingDoc>) {
        let id = entry.doc.identity.clone();
        let entries = self.pairings.entry(id.clone()).or_default();
        if let Some(first) = entries.first() {
            self.findings.push(duplicate(&id, &first.path, &entry.path));
        }
        entries.push(entry);
    }

    /// Keeps an invalid listed document under the identity it is listed as.
    fn add_broken(&mut self, key: &IndexKey, path: &Path, diagnostics: Diagnostics) {
        if let (Some(kind), Some(id)) = (key.section.document_kind(), key.identity()) {
            self.broken.entry((kind, id)).or_insert(Broken {
                path: path.to_path_buf(),
                diagnostics,
            });
        }
    }

    fn add_file(&mut self, path: &Path, repo: &Path) {
        let Ok((file, sha)) = SourceFile::read(path) else {
            // Unreadable files are not ours to judge here; `validate` reports them.
            return;
        };
        let is_node_file = path.file_name() == Some(OsStr::new("peppy.json5"));
        let Ok((root, read)) = crate::json::parse(&file) else {
            return;
        };
        let kind = detect_kind(&root);
        match kind {
            Some(DocumentKind::Node) if !is_node_file => return,
            Some(
                DocumentKind::Node
                | DocumentKind::Interface
                | DocumentKind::Launcher
                | DocumentKind::Pairing,
            ) => {}
            _ => return,
        }
        match parse_tree(&file, &sha, &root, read) {
            Ok((Document::Node(n), _)) => {
                let id = n.identity();
                self.insert_node(
                    id,
                    Entry {
                        doc: Arc::new(n),
                        path: path.to_path_buf(),
                        repository: repo.to_path_buf(),
                    },
                );
            }
            Ok((Document::Interface(i), _)) => {
                let id = i.identity.clone();
                self.insert_interface(
                    id,
                    Entry {
                        doc: Arc::new(i),
                        path: path.to_path_buf(),
                        repository: repo.to_path_buf(),
                    },
                );
            }
            Ok((Document::Pairing(p), _)) => self.insert_pairing(Entry {
                doc: Arc::new(p),
                path: path.to_path_buf(),
                repository: repo.to_path_buf(),
            }),
            Ok((Document::Launcher(_), _)) => self.add_launcher(path),
            Ok((Document::Repositories(_) | Document::RepositoryIndex(_), _)) => {}
            // A launcher is found by its file name, valid or not: whoever
            // asks for it by name is told what is wrong with it.
            Err(_) if kind == Some(DocumentKind::Launcher) => self.add_launcher(path),
            Err(diagnostics) => {
                if let (Some(kind), Some(id)) = (kind, peek_identity(&root)) {
                    self.broken.entry((kind, id)).or_insert(Broken {
                        path: path.to_path_buf(),
                        diagnostics,
                    });
                }
            }
        }
    }

    /// Lists a launcher file under its stem (launchers have no tag).
    fn add_launcher(&mut self, path: &Path) {
        let stem = path
            .file_stem()
            .and_then(OsStr::to_str)
            .unwrap_or_default()
            .to_string();
        self.launchers
            .entry(stem)
            .or_default()
            .push(path.to_path_buf());
    }

    /// Adds a node ahead of everything scanned (a launcher's deployed nodes
    /// win over repository copies of the same `name:tag`).
    pub fn overlay_node(&mut self, doc: Arc<NodeDoc>, path: PathBuf) {
        let id = doc.identity();
        let entries = self.nodes.entry(id).or_default();
        if entries.first().is_some_and(|e| e.path == path) {
            return;
        }
        let repository = path.parent().map(Path::to_path_buf).unwrap_or_default();
        entries.insert(
            0,
            Entry {
                doc,
                path,
                repository,
            },
        );
    }

    fn insert_node(&mut self, id: Identity, entry: Entry<NodeDoc>) {
        let entries = self.nodes.entry(id.clone()).or_default();
        if let Some(first) = entries.first() {
            self.findings.push(duplicate(&id, &first.path, &entry.path));
        }
        entries.push(entry);
    }

    fn insert_interface(&mut self, id: Identity, entry: Entry<InterfaceDoc>) {
        let entries = self.interfaces.entry(id.clone()).or_default();
        if let Some(first) = entries.first() {
            self.findings.push(duplicate(&id, &first.path, &entry.path));
        }
        entries.push(entry);
    }

    /// The repositories scanned, in priority order.
    pub fn repositories(&self) -> &[PathBuf] {
        &self.repositories
    }

    /// The winning node document for `id`.
    pub fn node(&self, id: &Identity) -> Option<&Entry<NodeDoc>> {
        self.nodes.get(id).and_then(|v| v.first())
    }

    /// Every interface document for `id`, winner first.
    pub fn interfaces(&self, id: &Identity) -> &[Entry<InterfaceDoc>] {
        self.interfaces.get(id).map_or(&[], Vec::as_slice)
    }

    /// The winning interface document for `id`.
    pub fn interface(&self, id: &Identity) -> Option<&Entry<InterfaceDoc>> {
        self.interfaces(id).first()
    }

    /// The winning pairing document for `id`.
    pub fn pairing(&self, id: &Identity) -> Option<&Entry<PairingDoc>> {
        self.pairings.get(id).and_then(|v| v.first())
    }

    /// A launcher by file stem.
    pub fn launcher(&self, stem: &str) -> Option<&Path> {
        self.launchers
            .get(stem)
            .and_then(|v| v.first())
            .map(PathBuf::as_path)
    }

    /// Every launcher file with this stem, in repository order: more than
    /// one is ambiguous (see [`find_launcher`](Self::find_launcher)).
    pub fn launchers_named(&self, stem: &str) -> &[PathBuf] {
        self.launchers.get(stem).map_or(&[], Vec::as_slice)
    }

    /// The stem of every launcher found, in name order.
    pub fn launcher_names(&self) -> impl Iterator<Item = &str> {
        self.launchers.keys().map(String::as_str)
    }

    /// The launcher a bare name means: the one file of that stem in the
    /// repositories. Launchers have no tag and no priority order, so a
    /// name two files answer to is ambiguous rather than won by the first
    /// repository.
    pub fn find_launcher(&self, name: &str) -> Result<&Path, LauncherLookup> {
        match self.launchers_named(name) {
            [one] => Ok(one),
            [] => match self.missing_launchers.get(name) {
                Some(listed) => Err(LauncherLookup::Missing {
                    name: name.to_string(),
                    listed: listed.clone(),
                }),
                None => Err(LauncherLookup::NotFound {
                    name: name.to_string(),
                    suggestion: crate::diag::did_you_mean(name, self.launcher_names())
                        .map(str::to_string),
                    searched: self.searched(),
                }),
            },
            many => Err(LauncherLookup::Ambiguous {
                name: name.to_string(),
                paths: many.to_vec(),
            }),
        }
    }

    /// An invalid document that claims `id`.
    pub fn broken(&self, kind: DocumentKind, id: &Identity) -> Option<&Broken> {
        self.broken.get(&(kind, id.clone()))
    }

    /// Every indexed node identity.
    pub fn node_ids(&self) -> impl Iterator<Item = &Identity> {
        self.nodes.keys()
    }

    /// Every indexed interface identity.
    pub fn interface_ids(&self) -> impl Iterator<Item = &Identity> {
        self.interfaces.keys()
    }

    /// Every indexed pairing identity.
    pub fn pairing_ids(&self) -> impl Iterator<Item = &Identity> {
        self.pairings.keys()
    }

    /// Every pairing document indexed as `id`, the winning one first.
    pub fn pairings(&self, id: &Identity) -> &[Entry<PairingDoc>] {
        self.pairings.get(id).map_or(&[], Vec::as_slice)
    }

    /// Warnings from the scan.
    pub fn findings(&self) -> &Diagnostics {
        &self.findings
    }

    /// `` `a`, `b` `` list of repositories for "not found" messages.
    pub fn searched(&self) -> String {
        let unfetched = if self.unfetched.is_empty() {
            String::new()
        } else {
            format!(
                "; not fetched yet: {} (`peppy-launch repo refresh` fetches them)",
                self.unfetched.join(", ")
            )
        };
        if self.repositories.is_empty() {
            return format!(
                "no repositories are configured (pass a path, set PEPPY_REPOSITORIES, or add a peppy_repositories.json5){unfetched}"
            );
        }
        let list: Vec<String> = self
            .repositories
            .iter()
            .map(|p| format!("`{}`", p.display()))
            .collect();
        format!("searched {}{unfetched}", list.join(", "))
    }
}

/// Why a launcher name found no one launcher in the repositories.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LauncherLookup {
    /// No repository has a launcher of that name.
    #[error("no repository provides launcher `{name}`{}; {searched}", suggestion.as_ref().map(|s| format!(" (did you mean `{s}`?)")).unwrap_or_default())]
    NotFound {
        /// The name given.
        name: String,
        /// The closest launcher name found, if one is close.
        suggestion: Option<String>,
        /// Where it was looked for.
        searched: String,
    },
    /// Several files answer to the name.
    #[error("launcher `{name}` is ambiguous: {} answer to it; give the path of the one you mean", paths.iter().map(|p| format!("`{}`", p.display())).collect::<Vec<_>>().join(" and "))]
    Ambiguous {
        /// The name given.
        name: String,
        /// Every file of that stem, in repository order.
        paths: Vec<PathBuf>,
    },
    /// A repository's index lists the launcher at a path that is no file.
    #[error("launcher `{name}` is listed at {}, which does not exist; write the repository's index again with `peppy-launch repo index`", listed.iter().map(|p| format!("`{}`", p.display())).collect::<Vec<_>>().join(" and "))]
    Missing {
        /// The name given.
        name: String,
        /// Where the indexes list it.
        listed: Vec<PathBuf>,
    },
}

fn duplicate(id: &Identity, first: &Path, second: &Path) -> Diagnostic {
    Diagnostic::warning(
        Code::DuplicateInRepositories,
        format!(
            "`{id}` is defined twice: `{}` wins over `{}`",
            first.display(),
            second.display()
        ),
    )
    .with_file_path(second)
    .with_help("repositories earlier in the list win; remove or rename one of them")
}
