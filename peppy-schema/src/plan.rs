//! The binding plan of a launcher: for every consumer instance and slot,
//! which producers fill it, and the routing filter the consumer applies.
//! The rules themselves are the binding engine's ([`crate::binding`]); this
//! module feeds it the launcher's bindings and locates its errors.

use serde::Serialize;

use crate::binding::{BindError, BindForm, BindRequest, Producer, SlotPlan, assign, conformances};
use crate::diag::{Code, Diagnostic, Diagnostics};
use crate::launcher::{Instance, LauncherDoc, LinkValue, RestartPolicy};
use crate::loc::Loc;
use crate::node::{Dependency, Identity, NodeDoc};
use crate::pairs::PairPlan;

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
    /// Its pairing slots, in order: each participant's peer, each
    /// observer's sources.
    pub pairs: Vec<PairPlan>,
    /// Parameters with defaults filled in.
    pub parameters: serde_json::Value,
    /// `env_vars`.
    pub env_vars: Vec<(String, String)>,
    /// The shutdown grace window its `env_vars` set
    /// ([`SHUTDOWN_GRACE_ENV`](crate::SHUTDOWN_GRACE_ENV), read with the
    /// launcher); `None` leaves it to the launch's environment and the node.
    pub shutdown_grace_secs: Option<f64>,
    /// Restart policy.
    pub restart: RestartPolicy,
    /// The core node it runs on: its `core_node`, or the first core node
    /// declared; `None` when the launcher names no machines.
    pub core_node: Option<String>,
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

    let mut pairs = crate::pair_links::plan_pairs(launcher, nodes, &mut diags);
    let mut instances = Vec::new();
    for (d, inst) in launcher.instances() {
        let Some(node) = nodes[d] else { continue };
        let slots = plan_instance(inst, node, launcher, nodes, &mut diags);
        let parameters = fill_parameters(inst, node, &mut diags);
        instances.push(InstancePlan {
            instance_id: inst.instance_id.clone(),
            deployment: d,
            node: node.identity(),
            slots,
            pairs: pairs.remove(&inst.instance_id).unwrap_or_default(),
            parameters,
            env_vars: inst.env_vars.clone(),
            shutdown_grace_secs: inst.shutdown_grace_secs,
            restart: inst.restart,
            core_node: launcher
                .core_node_of(inst.core_node.as_ref().map(|(name, _)| name.as_str()))
                .map(str::to_string),
        });
    }
    diags.into_result(BindingPlan { instances })
}

/// The launcher's instances that could fill `dep`, for help texts.
fn candidates(dep: &Dependency, launcher: &LauncherDoc, nodes: &[Option<&NodeDoc>]) -> Vec<String> {
    launcher
        .instances()
        .filter(|(d, _)| {
            nodes[*d].is_some_and(|n| {
                let conforms = conformances(n);
                let id = n.identity();
                Producer {
                    node: &id,
                    conforms_to: &conforms,
                }
                .fits(dep.kind, &dep.target)
            })
        })
        .map(|(_, i)| i.instance_id.clone())
        .collect()
}

/// One binding as the launcher writes it, for the engine and for locating
/// its errors: a `launcher_v1` binding or one target (or an empty list,
/// or a vacancy) of `launcher/v1`'s links.
struct Written<'a> {
    key: &'a str,
    instance: &'a str,
    form: BindForm<'a>,
    key_loc: &'a Loc,
    value_loc: &'a Loc,
}

/// The links of an instance (`launcher_v1` bindings among them), one
/// [`Written`] per target. Targets no deployment declares were reported by
/// [`crate::launcher::stack_rules`]; their keys are returned apart, so the
/// slot they name is not also reported unbound.
fn written(inst: &Instance) -> Vec<Written<'_>> {
    let mut out = Vec::new();
    for l in &inst.links {
        match &l.value {
            LinkValue::Bound(t) => out.push(Written {
                key: &l.key,
                instance: &t.instance,
                form: BindForm::Key,
                key_loc: &l.key_loc,
                value_loc: &t.loc,
            }),
            LinkValue::One(t) => out.push(Written {
                key: &l.key,
                instance: &t.instance,
                form: BindForm::Scalar,
                key_loc: &l.key_loc,
                value_loc: &t.loc,
            }),
            LinkValue::Many(targets, loc) if targets.is_empty() => out.push(Written {
                key: &l.key,
                instance: "",
                form: BindForm::EmptyList,
                key_loc: &l.key_loc,
                value_loc: loc,
            }),
            LinkValue::Many(targets, _) => out.extend(targets.iter().map(|t| Written {
                key: &l.key,
                instance: &t.instance,
                form: BindForm::Item,
                key_loc: &l.key_loc,
                value_loc: &t.loc,
            })),
            LinkValue::Vacant { reason, loc } => out.push(Written {
                key: &l.key,
                instance: "",
                form: BindForm::Vacant(reason),
                key_loc: &l.key_loc,
                value_loc: loc,
            }),
        }
    }
    out
}

