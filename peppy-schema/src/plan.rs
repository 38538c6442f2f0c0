//! The binding plan of a launcher: for every consumer instance and slot,
//! which producers fill it, and the routing filter the consumer applies.

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use crate::diag::{Code, Diagnostic, Diagnostics, list};
use crate::launcher::{Binding, Instance, LauncherDoc, RestartPolicy};
use crate::node::{Dependency, Identity, NodeDoc, SlotKind};

/// What fills one slot.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum SlotBinding {
    /// A pinned slot bound to one producer.
    Pinned {
        /// The producer instance.
        producer: String,
    },
    /// A `from_any` slot with explicit producers: only these flow in.
    FromAnyBound {
        /// Producer instances, in binding order.
        producers: Vec<String>,
    },
    /// A `from_any` slot without bindings: any unclaimed producer of its kind.
    FromAnyUnbound,
}

/// Which producers' messages a consumer keeps for one slot (SPEC 5).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "producers")]
pub enum RouteFilter {
    /// Only this producer.
    Pin(String),
    /// Only these producers.
    OnlyFrom(BTreeSet<String>),
    /// Any producer of the slot's kind except these.
    AnyExcept(BTreeSet<String>),
    /// Any producer of the slot's kind.
    Any,
}

impl RouteFilter {
    /// Whether a message from `producer` (already of the slot's kind) passes.
    pub fn accepts(&self, producer: &str) -> bool {
        match self {
            RouteFilter::Pin(p) => p == producer,
            RouteFilter::OnlyFrom(set) => set.contains(producer),
            RouteFilter::AnyExcept(set) => !set.contains(producer),
            RouteFilter::Any => true,
        }
    }
}

/// One slot of one consumer instance.
#[derive(Debug, Clone, Serialize)]
pub struct SlotPlan {
    /// The slot's link_id.
    pub link_id: String,
    /// Node or interface slot.
    pub kind: SlotKind,
    /// The node or interface it wants.
    pub target: Identity,
    /// What fills it.
    pub binding: SlotBinding,
    /// The consumer-side filter.
    pub filter: RouteFilter,
}

/// One instance, ready to run.
#[derive(Debug, Clone, Serialize)]
pub struct InstancePlan {
    /// Its id.
    pub instance_id: String,
    /// Index of its deployment in the launcher.
    pub deployment: usize,
    /// The node it runs.
    pub node: Identity,
    /// Its slots, in `depends_on` order.
    pub slots: Vec<SlotPlan>,
    /// Parameters with defaults filled in.
    pub parameters: serde_json::Value,
    /// `env_vars`.
    pub env_vars: Vec<(String, String)>,
    /// Restart policy.
    pub restart: RestartPolicy,
}

/// Every instance of a launcher with its slots filled.
#[derive(Debug, Clone, Serialize)]
pub struct BindingPlan {
    /// Instances in launcher order.
    pub instances: Vec<InstancePlan>,
}

impl BindingPlan {
    /// The instance named `id`.
    pub fn instance(&self, id: &str) -> Option<&InstancePlan> {
        self.instances.iter().find(|i| i.instance_id == id)
    }
}

