//! Any peppy document: its kind is read from `peppy_schema`, never from the
//! file name.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::diag::{Code, Diagnostic, Diagnostics, did_you_mean, list};
use crate::interface::{InterfaceDoc, parse_interface};
use crate::json::{Node, Value};
use crate::launcher::{LauncherDoc, parse_launcher};
pub(crate) use crate::model::Spelling;
use crate::node::{NodeDoc, parse_node};
use crate::pairing::{PairingDoc, parse_pairing};
use crate::read::{Loc, Reader, index};
use crate::repository_index::{RepositoryIndexDoc, parse_repository_index};
use crate::source::{SourceFile, sha256_hex};

/// The kinds of peppy documents.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DocumentKind {
    /// `node_v1` (or legacy `schema_version: 1`).
    Node,
    /// `interface_v1`, or `contract/v1` (the same content).
    Interface,
    /// `launcher_v1`, or `launcher/v1` (flat launchers only).
    Launcher,
    /// `peppy_repositories.json5`: a list of repositories.
    Repositories,
    /// `pairing/v1`: two roles and the topics between them.
    Pairing,
    /// `repository/v1` (`peppy_repository.json5`): the index of one
    /// repository.
    RepositoryIndex,
}

impl DocumentKind {
    /// `a node`, `an interface`, ... for messages.
    fn article(self) -> &'static str {
        match self {
            DocumentKind::Interface => "an interface",
            DocumentKind::Node => "a node",
            DocumentKind::Launcher => "a launcher",
            DocumentKind::Repositories => "a repositories",
            DocumentKind::Pairing => "a pairing",
            DocumentKind::RepositoryIndex => "a repository index",
        }
    }

    /// `node`, `interface`, `launcher`, `repositories`, `pairing`, `repository_index`.
    pub fn as_str(self) -> &'static str {
        match self {
            DocumentKind::Node => "node",
            DocumentKind::Interface => "interface",
            DocumentKind::Launcher => "launcher",
            DocumentKind::Repositories => "repositories",
            DocumentKind::Pairing => "pairing",
            DocumentKind::RepositoryIndex => "repository_index",
        }
    }
}

/// The `peppy_schema` values.
pub const SCHEMAS: &[&str] = &[
    "node_v1",
    "interface_v1",
    "launcher_v1",
    "node/v1",
    "contract/v1",
    "pairing/v1",
    "launcher/v1",
    "repository/v1",
];

impl Spelling {
    /// The spelling of a document whose root is `root`.
    pub(crate) fn of(root: &Node) -> Spelling {
        match root.get("peppy_schema").and_then(Node::as_str) {
            Some(s) if s.contains('/') => Spelling::SlashIds,
            _ => Spelling::UnderscoreIds,
        }
    }
}

/// The file name of a repositories list.
pub const REPOSITORIES_FILE: &str = "peppy_repositories.json5";

/// A parsed document of any kind.
#[derive(Debug, Clone)]
#[expect(
    clippy::large_enum_variant,
    reason = "built once per file read; boxing would only add a hop"
)]
pub enum Document {
    /// A node.
    Node(NodeDoc),
    /// An interface.
    Interface(InterfaceDoc),
    /// A launcher.
    Launcher(LauncherDoc),
    /// A repositories list.
    Repositories(RepositoriesDoc),
    /// A pairing.
    Pairing(PairingDoc),
    /// A repository's index.
    RepositoryIndex(RepositoryIndexDoc),
}

impl Document {
    /// This document's kind.
    pub fn kind(&self) -> DocumentKind {
        match self {
            Document::Node(_) => DocumentKind::Node,
            Document::Interface(_) => DocumentKind::Interface,
            Document::Launcher(_) => DocumentKind::Launcher,
            Document::Repositories(_) => DocumentKind::Repositories,
            Document::Pairing(_) => DocumentKind::Pairing,
            Document::RepositoryIndex(_) => DocumentKind::RepositoryIndex,
        }
    }
}

