//! Composing a selection into the flat launcher: collect deployments,
//! merge equal sources, union core nodes, apply adjustments, print, and
//! read the result back as an ordinary flat launcher.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::print::{FlatDeployment, FlatInstance, FlatLauncher, compact};
use super::{
    Adjustment, AppliedChange, Composition, ResolveReport, Resolved, Selection, SkippedAdjustment,
};
use crate::diag::{Code, Diagnostic, Diagnostics};
use crate::document::{DocumentKind, Spelling, detect_kind};
use crate::json::{Member, Node, Value};
use crate::source::{SourceFile, Span};

/// A node with no place: what composing creates.
fn node(value: Value) -> Node {
    Node {
        span: Span::default(),
        value,
    }
}

fn member(key: &str, value: Node) -> Member {
    Member {
        key: key.to_string(),
        key_span: Span::default(),
        value,
    }
}

/// `name:tag` for a repository source, else the source as JSON: equal
/// keys are one deployment.
fn source_key(source: &Node) -> String {
    match (
        source.get("name").and_then(Node::as_str),
        source.get("tag").and_then(Node::as_str),
    ) {
        (Some(n), Some(t)) => format!("{n}:{t}"),
        (Some(n), None) if n.contains(':') => n.to_string(),
        _ => source.to_json().to_string(),
    }
}

/// The source as printed: `{ name, tag }` for a repository source, a
/// `local` path made relative to the launcher's directory.
fn normal_source(source: &Node, dir: &Path) -> Node {
    if let Some(local) = source.get("local").and_then(Node::as_str) {
        let path = if dir.as_os_str().is_empty() {
            local.to_string()
        } else {
            format!("{}/{local}", dir.to_string_lossy().replace('\\', "/"))
        };
        return node(Value::Object(vec![member(
            "local",
            node(Value::String(path)),
        )]));
    }
    let key = source_key(source);
    match key.split_once(':') {
        Some((n, t)) if source.get("name").is_some() => node(Value::Object(vec![
            member("name", node(Value::String(n.to_string()))),
            member("tag", node(Value::String(t.to_string()))),
        ])),
        _ => source.clone(),
    }
}

/// One collected deployment: its node, its file and how reports name it.
struct Collected<'c> {
    deployment: &'c Node,
    file: &'c Arc<SourceFile>,
    origin: &'c str,
    dir: &'c Path,
}

/// Deployments merged by source, in collection order.
fn merge(collected: &[Collected<'_>], diags: &mut Diagnostics) -> Vec<FlatDeployment> {
    let mut out: Vec<(String, FlatDeployment)> = Vec::new();
    let mut seen: BTreeMap<String, (&str, Span, Arc<SourceFile>)> = BTreeMap::new();
    for c in collected {
        let Some(source) = c.deployment.get("source") else {
            continue;
        };
        let key = source_key(source);
        let instances: Vec<FlatInstance> = match c.deployment.get("instances").map(|i| &i.value) {
            Some(Value::Array(items)) => items
                .iter()
                .filter_map(|i| {
                    let Value::Object(members) = &i.value else {
                        return None;
                    };
                    let id_node = i.get("instance_id")?;
                    let id = id_node.as_str()?.to_string();
                    if let Some((first, at, file)) = seen.get(&id) {
                        let lc = file.line_col(at.start);
                        diags.push(
                            Diagnostic::error(
                                Code::DuplicateInstanceId,
                                format!(
                                    "instance `{id}` is defined by both {first} and {}",
                                    c.origin
                                ),
                            )
                            .at(c.file, id_node.span)
                            .with_help(format!(
                                "each instance id belongs to one origin; the first is at {}:{}:{}",
                                file.path().display(),
                                lc.line,
                                lc.column
                            )),
                        );
                        return None;
                    }
                    seen.insert(id.clone(), (c.origin, id_node.span, c.file.clone()));
                    Some(FlatInstance {
                        id,
                        members: members
                            .iter()
                            .filter(|m| m.key != "instance_id")
                            .cloned()
                            .collect(),
                    })
                })
                .collect(),
            _ => Vec::new(),
        };
        match out.iter_mut().find(|(k, _)| *k == key) {
            Some((_, d)) => d.instances.extend(instances),
            None => out.push((
                key,
                FlatDeployment {
                    source: normal_source(source, c.dir),
                    instances,
                },
            )),
        }
    }
    out.into_iter().map(|(_, d)| d).collect()
}

/// `core_nodes` of the base then of each fragment, each name once.
fn union_core_nodes<'n>(lists: impl Iterator<Item = &'n Node>) -> Option<Node> {
    let mut names: Vec<(String, Option<Node>)> = Vec::new();
    let mut any = false;
    for list in lists {
        any = true;
        let entries: Vec<(String, Option<Node>)> = match &list.value {
            Value::Array(items) => items
                .iter()
                .filter_map(|i| i.as_str().map(|s| (s.to_string(), None)))
                .collect(),
            Value::Object(members) => members
                .iter()
                .map(|m| (m.key.clone(), Some(m.value.clone())))
                .collect(),
            _ => Vec::new(),
        };
        for (name, value) in entries {
            match names.iter_mut().find(|(n, _)| *n == name) {
                Some((_, v)) if v.is_none() => *v = value,
                Some(_) => {}
                None => names.push((name, value)),
            }
        }
    }
    if !any {
        return None;
    }
    Some(if names.iter().all(|(_, v)| v.is_none()) {
        node(Value::Array(
            names
                .into_iter()
                .map(|(n, _)| node(Value::String(n)))
                .collect(),
        ))
    } else {
        node(Value::Object(
            names
                .into_iter()
                .map(|(n, v)| member(&n, v.unwrap_or_else(|| node(Value::Object(Vec::new())))))
                .collect(),
        ))
    })
}