/// Checks every binding rule of SPEC 6.1 and builds the plan. `nodes[i]` is
/// the node of `launcher.deployments[i]`, or `None` when it could not be
/// loaded (its instances are then skipped; the reason is reported elsewhere).
pub fn plan_bindings(
    launcher: &LauncherDoc,
    nodes: &[Option<&NodeDoc>],
) -> Result<(BindingPlan, Diagnostics), Diagnostics> {
    let mut diags = crate::launcher::stack_rules(launcher);

    // Two deployments of one node.
    for (i, node) in nodes.iter().enumerate() {
        let Some(node) = node else { continue };
        if let Some(first) = nodes[..i]
            .iter()
            .position(|n| n.is_some_and(|n| n.identity() == node.identity()))
        {
            let first_loc = &launcher.deployments[first].source_loc;
            let lc = first_loc.file.line_col(first_loc.span.start);
            diags.push(
                launcher.deployments[i]
                    .source_loc
                    .error(
                        Code::DuplicateDeployment,
                        format!("`{}` is deployed twice", node.identity()),
                    )
                    .with_help(format!(
                        "put all its instances in the deployment at line {}, column {}",
                        lc.line, lc.column
                    )),
            );
        }
    }

    let producer = |id: &str| -> Option<&NodeDoc> {
        launcher
            .instances()
            .find(|(_, inst)| inst.instance_id == id)
            .and_then(|(d, _)| nodes[d])
    };

    let mut instances = Vec::new();
    for (d, inst) in launcher.instances() {
        let Some(node) = nodes[d] else { continue };
        let slots = plan_instance(inst, node, &producer, launcher, nodes, &mut diags);
        let parameters = fill_parameters(inst, node, &mut diags);
        instances.push(InstancePlan {
            instance_id: inst.instance_id.clone(),
            deployment: d,
            node: node.identity(),
            slots,
            parameters,
            env_vars: inst.env_vars.clone(),
            restart: inst.restart,
        });
    }
    diags.into_result(BindingPlan { instances })
}

fn fills(dep: &Dependency, producer: &NodeDoc) -> bool {
    match dep.kind {
        SlotKind::Node => producer.identity() == dep.target,
        SlotKind::Interface => producer.conforms_to(&dep.target),
    }
}

fn describe_slot(dep: &Dependency) -> String {
    format!("{} `{}`", dep.kind.as_str(), dep.target)
}

/// Instances in the launcher that could fill `dep`, for help texts.
fn candidates(dep: &Dependency, launcher: &LauncherDoc, nodes: &[Option<&NodeDoc>]) -> Vec<String> {
    launcher
        .instances()
        .filter(|(d, _)| nodes[*d].is_some_and(|n| fills(dep, n)))
        .map(|(_, i)| i.instance_id.clone())
        .collect()
}

fn mismatch(b: &Binding, inst: &Instance, dep: &Dependency, target: &NodeDoc) -> Diagnostic {
    match dep.kind {
        SlotKind::Node => b
            .target_loc
            .error(
                Code::BindingTargetMismatch,
                format!(
                    "binding `{}` on instance `{}`: `{}` deploys node `{}`, but slot `{}` expects node `{}`",
                    b.key,
                    inst.instance_id,
                    b.target,
                    target.identity(),
                    dep.link_id,
                    dep.target
                ),
            )
            .with_help(format!("bind an instance of `{}`", dep.target)),
        SlotKind::Interface => b
            .target_loc
            .error(
                Code::BindingInterfaceNotConformed,
                format!(
                    "binding `{}` on instance `{}`: `{}` deploys `{}`, which does not conform to interface `{}` required by slot `{}`",
                    b.key,
                    inst.instance_id,
                    b.target,
                    target.identity(),
                    dep.target,
                    dep.link_id
                ),
            )
            .with_help(format!(
                "bind an instance of a node that declares it, or add `conforms_to: [{{ name: \"{}\", tag: \"{}\" }}]` to `{}` (a matching name or matching topics do not count)",
                dep.target.name,
                dep.target.tag,
                target.identity()
            )),
    }
}

