//! Launcher documents: which nodes to run, how many instances, and how
//! their slots are filled. Two spellings are read into one model: the
//! underscored one (`peppy_schema: "launcher_v1"`, slots filled by
//! `bindings`) and the slashed one (`"launcher/v1"`, slots filled by
//! `links`, plus `framework`). A composed launcher (components,
//! fragments, adjustments, constraints) is read through `crate::compose`:
//! parsed on its own, it is the flat launcher of its default selection.

use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

use serde::Serialize;

use crate::core_nodes::CoreNode;
use crate::diag::{Code, Diagnostic, Diagnostics, list};
use crate::document::Spelling;
use crate::json::{Node, Value};
use crate::names::{check_name, check_tag};
use crate::node::{Identity, read_sha256};
use crate::read::{Loc, Obj, Reader, display_path, index, join};
use crate::source::{SourceFile, Span};

/// Loader variables a launcher may not set: they change what code a
/// process runs rather than how it behaves.
pub const FORBIDDEN_ENV_VARS: &[&str] = &[
    "LD_PRELOAD",
    "LD_LIBRARY_PATH",
    "LD_AUDIT",
    "LD_DEBUG",
    "DYLD_INSERT_LIBRARIES",
    "DYLD_LIBRARY_PATH",
    "DYLD_FRAMEWORK_PATH",
    "BASH_ENV",
    "ENV",
    "CDPATH",
    "IFS",
    "SHELLOPTS",
    "BASHOPTS",
    "PS4",
    "PROMPT_COMMAND",
    "GLOBIGNORE",
];

/// `peppy_schema` of PeppyOS's launcher fragments.
pub(crate) const FRAGMENT_SCHEMA: &str = "launcher_fragment/v1";

/// A `launcher_fragment/v1` document read on its own: it is only a part of
/// the launchers whose `components` name it.
pub(crate) fn fragment_refused(file: &Arc<SourceFile>, schema: &Node) -> Diagnostic {
    Diagnostic::error(
        Code::WrongDocumentKind,
        format!("`{FRAGMENT_SCHEMA}` is a launcher fragment, not a document on its own"),
    )
    .at(file, schema.span)
    .with_key_path("peppy_schema")
    .with_help(
        "a fragment is read through the `components` of a `launcher/v1` launcher; check or resolve that launcher",
    )
}

/// A parsed, validated launcher.
#[derive(Debug, Clone)]
pub struct LauncherDoc {
    /// The document's text.
    pub file: Arc<SourceFile>,
    /// How the document is spelled: `launcher_v1` or `launcher/v1`; it
    /// decides whether instances say `bindings` or `links`.
    pub spelling: Spelling,
    /// `core_nodes`: the machines the stack runs on, in order (empty: one
    /// machine, wherever it is launched).
    pub core_nodes: Vec<CoreNode>,
    /// `deployments`, in order.
    pub deployments: Vec<Deployment>,
    /// `security`: `true` or `false` as written, with where; `None` lets
    /// the launch decide (on as soon as a router is reachable beyond
    /// loopback).
    pub security: Option<(bool, Loc)>,
}

/// One node and its instances.
#[derive(Debug, Clone)]
pub struct Deployment {
    /// Where the node comes from.
    pub source: Source,
    /// Where `source` is.
    pub source_loc: Loc,
    /// Its instances.
    pub instances: Vec<Instance>,
}

/// Where a deployment's node comes from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Source {
    /// A directory (or its `peppy.json5`), relative to the launcher file.
    Local {
        /// The path as written.
        path: PathBuf,
    },
    /// A node found in the repositories.
    Repository {
        /// `name:tag`.
        identity: Identity,
    },
    /// A node in a git repository, at a branch, tag or commit.
    Git {
        /// Repository URL.
        repo: String,
        /// Path of the node inside it.
        path: String,
        /// Branch, tag or commit.
        reference: String,
    },
    /// A node in an archive (`.tar`, `.tar.gz`) by URL, checked by sha256.
    Archive {
        /// Archive URL.
        url: String,
        /// Expected sha256.
        sha256: String,
    },
}

/// When a stopped instance is started again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    /// Never (the default).
    #[default]
    No,
    /// When it exits with a failure.
    OnFailure,
    /// Whenever it exits, until the stack stops.
    Always,
}

