//! Reading a composed launcher: its axes, every fragment of every option,
//! adjustments and constraints, each mistake located where it is written.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use super::{Adjustment, Axis, AxisOption, Composition, Constraint, Fragment, Pair};
use crate::diag::{Code, Diagnostic, Diagnostics, did_you_mean, list};
use crate::document::{DocumentKind, Spelling, detect_kind};
use crate::json::{Node, Value};
use crate::launcher::{FRAGMENT_SCHEMA, parse_deployment, parse_link_value};
use crate::names::check_name;
use crate::read::{Loc, Obj, Reader, index, join};
use crate::source::{SourceFile, Span};

/// `launcher/v1`'s top-level keys that make a launcher composed.
pub(crate) const COMPOSITION_KEYS: &[&str] = &["components", "adjustments", "constraints"];

/// Whether `root` is a composed launcher (`launcher/v1` with any of
/// [`COMPOSITION_KEYS`]).
pub(crate) fn is_composed(root: &Node) -> bool {
    Spelling::of(root) == Spelling::SlashIds
        && COMPOSITION_KEYS.iter().any(|k| root.get(k).is_some())
}

/// Reads `file` as a launcher: composed (fragments loaded) or flat.
pub(crate) fn parse_composition(file: &Arc<SourceFile>) -> Result<Composition, Diagnostics> {
    let (root, mut diags) = crate::json::parse(file)?;
    if detect_kind(&root) != Some(DocumentKind::Launcher) {
        return Err(crate::document::parse_as(file, "", DocumentKind::Launcher)
            .err()
            .unwrap_or_default());
    }
    if !is_composed(&root) {
        return match crate::launcher::parse_launcher(file, &root, &mut diags, false) {
            Some(doc) if !diags.has_errors() => Ok(Composition {
                file: file.clone(),
                axes: Vec::new(),
                constraints: Vec::new(),
                adjustments: Vec::new(),
                components_loc: Loc {
                    file: file.clone(),
                    span: root.span,
                    key_path: String::new(),
                },
                flat: Some(doc),
                root,
                fragments: Vec::new(),
                base_deployments: Vec::new(),
                base_core_nodes: None,
            }),
            _ => Err(diags),
        };
    }
    let composition = read_composed(file, &root, &mut diags);
    match composition {
        Some(c) if !diags.has_errors() => Ok(c),
        _ => Err(diags),
    }
}

/// The composed launcher at `root`.
fn read_composed(
    file: &Arc<SourceFile>,
    root: &Node,
    diags: &mut Diagnostics,
) -> Option<Composition> {
    let mut r = Reader::new(file, diags);
    let obj = r.object(
        root,
        "",
        &[
            "peppy_schema",
            "core_nodes",
            "security",
            "deployments",
            "components",
            "adjustments",
            "constraints",
        ],
    )?;
    let file_name = file
        .path()
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| file.path().display().to_string());
    let base_origin = format!("{file_name} (base)");

    // Base deployments: checked like a flat launcher's; instances whose
    // links name fragments' instances are checked after composing.
    let mut base_deployments = Vec::new();
    if let Some(list) = obj.get("deployments")
        && let Some(items) = r.array(list, "deployments")
    {
        for (i, item) in items.iter().enumerate() {
            parse_deployment(&mut r, item, &index("deployments", i), Spelling::SlashIds);
            base_deployments.push(item.clone());
        }
    }
    if let Some(n) = obj.get("core_nodes") {
        crate::core_nodes::parse_core_nodes(&mut r, n, crate::Spelling::SlashIds);
    }
    if let Some(n) = obj.get("security") {
        r.bool(n, "security");
    }

    let Some(components) = obj.member("components") else {
        let key = obj
            .members
            .iter()
            .find(|m| COMPOSITION_KEYS.contains(&m.key.as_str()))?;
        r.error_help(
            Code::MissingKey,
            key.key_span,
            &key.key,
            format!("`{}` needs `components`: it edits the stacks a launcher's axes select", key.key),
            "add `components` (the axes and their options), or write the adjustment into the deployments",
        );
        return None;
    };
    let components_loc = r.loc(components.key_span, "components");
    let mut loader = Loader {
        base_dir: parent_dir(file.path()),
        fragments: Vec::new(),
        by_path: HashMap::new(),
    };
    let axes = read_axes(&mut r, &components.value, &mut loader);

    let adjustments = obj
        .get("adjustments")
        .map(|n| read_adjustments(&mut r, n, "adjustments", &base_origin))
        .unwrap_or_default();
    let constraints = obj
        .get("constraints")
        .map(|n| read_constraints(&mut r, n))
        .unwrap_or_default();
    if r.diags.has_errors() {
        return None;
    }

    let composition = Composition {
        file: file.clone(),
        axes,
        constraints,
        adjustments,
        components_loc,
        flat: None,
        root: root.clone(),
        fragments: loader.fragments,
        base_deployments,
        base_core_nodes: obj.get("core_nodes").cloned(),
    };
    cross_checks(&composition, diags);
    Some(composition)
}

