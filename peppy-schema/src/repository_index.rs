//! Repository indexes (`peppy_schema: "repository/v1"`, the file
//! `peppy_repository.json5`): which file of a repository declares each
//! node, contract, pairing, MCP exposure and launcher, so that a repository
//! is read through its index rather than by walking it.
//!
//! Also what `repo index` writes ([`declared_in`], every document a
//! directory declares, read from raw trees so that it works for kinds peppy
//! does not read yet) and how `repo index --check` compares that with the
//! committed index ([`check_index`]).

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;
use std::sync::Arc;

use serde::Serialize;

use crate::diag::{Code, Diagnostic, Diagnostics, Severity};
use crate::document::{Document, DocumentKind, Parsed, load_as, parse_as};
use crate::json::{Member, Node, Value};
use crate::loc::Loc;
use crate::model::Identity;
use crate::names::{check_name, check_tag};
use crate::read::{Reader, display_path, join};
use crate::repos::json5_files;
use crate::source::{SourceFile, sha256_hex};

/// The file name of a repository's index.
pub const REPOSITORY_INDEX_FILE: &str = "peppy_repository.json5";

/// The `peppy_schema` of a repository index.
pub const REPOSITORY_INDEX_SCHEMA: &str = "repository/v1";

/// The sections of a repository index, in the order they are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IndexSection {
    /// `nodes`: `node_v1` and `node/v1` documents, by `name` and `tag`.
    Nodes,
    /// `launchers`: `launcher_v1` and `launcher/v1` documents, by file stem.
    Launchers,
    /// `contracts`: `interface_v1` and `contract/v1` documents.
    Contracts,
    /// `pairings`: `pairing/v1` documents.
    Pairings,
    /// `mcp_exposures`: `mcp_exposure/v1` documents.
    McpExposures,
}

impl IndexSection {
    /// Every section, in the order they are written.
    pub const ALL: [IndexSection; 5] = [
        IndexSection::Nodes,
        IndexSection::Launchers,
        IndexSection::Contracts,
        IndexSection::Pairings,
        IndexSection::McpExposures,
    ];

    /// The section's key: `nodes`, `launchers`, ...
    pub fn key(self) -> &'static str {
        match self {
            IndexSection::Nodes => "nodes",
            IndexSection::Launchers => "launchers",
            IndexSection::Contracts => "contracts",
            IndexSection::Pairings => "pairings",
            IndexSection::McpExposures => "mcp_exposures",
        }
    }

    /// What one entry is, for messages: `node`, `launcher`, ...
    pub fn noun(self) -> &'static str {
        match self {
            IndexSection::Nodes => "node",
            IndexSection::Launchers => "launcher",
            IndexSection::Contracts => "contract",
            IndexSection::Pairings => "pairing",
            IndexSection::McpExposures => "MCP exposure",
        }
    }

    /// The section that lists documents of `peppy_schema` `schema`, in
    /// either spelling. `launcher_fragment/v1` (never launchable), the index
    /// itself and unknown kinds are listed nowhere.
    pub fn of_schema(schema: &str) -> Option<IndexSection> {
        match schema {
            "node_v1" | "node/v1" => Some(IndexSection::Nodes),
            "interface_v1" | "contract/v1" => Some(IndexSection::Contracts),
            "pairing/v1" => Some(IndexSection::Pairings),
            "mcp_exposure/v1" => Some(IndexSection::McpExposures),
            "launcher_v1" | "launcher/v1" => Some(IndexSection::Launchers),
            _ => None,
        }
    }

    /// Whether entries have a tag level (every section but `launchers`).
    pub fn is_tagged(self) -> bool {
        self != IndexSection::Launchers
    }

    /// The kind peppy reads documents of this section as, if it reads them.
    pub(crate) fn document_kind(self) -> Option<DocumentKind> {
        match self {
            IndexSection::Nodes => Some(DocumentKind::Node),
            IndexSection::Contracts => Some(DocumentKind::Interface),
            IndexSection::Launchers => Some(DocumentKind::Launcher),
            IndexSection::Pairings | IndexSection::McpExposures => None,
        }
    }
}

/// What one index entry lists: a section, a name and (except for
/// launchers) a tag.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct IndexKey {
    /// The section.
    pub section: IndexSection,
    /// The name (a launcher's file stem).
    pub name: String,
    /// The tag; `None` for launchers.
    pub tag: Option<String>,
}