/// One instance of a deployment.
#[derive(Debug, Clone)]
pub struct Instance {
    /// Unique across the stack.
    pub instance_id: String,
    /// Where `instance_id` is.
    pub id_loc: Loc,
    /// `links` (`launcher/v1`) or `bindings` (`launcher_v1`, read as
    /// [`LinkValue::Bound`] links), in document order. Only their shape is
    /// checked here: whether a key names a slot and the value fits it is
    /// the plan's business.
    pub links: Vec<Link>,
    /// `framework` (`launcher/v1`); all unset in a `launcher_v1` file.
    pub framework: Framework,
    /// `arguments` as written (checked against the node's parameters when planning).
    pub arguments: Option<Node>,
    /// Where `arguments` is.
    pub arguments_loc: Option<Loc>,
    /// `env_vars`, in document order.
    pub env_vars: Vec<(String, String)>,
    /// The shutdown grace window its `env_vars` set
    /// (`PEPPY_SHUTDOWN_GRACE_SECS`, checked as it was read).
    pub shutdown_grace_secs: Option<f64>,
    /// `restart`.
    pub restart: RestartPolicy,
    /// `core_node`: the machine it runs on, and where that is written.
    pub core_node: Option<(String, Loc)>,
}

/// Per-instance framework knobs (`framework`, `launcher/v1`): fixed,
/// owned by the runtime rather than the node's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct Framework {
    /// `use_sim_time`: follow simulated time; `None` leaves it to the launch.
    pub use_sim_time: Option<bool>,
}

/// One `links` entry (`launcher/v1`): a slot's link_id and what fills it.
#[derive(Debug, Clone)]
pub struct Link {
    /// The slot's link_id as written.
    pub key: String,
    /// Where the key is.
    pub key_loc: Loc,
    /// What fills the slot.
    pub value: LinkValue,
}

/// What a link says about its slot.
#[derive(Debug, Clone)]
pub enum LinkValue {
    /// `launcher_v1`'s `bindings: { key: "inst" }`: one target, under a
    /// slot's link_id or (for a `from_any` slot) a free-form label.
    Bound(LinkTarget),
    /// `"inst"` or `"inst/peer_slot"`: one target.
    One(LinkTarget),
    /// `["a", "b"]`: targets in order, no repeats, maybe none; with where
    /// the list is.
    Many(Vec<LinkTarget>, Loc),
    /// `{ vacant: "<why>" }`: deliberately empty.
    Vacant {
        /// The reason, trimmed and non-empty.
        reason: String,
        /// Where the vacancy is.
        loc: Loc,
    },
}

impl LinkValue {
    /// The targets, in order (none for a vacancy).
    pub fn targets(&self) -> &[LinkTarget] {
        match self {
            LinkValue::One(t) | LinkValue::Bound(t) => std::slice::from_ref(t),
            LinkValue::Many(ts, _) => ts,
            LinkValue::Vacant { .. } => &[],
        }
    }

    /// Where the value is.
    pub fn loc(&self) -> &Loc {
        match self {
            LinkValue::One(t) | LinkValue::Bound(t) => &t.loc,
            LinkValue::Many(_, loc) | LinkValue::Vacant { loc, .. } => loc,
        }
    }
}

/// One target of a link: an instance, and for a pairing the peer's slot
/// when the peer has several that fit.
#[derive(Debug, Clone)]
pub struct LinkTarget {
    /// The instance (the part before `/`).
    pub instance: String,
    /// The peer's slot (the part after `/`), if written.
    pub peer_slot: Option<String>,
    /// Where the target is.
    pub loc: Loc,
}

/// As written: `inst` or `inst/peer_slot`.
impl fmt::Display for LinkTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.peer_slot {
            Some(p) => write!(f, "{}/{p}", self.instance),
            None => f.write_str(&self.instance),
        }
    }
}

impl LauncherDoc {
    /// Every instance with its deployment index.
    pub fn instances(&self) -> impl Iterator<Item = (usize, &Instance)> {
        self.deployments
            .iter()
            .enumerate()
            .flat_map(|(i, d)| d.instances.iter().map(move |inst| (i, inst)))
    }

    /// The core node an instance runs on: its `core_node`, else the first
    /// core node declared (where the stack's home is); `None` when the
    /// launcher names no machines.
    pub fn core_node_of<'a>(&'a self, placed: Option<&'a str>) -> Option<&'a str> {
        placed.or_else(|| self.core_nodes.first().map(|c| c.name.as_str()))
    }

    /// The declared core node named `name`.
    pub fn core_node(&self, name: &str) -> Option<&CoreNode> {
        self.core_nodes.iter().find(|c| c.name == name)
    }

    /// The directory relative sources are resolved against.
    pub fn base_dir(&self) -> PathBuf {
        self.file
            .path()
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    PathBuf::from(".")
                } else {
                    p.to_path_buf()
                }
            })
            .unwrap_or_else(|| PathBuf::from("."))
    }
}

