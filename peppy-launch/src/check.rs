//! `peppy-launch check LAUNCHER`: the same validation `up` runs, then the plan.

use std::fmt::Write as _;
use std::path::Path;

use peppy_schema::{
    Composition, Diagnostics, RepoOptions, RouteFilter, SlotBinding, SlotKind, StackCheck,
    check_launcher_selection, check_resolved,
};
use serde::Serialize;

use crate::cli::{CheckArgs, Format};
use crate::error::{LaunchError, Result};
use crate::report::{self, JsonDiagnostic};

#[derive(Serialize)]
struct JsonReport<'a> {
    valid: bool,
    launcher: String,
    /// The selection checked (`axis=option` echo), for a composed launcher.
    #[serde(skip_serializing_if = "Option::is_none")]
    selection: Option<String>,
    repositories: Vec<String>,
    diagnostics: Vec<JsonDiagnostic>,
    /// The machines, when the launcher places instances on several.
    core_nodes: Vec<&'a peppy_schema::CoreNode>,
    plan: Option<&'a peppy_schema::BindingPlan>,
    /// With `--security`: whether `up` would run secured, and the policy.
    #[serde(skip_serializing_if = "Option::is_none")]
    security: Option<SecurityReport>,
}

#[derive(Serialize)]
struct SecurityReport {
    /// Whether `up` without flags runs this launcher secured.
    on: bool,
    /// Why.
    reason: String,
    policy: crate::security::policy::Policy,
}

/// The policy `up` would enforce, for `--security`.
fn security_report(stack: &StackCheck, args: &CheckArgs) -> SecurityReport {
    let namespace = args
        .namespace
        .clone()
        .unwrap_or_else(|| crate::up::default_namespace(&args.launcher));
    let decision = crate::security::decide(&stack.launcher, &[], &[], false);
    SecurityReport {
        on: decision.on,
        reason: decision.reason,
        policy: crate::security::policy::derive(stack, &namespace, &|inst| {
            stack
                .launcher
                .core_node_of(inst.core_node.as_deref())
                .map(str::to_string)
        }),
    }
}

pub(crate) fn run(args: &CheckArgs) -> Result {
    let options = crate::repositories::options(args.repos.clone())?;
    if args.all_selections {
        return all_selections(args, &options);
    }
    let result = check_launcher_selection(
        &args.launcher,
        &args.with,
        &options,
        &crate::sources::Fetcher::new(),
    );
    // `--place`: show the stack on its machines.
    let result = match result {
        Ok(stack) => Ok(crate::placement::place(
            stack,
            &args.placing.place,
            &mut crate::placement::host_core_node,
        )?),
        Err(d) => Err(d),
    };
    let (diags, stack) = match &result {
        Ok(stack) => {
            // A container node that cannot run on this machine is a
            // warning here (`up` refuses it).
            let mut warnings = stack.warnings.clone();
            warnings.extend(crate::container::assess(stack).1);
            (warnings, Some(stack))
        }
        Err(d) => (d.clone(), None),
    };
    match args.format {
        Format::Json => report::print_json(&JsonReport {
            valid: stack.is_some(),
            launcher: args.launcher.display().to_string(),
            selection: stack.and_then(|s| s.selection.as_ref().map(ToString::to_string)),
            repositories: stack
                .map(|s| {
                    s.repositories
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect()
                })
                .unwrap_or_default(),
            diagnostics: report::json_list(&diags),
            core_nodes: stack
                .map(|s| s.launcher.core_nodes.iter().collect())
                .unwrap_or_default(),
            plan: stack.map(|s| &s.plan),
            security: stack
                .filter(|_| args.security)
                .map(|s| security_report(s, args)),
        }),
        Format::Human => {
            if !diags.is_empty() {
                report::print_human(&diags);
            }
            match stack {
                Some(stack) => {
                    print!("{}", render_plan(stack));
                    if args.security {
                        let report = security_report(stack, args);
                        println!(
                            "\nsecurity: {} under `up` ({}; `security: true|false` in the launcher or `up --insecure` decide otherwise)",
                            if report.on { "on" } else { "off" },
                            report.reason
                        );
                        print!("{}", report.policy.table());
                    }
                }
                None => summary(&diags),
            }
        }
    }
    match stack {
        Some(_) => Ok(()),
        None => Err(LaunchError::Invalid {
            errors: diags.error_count(),
        }),
    }
}