/// The flat form of a flat `launcher/v1` document's root.
pub(super) fn flat_of_root(root: &Node, file: &Arc<SourceFile>) -> FlatLauncher {
    let deployments: Vec<Collected<'_>> = match root.get("deployments").map(|d| &d.value) {
        Some(Value::Array(items)) => items
            .iter()
            .map(|d| Collected {
                deployment: d,
                file,
                origin: "",
                dir: Path::new(""),
            })
            .collect(),
        _ => Vec::new(),
    };
    let mut ignored = Diagnostics::new();
    FlatLauncher {
        core_nodes: root.get("core_nodes").cloned(),
        security: root.get("security").cloned(),
        deployments: merge_keeping(&deployments, &mut ignored),
    }
}

/// [`merge`] without merging: a flat launcher is printed as written.
fn merge_keeping(collected: &[Collected<'_>], _diags: &mut Diagnostics) -> Vec<FlatDeployment> {
    collected
        .iter()
        .filter_map(|c| {
            let source = c.deployment.get("source")?;
            let instances = match c.deployment.get("instances").map(|i| &i.value) {
                Some(Value::Array(items)) => items
                    .iter()
                    .filter_map(|i| {
                        let Value::Object(members) = &i.value else {
                            return None;
                        };
                        Some(FlatInstance {
                            id: i.get("instance_id")?.as_str()?.to_string(),
                            members: members
                                .iter()
                                .filter(|m| m.key != "instance_id")
                                .cloned()
                                .collect(),
                        })
                    })
                    .collect(),
                _ => Vec::new(),
            };
            Some(FlatDeployment {
                source: normal_source(source, c.dir),
                instances,
            })
        })
        .collect()
}

/// The virtual file a composed launcher's flat text is read from: beside
/// the launcher, so relative paths resolve as they do from it.
fn flat_path(file: &SourceFile) -> PathBuf {
    let name = file
        .path()
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    file.path().with_file_name(format!("{name} (resolved)"))
}

pub(super) fn resolve(c: &Composition, selection: &Selection) -> Result<Resolved, Diagnostics> {
    if let Some(flat) = &c.flat {
        if !selection.choices.is_empty() {
            return Err(c
                .select(&[selection.with_words()])
                .err()
                .unwrap_or_default());
        }
        let text = if Spelling::of(&c.root) == Spelling::SlashIds {
            flat_of_root(&c.root, &c.file).render()
        } else {
            c.file.text().to_string()
        };
        return Ok(Resolved {
            launcher: flat.clone(),
            text,
            report: ResolveReport::default(),
            warnings: Diagnostics::new(),
        });
    }
    c.judge(selection)?;
    let mut diags = Diagnostics::new();
    let base_origin = format!(
        "{} (base)",
        c.file
            .path()
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    let empty = PathBuf::new();
    let mut collected: Vec<Collected<'_>> = c
        .base_deployments
        .iter()
        .map(|d| Collected {
            deployment: d,
            file: &c.file,
            origin: &base_origin,
            dir: &empty,
        })
        .collect();
    let mut selected: Vec<usize> = Vec::new();
    for choice in &selection.choices {
        let Some(option) = &choice.option else {
            continue;
        };
        let Some(o) = c
            .axes
            .iter()
            .find(|a| a.name == choice.axis)
            .and_then(|a| a.options.iter().find(|o| o.name == *option))
        else {
            return Err(c
                .components_loc
                .error(
                    Code::UnknownSelection,
                    format!(
                        "`{}={option}` is not an option of this launcher",
                        choice.axis
                    ),
                )
                .into());
        };
        selected.extend(o.fragments.iter().copied());
    }
    for &f in &selected {
        let frag = &c.fragments[f];
        collected.extend(frag.deployments.iter().map(|d| Collected {
            deployment: d,
            file: &frag.file,
            origin: &frag.origin,
            dir: &frag.dir,
        }));
    }
    let mut deployments = merge(&collected, &mut diags);
    let core_nodes = union_core_nodes(
        c.base_core_nodes.iter().chain(
            selected
                .iter()
                .filter_map(|&f| c.fragments[f].core_nodes.as_ref()),
        ),
    );
    if diags.has_errors() {
        return Err(diags);
    }

    // Fragments' adjustments first, in collection order, then the base's.
    let active: Vec<(Option<usize>, &Adjustment)> = selected
        .iter()
        .flat_map(|&f| c.fragments[f].adjustments.iter().map(move |a| (Some(f), a)))
        .chain(c.adjustments.iter().map(|a| (None, a)))
        .collect();
    let mut report = ResolveReport {
        selection: Some(selection.clone()),
        constraints_checked: c.constraints.len(),
        ..ResolveReport::default()
    };
    // Which fragment wrote each field, and whether by appending.
    let mut written: BTreeMap<(String, String), (usize, &str, bool)> = BTreeMap::new();
    for (frag, a) in &active {
        if let Some(p) = a
            .when
            .iter()
            .find(|p| selection.option_of(&p.axis) != Some(p.option.as_str()))
        {
            report.skipped.push(SkippedAdjustment {
                target: a.target.clone(),
                reason: format!("guard {}={} is not met", p.axis, p.option),
                origin: a.origin.clone(),
            });
            continue;
        }
        let Some(inst) = deployments
            .iter_mut()
            .flat_map(|d| d.instances.iter_mut())
            .find(|i| i.id == a.target)
        else {
            report.skipped.push(SkippedAdjustment {
                target: a.target.clone(),
                reason: "target is not in this selection".to_string(),
                origin: a.origin.clone(),
            });
            continue;
        };
        if let Some(f) = frag {
            let fields = a
                .set_arguments
                .iter()
                .map(|(k, _)| (format!("arguments.{k}"), false))
                .chain(
                    a.set_links
                        .iter()
                        .map(|(k, _)| (format!("links.{k}"), false)),
                )
                .chain(a.unset_links.iter().map(|k| (format!("links.{k}"), false)))
                .chain(
                    a.add_links
                        .iter()
                        .map(|(k, _)| (format!("links.{k}"), true)),
                );
            for (field, adds) in fields {
                let key = (a.target.clone(), field.clone());
                match written.get(&key) {
                    Some((g, first, first_adds)) if *g != *f || *first_adds != adds => {
                        diags.push(
                            a.loc
                                .error(
                                    Code::AdjustmentsConflict,
                                    format!("{first} and {} both write `{}.{field}`", a.origin, a.target),
                                )
                                .with_help(if g == f {
                                    "one fragment may not both append to a slot and replace or remove it"
                                } else {
                                    "fragments may not fight over one value; let the base decide (base adjustments override fragments)"
                                }),
                        );
                    }
                    _ => {
                        written.insert(key, (*f, &c.fragments[*f].origin, adds));
                    }
                }
            }
        }
        apply(inst, a, &mut report.applied, &mut diags);
    }
    if diags.has_errors() {
        return Err(diags);
    }
    let flat = FlatLauncher {
        core_nodes,
        security: c.root.get("security").cloned(),
        deployments,
    };
    let text = flat.render();
    let file = SourceFile::new(flat_path(&c.file), text.clone());
    let (root, mut warnings) = crate::json::parse(&file)?;
    debug_assert_eq!(detect_kind(&root), Some(DocumentKind::Launcher));
    let Some(launcher) = crate::launcher::parse_launcher(&file, &root, &mut warnings, false) else {
        return Err(warnings);
    };
    if warnings.has_errors() {
        return Err(warnings);
    }
    Ok(Resolved {
        launcher,
        text,
        report,
        warnings,
    })
}

fn get_member<'m>(members: &'m mut Vec<Member>, key: &str) -> &'m mut Vec<Member> {
    if !members.iter().any(|m| m.key == key) {
        members.push(member(key, node(Value::Object(Vec::new()))));
    }
    let m = members
        .iter_mut()
        .find(|m| m.key == key)
        .expect("just made");
    if !matches!(m.value.value, Value::Object(_)) {
        m.value = node(Value::Object(Vec::new()));
    }
    match &mut m.value.value {
        Value::Object(inner) => inner,
        _ => unreachable!("made an object above"),
    }
}