/// The directory a file's relative paths start from.
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Loads fragments, each file once.
struct Loader {
    base_dir: PathBuf,
    fragments: Vec<super::Fragment>,
    by_path: HashMap<String, usize>,
}

fn read_axes(r: &mut Reader<'_>, node: &Node, loader: &mut Loader) -> Vec<Axis> {
    let Some(items) = r.array(node, "components") else {
        return Vec::new();
    };
    if items.is_empty() {
        r.error(
            Code::InvalidValue,
            node.span,
            "components",
            "`components` is empty: a composed launcher has at least one axis",
        );
    }
    let mut axes: Vec<Axis> = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let path = index("components", i);
        let Some(obj) = r.object(
            item,
            &path,
            &["name", "options", "default", "optional", "provides"],
        ) else {
            continue;
        };
        let Some(name_node) = r.required(&obj, "name") else {
            continue;
        };
        let Some(name) = r.string(name_node, &obj.path_of("name")) else {
            continue;
        };
        if let Err(why) = check_name(&name) {
            r.error(
                Code::InvalidName,
                name_node.span,
                &obj.path_of("name"),
                format!("invalid axis name `{name}`: {why}"),
            );
        }
        let loc = r.loc(name_node.span, &obj.path_of("name"));
        if let Some(first) = axes.iter().find(|a| a.name == name) {
            let at = first.loc.file.line_col(first.loc.span.start);
            r.error_help(
                Code::DuplicateAxis,
                name_node.span,
                &obj.path_of("name"),
                format!("axis `{name}` is declared twice"),
                format!(
                    "the first is at line {}, column {}; axis names are unique",
                    at.line, at.column
                ),
            );
        }
        let optional = obj
            .get("optional")
            .and_then(|n| r.bool(n, &obj.path_of("optional")))
            .unwrap_or(false);
        let provides = obj
            .get("provides")
            .and_then(|n| r.string_list(n, &obj.path_of("provides")))
            .unwrap_or_default();
        let mut options = Vec::new();
        if let Some(opts) = r.required(&obj, "options") {
            let opath = obj.path_of("options");
            match &opts.value {
                Value::Object(members) if !members.is_empty() => {
                    for m in members {
                        let kpath = join(&opath, &m.key);
                        if let Err(why) = check_name(&m.key) {
                            r.error(
                                Code::InvalidName,
                                m.key_span,
                                &kpath,
                                format!("invalid option name `{}`: {why}", m.key),
                            );
                        }
                        let origin = format!("inline option `{name}.{}`", m.key);
                        let fragments = read_spec(r, &m.value, &kpath, &origin, loader);
                        options.push(AxisOption {
                            name: m.key.clone(),
                            loc: r.loc(m.key_span, &kpath),
                            fragments,
                        });
                    }
                }
                Value::Object(_) => r.error(
                    Code::InvalidValue,
                    opts.span,
                    &opath,
                    format!("axis `{name}` has no options"),
                ),
                other => r.error(
                    Code::WrongType,
                    opts.span,
                    &opath,
                    format!(
                        "expected an object of `option: fragment` for `{opath}`, found {}",
                        other.kind()
                    ),
                ),
            }
        }
        let default = obj.get("default").and_then(|n| {
            let dpath = obj.path_of("default");
            let d = r.string(n, &dpath)?;
            if !options.iter().any(|o| o.name == d) {
                let names = options.iter().map(|o| o.name.as_str());
                let help = match did_you_mean(&d, names.clone()) {
                    Some(s) => format!("did you mean `{s}`? options of `{name}`: {}", list(names)),
                    None => format!("options of `{name}`: {}", list(names)),
                };
                r.error_help(Code::UnknownSelection, n.span, &dpath, format!("default `{d}` is not an option of axis `{name}`"), help);
            }
            if optional {
                r.error_help(
                    Code::InvalidValue,
                    n.span,
                    &dpath,
                    format!("axis `{name}` is `optional` and has a `default`"),
                    "an optional axis stays unfilled when nothing selects it; a default fills it: keep one",
                );
            }
            Some(d)
        });
        axes.push(Axis {
            name,
            options,
            default,
            optional,
            provides,
            loc,
        });
    }
    // A bare `--with` word names an option; an axis of that name elsewhere
    // would read as two things.
    for a in &axes {
        for b in &axes {
            if a.name != b.name
                && let Some(o) = b.options.iter().find(|o| o.name == a.name)
            {
                r.diags.push(
                    a.loc
                        .error(Code::InvalidName, format!("axis `{}` has the name of an option of axis `{}`", a.name, b.name))
                        .with_help(format!("`--with {}` would be ambiguous; rename the axis or the option at line {}", a.name, o.loc.file.line_col(o.loc.span.start).line)),
                );
            }
        }
    }
    axes
}