fn plan_instance<'a>(
    inst: &Instance,
    node: &NodeDoc,
    producer: &dyn Fn(&str) -> Option<&'a NodeDoc>,
    launcher: &LauncherDoc,
    nodes: &[Option<&NodeDoc>],
    diags: &mut Diagnostics,
) -> Vec<SlotPlan> {
    let mut pinned: Vec<(String, Option<String>)> = node
        .dependencies
        .iter()
        .filter(|d| !d.from_any)
        .map(|d| (d.link_id.clone(), None))
        .collect();
    let mut from_any: Vec<(&Dependency, Vec<String>)> = node
        .dependencies
        .iter()
        .filter(|d| d.from_any)
        .map(|d| (d, Vec::new()))
        .collect();
    from_any.sort_by(|a, b| a.0.link_id.cmp(&b.0.link_id));
    let mut keyed_but_failed: Vec<&str> = Vec::new();

    for b in &inst.bindings {
        // Unknown targets were reported with the launcher.
        let Some(target) = producer(&b.target) else {
            keyed_but_failed.push(&b.key);
            continue;
        };
        if let Some(dep) = node.dependency(&b.key) {
            // The key names a slot: it binds that slot.
            if !fills(dep, target) {
                diags.push(mismatch(b, inst, dep, target));
                keyed_but_failed.push(&b.key);
                continue;
            }
            if dep.from_any {
                if let Some((_, list)) = from_any.iter_mut().find(|(d, _)| d.link_id == dep.link_id)
                {
                    list.push(b.target.clone());
                }
            } else if let Some((_, slot)) = pinned.iter_mut().find(|(l, _)| *l == dep.link_id) {
                *slot = Some(b.target.clone());
            }
            continue;
        }
        // A free-form key: the first from_any slot (by link_id) that takes the target.
        match from_any.iter_mut().find(|(d, _)| fills(d, target)) {
            Some((_, list)) => list.push(b.target.clone()),
            None => {
                let declared: Vec<&str> = node
                    .dependencies
                    .iter()
                    .map(|d| d.link_id.as_str())
                    .collect();
                let from_any_slots: Vec<String> = node
                    .dependencies
                    .iter()
                    .filter(|d| d.from_any)
                    .map(|d| format!("`{}` ({})", d.link_id, describe_slot(d)))
                    .collect();
                let help = if declared.is_empty() {
                    format!(
                        "node `{}` declares no slots (`manifest.depends_on` is empty); remove the binding",
                        node.identity()
                    )
                } else if from_any_slots.is_empty() {
                    format!(
                        "declared link_ids: {}; a free-form key needs a from_any slot, and `{}` has none",
                        list(declared.iter().copied()),
                        node.identity()
                    )
                } else {
                    format!(
                        "declared link_ids: {}; from_any slots: {}; `{}` deploys `{}`",
                        list(declared.iter().copied()),
                        from_any_slots.join(", "),
                        b.target,
                        target.identity()
                    )
                };
                diags.push(
                    b.key_loc
                        .error(
                            Code::DeadBindingKey,
                            format!(
                                "binding `{}` on instance `{}` matches no slot of `{}`, and no from_any slot accepts `{}`",
                                b.key,
                                inst.instance_id,
                                node.identity(),
                                b.target
                            ),
                        )
                        .with_help(help),
                );
            }
        }
    }

    let mut slots = Vec::new();
    for dep in &node.dependencies {
        let binding = if dep.from_any {
            let list = &from_any
                .iter()
                .find(|(d, _)| d.link_id == dep.link_id)
                .expect("from_any slot")
                .1;
            if list.is_empty() {
                SlotBinding::FromAnyUnbound
            } else {
                SlotBinding::FromAnyBound {
                    producers: list.clone(),
                }
            }
        } else {
            match &pinned
                .iter()
                .find(|(l, _)| *l == dep.link_id)
                .expect("pinned slot")
                .1
            {
                Some(p) => SlotBinding::Pinned {
                    producer: p.clone(),
                },
                None => {
                    if !keyed_but_failed.contains(&dep.link_id.as_str()) {
                        let fit = candidates(dep, launcher, nodes);
                        let help = if fit.is_empty() {
                            format!(
                                "add `bindings: {{ {}: \"<instance_id>\" }}`; no instance in this launcher fills {} yet",
                                dep.link_id,
                                describe_slot(dep)
                            )
                        } else {
                            format!(
                                "add `bindings: {{ {}: \"{}\" }}`; instances that fit: {}",
                                dep.link_id,
                                fit[0],
                                list(fit.iter().map(String::as_str))
                            )
                        };
                        diags.push(
                            inst.id_loc
                                .error(
                                    Code::PinnedSlotUnbound,
                                    format!(
                                        "instance `{}`: pinned slot `{}` ({}) is unbound",
                                        inst.instance_id,
                                        dep.link_id,
                                        describe_slot(dep)
                                    ),
                                )
                                .with_help(help),
                        );
                    }
                    continue;
                }
            }
        };
        slots.push(SlotPlan {
            link_id: dep.link_id.clone(),
            kind: dep.kind,
            target: dep.target.clone(),
            binding,
            filter: RouteFilter::Any,
        });
    }
    compute_filters(&mut slots);
    slots
}