/// Replaces or creates `key` in `map`; the old value, if any.
fn set(map: &mut Vec<Member>, key: &str, value: Node) -> Option<Node> {
    match map.iter_mut().find(|m| m.key == key) {
        Some(m) => Some(std::mem::replace(&mut m.value, value)),
        None => {
            map.push(member(key, value));
            None
        }
    }
}

fn shown(old: Option<&Node>) -> String {
    old.map_or_else(|| "(absent)".to_string(), compact)
}

fn apply(
    inst: &mut FlatInstance,
    a: &Adjustment,
    applied: &mut Vec<AppliedChange>,
    diags: &mut Diagnostics,
) {
    let mut record = |field: String, change: String| {
        applied.push(AppliedChange {
            target: a.target.clone(),
            field,
            change,
            origin: a.origin.clone(),
        })
    };
    for (k, v) in &a.set_arguments {
        let old = set(get_member(&mut inst.members, "arguments"), k, v.clone());
        record(
            format!("arguments.{k}"),
            format!("{} -> {}", shown(old.as_ref()), compact(v)),
        );
    }
    for (k, v) in &a.set_links {
        let old = set(get_member(&mut inst.members, "links"), k, v.clone());
        record(
            format!("links.{k}"),
            format!("{} -> {}", shown(old.as_ref()), compact(v)),
        );
    }
    for (k, targets) in &a.add_links {
        let links = get_member(&mut inst.members, "links");
        let entry = match links.iter_mut().find(|m| m.key == *k) {
            Some(m) => m,
            None => {
                links.push(member(k, node(Value::Array(Vec::new()))));
                links.last_mut().expect("just pushed")
            }
        };
        let Value::Array(items) = &mut entry.value.value else {
            let holds = if matches!(entry.value.value, Value::Object(_)) {
                "a vacancy"
            } else {
                "a single target"
            };
            diags.push(
                a.loc
                    .error(Code::AddLinksOnNonArray, format!("cannot append to slot `{k}` of `{}`: it holds {holds}", a.target))
                    .with_help("`add_links` appends to a list binding; `set_links` replaces a slot's whole entry"),
            );
            continue;
        };
        for t in targets {
            if items.iter().any(|i| i.as_str() == Some(t)) {
                diags.push(
                    a.loc
                        .error(
                            Code::AddLinksDuplicateTarget,
                            format!("slot `{k}` of `{}` already lists `{t}`", a.target),
                        )
                        .with_help("a slot lists each producer once"),
                );
                continue;
            }
            items.push(node(Value::String(t.clone())));
        }
        record(format!("links.{k}"), format!("+ {}", targets.join(", ")));
    }
    for k in &a.unset_links {
        let links = get_member(&mut inst.members, "links");
        let old = links
            .iter()
            .position(|m| m.key == *k)
            .map(|i| links.remove(i).value);
        record(
            format!("links.{k}"),
            format!("removed (was {})", shown(old.as_ref())),
        );
    }
}