/// A `FragmentSpec`: a path, an inline fragment, or a non-empty list of both.
fn read_spec(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    origin: &str,
    loader: &mut Loader,
) -> Vec<usize> {
    match &node.value {
        Value::String(_) | Value::Object(_) => read_part(r, node, path, origin, loader)
            .into_iter()
            .collect(),
        Value::Array(items) if !items.is_empty() => items
            .iter()
            .enumerate()
            .filter_map(|(i, item)| match &item.value {
                Value::String(_) | Value::Object(_) => {
                    read_part(r, item, &index(path, i), origin, loader)
                }
                other => {
                    r.error(
                        Code::WrongType,
                        item.span,
                        &index(path, i),
                        format!(
                            "expected a fragment path or an inline fragment, found {}",
                            other.kind()
                        ),
                    );
                    None
                }
            })
            .collect(),
        Value::Array(_) => {
            r.error(
                Code::InvalidValue,
                node.span,
                path,
                "an option's fragment list is empty",
            );
            Vec::new()
        }
        other => {
            r.error_help(
                Code::WrongType,
                node.span,
                path,
                format!("expected a fragment for `{path}`, found {}", other.kind()),
                "an option is an inline fragment `{ deployments: [...] }`, a relative path to a `launcher_fragment/v1` file, or a list of both",
            );
            Vec::new()
        }
    }
}

fn read_part(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    origin: &str,
    loader: &mut Loader,
) -> Option<usize> {
    match &node.value {
        Value::Object(_) => {
            let frag =
                read_fragment_body(r, node, path, origin.to_string(), PathBuf::new(), false)?;
            loader.fragments.push(frag);
            Some(loader.fragments.len() - 1)
        }
        Value::String(p) => {
            if let Some(&i) = loader.by_path.get(p) {
                return Some(i);
            }
            let rel = fragment_path(r, p, node.span, path)?;
            let full = loader.base_dir.join(&rel);
            let file = read_fragment_file(r, &full, p, node.span, path, &loader.base_dir)?;
            let mut fdiags = Diagnostics::new();
            let frag = {
                let (root, jd) = match crate::json::parse(&file) {
                    Ok(v) => v,
                    Err(e) => {
                        r.diags.push(
                            r.loc(node.span, path)
                                .error(
                                    Code::FragmentInvalid,
                                    format!("fragment `{p}` does not parse"),
                                )
                                .with_help("its errors follow"),
                        );
                        r.diags.extend(e);
                        return None;
                    }
                };
                fdiags.extend(jd);
                let schema = root.get("peppy_schema").and_then(Node::as_str);
                if schema != Some(FRAGMENT_SCHEMA) {
                    let is = match schema {
                        Some(s) => format!("its `peppy_schema` is `{s}`"),
                        None => "it has no `peppy_schema`".to_string(),
                    };
                    r.diags.push(
                        r.loc(node.span, path)
                            .error(
                                Code::FragmentInvalid,
                                format!("`{p}` is not a launcher fragment: {is}"),
                            )
                            .with_help(format!(
                                "a fragment file says `peppy_schema: \"{FRAGMENT_SCHEMA}\"`"
                            )),
                    );
                    return None;
                }
                let dir = rel.parent().map(Path::to_path_buf).unwrap_or_default();
                let mut fr = Reader::new(&file, &mut fdiags);
                read_fragment_body(&mut fr, &root, "", p.clone(), dir, true)
            };
            let bad = fdiags.has_errors();
            r.diags.extend(fdiags);
            let frag = frag.filter(|_| !bad)?;
            loader.fragments.push(frag);
            let i = loader.fragments.len() - 1;
            loader.by_path.insert(p.clone(), i);
            Some(i)
        }
        _ => None,
    }
}