pub(crate) fn parse_launcher(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
    cross_check: bool,
) -> Option<LauncherDoc> {
    let spelling = Spelling::of(root);
    let slashed = spelling == Spelling::SlashIds;
    let mut r = Reader::new(file, diags);
    let keys: &[&str] = if slashed {
        &[
            "peppy_schema",
            "core_nodes",
            "security",
            "deployments",
            "components",
            "adjustments",
            "constraints",
        ]
    } else {
        &["peppy_schema", "core_nodes", "security", "deployments"]
    };
    if slashed && crate::compose::is_composed(root) {
        return crate::compose::default_flat(file, r.diags, cross_check);
    }
    let obj = r.object(root, "", keys)?;
    let core_nodes = obj
        .get("core_nodes")
        .map(|n| crate::core_nodes::parse_core_nodes(&mut r, n, spelling))
        .unwrap_or_default();
    let security = obj.get("security").and_then(|n| {
        r.bool(n, "security")
            .map(|on| (on, r.loc(n.span, "security")))
    });
    let list_node = r.required(&obj, "deployments")?;
    let items = r.array(list_node, "deployments")?;
    if items.is_empty() {
        r.error(
            Code::InvalidValue,
            list_node.span,
            "deployments",
            "`deployments` is empty: a launcher runs at least one node",
        );
    }
    let mut deployments = Vec::new();
    for (i, item) in items.iter().enumerate() {
        if let Some(d) = parse_deployment(&mut r, item, &index("deployments", i), spelling) {
            deployments.push(d);
        }
    }
    if r.diags.has_errors() {
        return None;
    }
    let doc = LauncherDoc {
        file: file.clone(),
        spelling,
        core_nodes,
        deployments,
        security,
    };
    if cross_check {
        r.diags.extend(stack_rules(&doc));
        if r.diags.has_errors() {
            return None;
        }
    }
    Some(doc)
}

/// Rules 7 and 8 of SPEC 6.1, which need the whole launcher: unique
/// instance ids and binding targets that exist. Run by every parse of a
/// launcher document and by the binding plan.
pub fn stack_rules(doc: &LauncherDoc) -> Diagnostics {
    let mut diags = Diagnostics::new();
    let deployments = &doc.deployments;
    let all: Vec<&Instance> = deployments
        .iter()
        .flat_map(|d| d.instances.iter())
        .collect();
    for (i, inst) in all.iter().enumerate() {
        if let Some(first) = all[..i].iter().find(|o| o.instance_id == inst.instance_id) {
            let lc = first.id_loc.file.line_col(first.id_loc.span.start);
            diags.push(
                inst.id_loc
                    .error(Code::DuplicateInstanceId, format!("duplicate instance_id `{}`", inst.instance_id))
                    .with_help(format!(
                        "instance_ids are unique across the whole stack; `{}` is already used at line {}, column {}",
                        inst.instance_id, lc.line, lc.column
                    )),
            );
        }
    }
    // In launcher order, each once.
    let mut ids: Vec<&str> = Vec::new();
    for inst in &all {
        if !ids.contains(&inst.instance_id.as_str()) {
            ids.push(&inst.instance_id);
        }
    }
    for inst in &all {
        if let Some(placed) = &inst.core_node {
            crate::core_nodes::check_placement(
                &doc.core_nodes,
                &inst.instance_id,
                placed,
                &mut diags,
            );
        }
    }
    for inst in &all {
        // The instance part of every target (a peer slot after `/` is the
        // plan's to check).
        for link in &inst.links {
            for t in link.value.targets() {
                if ids.contains(&t.instance.as_str()) {
                    continue;
                }
                let help = match crate::diag::did_you_mean(&t.instance, ids.iter().copied()) {
                    Some(s) => format!(
                        "did you mean `{s}`? instances in this launcher: {}",
                        list(ids.iter().copied())
                    ),
                    None => format!("instances in this launcher: {}", list(ids.iter().copied())),
                };
                let (code, message) = match link.value {
                    LinkValue::Bound(_) => (
                        Code::UnknownBindingTarget,
                        format!(
                            "binding `{}` on instance `{}` names `{}`, which no deployment declares",
                            link.key, inst.instance_id, t.instance
                        ),
                    ),
                    _ => (
                        Code::UnknownInstanceId,
                        format!(
                            "link `{}` on instance `{}` names instance `{}`, which no deployment declares",
                            link.key, inst.instance_id, t.instance
                        ),
                    ),
                };
                diags.push(t.loc.error(code, message).with_help(help));
            }
        }
    }
    diags
}