impl IndexKey {
    /// A node, contract, pairing or MCP exposure entry.
    pub fn tagged(section: IndexSection, identity: &Identity) -> IndexKey {
        IndexKey {
            section,
            name: identity.name.clone(),
            tag: Some(identity.tag.clone()),
        }
    }

    /// A launcher entry, by file stem.
    pub fn launcher(stem: impl Into<String>) -> IndexKey {
        IndexKey {
            section: IndexSection::Launchers,
            name: stem.into(),
            tag: None,
        }
    }

    /// `name:tag`, if the entry has a tag.
    pub fn identity(&self) -> Option<Identity> {
        self.tag.as_ref().map(|t| Identity::new(&self.name, t))
    }

    /// `name:tag`, or a launcher's stem.
    pub fn id(&self) -> String {
        match &self.tag {
            Some(tag) => format!("{}:{tag}", self.name),
            None => self.name.clone(),
        }
    }
}

/// `node `cam:v1``, `launcher `demo``.
impl fmt::Display for IndexKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} `{}`", self.section.noun(), self.id())
    }
}

/// Where an index lists an entry's file.
#[derive(Debug, Clone)]
pub struct Listed {
    /// The file, relative to the repository root, `/`-separated.
    pub path: String,
    /// Where the `path` value is in the index.
    pub loc: Loc,
}

/// A parsed, validated `peppy_repository.json5`.
#[derive(Debug, Clone)]
pub struct RepositoryIndexDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// Every entry, in section, name and tag order.
    pub entries: BTreeMap<IndexKey, Listed>,
}

impl RepositoryIndexDoc {
    /// Reads and parses a `peppy_repository.json5`.
    pub fn load(path: &Path) -> Parsed<RepositoryIndexDoc> {
        load_as(path, DocumentKind::RepositoryIndex).map(|(d, w)| match d {
            Document::RepositoryIndex(r) => (r, w),
            _ => unreachable!("load_as checked the kind"),
        })
    }

    /// Parses a repository index from text.
    pub fn parse(
        path: impl Into<std::path::PathBuf>,
        text: impl Into<String>,
    ) -> Parsed<RepositoryIndexDoc> {
        let text = text.into();
        let sha = sha256_hex(text.as_bytes());
        parse_as(
            &SourceFile::new(path, text),
            &sha,
            DocumentKind::RepositoryIndex,
        )
        .map(|(d, w)| match d {
            Document::RepositoryIndex(r) => (r, w),
            _ => unreachable!("parse_as checked the kind"),
        })
    }
}

