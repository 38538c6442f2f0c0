//! End-to-end checks from a file on disk: one node (what the build script
//! and the macro need) or a whole launcher (what `check` and `up` share).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::compose::{Resolved, Selection};
use crate::diag::{Code, Diagnostics};
use crate::document::{GitRepository, RepositoryEntry};
use crate::launcher::{Deployment, LauncherDoc, Source};
use crate::node::NodeDoc;
use crate::plan::{BindingPlan, plan_bindings};
use crate::repos::{ListedBy, REPOSITORIES_ENV, RepoIndex, RepositoryList, absolute};
use crate::resolve::{ResolvedNode, resolve_node};

/// Where to look for repositories besides the nearest
/// `peppy_repositories.json5`.
#[derive(Debug, Clone, Default)]
pub struct RepoOptions {
    /// Explicit repository paths (highest priority).
    pub explicit: Vec<PathBuf>,
    /// The value of `PEPPY_REPOSITORIES`; `None` reads the process environment.
    pub env: Option<OsString>,
    /// Repositories searched last, after the nearest list: the user's own
    /// list, which `peppy-launch repo` keeps (none for a build script).
    pub last: Vec<(RepositoryEntry, ListedBy)>,
}

impl RepoOptions {
    fn env_value(&self) -> Option<OsString> {
        self.env
            .clone()
            .or_else(|| std::env::var_os(REPOSITORIES_ENV))
    }

    /// The repositories these options name from `start_dir`, in priority
    /// order: explicit paths, `PEPPY_REPOSITORIES`, the nearest
    /// `peppy_repositories.json5`, then [`last`](Self::last). Git
    /// repositories are not fetched yet ([`RepositoryList::fetch_git`]).
    pub fn discover(&self, start_dir: &Path) -> Result<RepositoryList, Diagnostics> {
        let mut list = self.discover_first(start_dir)?;
        self.add_last(&mut list);
        Ok(list)
    }

    /// [`discover`](Self::discover) without [`last`](Self::last), for a
    /// caller that adds lists of its own before them.
    fn discover_first(&self, start_dir: &Path) -> Result<RepositoryList, Diagnostics> {
        RepositoryList::discover(&self.explicit, self.env_value().as_deref(), start_dir)
    }

    fn add_last(&self, list: &mut RepositoryList) {
        for (entry, by) in &self.last {
            list.add(entry.clone(), by.clone());
        }
    }
}

/// A node resolved from its `peppy.json5`.
#[derive(Debug, Clone)]
pub struct NodeCheck {
    /// The resolved node.
    pub resolved: ResolvedNode,
    /// The repositories used, and the files read to find them.
    pub repositories: RepositoryList,
    /// Warnings.
    pub warnings: Diagnostics,
}

/// Loads and resolves the node document at `path` (a `peppy.json5` or its
/// directory).
pub fn check_node(path: &Path, options: &RepoOptions) -> Result<NodeCheck, Diagnostics> {
    check_node_with(path, options, &NoFetch)
}

/// [`check_node`], with `fetcher` bringing the git repositories the lists
/// name to local trees first.
pub fn check_node_with(
    path: &Path,
    options: &RepoOptions,
    fetcher: &dyn FetchSource,
) -> Result<NodeCheck, Diagnostics> {
    let file = node_file(path);
    let (doc, mut warnings) = NodeDoc::load(&file)?;
    let dir = file.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut repositories = options.discover(&dir)?;
    if repositories.unfetched().next().is_some() {
        warnings.extend(repositories.fetch_git(fetcher));
    }
    let index = RepoIndex::of(&repositories);
    let (resolved, more) = resolve_node(Arc::new(doc), absolute(&file), &index)?;
    warnings.extend(more);
    Ok(NodeCheck {
        resolved,
        repositories,
        warnings,
    })
}

/// `dir/peppy.json5` for a directory, else the path itself.
pub fn node_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("peppy.json5")
    } else {
        path.to_path_buf()
    }
}

/// One deployment of a checked launcher.
#[derive(Debug, Clone)]
pub struct DeployedNode {
    /// The node's directory (where `build_cmd` and `run_cmd` run).
    pub dir: PathBuf,
    /// The resolved node.
    pub resolved: ResolvedNode,
}