pub(crate) fn parse_deployment(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    spelling: Spelling,
) -> Option<Deployment> {
    let obj = r.object(node, path, &["source", "instances"])?;
    let source_node = r.required(&obj, "source");
    let source = source_node.and_then(|s| parse_source(r, s, &obj.path_of("source"), spelling));
    let mut instances = Vec::new();
    let mut ok = true;
    if let Some(list) = r.required(&obj, "instances") {
        let ipath = obj.path_of("instances");
        if let Some(items) = r.array(list, &ipath) {
            if items.is_empty() {
                r.error_help(
                    Code::EmptyDeployment,
                    list.span,
                    &ipath,
                    "deployment has no instances",
                    "add `{ instance_id: \"...\" }`, or remove the deployment",
                );
                ok = false;
            }
            for (i, item) in items.iter().enumerate() {
                match parse_instance(r, item, &index(&ipath, i), spelling) {
                    Some(inst) => instances.push(inst),
                    None => ok = false,
                }
            }
        }
    }
    let source_node = source_node?;
    let source = source?;
    ok.then(|| Deployment {
        source,
        source_loc: r.loc(source_node.span, &obj.path_of("source")),
        instances,
    })
}

/// A deployment's source. PeppyOS reads only `{ name, tag }` and
/// `{ name: "n:t" }`; peppy keeps `local`, git and archive sources in both
/// spellings (documented extension).
fn parse_source(r: &mut Reader<'_>, node: &Node, path: &str, spelling: Spelling) -> Option<Source> {
    let obj = r.object(
        node,
        path,
        &[
            "local", "name", "tag", "repo", "path", "ref", "url", "sha256",
        ],
    )?;
    let has = |k: &str| obj.get(k).is_some();
    let shape = if has("local") {
        "local"
    } else if has("repo") || has("path") || has("ref") {
        "git"
    } else if has("url") {
        "url"
    } else if has("name") {
        "name"
    } else {
        "none"
    };
    let allowed: &[&str] = match shape {
        "local" => &["local"],
        "git" => &["repo", "path", "ref"],
        "url" => &["url", "sha256"],
        "name" => &["name", "tag"],
        _ => &[],
    };
    let stray: Vec<&str> = obj
        .members
        .iter()
        .map(|m| m.key.as_str())
        .filter(|k| !allowed.contains(k))
        .collect();
    if shape == "none" || !stray.is_empty() {
        r.error_help(
            Code::InvalidSource,
            node.span,
            path,
            if shape == "none" {
                "`source` names no node".to_string()
            } else {
                format!("`source` mixes `{shape}` keys with {}", list(stray.iter().copied()))
            },
            "a source is one of: `{ local: \"path\" }`, `{ name: \"n:t\" }`, `{ name, tag }`, `{ repo, path, ref }`, `{ url, sha256 }`",
        );
        return None;
    }
    match shape {
        "local" => {
            let p = r.string(obj.get("local")?, &obj.path_of("local"))?;
            if p.trim().is_empty() {
                r.error(
                    Code::InvalidSource,
                    node.span,
                    path,
                    "`source.local` is empty; give the node's directory relative to the launcher",
                );
                return None;
            }
            Some(Source::Local {
                path: PathBuf::from(p.trim()),
            })
        }
        "name" => repository_source(r, &obj, spelling),
        "git" => {
            let repo = r
                .required(&obj, "repo")
                .and_then(|n| r.string(n, &obj.path_of("repo")));
            let sub = r
                .required(&obj, "path")
                .and_then(|n| r.string(n, &obj.path_of("path")));
            let reference = r
                .required(&obj, "ref")
                .and_then(|n| r.string(n, &obj.path_of("ref")));
            let (repo, sub, reference) = (repo?, sub?, reference?);
            if sub.starts_with('/') || sub.split('/').any(|c| c == "..") {
                r.error(
                    Code::InvalidSource,
                    obj.get("path")?.span,
                    &obj.path_of("path"),
                    "`source.path` must be relative to the repository and stay inside it",
                );
                return None;
            }
            Some(Source::Git {
                repo,
                path: sub,
                reference,
            })
        }
        _ => {
            let url = r.string(obj.get("url")?, &obj.path_of("url"))?;
            let sha = r
                .required(&obj, "sha256")
                .and_then(|n| read_sha256(r, n, &obj.path_of("sha256")))?;
            Some(Source::Archive { url, sha256: sha })
        }
    }
}