pub(crate) fn parse_repository_index(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<RepositoryIndexDoc> {
    let mut r = Reader::new(file, diags);
    let mut allowed = vec!["peppy_schema"];
    allowed.extend(IndexSection::ALL.map(IndexSection::key));
    let obj = r.object(root, "", &allowed)?;
    let mut entries = BTreeMap::new();
    for section in IndexSection::ALL {
        let Some(node) = obj.get(section.key()) else {
            continue;
        };
        let Some(names) = map(&mut r, node, section.key()) else {
            continue;
        };
        for m in names {
            let name_path = join(section.key(), &m.key);
            let name_ok = match check_name(&m.key) {
                Ok(()) => true,
                Err(why) => {
                    let help = if section.is_tagged() {
                        format!("a {} is listed by its `manifest.name`", section.noun())
                    } else {
                        "a launcher is listed by its file name without `.json5`".to_string()
                    };
                    r.error_help(
                        Code::InvalidName,
                        m.key_span,
                        &name_path,
                        format!("invalid {} name `{}`: {why}", section.noun(), m.key),
                        help,
                    );
                    false
                }
            };
            if !section.is_tagged() {
                if let Some(listed) = entry(&mut r, &m.value, &name_path)
                    && name_ok
                {
                    entries.insert(IndexKey::launcher(&m.key), listed);
                }
                continue;
            }
            let Some(tags) = map(&mut r, &m.value, &name_path) else {
                continue;
            };
            for t in tags {
                let tag_path = join(&name_path, &t.key);
                let tag_ok = match check_tag(&t.key, false) {
                    Ok(()) => true,
                    Err(why) => {
                        r.error(
                            Code::InvalidTag,
                            t.key_span,
                            &tag_path,
                            format!(
                                "invalid tag `{}` of {} `{}`: {why}",
                                t.key,
                                section.noun(),
                                m.key
                            ),
                        );
                        false
                    }
                };
                if let Some(listed) = entry(&mut r, &t.value, &tag_path)
                    && name_ok
                    && tag_ok
                {
                    let key = IndexKey {
                        section,
                        name: m.key.clone(),
                        tag: Some(t.key.clone()),
                    };
                    entries.insert(key, listed);
                }
            }
        }
    }
    (!r.diags.has_errors()).then(|| RepositoryIndexDoc {
        file: file.clone(),
        entries,
    })
}

/// An object whose keys are names or tags (any key is accepted here; the
/// caller checks each).
fn map<'n>(r: &mut Reader<'_>, node: &'n Node, path: &str) -> Option<&'n [Member]> {
    match &node.value {
        Value::Object(members) => Some(members),
        other => {
            r.error(
                Code::WrongType,
                node.span,
                path,
                format!(
                    "expected an object for `{}`, found {}",
                    display_path(path),
                    other.kind()
                ),
            );
            None
        }
    }
}

/// `{ path }` of one entry.
fn entry(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<Listed> {
    let obj = r.object(node, path, &["path"])?;
    let value = r.required(&obj, "path")?;
    let value_path = obj.path_of("path");
    let text = r.string(value, &value_path)?;
    if let Err(why) = check_index_path(&text) {
        r.error_help(
            Code::NonCanonicalPath,
            value.span,
            &value_path,
            format!("`path` `{text}` is not canonical: {why}"),
            "write the file's path from the repository root, segments separated by `/`, e.g. `cameras/rgb_camera.json5`",
        );
        return None;
    }
    Some(Listed {
        path: text,
        loc: r.loc(value.span, &value_path),
    })
}

/// Checks an index `path`: non-empty, repository-relative, `/`-separated,
/// with no `.`, `..` or empty segment and no trailing `/`.
pub fn check_index_path(path: &str) -> Result<(), String> {
    if path.is_empty() {
        return Err("it is empty".into());
    }
    if path.contains('\\') {
        return Err("it contains a backslash; separate segments with `/`".into());
    }
    if path.starts_with('/') {
        return Err("it starts with `/`; paths are relative to the repository root".into());
    }
    if path.ends_with('/') {
        return Err("it ends with `/`; it names a file".into());
    }
    for segment in path.split('/') {
        match segment {
            "" => return Err("it has an empty segment (`//`)".into()),
            "." => return Err("it has a `.` segment".into()),
            ".." => return Err("it has a `..` segment".into()),
            _ => {}
        }
    }
    Ok(())
}

/// The `peppy_schema` a tree is written in and the index section listing
/// it, read without validating anything else. A legacy node
/// (`schema_version`, no `peppy_schema`) is a node.
pub(crate) fn peek_section(root: &Node) -> Option<(String, IndexSection)> {
    if !matches!(root.value, Value::Object(_)) {
        return None;
    }
    match root.get("peppy_schema") {
        Some(schema) => {
            let s = schema.as_str()?;
            IndexSection::of_schema(s).map(|section| (s.to_string(), section))
        }
        None => root
            .get("schema_version")
            .map(|_| ("schema_version".to_string(), IndexSection::Nodes)),
    }
}

/// `manifest.name` / `manifest.tag` of a tree, when both are strings.
pub(crate) fn peek_identity(root: &Node) -> Option<Identity> {
    let m = root.get("manifest")?;
    Some(Identity::new(
        m.get("name")?.as_str()?,
        m.get("tag")?.as_str()?,
    ))
}

/// Why a listed file does not declare `key`, from its raw tree; `None`
/// when it does. `file_stem` is the listed file's name without its
/// extension (a launcher is listed by it).
pub(crate) fn mismatch(key: &IndexKey, root: &Node, file_stem: Option<&str>) -> Option<String> {
    let Some((schema, section)) = peek_section(root) else {
        return Some(match root.get("peppy_schema").and_then(Node::as_str) {
            Some("launcher_fragment/v1") => {
                "which is a `launcher_fragment/v1` document (fragments are never listed)"
                    .to_string()
            }
            Some(s) => format!(
                "which is not a {} (its `peppy_schema` is `{s}`)",
                key.section.noun()
            ),
            None => "which is not a peppy document (no `peppy_schema`)".to_string(),
        });
    };
    if section != key.section {
        return Some(format!(
            "which is not a {} (its `peppy_schema` is `{schema}`)",
            key.section.noun()
        ));
    }
    if !key.section.is_tagged() {
        return match file_stem {
            Some(stem) if stem == key.name => None,
            Some(stem) => Some(format!(
                "which is launcher `{stem}` (a launcher is listed by its file stem)"
            )),
            None => Some("whose file name is not UTF-8".to_string()),
        };
    }
    match (peek_identity(root), key.identity()) {
        (Some(declared), Some(listed)) if declared != listed => {
            Some(format!("which declares `{declared}`"))
        }
        _ => None,
    }
}

/// Every entry a directory declares: what `repo index` writes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DeclaredIndex {
    /// Each entry's declaring file, relative to the directory,
    /// `/`-separated.
    pub entries: BTreeMap<IndexKey, String>,
}

impl DeclaredIndex {
    /// How many entries a section has.
    pub fn count(&self, section: IndexSection) -> usize {
        self.entries.keys().filter(|k| k.section == section).count()
    }

    /// The index as `repo index` writes it: sections in [`IndexSection::ALL`]
    /// order (empty ones left out), names and tags sorted, two-space
    /// indentation, keys unquoted where JSON5 allows.
    pub fn render(&self) -> String {
        let mut root = vec![(
            "peppy_schema".to_string(),
            Out::Str(REPOSITORY_INDEX_SCHEMA.to_string()),
        )];
        for section in IndexSection::ALL {
            let mut names: Vec<(String, Out)> = Vec::new();
            for (key, path) in self.entries.iter().filter(|(k, _)| k.section == section) {
                let leaf = Out::Obj(vec![("path".to_string(), Out::Str(path.clone()))]);
                let Some(tag) = &key.tag else {
                    names.push((key.name.clone(), leaf));
                    continue;
                };
                // Entries come sorted, so one name's tags are adjacent.
                if !matches!(names.last(), Some((name, _)) if *name == key.name) {
                    names.push((key.name.clone(), Out::Obj(Vec::new())));
                }
                if let Some((_, Out::Obj(tags))) = names.last_mut() {
                    tags.push((tag.clone(), leaf));
                }
            }
            if !names.is_empty() {
                root.push((section.key().to_string(), Out::Obj(names)));
            }
        }
        let mut out = String::new();
        write_out(&mut out, &Out::Obj(root), 0);
        out.push('\n');
        out
    }
}

/// A value of the written index.
enum Out {
    Str(String),
    Obj(Vec<(String, Out)>),
}

fn write_out(out: &mut String, value: &Out, depth: usize) {
    match value {
        Out::Str(s) => quote(out, s),
        Out::Obj(members) if members.is_empty() => out.push_str("{}"),
        Out::Obj(members) => {
            out.push_str("{\n");
            for (i, (key, value)) in members.iter().enumerate() {
                out.push_str(&"  ".repeat(depth + 1));
                if is_bare_key(key) {
                    out.push_str(key);
                } else {
                    quote(out, key);
                }
                out.push_str(": ");
                write_out(out, value, depth + 1);
                if i + 1 < members.len() {
                    out.push(',');
                }
                out.push('\n');
            }
            out.push_str(&"  ".repeat(depth));
            out.push('}');
        }
    }
}

/// Whether `key` can be written unquoted: an ASCII identifier that no
/// reader could take for a literal.
fn is_bare_key(key: &str) -> bool {
    let mut chars = key.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_' || c == '$')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '$')
        && !matches!(key, "true" | "false" | "null" | "Infinity" | "NaN")
}

/// `s` as a double-quoted string literal.
fn quote(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 || c == '\u{2028}' || c == '\u{2029}' => {
                out.push_str(&format!("\\u{:04x}", c as u32))
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// Every document `dir` declares, as `repo index` lists them: each `.json5`
/// under `dir` (hidden entries and [`SKIPPED_DIRS`](crate::SKIPPED_DIRS)
/// left out) is classified by its `peppy_schema` and listed under its
/// `manifest.name` and `manifest.tag` (a launcher under its file stem),
/// read from the raw tree so that every kind is listed, also those peppy
/// does not read yet. `launcher_fragment/v1` files and files that are not
/// peppy documents are not listed; a file that cannot be read or is not
/// JSON5 is skipped with a warning.
///
/// Errors: one identity claimed by two files (`DuplicateIdentity`), an
/// identity the index could not hold (`InvalidName`, `InvalidTag`), a
/// document without one (`MissingKey`, `WrongType`), a directory that
/// cannot be walked (`CannotRead`).
pub fn declared_in(dir: &Path) -> Parsed<DeclaredIndex> {
    let mut diags = Diagnostics::new();
    if !dir.is_dir() {
        diags.push(
            Diagnostic::error(
                Code::CannotRead,
                format!("`{}` is not a directory", dir.display()),
            )
            .with_file_path(dir),
        );
        return Err(diags);
    }
    let mut claims: BTreeMap<IndexKey, Vec<String>> = BTreeMap::new();
    for found in json5_files(dir) {
        let path = match found {
            Ok(p) => p,
            Err(e) => {
                diags.push(
                    Diagnostic::error(
                        Code::CannotRead,
                        format!("cannot walk `{}`: {e}", dir.display()),
                    )
                    .with_file_path(e.path().unwrap_or(dir)),
                );
                continue;
            }
        };
        // Hidden directories are never entered; hidden files are skipped too.
        if path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with('.'))
        {
            continue;
        }
        let file = match SourceFile::read(&path) {
            Ok((file, _)) => file,
            Err(d) => {
                diags.push(skipped(*d));
                continue;
            }
        };
        let root = match crate::json::parse(&file) {
            Ok((root, _)) => root,
            Err(errors) => {
                for d in errors {
                    diags.push(skipped(d));
                }
                continue;
            }
        };
        let Some((schema, section)) = peek_section(&root) else {
            continue;
        };
        let rel = match relative(dir, &path) {
            Some(rel) => rel,
            None => {
                diags.push(
                    Diagnostic::error(
                        Code::NonCanonicalPath,
                        format!(
                            "`{}` cannot be listed: its path is not UTF-8",
                            path.display()
                        ),
                    )
                    .with_file_path(&path),
                );
                continue;
            }
        };
        match declared_key(&file, &root, &schema, section, &path) {
            Ok(key) => claims.entry(key).or_default().push(rel),
            Err(d) => diags.push(*d),
        }
    }
    let mut declared = DeclaredIndex::default();
    for (key, paths) in claims {
        if paths.len() > 1 {
            let what = if key.section.is_tagged() {
                "manifests"
            } else {
                "files"
            };
            diags.push(
                Diagnostic::error(
                    Code::DuplicateIdentity,
                    format!(
                        "{} {} {what} claim `{}`: {}",
                        paths.len(),
                        key.section.noun(),
                        key.id(),
                        paths.join(", ")
                    ),
                )
                .with_file_path(&dir.join(&paths[1]))
                .with_help(
                    "one identity has one file in a repository: rename or remove all but one",
                ),
            );
            continue;
        }
        declared
            .entries
            .insert(key, paths.into_iter().next().unwrap_or_default());
    }
    diags.into_result(declared)
}

/// A finding about a file `repo index` passes over, as a warning.
fn skipped(mut d: Diagnostic) -> Diagnostic {
    d.severity = Severity::Warning;
    d.help = Some(match d.help.take() {
        Some(h) => format!("{h}; `repo index` skipped this file"),
        None => "`repo index` skipped this file".to_string(),
    });
    d
}

/// `path` relative to `dir`, `/`-separated, if it is UTF-8.
fn relative(dir: &Path, path: &Path) -> Option<String> {
    let rel = path.strip_prefix(dir).ok()?;
    let parts: Option<Vec<&str>> = rel.iter().map(|c| c.to_str()).collect();
    Some(parts?.join("/"))
}

/// The entry a document claims, its name and tag held to the index's rules.
fn declared_key(
    file: &Arc<SourceFile>,
    root: &Node,
    schema: &str,
    section: IndexSection,
    path: &Path,
) -> Result<IndexKey, Box<Diagnostic>> {
    if !section.is_tagged() {
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        return match check_name(stem) {
            Ok(()) => Ok(IndexKey::launcher(stem)),
            Err(why) => fail(
                Diagnostic::error(
                    Code::InvalidName,
                    format!("launcher file stem `{stem}` cannot be listed: {why}"),
                )
                .with_file_path(path)
                .with_help(
                    "a launcher is listed by its file name without `.json5`: rename the file",
                ),
            ),
        };
    }
    let at_root = crate::source::Span::new(root.span.start, root.span.start + 1);
    let Some(manifest) = root.get("manifest") else {
        return fail(
            Diagnostic::error(
                Code::MissingKey,
                format!("a `{schema}` document without a `manifest` cannot be listed"),
            )
            .at(file, at_root),
        );
    };
    let field = |key: &str| -> Result<(&str, &Node), Box<Diagnostic>> {
        match manifest.get(key) {
            Some(n) => match n.as_str() {
                Some(s) => Ok((s, n)),
                None => fail(
                    Diagnostic::error(
                        Code::WrongType,
                        format!(
                            "expected a string for `manifest.{key}`, found {}",
                            n.value.kind()
                        ),
                    )
                    .at(file, n.span)
                    .with_key_path(format!("manifest.{key}")),
                ),
            },
            None => fail(
                Diagnostic::error(
                    Code::MissingKey,
                    format!("a `{schema}` document without `manifest.{key}` cannot be listed"),
                )
                .at(
                    file,
                    crate::source::Span::new(manifest.span.start, manifest.span.start + 1),
                )
                .with_key_path("manifest"),
            ),
        }
    };
    let (name, name_node) = field("name")?;
    let (tag, tag_node) = field("tag")?;
    if let Err(why) = check_name(name) {
        return fail(
            Diagnostic::error(
                Code::InvalidName,
                format!("`manifest.name` `{name}` cannot be listed: {why}"),
            )
            .at(file, name_node.span)
            .with_key_path("manifest.name"),
        );
    }
    if let Err(why) = check_tag(tag, false) {
        return fail(
            Diagnostic::error(
                Code::InvalidTag,
                format!("`manifest.tag` `{tag}` cannot be listed: {why}"),
            )
            .at(file, tag_node.span)
            .with_key_path("manifest.tag"),
        );
    }
    Ok(IndexKey::tagged(section, &Identity::new(name, tag)))
}

/// `Err` of a boxed finding (a [`Diagnostic`] is large).
fn fail<T>(d: Diagnostic) -> Result<T, Box<Diagnostic>> {
    Err(Box::new(d))
}

/// How a committed index differs from what its directory declares.
#[derive(Debug, Clone)]
pub enum Drift {
    /// Declared in the tree, missing from the index.
    Unlisted {
        /// The entry.
        key: IndexKey,
        /// The declaring file.
        declared_at: String,
    },
    /// Listed at another path than the file that declares it.
    Moved {
        /// The entry.
        key: IndexKey,
        /// Where the index lists it.
        listed: Listed,
        /// The declaring file.
        declared_at: String,
    },
    /// Listed, but its file is missing, not a file, of another kind, or
    /// declares another identity.
    Unmatched {
        /// The entry.
        key: IndexKey,
        /// Where the index lists it.
        listed: Listed,
        /// What the listed file is instead (`which does not exist`, ...).
        why: String,
    },
}

impl Drift {
    /// The entry that drifted.
    pub fn key(&self) -> &IndexKey {
        match self {
            Drift::Unlisted { key, .. }
            | Drift::Moved { key, .. }
            | Drift::Unmatched { key, .. } => key,
        }
    }

    /// `Unlisted`, `Moved` or `Unmatched`.
    pub fn kind(&self) -> &'static str {
        match self {
            Drift::Unlisted { .. } => "Unlisted",
            Drift::Moved { .. } => "Moved",
            Drift::Unmatched { .. } => "Unmatched",
        }
    }
}

/// One line: `Moved: node `cam:v1` is listed at `old/peppy.json5` (line 7), declared in `cam/peppy.json5``.
impl fmt::Display for Drift {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let line = |l: &Listed| l.loc.file.line_col(l.loc.span.start).line;
        match self {
            Drift::Unlisted { key, declared_at } => write!(
                f,
                "Unlisted: {key} is declared in `{declared_at}`, not listed"
            ),
            Drift::Moved {
                key,
                listed,
                declared_at,
            } => write!(
                f,
                "Moved: {key} is listed at `{}` (line {}), declared in `{declared_at}`",
                listed.path,
                line(listed)
            ),
            Drift::Unmatched { key, listed, why } => write!(
                f,
                "Unmatched: {key} is listed at `{}` (line {}), {why}",
                listed.path,
                line(listed)
            ),
        }
    }
}