/// A launcher checked end to end: every source found, every node resolved,
/// every binding planned.
#[derive(Debug, Clone)]
pub struct StackCheck {
    /// The launcher (a composed one: the flat launcher of `selection`).
    pub launcher: LauncherDoc,
    /// The selection checked, for a composed launcher.
    pub selection: Option<Selection>,
    /// `deployments[i]` is the node of `launcher.deployments[i]`.
    pub deployments: Vec<DeployedNode>,
    /// The binding plan.
    pub plan: BindingPlan,
    /// Repositories used.
    pub repositories: Vec<PathBuf>,
    /// Warnings.
    pub warnings: Diagnostics,
}

impl StackCheck {
    /// The resolved node instance `id` runs.
    pub fn node_of(&self, id: &str) -> Option<&ResolvedNode> {
        self.plan
            .instance(id)
            .map(|i| &self.deployments[i.deployment].resolved)
    }

    /// The instances of the stack whose messages `slot` of `consumer`
    /// takes: its pinned producer, its bound producers, or, for an unbound
    /// `from_any` slot, every other instance that fits it (the binding
    /// engine's rule) and its filter accepts.
    pub fn slot_producers(
        &self,
        consumer: &crate::plan::InstancePlan,
        slot: &crate::binding::SlotPlan,
    ) -> Vec<String> {
        use crate::binding::{RouteFilter, SlotBinding};
        match &slot.binding {
            SlotBinding::Pinned { producer } => vec![producer.clone()],
            SlotBinding::Set { producers, .. } => producers.clone(),
            SlotBinding::FromAnyBound { .. } => match &slot.filter {
                RouteFilter::OnlyFrom(set) => set.iter().cloned().collect(),
                _ => Vec::new(),
            },
            SlotBinding::FromAnyUnbound => self
                .plan
                .instances
                .iter()
                .filter(|p| p.instance_id != consumer.instance_id)
                .filter(|p| {
                    self.node_of(&p.instance_id)
                        .is_some_and(|r| fills(slot.kind, &slot.target, &r.node))
                })
                .filter(|p| slot.filter.accepts(&p.instance_id))
                .map(|p| p.instance_id.clone())
                .collect(),
        }
    }
}

/// Whether `producer` can fill a slot of `kind` wanting `target`: the
/// binding engine's rule.
pub fn fills(kind: crate::SlotKind, target: &crate::Identity, producer: &NodeDoc) -> bool {
    let conforms = crate::binding::conformances(producer);
    crate::binding::Producer {
        node: &producer.identity(),
        conforms_to: &conforms,
    }
    .fits(kind, target)
}

/// Brings the files of a remote source (`{ repo, path, ref }` or
/// `{ url, sha256 }`) to a local directory. The schema only describes
/// sources; a launcher that fetches them (git, downloads, a cache)
/// implements this and passes it to [`check_launcher_with`].
pub trait FetchSource {
    /// The directory holding the source's node (its `peppy.json5`), or why
    /// it cannot be had (its text becomes the deployment's diagnostic).
    /// Called only for [`Source::Git`] and [`Source::Archive`].
    fn fetch(&self, source: &Source) -> Result<PathBuf, FetchError>;

    /// The local tree of a git repository a repository list names, or why
    /// it cannot be had. By default there is none: only a launcher that
    /// keeps a cache of git repositories reads them (`peppy-launch`).
    /// `Ok(None)`: not fetched on purpose (a list read from the cache
    /// only); it is named where a lookup finds nothing.
    fn repository(
        &self,
        repository: &GitRepository,
        by: &ListedBy,
    ) -> Result<Option<PathBuf>, FetchError> {
        let _ = (repository, by);
        Ok(None)
    }
}

/// Why a remote source could not be fetched: the fetcher's own error.
pub type FetchError = Box<dyn std::error::Error + Send + Sync>;

/// The fetcher of [`check_launcher`]: remote sources are not supported.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoFetch;

impl FetchSource for NoFetch {
    fn fetch(&self, source: &Source) -> Result<PathBuf, FetchError> {
        let kind = if matches!(source, Source::Git { .. }) {
            "git (`repo`/`path`/`ref`)"
        } else {
            "archive (`url`/`sha256`)"
        };
        Err(format!(
            "{kind} sources are not supported here (`peppy-launch check` and `up` fetch them)"
        )
        .into())
    }
}