/// `{ name: "n:t" }` or `{ name: "n", tag: "t" }`: a node found in the
/// repositories. `launcher/v1` checks the tag as PeppyOS does (a
/// letter first, no dots); `launcher_v1` also takes dotted versions.
fn repository_source(r: &mut Reader<'_>, obj: &Obj<'_>, spelling: Spelling) -> Option<Source> {
    let name_node = obj.get("name")?;
    let name = r.string(name_node, &obj.path_of("name"))?;
    let identity = match (name.split_once(':'), obj.get("tag")) {
        (Some(_), Some(t)) => {
            r.error_help(
                Code::InvalidSource,
                t.span,
                &obj.path_of("tag"),
                format!("`source.name` `{name}` already has a tag"),
                "write either `{ name: \"n:t\" }` or `{ name: \"n\", tag: \"t\" }`",
            );
            return None;
        }
        (Some((n, t)), None) => Identity::new(n, t),
        (None, Some(t)) => Identity::new(name.clone(), r.string(t, &obj.path_of("tag"))?),
        (None, None) => {
            r.error_help(
                Code::InvalidSource,
                name_node.span,
                &obj.path_of("name"),
                format!("`source.name` `{name}` has no tag"),
                format!("write `{{ name: \"{name}:v1\" }}` or add `tag`"),
            );
            return None;
        }
    };
    let mut ok = true;
    if let Err(why) = check_name(&identity.name) {
        r.error(
            Code::InvalidName,
            name_node.span,
            &obj.path_of("name"),
            format!("invalid node name `{}`: {why}", identity.name),
        );
        ok = false;
    }
    // Dotted tags exist in legacy documents; the repository lookup decides.
    if let Err(why) = check_tag(&identity.tag, spelling == Spelling::UnderscoreIds) {
        r.error(
            Code::InvalidTag,
            name_node.span,
            &obj.path_of("name"),
            format!("invalid tag `{}`: {why}", identity.tag),
        );
        ok = false;
    }
    ok.then_some(Source::Repository { identity })
}

fn parse_instance(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    spelling: Spelling,
) -> Option<Instance> {
    // `restart` is peppy's extension, accepted in both spellings.
    let obj = match spelling {
        Spelling::UnderscoreIds => object_except(
            r,
            node,
            path,
            &[
                "instance_id",
                "bindings",
                "arguments",
                "env_vars",
                "restart",
                "core_node",
            ],
            "links",
            "`links` is the slashed spelling (`launcher/v1`); a `launcher_v1` file writes `bindings`",
        ),
        Spelling::SlashIds => object_except(
            r,
            node,
            path,
            &[
                "instance_id",
                "links",
                "arguments",
                "env_vars",
                "framework",
                "restart",
                "core_node",
            ],
            "bindings",
            "`bindings` is the underscored spelling (`launcher_v1`); write `links`",
        ),
    }?;
    let mut ok = true;
    let id = r.required(&obj, "instance_id").and_then(|n| {
        let p = obj.path_of("instance_id");
        let s = r.string(n, &p)?;
        match check_name(&s) {
            Ok(()) => Some((s, r.loc(n.span, &p))),
            Err(why) => {
                r.error(
                    Code::InvalidName,
                    n.span,
                    &p,
                    format!("invalid instance_id `{s}`: {why}"),
                );
                None
            }
        }
    });
    let (links, framework) = match spelling {
        Spelling::UnderscoreIds => (
            parse_bindings(r, &obj, id.as_ref().map(|(i, _)| i.as_str()), &mut ok),
            Framework::default(),
        ),
        Spelling::SlashIds => (
            parse_links(r, &obj, &mut ok),
            parse_framework(r, &obj, &mut ok),
        ),
    };
    let (arguments, arguments_loc) = match obj.get("arguments") {
        Some(a) => {
            let apath = obj.path_of("arguments");
            if !matches!(a.value, Value::Object(_)) {
                r.error(
                    Code::WrongType,
                    a.span,
                    &apath,
                    format!(
                        "expected an object of parameter values for `{apath}`, found {}",
                        a.value.kind()
                    ),
                );
                ok = false;
            }
            (Some(a.clone()), Some(r.loc(a.span, &apath)))
        }
        None => (None, None),
    };
    let (env_vars, shutdown_grace_secs) = parse_env_vars(r, &obj, spelling, &mut ok);
    let restart = parse_restart(r, &obj, &mut ok);
    let core_node = match obj.get("core_node") {
        Some(n) => {
            let p = obj.path_of("core_node");
            match r.string(n, &p) {
                Some(name) => Some((name, r.loc(n.span, &p))),
                None => {
                    ok = false;
                    None
                }
            }
        }
        None => None,
    };
    let (instance_id, id_loc) = id?;
    ok.then_some(Instance {
        instance_id,
        id_loc,
        links,
        framework,
        arguments,
        arguments_loc,
        env_vars,
        shutdown_grace_secs,
        restart,
        core_node,
    })
}