/// What `repo index --check` found.
#[derive(Debug, Clone)]
pub struct IndexCheck {
    /// What the directory declares.
    pub declared: DeclaredIndex,
    /// The committed index; `None` when there is none.
    pub index: Option<RepositoryIndexDoc>,
    /// Every difference, in entry order.
    pub drifts: Vec<Drift>,
}

impl IndexCheck {
    /// Whether the committed index is what `repo index` would write (up to
    /// comments and formatting).
    pub fn is_current(&self) -> bool {
        self.index.is_some() && self.drifts.is_empty()
    }
}

/// Compares `dir`'s committed `peppy_repository.json5` with what `dir`
/// declares ([`declared_in`]), reporting every drift at once. `Err`: the
/// tree cannot be indexed, or the committed index is invalid (both are
/// reported together). A missing index is [`IndexCheck::index`] `None`,
/// with every entry `Unlisted`.
pub fn check_index(dir: &Path) -> Parsed<IndexCheck> {
    let mut findings = Diagnostics::new();
    let declared = keep(declared_in(dir), &mut findings);
    let index_path = dir.join(REPOSITORY_INDEX_FILE);
    let index = index_path
        .exists()
        .then(|| keep(RepositoryIndexDoc::load(&index_path), &mut findings));
    let (Some(declared), false) = (declared, findings.has_errors()) else {
        return Err(findings);
    };
    let index = index.flatten();
    let mut drifts = Vec::new();
    let listed = index.as_ref().map(|i| &i.entries);
    for (key, declared_at) in &declared.entries {
        match listed.and_then(|l| l.get(key)) {
            None => drifts.push(Drift::Unlisted {
                key: key.clone(),
                declared_at: declared_at.clone(),
            }),
            Some(l) if l.path != *declared_at => drifts.push(Drift::Moved {
                key: key.clone(),
                listed: l.clone(),
                declared_at: declared_at.clone(),
            }),
            Some(_) => {}
        }
    }
    for (key, l) in listed.into_iter().flatten() {
        if !declared.entries.contains_key(key) {
            drifts.push(Drift::Unmatched {
                key: key.clone(),
                listed: l.clone(),
                why: why_unmatched(dir, key, &l.path),
            });
        }
    }
    drifts.sort_by(|a, b| a.key().cmp(b.key()));
    findings.into_result(IndexCheck {
        declared,
        index,
        drifts,
    })
}