/// `check --all-selections`: every selection of the launcher, each resolved
/// and checked like `check --with` would; refused ones are listed with
/// the constraint that refuses them.
fn all_selections(args: &CheckArgs, options: &RepoOptions) -> Result {
    let composition = Composition::load(&args.launcher).map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    let fetcher = crate::sources::Fetcher::new();
    let (mut valid, mut refused, mut invalid, mut errors) = (0, 0, 0, 0);
    let verdicts = composition.selections().map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    for verdict in verdicts {
        let words = verdict.selection.with_words();
        let shown = if composition.is_composed() {
            format!("--with {words}")
        } else {
            "(flat launcher)".to_string()
        };
        if let Some((i, reason)) = &verdict.refused_by {
            println!("refused  {shown}: constraint {} says: {reason}", i + 1);
            refused += 1;
            continue;
        }
        match composition
            .resolve(&verdict.selection)
            .and_then(|r| check_resolved(r, options, &fetcher))
        {
            Ok(stack) => {
                println!(
                    "valid    {shown} ({})",
                    report::count(stack.launcher.instances().count(), "instance")
                );
                valid += 1;
            }
            Err(diags) => {
                println!("invalid  {shown}");
                report::print_human(&diags);
                invalid += 1;
                errors += diags.error_count();
            }
        }
    }
    println!(
        "{} selections: {valid} valid, {refused} refused by constraints, {invalid} invalid",
        valid + refused + invalid
    );
    if invalid == 0 {
        Ok(())
    } else {
        Err(LaunchError::Invalid { errors })
    }
}

fn summary(diags: &Diagnostics) {
    let errors = diags.error_count();
    eprintln!(
        "invalid: {}, {}; nothing was built or started",
        report::count(errors, "error"),
        report::count(diags.len() - errors, "warning")
    );
}

fn relative(p: &Path) -> String {
    let base = report::cwd();
    base.as_deref()
        .and_then(|b| p.strip_prefix(b).ok())
        .unwrap_or(p)
        .display()
        .to_string()
}