/// Checks the launcher at `path`: all errors of every stage are collected.
/// Remote sources are refused; see [`check_launcher_with`].
pub fn check_launcher(path: &Path, options: &RepoOptions) -> Result<StackCheck, Diagnostics> {
    check_launcher_with(path, options, &NoFetch)
}

/// [`check_launcher`], with `fetcher` bringing remote sources' nodes to
/// local directories first; from there they are checked like `local` ones.
/// A composed launcher is checked for its default selection.
pub fn check_launcher_with(
    path: &Path,
    options: &RepoOptions,
    fetcher: &dyn FetchSource,
) -> Result<StackCheck, Diagnostics> {
    check_launcher_selection(path, &[], options, fetcher)
}

/// [`check_launcher_with`] for the selection `with` words give (`option`
/// or `axis=option`, comma-separated): the launcher is resolved by
/// [`resolve_launcher`](crate::resolve_launcher), then checked.
pub fn check_launcher_selection(
    path: &Path,
    with: &[String],
    options: &RepoOptions,
    fetcher: &dyn FetchSource,
) -> Result<StackCheck, Diagnostics> {
    check_resolved(
        crate::compose::resolve_launcher(path, with)?,
        options,
        fetcher,
    )
}

/// Checks a launcher already resolved for one selection (what
/// `check --all-selections` does for each).
pub fn check_resolved(
    resolved: Resolved,
    options: &RepoOptions,
    fetcher: &dyn FetchSource,
) -> Result<StackCheck, Diagnostics> {
    let selection = resolved.report.selection.clone();
    let (launcher, mut diags) = (resolved.launcher, resolved.warnings);
    let base = absolute(&launcher.base_dir());
    let mut repositories = options.discover_first(&base)?;
    // Remote sources become local directories before anything looks at them.
    let fetched: Vec<Option<PathBuf>> = launcher
        .deployments
        .iter()
        .map(|d| match &d.source {
            Source::Git { .. } | Source::Archive { .. } => match fetcher.fetch(&d.source) {
                Ok(dir) => Some(dir),
                Err(why) => {
                    diags.push(
                        d.source_loc
                            .error(Code::UnsupportedSource, why.to_string())
                            .with_help("a local checkout works offline: `{ local: \"path\" }`"),
                    );
                    None
                }
            },
            _ => None,
        })
        .collect();
    // Local (and fetched) nodes bring their own nearest repositories list.
    for (d, fetched) in launcher.deployments.iter().zip(&fetched) {
        let dir = match (&d.source, fetched) {
            (Source::Local { path }, _) => base.join(path),
            (_, Some(dir)) => dir.clone(),
            _ => continue,
        };
        let dir = if dir.is_file() {
            dir.parent().map(Path::to_path_buf).unwrap_or(dir)
        } else {
            dir
        };
        if let Err(e) = repositories.add_nearest_file(&dir) {
            diags.extend(e);
        }
    }
    // The user's list last: after every list the stack's own files name.
    options.add_last(&mut repositories);
    if repositories.unfetched().next().is_some() {
        diags.extend(repositories.fetch_git(fetcher));
    }
    let mut index = RepoIndex::of(&repositories);

    // Load every deployment's node.
    let loaded: Vec<Option<(Arc<NodeDoc>, PathBuf)>> = launcher
        .deployments
        .iter()
        .zip(&fetched)
        .map(|(d, fetched)| match fetched {
            Some(dir) => load_local(d, dir, &mut diags),
            None => load_deployment(d, &base, &index, &mut diags),
        })
        .collect();
    // Calls round a loop can deadlock: refused before anything runs.
    let mut stack_nodes: Vec<&NodeDoc> = Vec::new();
    for (doc, _) in loaded.iter().flatten() {
        if !stack_nodes.iter().any(|n| n.identity() == doc.identity()) {
            stack_nodes.push(doc);
        }
    }
    if let Some(cycle) = crate::call_cycles::call_cycle(&stack_nodes) {
        diags.push(cycle);
    }
    // What the launcher deploys is what its consumers depend on.
    for (doc, path) in loaded.iter().flatten() {
        index.overlay_node(doc.clone(), path.clone());
    }
    diags.extend(index.findings().clone());

    let mut deployments = Vec::new();
    let mut resolved_ok = Vec::new();
    for entry in &loaded {
        match entry {
            Some((doc, path)) => match resolve_node(doc.clone(), path.clone(), &index) {
                Ok((resolved, w)) => {
                    diags.extend(w);
                    resolved_ok.push(true);
                    deployments.push(Some(DeployedNode {
                        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
                        resolved,
                    }));
                }
                Err(e) => {
                    diags.extend(e);
                    resolved_ok.push(false);
                    deployments.push(None);
                }
            },
            None => {
                resolved_ok.push(false);
                deployments.push(None);
            }
        }
    }
    // Bindings only need manifests, so plan even when a node's own
    // resolution failed: the user sees binding errors in the same run.
    let nodes: Vec<Option<&NodeDoc>> = loaded
        .iter()
        .map(|e| e.as_ref().map(|(d, _)| d.as_ref()))
        .collect();
    let plan = match plan_bindings(&launcher, &nodes) {
        Ok((plan, w)) => {
            diags.extend(w);
            Some(plan)
        }
        Err(e) => {
            diags.extend(e);
            None
        }
    };
    if diags.has_errors() {
        return Err(diags);
    }
    Ok(StackCheck {
        launcher,
        selection,
        deployments: deployments
            .into_iter()
            .map(|d| d.expect("no errors means every node resolved"))
            .collect(),
        plan: plan.expect("no errors means a plan"),
        repositories: repositories.paths,
        warnings: diags,
    })
}