/// A fragment path: relative to the launcher's directory, plain, inside it.
fn fragment_path(r: &mut Reader<'_>, p: &str, span: Span, path: &str) -> Option<PathBuf> {
    let why = if p.trim().is_empty() {
        Some("it is empty")
    } else if Path::new(p).is_absolute() || p.starts_with('/') || p.starts_with('\\') {
        Some("it is absolute")
    } else if p
        .split(['/', '\\'])
        .any(|s| s.is_empty() || s == "." || s == "..")
    {
        Some("it has an empty, `.` or `..` segment")
    } else if Path::new(p)
        .components()
        .any(|c| !matches!(c, Component::Normal(_)))
    {
        Some("it is not a plain relative path")
    } else {
        None
    };
    if let Some(why) = why {
        r.error_help(
            Code::FragmentPath,
            span,
            path,
            format!("fragment path `{p}` is not usable: {why}"),
            "a fragment path is relative to the launcher's directory and stays inside it (`fragments/sim.json5`)",
        );
        return None;
    }
    Some(PathBuf::from(p))
}

fn read_fragment_file(
    r: &mut Reader<'_>,
    full: &Path,
    p: &str,
    span: Span,
    path: &str,
    base_dir: &Path,
) -> Option<Arc<SourceFile>> {
    if !full.is_file() {
        let what = if full.exists() {
            "is not a file"
        } else {
            "does not exist"
        };
        r.error_help(
            Code::FragmentUnreadable,
            span,
            path,
            format!("fragment `{p}` {what}"),
            format!(
                "paths are relative to the launcher's directory, `{}`",
                base_dir.display()
            ),
        );
        return None;
    }
    // Symlinks may not lead a fragment out of the launcher's directory.
    if let (Ok(real), Ok(base)) = (full.canonicalize(), base_dir.canonicalize())
        && !real.starts_with(&base)
    {
        r.error_help(
            Code::FragmentPath,
            span,
            path,
            format!(
                "fragment path `{p}` leads outside the launcher's directory (through a symlink)"
            ),
            "a fragment stays inside the launcher's directory",
        );
        return None;
    }
    match SourceFile::read(full) {
        Ok((file, _)) => Some(file),
        Err(e) => {
            r.error(
                Code::FragmentUnreadable,
                span,
                path,
                format!("fragment `{p}` cannot be read: {}", e.message),
            );
            None
        }
    }
}

/// A fragment's body (a file's root, or an inline option).
fn read_fragment_body(
    r: &mut Reader<'_>,
    node: &Node,
    path: &str,
    origin: String,
    dir: PathBuf,
    file_form: bool,
) -> Option<Fragment> {
    let keys: &[&str] = if file_form {
        &["peppy_schema", "deployments", "adjustments", "core_nodes"]
    } else {
        &["deployments", "adjustments", "core_nodes"]
    };
    let obj = r.object(node, path, keys)?;
    let mut deployments = Vec::new();
    if let Some(list) = obj.get("deployments") {
        let dpath = obj.path_of("deployments");
        if let Some(items) = r.array(list, &dpath) {
            for (i, item) in items.iter().enumerate() {
                parse_deployment(r, item, &index(&dpath, i), Spelling::SlashIds);
                deployments.push(item.clone());
            }
        }
    }
    if let Some(n) = obj.get("core_nodes") {
        crate::core_nodes::parse_core_nodes(r, n, crate::Spelling::SlashIds);
    }
    let adjustments = obj
        .get("adjustments")
        .map(|n| read_adjustments(r, n, &obj.path_of("adjustments"), &origin))
        .unwrap_or_default();
    Some(Fragment {
        file: r.file.clone(),
        origin,
        dir,
        deployments,
        core_nodes: obj.get("core_nodes").cloned(),
        adjustments,
    })
}