/// `peppy_repositories.json5`: where to look for nodes, interfaces and launchers.
#[derive(Debug, Clone)]
pub struct RepositoriesDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// The repositories, in priority order: by `id` where entries give one
    /// (lower first, as PeppyOS orders them), else as written.
    pub entries: Vec<RepositoryEntry>,
}

/// One repository of a repository list.
#[derive(Debug, Clone)]
pub enum RepositoryEntry {
    /// `{ type: "fs", path }`: a folder, resolved against the list's
    /// directory.
    Folder(PathBuf),
    /// `{ type: "git", url, ref? }`: a git repository, read from a local
    /// cache its fetcher keeps.
    Git(GitRepository),
}

/// A git repository a list names.
#[derive(Debug, Clone)]
pub struct GitRepository {
    /// `url`: anything `git clone` takes. A relative file path is resolved
    /// against the list's directory.
    pub url: String,
    /// `ref`: a branch, a tag or a full commit id; `None` is the
    /// repository's default branch.
    pub reference: Option<String>,
    /// Where the list names it, for messages.
    pub loc: Loc,
}

impl GitRepository {
    /// A short name for messages and `repo remove`: the URL's last
    /// segment without `.git` (`nodes-hub`).
    pub fn short_name(&self) -> &str {
        let trimmed = self.url.trim_end_matches('/');
        let last = trimmed.rsplit(['/', ':']).next().unwrap_or(trimmed);
        last.strip_suffix(".git").unwrap_or(last)
    }

    /// `url` or `url@ref`.
    pub fn describe(&self) -> String {
        match &self.reference {
            Some(r) => format!("{}@{r}", self.url),
            None => self.url.clone(),
        }
    }
}

/// Reads a document's kind without validating the rest.
pub fn detect_kind(root: &Node) -> Option<DocumentKind> {
    match &root.value {
        Value::Array(_) => Some(DocumentKind::Repositories),
        Value::Object(_) => {
            if let Some(s) = root.get("peppy_schema").and_then(Node::as_str) {
                return match s {
                    "node_v1" | "node/v1" => Some(DocumentKind::Node),
                    "interface_v1" | "contract/v1" => Some(DocumentKind::Interface),
                    "launcher_v1" | "launcher/v1" => Some(DocumentKind::Launcher),
                    "pairing/v1" => Some(DocumentKind::Pairing),
                    "repository/v1" => Some(DocumentKind::RepositoryIndex),
                    _ => None,
                };
            }
            root.get("schema_version").map(|_| DocumentKind::Node)
        }
        _ => None,
    }
}

/// The result of parsing: the document and its warnings, or every finding.
pub type Parsed<T> = Result<(T, Diagnostics), Diagnostics>;

/// Parses a document of any kind from text already loaded.
pub fn parse_document(file: &Arc<SourceFile>, sha256: &str) -> Parsed<Document> {
    let (root, diags) = crate::json::parse(file)?;
    parse_tree(file, sha256, &root, diags)
}

/// [`parse_document`] for a caller that already holds `file`'s JSON5 tree
/// (`root`, with the findings of reading it): the text is not read twice.
pub(crate) fn parse_tree(
    file: &Arc<SourceFile>,
    sha256: &str,
    root: &Node,
    mut diags: Diagnostics,
) -> Parsed<Document> {
    let kind = match detect_kind(root) {
        Some(k) => k,
        None => {
            diags.push(unknown_schema(file, root));
            return Err(diags);
        }
    };
    parse_kind(file, sha256, root, kind, diags)
}

/// Parses `file`, requiring it to be of `kind`.
pub fn parse_as(file: &Arc<SourceFile>, sha256: &str, kind: DocumentKind) -> Parsed<Document> {
    let (root, mut diags) = crate::json::parse(file)?;
    match detect_kind(&root) {
        Some(k) if k == kind => parse_kind(file, sha256, &root, kind, diags),
        Some(other) => {
            let at = root.get("peppy_schema").map_or(root.span, |n| n.span);
            diags.push(
                Diagnostic::error(
                    Code::WrongDocumentKind,
                    format!(
                        "expected {} document, found {} document",
                        kind.article(),
                        other.article()
                    ),
                )
                .at(file, at)
                .with_key_path("peppy_schema"),
            );
            Err(diags)
        }
        None => {
            diags.push(unknown_schema(file, &root));
            Err(diags)
        }
    }
}