/// Links that cannot reach the engine: a key naming a pairing slot
/// (planned by [`crate::pair_links`]), and a `peer/slot` target on a slot
/// that is not a pairing's (refused). Returns the keys left out.
fn links_outside_the_engine<'a>(
    inst: &'a Instance,
    node: &NodeDoc,
    diags: &mut Diagnostics,
) -> Vec<&'a str> {
    let mut skipped = Vec::new();
    // A `launcher_v1` binding never names a pairing slot: the engine
    // reports it like any key that names no producer slot.
    for l in inst
        .links
        .iter()
        .filter(|l| !matches!(l.value, LinkValue::Bound(_)))
    {
        if crate::pair_links::is_pairing_link(node, &l.key) {
            skipped.push(l.key.as_str());
            continue;
        }
        for t in l.value.targets().iter().filter(|t| t.peer_slot.is_some()) {
            diags.push(
                t.loc
                    .error(
                        Code::UnknownInstanceId,
                        format!(
                            "link `{}` on instance `{}` names `{t}`; a producer slot takes a bare instance id (`inst/slot` names a pairing peer's slot)",
                            l.key, inst.instance_id
                        ),
                    )
                    .with_help(format!("write `\"{}\"`", t.instance)),
            );
            skipped.push(l.key.as_str());
        }
    }
    skipped
}

/// A producer instance's node and the contracts it implements.
type ProducerNode = (Identity, Vec<Identity>);

/// One instance's slots through the binding engine, its errors located in
/// the launcher.
fn plan_instance(
    inst: &Instance,
    node: &NodeDoc,
    launcher: &LauncherDoc,
    nodes: &[Option<&NodeDoc>],
    diags: &mut Diagnostics,
) -> Vec<SlotPlan> {
    let producer_of = |id: &str| -> Option<ProducerNode> {
        launcher
            .instances()
            .find(|(_, i)| i.instance_id == id)
            .and_then(|(d, _)| nodes[d])
            .map(|n| (n.identity(), conformances(n)))
    };
    let mut skipped_keys = links_outside_the_engine(inst, node, diags);
    let mut known: Vec<(Written<'_>, Option<ProducerNode>)> = Vec::new();
    for w in written(inst) {
        if skipped_keys.contains(&w.key) {
            continue;
        }
        if !matches!(w.form, BindForm::EmptyList | BindForm::Vacant(_)) {
            match producer_of(w.instance) {
                Some(p) => known.push((w, Some(p))),
                // Reported with the launcher: leave it out, and do not also
                // report the slot it names as unbound.
                None => skipped_keys.push(w.key),
            }
            continue;
        }
        known.push((w, None));
    }
    let requests: Vec<BindRequest<'_>> = known
        .iter()
        .map(|(w, p)| BindRequest {
            key: w.key,
            instance: w.instance,
            producer: p.as_ref().map(|(id, conforms)| Producer {
                node: id,
                conforms_to: conforms,
            }),
            form: w.form,
        })
        .collect();
    let outcome = assign(
        &inst.instance_id,
        &node.identity(),
        node.spelling,
        &node.dependencies,
        &requests,
    );
    for (index, error) in outcome.errors {
        let diagnostic = match (index, &error) {
            (
                Some(i),
                BindError::TargetMismatch { .. }
                | BindError::NotConformed { .. }
                | BindError::DuplicateProducer { .. }
                | BindError::PinnedTwice { .. }
                | BindError::Shape { .. },
            ) => known[i].0.value_loc.error(error.code(), error.to_string()),
            (Some(i), _) => known[i].0.key_loc.error(error.code(), error.to_string()),
            (
                None,
                BindError::PinnedUnbound { link_id, .. } | BindError::Unfulfilled { link_id, .. },
            ) => {
                if skipped_keys.contains(&link_id.as_str()) {
                    continue;
                }
                // `[]` on a `one_or_more` slot: the empty list is the error.
                let empty = known
                    .iter()
                    .find(|(w, _)| w.key == link_id && w.form == BindForm::EmptyList);
                match empty {
                    Some((w, _)) => w.value_loc.error(error.code(), error.to_string()),
                    None => inst.id_loc.error(error.code(), error.to_string()),
                }
            }
            (None, _) => inst.id_loc.error(error.code(), error.to_string()),
        };
        let fit = match &error {
            BindError::PinnedUnbound { link_id, .. } | BindError::Unfulfilled { link_id, .. } => {
                node.dependency(link_id)
                    .map(|d| candidates(d, launcher, nodes))
                    .unwrap_or_default()
            }
            _ => Vec::new(),
        };
        diags.push(diagnostic.with_help(error.launcher_help(&fit)));
    }
    outcome.slots
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
