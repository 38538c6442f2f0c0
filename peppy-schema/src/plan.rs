//! The binding plan of a launcher: for every consumer instance and slot,
//! which producers fill it, and the routing filter the consumer applies.
//! The rules themselves are the binding engine's ([`crate::binding`]); this
//! module feeds it the launcher's bindings and locates its errors.

use serde::Serialize;

use crate::binding::{BindError, BindRequest, Producer, SlotPlan, assign, conformances};
use crate::diag::{Code, Diagnostic, Diagnostics};
use crate::launcher::{Binding, Instance, LauncherDoc, RestartPolicy};
use crate::node::{Dependency, Identity, NodeDoc};

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
            parameters,
            env_vars: inst.env_vars.clone(),
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

/// One instance's slots through the binding engine, its errors located in
/// the launcher.
fn plan_instance(
    inst: &Instance,
    node: &NodeDoc,
    launcher: &LauncherDoc,
    nodes: &[Option<&NodeDoc>],
    diags: &mut Diagnostics,
) -> Vec<SlotPlan> {
    let producer_of = |id: &str| -> Option<(Identity, Vec<Identity>)> {
        launcher
            .instances()
            .find(|(_, i)| i.instance_id == id)
            .and_then(|(d, _)| nodes[d])
            .map(|n| (n.identity(), conformances(n)))
    };
    // Unknown targets were reported with the launcher: leave their bindings
    // out, and do not also report the slot they name as unbound.
    let known: Vec<(&Binding, (Identity, Vec<Identity>))> = inst
        .bindings
        .iter()
        .filter_map(|b| producer_of(&b.target).map(|p| (b, p)))
        .collect();
    let unknown_keys: Vec<&str> = inst
        .bindings
        .iter()
        .filter(|b| producer_of(&b.target).is_none())
        .map(|b| b.key.as_str())
        .collect();
    let requests: Vec<BindRequest<'_>> = known
        .iter()
        .map(|(b, (id, conforms))| {
            BindRequest::key(
                &b.key,
                &b.target,
                Some(Producer {
                    node: id,
                    conforms_to: conforms,
                }),
            )
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
            (Some(i), BindError::TargetMismatch { .. } | BindError::NotConformed { .. }) => {
                known[i].0.target_loc.error(error.code(), error.to_string())
            }
            (Some(i), _) => known[i].0.key_loc.error(error.code(), error.to_string()),
            (None, BindError::PinnedUnbound { link_id, .. }) => {
                if unknown_keys.contains(&link_id.as_str()) {
                    continue;
                }
                inst.id_loc.error(error.code(), error.to_string())
            }
            (None, _) => inst.id_loc.error(error.code(), error.to_string()),
        };
        let fit = match &error {
            BindError::PinnedUnbound { link_id, .. } => node
                .dependency(link_id)
                .map(|d| candidates(d, launcher, nodes))
                .unwrap_or_default(),
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