fn parse_kind(
    file: &Arc<SourceFile>,
    sha256: &str,
    root: &Node,
    kind: DocumentKind,
    mut diags: Diagnostics,
) -> Parsed<Document> {
    let doc = match kind {
        DocumentKind::Node => parse_node(file, root, &mut diags).map(Document::Node),
        DocumentKind::Interface => {
            parse_interface(file, sha256.to_string(), root, &mut diags).map(Document::Interface)
        }
        DocumentKind::Launcher => {
            parse_launcher(file, root, &mut diags, true).map(Document::Launcher)
        }
        DocumentKind::Repositories => {
            parse_repositories(file, root, &mut diags).map(Document::Repositories)
        }
        DocumentKind::Pairing => {
            parse_pairing(file, sha256.to_string(), root, &mut diags).map(Document::Pairing)
        }
        DocumentKind::RepositoryIndex => {
            parse_repository_index(file, root, &mut diags).map(Document::RepositoryIndex)
        }
    };
    match doc {
        Some(d) if !diags.has_errors() => Ok((d, diags)),
        _ => {
            if !diags.has_errors() {
                // A parser returned nothing without saying why: never hide that.
                diags.push(
                    Diagnostic::error(Code::InvalidValue, "document is invalid")
                        .at(file, root.span),
                );
            }
            Err(diags)
        }
    }
}

/// PeppyOS document kinds (slashed schema ids) peppy does not read yet,
/// each with the underscored kind that says the same (empty if none does).
const NOT_YET_READ: &[(&str, &str)] = &[("mcp_exposure/v1", "")];

fn unknown_schema(file: &Arc<SourceFile>, root: &Node) -> Diagnostic {
    if let Some(n) = root.get("peppy_schema")
        && n.as_str() == Some(crate::launcher::FRAGMENT_SCHEMA)
    {
        return crate::launcher::fragment_refused(file, n);
    }
    let not_yet_read = root
        .get("peppy_schema")
        .and_then(Node::as_str)
        .and_then(|s| NOT_YET_READ.iter().find(|(k, _)| *k == s));
    if let (Some((kind, underscored)), Some(n)) = (not_yet_read, root.get("peppy_schema")) {
        let instead = if underscored.is_empty() {
            String::new()
        } else {
            format!("; write this document as `{underscored}` meanwhile")
        };
        return Diagnostic::error(
            Code::UnknownSchema,
            format!("`{kind}` is a PeppyOS document kind peppy does not read yet"),
        )
        .at(file, n.span)
        .with_key_path("peppy_schema")
        .with_help(format!(
            "the slashed schema ids peppy reads are {}{instead} (docs/DOCUMENTS.md)",
            list(SCHEMAS.iter().copied().filter(|s| s.contains('/')))
        ));
    }
    match (&root.value, root.get("peppy_schema")) {
        (Value::Object(_), Some(n)) => {
            let found = n
                .as_str()
                .map_or_else(|| n.value.kind().to_string(), |s| format!("`{s}`"));
            let help = match n
                .as_str()
                .and_then(|s| did_you_mean(s, SCHEMAS.iter().copied()))
            {
                Some(s) => format!(
                    "did you mean `{s}`? known: {}",
                    list(SCHEMAS.iter().copied())
                ),
                None => format!("known: {}", list(SCHEMAS.iter().copied())),
            };
            Diagnostic::error(
                Code::UnknownSchema,
                format!("unknown `peppy_schema` {found}"),
            )
            .at(file, n.span)
            .with_key_path("peppy_schema")
            .with_help(help)
        }
        (Value::Object(_), None) => Diagnostic::error(
            Code::UnknownSchema,
            "missing `peppy_schema`: cannot tell what kind of document this is",
        )
        .at(
            file,
            crate::source::Span::new(root.span.start, root.span.start + 1),
        )
        .with_help(format!(
            "add `peppy_schema: \"node_v1\"` (or one of {})",
            list(SCHEMAS.iter().copied())
        )),
        _ => Diagnostic::error(
            Code::UnknownSchema,
            format!("a peppy document is an object, found {}", root.value.kind()),
        )
        .at(file, root.span),
    }
}