/// The plan as people read it: each instance, each slot and what fills it.
pub(crate) fn render_plan(stack: &StackCheck) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "launcher: {}", relative(stack.launcher.file.path()));
    if let Some(selection) = &stack.selection {
        let _ = writeln!(out, "components: {selection}");
    }
    let repos: Vec<String> = stack.repositories.iter().map(|p| relative(p)).collect();
    let _ = writeln!(
        out,
        "repositories: {}",
        if repos.is_empty() {
            "(none)".to_string()
        } else {
            repos.join(", ")
        }
    );
    let cores = &stack.launcher.core_nodes;
    if !cores.is_empty() {
        let _ = writeln!(out, "core nodes:");
        for c in cores {
            let mut ends = Vec::new();
            if !c.listen.is_empty() {
                ends.push(format!("listen {}", c.listen.join(", ")));
            }
            if !c.connect.is_empty() {
                ends.push(format!("connect {}", c.connect.join(", ")));
            }
            let _ = writeln!(
                out,
                "  {}{}",
                c.name,
                if ends.is_empty() {
                    String::new()
                } else {
                    format!("  ({})", ends.join("; "))
                }
            );
        }
    }
    let _ = writeln!(out, "instances:");
    let width = stack
        .plan
        .instances
        .iter()
        .map(|i| i.instance_id.len())
        .max()
        .unwrap_or(0);
    for inst in &stack.plan.instances {
        let dir = &stack.deployments[inst.deployment].dir;
        let placed = stack
            .launcher
            .core_node_of(inst.core_node.as_deref())
            .map(|c| format!("  on {c}"))
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "  {:width$}  {}  {}{placed}",
            inst.instance_id,
            inst.node,
            relative(dir)
        );
        if inst.parameters.as_object().is_some_and(|m| !m.is_empty()) {
            let _ = writeln!(out, "  {:width$}    parameters: {}", "", inst.parameters);
        }
        let slot_width = inst
            .slots
            .iter()
            .map(|s| s.link_id.len())
            .chain(inst.pairs.iter().map(|p| p.link_id.len()))
            .max()
            .unwrap_or(0);
        let mut rows = Vec::new();
        // Named in the consumer's own words: `contract/v1` or `interface_v1`.
        let contract = stack.deployments[inst.deployment]
            .resolved
            .node
            .spelling
            .contract_word();
        for slot in &inst.slots {
            let kind = match slot.kind {
                SlotKind::Node => "node",
                SlotKind::Interface => contract,
            };
            let (mode, fill) = match (&slot.binding, &slot.filter) {
                (SlotBinding::Pinned { producer }, _) => ("pinned", producer.clone()),
                (
                    SlotBinding::Set {
                        vacant: Some(why), ..
                    },
                    _,
                ) => ("vacant", format!("(vacant: {why})")),
                (SlotBinding::Set { producers, .. }, _) if producers.is_empty() => {
                    ("linked", "(nothing)".to_string())
                }
                (SlotBinding::Set { producers, .. }, _) => ("linked", producers.join(", ")),
                (SlotBinding::FromAnyBound { producers }, _) if producers.is_empty() => {
                    ("from_any", "(nothing: linked to [])".to_string())
                }
                (SlotBinding::FromAnyBound { .. }, RouteFilter::OnlyFrom(set))
                    if set.is_empty() =>
                {
                    (
                        "from_any",
                        "(nothing: every bound producer is pinned by a sibling slot)".to_string(),
                    )
                }
                (SlotBinding::FromAnyBound { .. }, RouteFilter::OnlyFrom(set)) => (
                    "from_any",
                    set.iter().cloned().collect::<Vec<_>>().join(", "),
                ),
                (SlotBinding::FromAnyUnbound, RouteFilter::AnyExcept(set)) => (
                    "from_any",
                    format!(
                        "(any) except {}",
                        set.iter().cloned().collect::<Vec<_>>().join(", ")
                    ),
                ),
                (_, _) => ("from_any", "(any)".to_string()),
            };
            rows.push((slot, fill, format!("{kind} {}, {mode}", slot.target)));
        }
        let fill_width = rows.iter().map(|r| r.1.len()).max().unwrap_or(0);
        for (slot, fill, what) in rows {
            let _ = writeln!(
                out,
                "  {:width$}    {:slot_width$} <- {fill:fill_width$}  ({what})",
                "", slot.link_id
            );
        }
        let node = &stack.deployments[inst.deployment].resolved;
        for (row, what) in pair_rows(inst, node, slot_width) {
            let _ = writeln!(out, "  {:width$}    {row}  ({what})", "");
        }
    }
    out
}

/// One line per pairing slot: the pair a participant forms, or the
/// sources an observer watches.
fn pair_rows(
    inst: &peppy_schema::InstancePlan,
    node: &peppy_schema::ResolvedNode,
    width: usize,
) -> Vec<(String, String)> {
    inst.pairs
        .iter()
        .filter_map(|plan| {
            let slot = node
                .node
                .pairings
                .iter()
                .find(|p| p.link_id == plan.link_id)?;
            let peers = plan
                .peers
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ");
            let fill = match (&plan.vacant, peers.is_empty()) {
                (Some(why), _) => format!("(vacant: {why})"),
                (None, true) => "(waiting for a peer to link to it)".to_string(),
                (None, false) => peers,
            };
            Some(if slot.observer {
                (
                    format!("{:width$} <~ {fill}", plan.link_id),
                    format!(
                        "observes {} of pairing {}, {}",
                        slot.role, slot.pairing, slot.cardinality
                    ),
                )
            } else {
                (
                    format!("{:width$} <> {fill}", plan.link_id),
                    format!(
                        "pairing {}, plays {}{}",
                        slot.pairing,
                        slot.role,
                        if slot.optional { ", optional" } else { "" }
                    ),
                )
            })
        })
        .collect()
}