/// `bindings`: keys (slot link_ids or free-form labels) and producer
/// instances; a repeated key is `DuplicateBindingKey` (rule 6).
fn parse_bindings(r: &mut Reader<'_>, obj: &Obj<'_>, id: Option<&str>, ok: &mut bool) -> Vec<Link> {
    let mut bindings = Vec::new();
    if let Some(b) = obj.get("bindings") {
        let bpath = obj.path_of("bindings");
        match &b.value {
            Value::Object(members) => {
                for m in members {
                    let kpath = format!("{bpath}.{}", m.key);
                    if !r.link_key(&m.key, m.key_span, &kpath, true) {
                        *ok = false;
                        continue;
                    }
                    let Some(target) = r.string(&m.value, &kpath) else {
                        *ok = false;
                        continue;
                    };
                    bindings.push(Link {
                        key: m.key.clone(),
                        key_loc: r.loc(m.key_span, &kpath),
                        value: LinkValue::Bound(LinkTarget {
                            instance: target,
                            peer_slot: None,
                            loc: r.loc(m.value.span, &kpath),
                        }),
                    });
                }
            }
            other => {
                r.error(
                    Code::WrongType,
                    b.span,
                    &bpath,
                    format!(
                        "expected an object of `key: \"instance_id\"` for `{bpath}`, found {}",
                        other.kind()
                    ),
                );
                *ok = false;
            }
        }
    }
    // The JSON layer reports a repeated key; inside `bindings` that is rule 6.
    if let (Some(b), Some(id)) = (obj.get("bindings"), id) {
        for d in r.diags.iter_mut() {
            let inside = d
                .span()
                .is_some_and(|s| s.start >= b.span.start && s.end <= b.span.end);
            if d.code == Code::DuplicateKey && inside {
                d.code = Code::DuplicateBindingKey;
                d.message = format!(
                    "instance `{id}` has binding key {} twice",
                    d.message.trim_start_matches("duplicate key ")
                );
                *ok = false;
            }
        }
    }
    bindings
}

/// `env_vars`, refusing loader and shell start-up variables.
/// `launcher/v1` also takes PeppyOS's stricter shape: a name is a shell
/// identifier and a value holds only characters a shell leaves alone (a
/// container node gets them through a script the shell sources).
fn parse_env_vars(
    r: &mut Reader<'_>,
    obj: &Obj<'_>,
    spelling: Spelling,
    ok: &mut bool,
) -> (Vec<(String, String)>, Option<f64>) {
    let mut env_vars = Vec::new();
    let mut grace = None;
    if let Some(e) = obj.get("env_vars") {
        let epath = obj.path_of("env_vars");
        match &e.value {
            Value::Object(members) => {
                for m in members {
                    let kpath = format!("{epath}.{}", m.key);
                    let upper = m.key.to_ascii_uppercase();
                    if spelling == Spelling::SlashIds && !is_shell_identifier(&m.key) {
                        r.error_help(
                            Code::ForbiddenEnvVar,
                            m.key_span,
                            &kpath,
                            format!("environment variable name `{}` is not a shell identifier", m.key),
                            "a name starts with a letter or `_` and holds only letters, digits and `_`",
                        );
                        *ok = false;
                    } else if m.key.is_empty() || m.key.contains('=') || m.key.contains('\0') {
                        r.error(
                            Code::ForbiddenEnvVar,
                            m.key_span,
                            &kpath,
                            format!("invalid environment variable name {:?}", m.key),
                        );
                        *ok = false;
                    } else if FORBIDDEN_ENV_VARS.contains(&upper.as_str()) {
                        r.error_help(
                            Code::ForbiddenEnvVar,
                            m.key_span,
                            &kpath,
                            format!("`{}` may not be set by a launcher", m.key),
                            "loader and shell start-up variables change which code runs; set them outside peppy if you must",
                        );
                        *ok = false;
                    }
                    match r.string(&m.value, &kpath) {
                        Some(v) if spelling == Spelling::SlashIds && !is_shell_safe_value(&v) => {
                            r.error_help(
                                Code::ForbiddenEnvVar,
                                m.value.span,
                                &kpath,
                                format!(
                                    "value of environment variable `{}` holds characters a node cannot receive intact",
                                    m.key
                                ),
                                "a value may hold letters, digits and `_ - . / : , = @ + %` (no whitespace, quotes or shell metacharacters)",
                            );
                            *ok = false;
                        }
                        Some(v) if m.key == crate::SHUTDOWN_GRACE_ENV => {
                            match crate::grace_window_env(Some(&v)) {
                                Ok(window) => {
                                    grace = window.map(|w| w.as_secs_f64());
                                    env_vars.push((m.key.clone(), v));
                                }
                                Err(why) => {
                                    r.error(
                                        Code::InvalidValue,
                                        m.value.span,
                                        &kpath,
                                        format!("invalid shutdown grace window: {why}"),
                                    );
                                    *ok = false;
                                }
                            }
                        }
                        Some(v) => env_vars.push((m.key.clone(), v)),
                        None => *ok = false,
                    }
                }
            }
            other => {
                r.error(
                    Code::WrongType,
                    e.span,
                    &epath,
                    format!(
                        "expected an object of `NAME: \"value\"` for `{epath}`, found {}",
                        other.kind()
                    ),
                );
                *ok = false;
            }
        }
    }
    (env_vars, grace)
}