/// The value of `result`, its findings moved to `findings`.
fn keep<T>(result: Parsed<T>, findings: &mut Diagnostics) -> Option<T> {
    match result {
        Ok((value, warnings)) => {
            findings.extend(warnings);
            Some(value)
        }
        Err(errors) => {
            findings.extend(errors);
            None
        }
    }
}

/// What the file an index lists for `key` is instead, when the tree does
/// not declare `key` there.
fn why_unmatched(dir: &Path, key: &IndexKey, listed: &str) -> String {
    let path = dir.join(listed);
    match std::fs::metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return "which does not exist".to_string();
        }
        Err(e) => return format!("which cannot be read: {e}"),
        Ok(m) if !m.is_file() => return "which is not a file".to_string(),
        Ok(_) => {}
    }
    let file = match SourceFile::read(&path) {
        Ok((file, _)) => file,
        Err(d) => return format!("which cannot be read: {}", d.message),
    };
    let Ok((root, _)) = crate::json::parse(&file) else {
        return "which is not valid JSON5".to_string();
    };
    let stem = path.file_stem().and_then(|s| s.to_str());
    mismatch(key, &root, stem).unwrap_or_else(|| {
        "which `repo index` does not read (a hidden or skipped directory, or not a `.json5` file)"
            .to_string()
    })
}