fn read_adjustments(r: &mut Reader<'_>, node: &Node, path: &str, origin: &str) -> Vec<Adjustment> {
    let Some(items) = r.array(node, path) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index(path, i);
        let Some(obj) = r.object(
            item,
            &ipath,
            &[
                "target",
                "when",
                "set_arguments",
                "set_links",
                "add_links",
                "unset_links",
            ],
        ) else {
            continue;
        };
        let target = r.required(&obj, "target").and_then(|n| {
            let s = r.string(n, &obj.path_of("target"))?;
            if let Err(why) = check_name(&s) {
                r.error(
                    Code::InvalidName,
                    n.span,
                    &obj.path_of("target"),
                    format!("invalid target `{s}`: {why}"),
                );
            }
            Some(s)
        });
        let when = obj
            .get("when")
            .map(|n| read_map(r, n, &obj.path_of("when")))
            .unwrap_or_default();
        let mut ops = 0;
        let mut set_arguments = Vec::new();
        if let Some(n) = obj.get("set_arguments") {
            let p = obj.path_of("set_arguments");
            for m in members_of(r, n, &p) {
                if m.key.is_empty() {
                    r.error(
                        Code::InvalidValue,
                        m.key_span,
                        &p,
                        "an argument name is empty",
                    );
                }
                set_arguments.push((m.key.clone(), m.value.clone()));
            }
            ops += set_arguments.len();
        }
        let mut set_links = Vec::new();
        if let Some(n) = obj.get("set_links") {
            let p = obj.path_of("set_links");
            for m in members_of(r, n, &p) {
                let kpath = join(&p, &m.key);
                link_key(r, m, &kpath);
                parse_link_value(r, &m.value, &kpath, &m.key);
                set_links.push((m.key.clone(), m.value.clone()));
            }
            ops += set_links.len();
        }
        let mut add_links = Vec::new();
        if let Some(n) = obj.get("add_links") {
            let p = obj.path_of("add_links");
            for m in members_of(r, n, &p) {
                let kpath = join(&p, &m.key);
                link_key(r, m, &kpath);
                match &m.value.value {
                    Value::Array(items) if !items.is_empty() => {
                        // The link grammar checks each target and repeats.
                        parse_link_value(r, &m.value, &kpath, &m.key);
                        let targets = items
                            .iter()
                            .filter_map(|t| t.as_str().map(str::to_string))
                            .collect();
                        add_links.push((m.key.clone(), targets));
                    }
                    _ => r.error_help(
                        Code::InvalidValue,
                        m.value.span,
                        &kpath,
                        format!("`add_links.{}` is not a non-empty list of targets", m.key),
                        "`add_links: { slot: [\"inst\", ...] }` appends to a list binding",
                    ),
                }
            }
            ops += add_links.len();
        }
        let mut unset_links: Vec<String> = Vec::new();
        if let Some(n) = obj.get("unset_links") {
            let p = obj.path_of("unset_links");
            if let Some(items) = r.array(n, &p) {
                for (j, s) in items.iter().enumerate() {
                    let Some(slot) = r.string(s, &index(&p, j)) else {
                        continue;
                    };
                    if slot.is_empty() || unset_links.contains(&slot) {
                        r.error(
                            Code::InvalidValue,
                            s.span,
                            &index(&p, j),
                            format!("`unset_links` lists `{slot}` twice or empty"),
                        );
                    }
                    unset_links.push(slot);
                }
            }
            ops += unset_links.len();
        }
        if ops == 0 {
            r.error_help(
                Code::InvalidValue,
                item.span,
                &ipath,
                "adjustment changes nothing",
                "give it at least one non-empty `set_arguments`, `set_links`, `add_links` or `unset_links`",
            );
        }
        if let Some(n) = obj.get("when")
            && when.is_empty()
        {
            r.error(
                Code::InvalidValue,
                n.span,
                &obj.path_of("when"),
                "`when` is empty; leave it out to apply always",
            );
        }
        let Some(target) = target else { continue };
        out.push(Adjustment {
            target,
            when,
            set_arguments,
            set_links,
            add_links,
            unset_links,
            origin: origin.to_string(),
            loc: r.loc(item.span, &ipath),
        });
    }
    out
}