/// Per slot, SPEC 5: pinned -> that producer; from_any bound -> the listed
/// producers minus those pinned by a sibling; from_any unbound -> any except
/// producers claimed by siblings. Siblings are slots of the same kind and
/// `name:tag`.
pub fn compute_filters(slots: &mut [SlotPlan]) {
    let snapshot: Vec<(SlotKind, Identity, String, SlotBinding)> = slots
        .iter()
        .map(|s| {
            (
                s.kind,
                s.target.clone(),
                s.link_id.clone(),
                s.binding.clone(),
            )
        })
        .collect();
    for slot in slots.iter_mut() {
        let siblings = snapshot
            .iter()
            .filter(|(k, t, l, _)| *k == slot.kind && *t == slot.target && *l != slot.link_id);
        slot.filter = match &slot.binding {
            SlotBinding::Pinned { producer } => RouteFilter::Pin(producer.clone()),
            SlotBinding::FromAnyBound { producers } => {
                let pinned_elsewhere: BTreeSet<&str> = siblings
                    .filter_map(|(_, _, _, b)| match b {
                        SlotBinding::Pinned { producer } => Some(producer.as_str()),
                        _ => None,
                    })
                    .collect();
                RouteFilter::OnlyFrom(
                    producers
                        .iter()
                        .filter(|p| !pinned_elsewhere.contains(p.as_str()))
                        .cloned()
                        .collect(),
                )
            }
            SlotBinding::FromAnyUnbound => {
                let claimed: BTreeSet<String> = siblings
                    .flat_map(|(_, _, _, b)| match b {
                        SlotBinding::Pinned { producer } => vec![producer.clone()],
                        SlotBinding::FromAnyBound { producers } => producers.clone(),
                        SlotBinding::FromAnyUnbound => Vec::new(),
                    })
                    .collect();
                if claimed.is_empty() {
                    RouteFilter::Any
                } else {
                    RouteFilter::AnyExcept(claimed)
                }
            }
        };
    }
}

fn fill_parameters(inst: &Instance, node: &NodeDoc, diags: &mut Diagnostics) -> serde_json::Value {
    let given = inst
        .arguments
        .as_ref()
        .map_or(serde_json::Value::Null, |a| a.to_json());
    match node.execution.parameters.resolve(&given) {
        Ok(v) => v,
        Err(errors) => {
            for e in errors {
                let (file, span, path) = match (&inst.arguments, &inst.arguments_loc) {
                    (Some(args), Some(loc)) => {
                        let at = parameter_node(args, &e.path).map_or(loc.span, |n| n.span);
                        (loc.file.clone(), at, format!("{}.{}", loc.key_path, e.path))
                    }
                    _ => (
                        inst.id_loc.file.clone(),
                        inst.id_loc.span,
                        inst.id_loc.key_path.clone(),
                    ),
                };
                let mut d =
                    Diagnostic::error(e.code(), format!("instance `{}`: {e}", inst.instance_id))
                        .at(&file, span)
                        .with_key_path(path);
                if let Some(h) = e.help() {
                    d = d.with_help(match e.kind {
                        crate::params::ParamErrorKind::Missing { .. } => "add it under `arguments`, or give it a `$default` in the node's `execution.parameters`".to_string(),
                        _ => h,
                    });
                }
                diags.push(d);
            }
            serde_json::Value::Null
        }
    }
}

/// The value at a parameter error path (`a.b[2].c`), if present.
fn parameter_node<'n>(args: &'n crate::json::Node, path: &str) -> Option<&'n crate::json::Node> {
    let mut node = args;
    for part in path.split('.') {
        let (key, indices) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !key.is_empty() {
            node = node.get(key)?;
        }
        for idx in indices.split('[').filter(|s| !s.is_empty()) {
            let i: usize = idx.trim_end_matches(']').parse().ok()?;
            node = match &node.value {
                crate::json::Value::Array(items) => items.get(i)?,
                _ => return None,
            };
        }
    }
    Some(node)
}