/// `restart`: `no` (default), `on-failure` or `always`.
fn parse_restart(r: &mut Reader<'_>, obj: &Obj<'_>, ok: &mut bool) -> RestartPolicy {
    match obj.get("restart") {
        None => RestartPolicy::No,
        Some(n) => {
            let rpath = obj.path_of("restart");
            match r.string(n, &rpath).as_deref() {
                Some("no") => RestartPolicy::No,
                Some("on-failure") => RestartPolicy::OnFailure,
                Some("always") => RestartPolicy::Always,
                Some(other) => {
                    r.error_help(
                        Code::InvalidValue,
                        n.span,
                        &rpath,
                        format!("unknown restart policy `{other}`"),
                        "accepted: `no`, `on-failure`, `always`",
                    );
                    *ok = false;
                    RestartPolicy::No
                }
                None => {
                    *ok = false;
                    RestartPolicy::No
                }
            }
        }
    }
}

/// `[A-Za-z_][A-Za-z0-9_]*`.
fn is_shell_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c == '_' || c.is_ascii_alphabetic())
        && chars.all(|c| c == '_' || c.is_ascii_alphanumeric())
}

/// Letters, digits and `_ - . / : , = @ + %`: what a shell sourcing the
/// value leaves as written.
fn is_shell_safe_value(value: &str) -> bool {
    value.chars().all(|c| {
        c.is_ascii_alphanumeric()
            || matches!(c, '_' | '-' | '.' | '/' | ':' | ',' | '=' | '@' | '+' | '%')
    })
}

/// An object whose keys must be in `allowed`, where `other` (the other
/// spelling's name for one of them) is refused with `help` saying so.
fn object_except<'n>(
    r: &mut Reader<'_>,
    node: &'n Node,
    path: &str,
    allowed: &[&str],
    other: &str,
    help: &str,
) -> Option<Obj<'n>> {
    let Value::Object(members) = &node.value else {
        return r.object(node, path, allowed);
    };
    for m in members {
        if m.key == other {
            r.error_help(
                Code::UnknownKey,
                m.key_span,
                &join(path, &m.key),
                format!("unknown key `{}` in `{}`", m.key, display_path(path)),
                help,
            );
        } else if !allowed.contains(&m.key.as_str()) {
            r.unknown_key(m, path, allowed);
        }
    }
    Some(Obj {
        node,
        members,
        path: path.to_string(),
    })
}

/// `framework: { use_sim_time?: bool }` (`launcher/v1`).
fn parse_framework(r: &mut Reader<'_>, obj: &Obj<'_>, ok: &mut bool) -> Framework {
    let Some(n) = obj.get("framework") else {
        return Framework::default();
    };
    let fpath = obj.path_of("framework");
    let Some(fobj) = r.object(n, &fpath, &["use_sim_time"]) else {
        *ok = false;
        return Framework::default();
    };
    if fobj.members.iter().any(|m| m.key != "use_sim_time") {
        *ok = false;
    }
    let use_sim_time = fobj.get("use_sim_time").and_then(|b| {
        let v = r.bool(b, &fobj.path_of("use_sim_time"));
        *ok &= v.is_some();
        v
    });
    Framework { use_sim_time }
}