fn members_of<'n>(r: &mut Reader<'_>, node: &'n Node, path: &str) -> &'n [crate::json::Member] {
    match &node.value {
        Value::Object(m) => m,
        other => {
            r.error(
                Code::WrongType,
                node.span,
                path,
                format!("expected an object for `{path}`, found {}", other.kind()),
            );
            &[]
        }
    }
}

/// An `{ axis: option, ... }` map; names are checked against the axes later.
fn read_map(r: &mut Reader<'_>, node: &Node, path: &str) -> Vec<Pair> {
    let mut out = Vec::new();
    for m in members_of(r, node, path) {
        let kpath = join(path, &m.key);
        if let Some(option) = r.string(&m.value, &kpath) {
            out.push(Pair {
                axis: m.key.clone(),
                option,
                loc: Loc {
                    file: r.file.clone(),
                    span: Span::new(m.key_span.start, m.value.span.end),
                    key_path: kpath,
                },
            });
        }
    }
    out
}

fn read_constraints(r: &mut Reader<'_>, node: &Node) -> Vec<Constraint> {
    let Some(items) = r.array(node, "constraints") else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index("constraints", i);
        let Some(obj) = r.object(item, &ipath, &["when", "requires", "forbids", "reason"]) else {
            continue;
        };
        let when = obj
            .get("when")
            .map(|n| read_map(r, n, &obj.path_of("when")))
            .unwrap_or_default();
        if let Some(n) = obj.get("when")
            && when.is_empty()
        {
            r.error(
                Code::InvalidValue,
                n.span,
                &obj.path_of("when"),
                "`when` is empty; leave it out to judge every selection",
            );
        }
        let requires = read_maps(r, &obj, "requires", &when);
        let forbids = read_maps(r, &obj, "forbids", &when);
        if requires.is_empty() && forbids.is_empty() {
            r.error_help(
                Code::InvalidValue,
                item.span,
                &ipath,
                "constraint neither requires nor forbids anything",
                "give it `requires: [{ axis: option }]` or `forbids: [{ axis: option }]`",
            );
        }
        for f in &forbids {
            if requires.iter().any(|q| same_map(q, f)) {
                r.diags.push(f[0].loc.error(
                    Code::InvalidValue,
                    "the same map is both required and forbidden",
                ));
            }
        }
        let reason = r.required(&obj, "reason").and_then(|n| {
            let s = r.string(n, &obj.path_of("reason"))?;
            if s.trim().is_empty() {
                r.error(
                    Code::InvalidValue,
                    n.span,
                    &obj.path_of("reason"),
                    "`reason` is empty: say why the selection is refused",
                );
            }
            Some(s)
        });
        let Some(reason) = reason else { continue };
        out.push(Constraint {
            when,
            requires,
            forbids,
            reason,
            loc: r.loc(item.span, &ipath),
        });
    }
    out
}

fn same_map(a: &[Pair], b: &[Pair]) -> bool {
    a.len() == b.len()
        && a.iter()
            .all(|p| b.iter().any(|q| q.axis == p.axis && q.option == p.option))
}

fn read_maps(r: &mut Reader<'_>, obj: &Obj<'_>, key: &str, when: &[Pair]) -> Vec<Vec<Pair>> {
    let Some(n) = obj.get(key) else {
        return Vec::new();
    };
    let path = obj.path_of(key);
    let Some(items) = r.array(n, &path) else {
        return Vec::new();
    };
    let mut out: Vec<Vec<Pair>> = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let ipath = index(&path, i);
        let map = read_map(r, item, &ipath);
        if map.is_empty() {
            r.error(
                Code::InvalidValue,
                item.span,
                &ipath,
                format!("an entry of `{key}` is empty"),
            );
            continue;
        }
        for p in &map {
            if when.iter().any(|w| w.axis == p.axis) {
                r.diags.push(p.loc.error(
                    Code::InvalidValue,
                    format!(
                        "`{key}` names axis `{}`, which the constraint's `when` already fixes",
                        p.axis
                    ),
                ));
            }
        }
        if out.iter().any(|m| same_map(m, &map)) {
            r.error(
                Code::InvalidValue,
                item.span,
                &ipath,
                format!("`{key}` lists the same map twice"),
            );
        }
        out.push(map);
    }
    out
}