/// The node a deployment's source names, read from its directory (`local`)
/// or found in the repositories (`name:tag`); `None` once reported.
fn load_deployment(
    d: &Deployment,
    base: &Path,
    index: &RepoIndex,
    diags: &mut Diagnostics,
) -> Option<(Arc<NodeDoc>, PathBuf)> {
    match &d.source {
        Source::Local { path } => load_local(d, &base.join(path), diags),
        Source::Repository { identity } => match index.node(identity) {
            Some(e) => Some((e.doc.clone(), e.path.clone())),
            None => {
                let diag = match index.broken(crate::document::DocumentKind::Node, identity) {
                    // Found, but invalid: say so, like a broken dependency.
                    Some(b) => {
                        let first = b
                            .diagnostics
                            .sorted()
                            .first()
                            .map(|first| first.jump_line(None))
                            .unwrap_or_default();
                        d.source_loc
                            .error(
                                Code::DependencyInvalid,
                                format!(
                                    "node `{identity}` is defined in `{}`, but that document is invalid",
                                    b.path.display()
                                ),
                            )
                            .with_help(format!(
                                "first problem: {first} (run `peppy-launch validate {}`)",
                                b.path.display()
                            ))
                    }
                    None => d
                        .source_loc
                        .error(
                            Code::DependencyNotFound,
                            format!("no repository provides node `{identity}`"),
                        )
                        .with_help(index.searched()),
                };
                diags.push(diag);
                None
            }
        },
        // Fetched (or refused) before: see `check_launcher_with`.
        Source::Git { .. } | Source::Archive { .. } => None,
    }
}

/// The node in directory (or file) `path`, for deployment `d`.
fn load_local(
    d: &Deployment,
    path: &Path,
    diags: &mut Diagnostics,
) -> Option<(Arc<NodeDoc>, PathBuf)> {
    let file = node_file(path);
    if !file.is_file() {
        diags.push(
            d.source_loc
                .error(
                    Code::InvalidSource,
                    format!("`{}` has no node: `{}` does not exist", path.display(), file.display()),
                )
                .with_help("`local` is a node's directory (or its peppy.json5), relative to the launcher file; a `repo` source's `path` is relative to the repository"),
        );
        return None;
    }
    match NodeDoc::load(&file) {
        Ok((doc, w)) => {
            diags.extend(w);
            Some((Arc::new(doc), absolute(&file)))
        }
        Err(e) => {
            diags.extend(e);
            None
        }
    }
}
