//! `peppy-launch graph LAUNCHER`: the stack as Graphviz DOT on stdout.

use std::fmt::Write as _;

use peppy_schema::{
    NodeDoc, Producer, RepoOptions, SlotBinding, SlotKind, StackCheck, check_launcher, conformances,
};

use crate::cli::GraphArgs;
use crate::error::{LaunchError, Result};
use crate::report;

pub(crate) fn run(args: &GraphArgs) -> Result {
    let options = RepoOptions {
        explicit: args.repos.clone(),
        env: None,
    };
    match check_launcher(&args.launcher, &options) {
        Ok(stack) => {
            print!("{}", dot(&stack));
            Ok(())
        }
        Err(diags) => {
            report::print_human(&diags);
            Err(LaunchError::Invalid {
                errors: diags.error_count(),
            })
        }
    }
}

fn quote(s: &str) -> String {
    format!(
        "\"{}\"",
        s.replace('\\', "\\\\")
            .replace('"', "\\\"")
            .replace('\n', "\\n")
    )
}

/// Whether `producer` can fill a slot: the binding engine's rule.
fn fills(kind: SlotKind, target: &peppy_schema::Identity, producer: &NodeDoc) -> bool {
    let conforms = conformances(producer);
    Producer {
        node: &producer.identity(),
        conforms_to: &conforms,
    }
    .fits(kind, target)
}

/// Instances are boxes; pinned and bound edges are solid and labelled with
/// the slot; unbound `from_any` slots get dashed `(any)` edges from every
/// instance they would take (or from an `(any)` placeholder when none is in
/// the stack); external consumed topics get dotted edges from every emitter.
pub(crate) fn dot(stack: &StackCheck) -> String {
    let name = stack
        .launcher
        .file
        .path()
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("stack");
    let node_of = |id: &str| {
        stack
            .plan
            .instance(id)
            .map(|i| &stack.deployments[i.deployment].resolved)
    };
    let mut out = String::new();
    let _ = writeln!(out, "digraph {} {{", quote(name));
    let _ = writeln!(
        out,
        "  rankdir=LR;\n  node [shape=box, fontname=\"monospace\"];"
    );
    for inst in &stack.plan.instances {
        let _ = writeln!(
            out,
            "  {} [label={}];",
            quote(&inst.instance_id),
            quote(&format!("{}\n{}", inst.instance_id, inst.node))
        );
    }
    for inst in &stack.plan.instances {
        let consumer = quote(&inst.instance_id);
        for slot in &inst.slots {
            match &slot.binding {
                SlotBinding::Pinned { producer } => {
                    let _ = writeln!(
                        out,
                        "  {} -> {consumer} [label={}];",
                        quote(producer),
                        quote(&slot.link_id)
                    );
                }
                SlotBinding::FromAnyBound { .. } => {
                    if let peppy_schema::RouteFilter::OnlyFrom(set) = &slot.filter {
                        for p in set {
                            let _ = writeln!(
                                out,
                                "  {} -> {consumer} [label={}];",
                                quote(p),
                                quote(&slot.link_id)
                            );
                        }
                    }
                }
                SlotBinding::FromAnyUnbound => {
                    let takers: Vec<&str> = stack
                        .plan
                        .instances
                        .iter()
                        .filter(|p| p.instance_id != inst.instance_id)
                        .filter(|p| {
                            node_of(&p.instance_id)
                                .is_some_and(|r| fills(slot.kind, &slot.target, &r.node))
                        })
                        .filter(|p| slot.filter.accepts(&p.instance_id))
                        .map(|p| p.instance_id.as_str())
                        .collect();
                    let label = quote(&format!("{} (any)", slot.link_id));
                    if takers.is_empty() {
                        let any = quote(&format!("{}.{}.any", inst.instance_id, slot.link_id));
                        let _ = writeln!(
                            out,
                            "  {any} [label={}, shape=ellipse, style=dashed];",
                            quote(&format!("(any) {}", slot.target))
                        );
                        let _ =
                            writeln!(out, "  {any} -> {consumer} [label={label}, style=dashed];");
                    }
                    for p in takers {
                        let _ = writeln!(
                            out,
                            "  {} -> {consumer} [label={label}, style=dashed];",
                            quote(p)
                        );
                    }
                }
            }
        }
        let Some(resolved) = node_of(&inst.instance_id) else {
            continue;
        };
        for topic in resolved.consumed_topics.iter().filter(|t| t.slot.is_none()) {
            for p in &stack.plan.instances {
                let emits = node_of(&p.instance_id)
                    .is_some_and(|r| r.emitted_topics.iter().any(|e| e.decl.name == topic.name));
                if emits && p.instance_id != inst.instance_id {
                    let _ = writeln!(
                        out,
                        "  {} -> {consumer} [label={}, style=dotted];",
                        quote(&p.instance_id),
                        quote(&format!("{} (external)", topic.name))
                    );
                }
            }
        }
    }
    out.push_str("}\n");
    out
}