/// `links` (`launcher/v1`): link_id -> `"inst"`, `"inst/peer_slot"`,
/// `[targets]` or `{ vacant: "<why>" }`. Only the shape is checked: which
/// keys and values fit the node's slots is decided when planning.
fn parse_links(r: &mut Reader<'_>, obj: &Obj<'_>, ok: &mut bool) -> Vec<Link> {
    let mut links = Vec::new();
    let Some(l) = obj.get("links") else {
        return links;
    };
    let lpath = obj.path_of("links");
    let Value::Object(members) = &l.value else {
        r.error(
            Code::WrongType,
            l.span,
            &lpath,
            format!(
                "expected an object of `link_id: target` for `{lpath}`, found {}",
                l.value.kind()
            ),
        );
        *ok = false;
        return links;
    };
    for m in members {
        let kpath = join(&lpath, &m.key);
        let key_ok = r.link_key(&m.key, m.key_span, &kpath, false);
        let value = parse_link_value(r, &m.value, &kpath, &m.key);
        match value {
            Some(value) if key_ok => links.push(Link {
                key: m.key.clone(),
                key_loc: r.loc(m.key_span, &kpath),
                value,
            }),
            _ => *ok = false,
        }
    }
    links
}

/// Help for a malformed target.
const TARGET_HELP: &str = "a target is an instance id (`\"cam\"`) or an instance and its peer's slot (`\"planner/deliberation\"`)";

pub(crate) fn parse_link_value(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    key: &str,
) -> Option<LinkValue> {
    match &node.value {
        Value::String(s) => link_target(r, s, node.span, path, key).map(LinkValue::One),
        Value::Array(items) => {
            let mut targets: Vec<LinkTarget> = Vec::with_capacity(items.len());
            let mut ok = true;
            for (i, item) in items.iter().enumerate() {
                let ipath = index(path, i);
                let Some(s) = r.string(item, &ipath) else {
                    ok = false;
                    continue;
                };
                let Some(t) = link_target(r, &s, item.span, &ipath, key) else {
                    ok = false;
                    continue;
                };
                if let Some(first) = targets
                    .iter()
                    .find(|f| f.instance == t.instance && f.peer_slot == t.peer_slot)
                {
                    let at = first.loc.file.line_col(first.loc.span.start);
                    let d = t
                        .loc
                        .error(
                            Code::DuplicateLinkTarget,
                            format!("link `{key}` lists `{t}` twice"),
                        )
                        .with_help(format!(
                            "`{t}` is already listed at line {}, column {}; a target fills a slot once",
                            at.line, at.column
                        ));
                    r.diags.push(d);
                    ok = false;
                    continue;
                }
                targets.push(t);
            }
            ok.then(|| LinkValue::Many(targets, r.loc(node.span, path)))
        }
        Value::Object(_) => {
            let vobj = r.object(node, path, &["vacant"])?;
            let reason_node = r.required(&vobj, "vacant")?;
            let vpath = vobj.path_of("vacant");
            let reason = r.string(reason_node, &vpath)?;
            let reason = reason.trim();
            if reason.is_empty() {
                r.error_help(
                    Code::InvalidVacancy,
                    reason_node.span,
                    &vpath,
                    format!("vacancy of link `{key}` gives no reason"),
                    "say why the slot is empty: `{ vacant: \"no camera on this rig\" }`",
                );
                return None;
            }
            // Another key was reported as unknown: a vacancy is exactly one key.
            (vobj.members.len() == 1).then(|| LinkValue::Vacant {
                reason: reason.to_string(),
                loc: r.loc(node.span, path),
            })
        }
        other => {
            r.error(
                Code::WrongType,
                node.span,
                path,
                format!(
                    "expected a target (`\"inst\"` or `\"inst/peer_slot\"`), a list of targets, or `{{ vacant: \"<why>\" }}` for `{path}`, found {}",
                    other.kind()
                ),
            );
            None
        }
    }
}

/// `inst` or `inst/peer_slot`: non-empty, at most one `/`, non-empty halves.
fn link_target(
    r: &mut Reader<'_>,
    s: &str,
    span: Span,
    path: &str,
    key: &str,
) -> Option<LinkTarget> {
    let (instance, peer_slot) = match s.split_once('/') {
        Some((i, p)) => (i, Some(p)),
        None => (s, None),
    };
    let why = if s.trim().is_empty() {
        Some(format!("link `{key}` has an empty target"))
    } else if peer_slot.is_some_and(|p| p.contains('/')) {
        Some(format!("link target `{s}` has more than one `/`"))
    } else if instance.is_empty() || peer_slot.is_some_and(str::is_empty) {
        Some(format!("link target `{s}` has an empty side of `/`"))
    } else {
        None
    };
    if let Some(message) = why {
        r.error_help(Code::InvalidLinkTarget, span, path, message, TARGET_HELP);
        return None;
    }
    Some(LinkTarget {
        instance: instance.to_string(),
        peer_slot: peer_slot.map(str::to_string),
        loc: r.loc(span, path),
    })
}