/// Rules that need the whole composition: names in maps, `provides`,
/// adjustment targets.
fn cross_checks(c: &Composition, diags: &mut Diagnostics) {
    let maps = c
        .constraints
        .iter()
        .flat_map(|k| {
            k.when
                .iter()
                .chain(k.requires.iter().flatten())
                .chain(k.forbids.iter().flatten())
        })
        .chain(c.all_adjustments().flat_map(|a| a.when.iter()));
    for p in maps {
        if let Some(d) = unknown_pair(c, p) {
            diags.push(d);
        }
    }
    // Every option defines what its axis provides.
    for axis in &c.axes {
        for option in &axis.options {
            let ids: Vec<&str> = option
                .fragments
                .iter()
                .flat_map(|&f| instance_ids(&c.fragments[f].deployments))
                .collect();
            for p in &axis.provides {
                if !ids.contains(&p.as_str()) {
                    diags.push(
                        option
                            .loc
                            .error(
                                Code::ProvidesUnmet,
                                format!("option `{}` of axis `{}` does not define `{p}`, which the axis `provides`", option.name, axis.name),
                            )
                            .with_help(format!("instances it defines: {}", list(ids.iter().copied()))),
                    );
                }
            }
        }
    }
    // An adjustment's target is defined by the base or some option.
    let everywhere: Vec<&str> = instance_ids(&c.base_deployments)
        .chain(
            c.fragments
                .iter()
                .flat_map(|f| instance_ids(&f.deployments)),
        )
        .collect();
    for a in c.all_adjustments() {
        if !everywhere.contains(&a.target.as_str()) {
            let help = match did_you_mean(&a.target, everywhere.iter().copied()) {
                Some(s) => format!(
                    "did you mean `{s}`? instances this launcher can deploy: {}",
                    list(everywhere.iter().copied())
                ),
                None => format!(
                    "instances this launcher can deploy: {}",
                    list(everywhere.iter().copied())
                ),
            };
            diags.push(
                a.loc
                    .error(Code::TargetDefinedNowhere, format!("adjustment targets `{}`, which neither the base nor any option defines", a.target))
                    .with_help(help),
            );
        }
    }
}

/// A map pair naming an axis or option that does not exist, as its error.
pub(crate) fn unknown_pair(c: &Composition, p: &Pair) -> Option<Diagnostic> {
    let names = || c.axes.iter().map(|a| a.name.as_str());
    let Some(axis) = c.axes.iter().find(|a| a.name == p.axis) else {
        let help = match did_you_mean(&p.axis, names()) {
            Some(s) => format!("did you mean `{s}`? axes: {}", list(names())),
            None => format!("axes: {}", list(names())),
        };
        return Some(
            p.loc
                .error(
                    Code::UnknownSelection,
                    format!("`{}` is not an axis of this launcher", p.axis),
                )
                .with_help(help),
        );
    };
    if axis.options.iter().any(|o| o.name == p.option) {
        return None;
    }
    let options = || axis.options.iter().map(|o| o.name.as_str());
    let help = match did_you_mean(&p.option, options()) {
        Some(s) => format!(
            "did you mean `{s}`? options of `{}`: {}",
            axis.name,
            list(options())
        ),
        None => format!("options of `{}`: {}", axis.name, list(options())),
    };
    Some(
        p.loc
            .error(
                Code::UnknownSelection,
                format!("`{}` is not an option of axis `{}`", p.option, p.axis),
            )
            .with_help(help),
    )
}

/// The instance ids of deployment nodes.
pub(crate) fn instance_ids(deployments: &[Node]) -> impl Iterator<Item = &str> {
    deployments
        .iter()
        .filter_map(|d| match d.get("instances").map(|i| &i.value) {
            Some(Value::Array(items)) => Some(items),
            _ => None,
        })
        .flatten()
        .filter_map(|i| i.get("instance_id").and_then(Node::as_str))
}

impl Composition {
    /// Every adjustment: every fragment's, then the base's.
    pub(crate) fn all_adjustments(&self) -> impl Iterator<Item = &Adjustment> {
        self.fragments
            .iter()
            .flat_map(|f| f.adjustments.iter())
            .chain(self.adjustments.iter())
    }
}

/// Checks a slot key of `set_links` / `add_links`.
fn link_key(r: &mut Reader<'_>, m: &crate::json::Member, path: &str) {
    r.link_key(&m.key, m.key_span, path, false);
}