/// Reads and parses a document of any kind from disk.
pub fn load_document(path: &Path) -> Parsed<Document> {
    let (file, sha) = SourceFile::read(path).map_err(|d| Diagnostics::from(*d))?;
    parse_document(&file, &sha)
}

/// Reads and parses a document that must be of `kind`.
pub fn load_as(path: &Path, kind: DocumentKind) -> Parsed<Document> {
    let (file, sha) = SourceFile::read(path).map_err(|d| Diagnostics::from(*d))?;
    parse_as(&file, &sha, kind)
}

impl NodeDoc {
    /// Reads and parses a node document (`peppy.json5`).
    pub fn load(path: &Path) -> Parsed<NodeDoc> {
        load_as(path, DocumentKind::Node).map(|(d, w)| match d {
            Document::Node(n) => (n, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }

    /// Parses a node document from text.
    pub fn parse(path: impl Into<PathBuf>, text: impl Into<String>) -> Parsed<NodeDoc> {
        let text = text.into();
        let sha = sha256_hex(text.as_bytes());
        parse_as(&SourceFile::new(path, text), &sha, DocumentKind::Node).map(|(d, w)| match d {
            Document::Node(n) => (n, w),
            _ => unreachable!("parse_as checked the kind"),
        })
    }
}

impl InterfaceDoc {
    /// Reads and parses an interface document.
    pub fn load(path: &Path) -> Parsed<InterfaceDoc> {
        load_as(path, DocumentKind::Interface).map(|(d, w)| match d {
            Document::Interface(i) => (i, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }

    /// Parses an interface document from text (its sha256 is that of `text`).
    pub fn parse(path: impl Into<PathBuf>, text: impl Into<String>) -> Parsed<InterfaceDoc> {
        let text = text.into();
        let sha = sha256_hex(text.as_bytes());
        parse_as(&SourceFile::new(path, text), &sha, DocumentKind::Interface).map(
            |(d, w)| match d {
                Document::Interface(i) => (i, w),
                _ => unreachable!("parse_as checked the kind"),
            },
        )
    }
}

impl PairingDoc {
    /// Reads and parses a pairing document.
    pub fn load(path: &Path) -> Parsed<PairingDoc> {
        load_as(path, DocumentKind::Pairing).map(|(d, w)| match d {
            Document::Pairing(p) => (p, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }

    /// Parses a pairing document from text (its sha256 is that of `text`).
    pub fn parse(path: impl Into<PathBuf>, text: impl Into<String>) -> Parsed<PairingDoc> {
        let text = text.into();
        let sha = sha256_hex(text.as_bytes());
        parse_as(&SourceFile::new(path, text), &sha, DocumentKind::Pairing).map(|(d, w)| match d {
            Document::Pairing(p) => (p, w),
            _ => unreachable!("parse_as checked the kind"),
        })
    }
}

impl LauncherDoc {
    /// Reads and parses a launcher.
    pub fn load(path: &Path) -> Parsed<LauncherDoc> {
        load_as(path, DocumentKind::Launcher).map(|(d, w)| match d {
            Document::Launcher(l) => (l, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }

    /// Parses a launcher from text.
    pub fn parse(path: impl Into<PathBuf>, text: impl Into<String>) -> Parsed<LauncherDoc> {
        let text = text.into();
        let sha = sha256_hex(text.as_bytes());
        parse_as(&SourceFile::new(path, text), &sha, DocumentKind::Launcher).map(|(d, w)| match d {
            Document::Launcher(l) => (l, w),
            _ => unreachable!("parse_as checked the kind"),
        })
    }
}

impl RepositoriesDoc {
    /// Reads and parses a `peppy_repositories.json5`.
    pub fn load(path: &Path) -> Parsed<RepositoriesDoc> {
        load_as(path, DocumentKind::Repositories).map(|(d, w)| match d {
            Document::Repositories(r) => (r, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }
}

fn parse_repositories(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<RepositoriesDoc> {
    let mut r = Reader::new(file, diags);
    let items = r.array(root, "")?;
    let base = file
        .path()
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let mut entries: Vec<(Option<u64>, RepositoryEntry)> = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index("", i);
        let Some(obj) = r.object(item, &ipath, &["id", "type", "path", "url", "ref"]) else {
            continue;
        };
        let id = obj
            .get("id")
            .and_then(|n| r.uint(n, &obj.path_of("id"), u64::from(u32::MAX)));
        let Some((ty, ty_span)) = r
            .required(&obj, "type")
            .and_then(|t| r.string(t, &obj.path_of("type")).map(|s| (s, t.span)))
        else {
            continue;
        };
        // A field of the other type is a mistake worth naming, not ignoring.
        let stray = |r: &mut Reader, keys: &[&str], ty: &str| {
            for key in keys {
                if let Some(m) = obj.member(key) {
                    r.error(
                        Code::InvalidValue,
                        m.key_span,
                        &obj.path_of(key),
                        format!("a `{ty}` repository has no `{key}`"),
                    );
                }
            }
        };
        match ty.as_str() {
            "fs" => {
                stray(&mut r, &["url", "ref"], "fs");
                if let Some(p) = r
                    .required(&obj, "path")
                    .and_then(|p| r.string(p, &obj.path_of("path")))
                {
                    let p = PathBuf::from(p);
                    let p = if p.is_absolute() { p } else { base.join(p) };
                    entries.push((id, RepositoryEntry::Folder(p)));
                }
            }
            "git" => {
                stray(&mut r, &["path"], "git");
                let Some(url_node) = r.required(&obj, "url") else {
                    continue;
                };
                let Some(url) = r.string(url_node, &obj.path_of("url")) else {
                    continue;
                };
                if url.trim().is_empty() || url.starts_with('-') {
                    // A leading `-` would reach git as an option.
                    r.error(
                        Code::InvalidValue,
                        url_node.span,
                        &obj.path_of("url"),
                        "`url` must be a repository's URL or path (not empty, not starting with `-`)",
                    );
                    continue;
                }
                let reference = match obj.get("ref") {
                    Some(n) => match r.string(n, &obj.path_of("ref")) {
                        Some(s) if !s.trim().is_empty() && !s.starts_with('-') => Some(s),
                        Some(_) => {
                            r.error(
                                Code::InvalidValue,
                                n.span,
                                &obj.path_of("ref"),
                                "`ref` must be a branch, a tag or a commit id",
                            );
                            continue;
                        }
                        None => continue,
                    },
                    None => None,
                };
                let loc = r.loc(item.span, &ipath);
                entries.push((
                    id,
                    RepositoryEntry::Git(GitRepository {
                        url: git_url(&url, &base),
                        reference,
                        loc,
                    }),
                ));
            }
            other => {
                r.error_help(
                    Code::InvalidValue,
                    ty_span,
                    &obj.path_of("type"),
                    format!("unknown repository type `{other}`"),
                    "accepted: `fs` (`{ type: \"fs\", path }`) and `git` (`{ type: \"git\", url, ref? }`)",
                );
            }
        }
    }
    // Lower ids first; entries without one keep their place after them.
    entries.sort_by_key(|(id, _)| id.unwrap_or(u64::MAX));
    (!r.diags.has_errors()).then(|| RepositoriesDoc {
        file: file.clone(),
        entries: entries.into_iter().map(|(_, e)| e).collect(),
    })
}

/// A git URL as the list means it: a relative path is a repository next to
/// the list (`../hub.git`), which git would otherwise read against
/// whatever directory the command runs in.
fn git_url(url: &str, base: &Path) -> String {
    let is_path = !url.contains("://") && !url.contains('@') && !Path::new(url).is_absolute();
    if is_path && (url.starts_with('.') || !url.contains(':')) {
        return base.join(url).display().to_string();
    }
    url.to_string()
}
