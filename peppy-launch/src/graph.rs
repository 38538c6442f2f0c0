//! `peppy-launch graph LAUNCHER`: the stack as a picture, Graphviz DOT on
//! stdout or DOT, SVG or HTML in a file.

use std::path::Path;

use peppy_schema::{SlotBinding, StackCheck, check_launcher_selection};

use crate::cli::GraphArgs;
use crate::drawing::{self, DrawEdge, DrawNode, Drawing, EdgeStyle, NodeState};
use crate::error::{LaunchError, Result, SetupError, UsageError};
use crate::flows;
use crate::report;

pub(crate) fn run(args: &GraphArgs) -> Result {
    // Refuse a bad file name before the (slower) check.
    let format = args.output.as_deref().map(Format::of).transpose()?;
    if args.live {
        let mut stack = args.stack.clone();
        stack.launcher = args.file.clone().or(stack.launcher);
        let picture = crate::inspect::block_on_value(crate::inspect::live_graph::picture(
            &stack,
            args.sample,
        ))?;
        return show(args.output.as_deref(), format, &picture);
    }
    let Some(launcher) = &args.file else {
        return Err(UsageError::NothingToDraw.into());
    };
    let options = crate::repositories::options(args.repos.clone())?;
    let stack = check_launcher_selection(
        launcher,
        &args.with,
        &options,
        &crate::sources::Fetcher::new(),
    )
    .map_err(|diags| {
        report::print_human(&diags);
        LaunchError::Invalid {
            errors: diags.error_count(),
        }
    })?;
    // DOT stays alone on stdout; the selection drawn is said beside it.
    if let Some(selection) = &stack.selection {
        eprintln!("components: {selection}");
    }
    // `--place`: one frame per machine.
    let stack = crate::placement::place(
        stack,
        &args.placing.place,
        &mut crate::placement::host_core_node,
    )?;
    show(args.output.as_deref(), format, &drawing(&stack))
}

/// DOT on stdout, or the picture written to `--output`.
fn show(output: Option<&Path>, format: Option<Format>, picture: &Drawing) -> Result {
    match (output, format) {
        (Some(path), Some(format)) => write(path, format, picture),
        _ => {
            print!("{}", drawing::dot(picture));
            Ok(())
        }
    }
}

/// What `--output` writes, from the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Format {
    /// Graphviz DOT.
    Dot,
    /// A self-contained SVG, laid out by [`drawing::svg`].
    Svg,
    /// A standalone page with the SVG and tables, by [`drawing::html`].
    Html,
}

impl Format {
    /// `.svg`, `.html`/`.htm`, `.dot`/`.gv`; a file without an extension
    /// gets DOT, and any other extension is refused rather than filled with
    /// something its name does not promise.
    pub(crate) fn of(path: &Path) -> Result<Format> {
        let Some(ext) = path.extension() else {
            return Ok(Format::Dot);
        };
        match ext.to_string_lossy().to_ascii_lowercase().as_str() {
            "svg" => Ok(Format::Svg),
            "html" | "htm" => Ok(Format::Html),
            "dot" | "gv" => Ok(Format::Dot),
            other => Err(UsageError::DrawingExtension {
                path: path.to_path_buf(),
                extension: other.to_string(),
            }
            .into()),
        }
    }

    /// The picture in this format.
    pub(crate) fn render(self, picture: &Drawing) -> String {
        match self {
            Format::Dot => drawing::dot(picture),
            Format::Svg => drawing::svg(picture),
            Format::Html => drawing::html(picture),
        }
    }
}

/// Writes the picture and says so on stderr, keeping stdout empty.
fn write(path: &Path, format: Format, picture: &Drawing) -> Result {
    std::fs::write(path, format.render(picture)).map_err(|source| SetupError::Write {
        path: path.to_path_buf(),
        source,
    })?;
    let instances = picture
        .nodes
        .iter()
        .filter(|n| n.state != NodeState::Placeholder)
        .count();
    eprintln!(
        "wrote {} ({instances} instances, {} edges)",
        path.display(),
        picture.edges.len()
    );
    Ok(())
}

/// The checked stack as a drawing. Instances are boxes; pinned and bound
/// edges are solid and labelled with the slot; unbound `from_any` slots get
/// dashed `(any)` edges from every instance they would take (or from an
/// `(any)` placeholder when none is in the stack); external consumed topics
/// get dotted edges from every emitter.
pub(crate) fn drawing(stack: &StackCheck) -> Drawing {
    let title = stack
        .launcher
        .file
        .path()
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("stack");
    let mut picture = Drawing {
        title: title.to_string(),
        nodes: stack
            .plan
            .instances
            .iter()
            .map(|inst| DrawNode {
                id: inst.instance_id.clone(),
                label: inst.instance_id.clone(),
                detail: inst.node.to_string(),
                // One frame per machine when the launcher names them.
                cluster: stack
                    .launcher
                    .core_node_of(inst.core_node.as_deref())
                    .map(str::to_string),
                state: NodeState::Planned,
            })
            .collect(),
        edges: Vec::new(),
    };
    for inst in &stack.plan.instances {
        slot_edges(stack, inst, &mut picture);
        pair_edges(stack, inst, &mut picture);
        external_edges(stack, inst, &mut picture);
    }
    picture
}

fn slot_edges(stack: &StackCheck, inst: &peppy_schema::InstancePlan, picture: &mut Drawing) {
    let consumer = &inst.instance_id;
    for slot in &inst.slots {
        let mut solid = |producer: &str| {
            picture
                .edges
                .push(edge(producer, consumer, &slot.link_id, EdgeStyle::Solid));
        };
        match &slot.binding {
            SlotBinding::Pinned { producer } => solid(producer),
            SlotBinding::Set { producers, .. } => producers.iter().for_each(|p| solid(p)),
            SlotBinding::FromAnyBound { .. } => {
                if let peppy_schema::RouteFilter::OnlyFrom(set) = &slot.filter {
                    set.iter().for_each(|p| solid(p));
                }
            }
            SlotBinding::FromAnyUnbound => {
                let takers = stack.slot_producers(inst, slot);
                let label = format!("{} (any)", slot.link_id);
                if takers.is_empty() {
                    let any = format!("{}.{}.any", inst.instance_id, slot.link_id);
                    picture.nodes.push(DrawNode {
                        id: any.clone(),
                        label: format!("(any) {}", slot.target),
                        detail: String::new(),
                        cluster: None,
                        state: NodeState::Placeholder,
                    });
                    picture
                        .edges
                        .push(edge(&any, consumer, &label, EdgeStyle::Dashed));
                }
                for p in &takers {
                    picture
                        .edges
                        .push(edge(p, consumer, &label, EdgeStyle::Dashed));
                }
            }
        }
    }
}

/// One solid edge per pair (drawn from the end written first in the
/// plan, labelled with both slots), and a dotted edge from each source to
/// the observer watching it.
fn pair_edges(stack: &StackCheck, inst: &peppy_schema::InstancePlan, picture: &mut Drawing) {
    let Some(resolved) = stack.node_of(&inst.instance_id) else {
        return;
    };
    for plan in &inst.pairs {
        let Some(slot) = resolved
            .node
            .pairings
            .iter()
            .find(|p| p.link_id == plan.link_id)
        else {
            continue;
        };
        for peer in &plan.peers {
            let peer_slot = peer.link_id.as_deref().unwrap_or("?");
            if slot.observer {
                picture.edges.push(edge(
                    &peer.instance,
                    &inst.instance_id,
                    &format!("{} (observes {peer_slot})", plan.link_id),
                    EdgeStyle::Dotted,
                ));
            } else if (inst.instance_id.as_str(), plan.link_id.as_str())
                < (peer.instance.as_str(), peer_slot)
            {
                picture.edges.push(edge(
                    &inst.instance_id,
                    &peer.instance,
                    &format!("{} <> {peer_slot} ({})", plan.link_id, slot.pairing.name),
                    EdgeStyle::Solid,
                ));
            }
        }
    }
}

fn external_edges(stack: &StackCheck, inst: &peppy_schema::InstancePlan, picture: &mut Drawing) {
    let Some(resolved) = stack.node_of(&inst.instance_id) else {
        return;
    };
    for topic in resolved.consumed_topics.iter().filter(|t| t.slot.is_none()) {
        let mut emitters: Vec<String> = flows::external_emitters(stack, inst, &topic.name)
            .into_iter()
            .map(|(p, _)| p)
            .collect();
        emitters.dedup();
        for p in emitters {
            picture.edges.push(edge(
                &p,
                &inst.instance_id,
                &format!("{} (external)", topic.name),
                EdgeStyle::Dotted,
            ));
        }
    }
}

fn edge(from: &str, to: &str, label: &str, style: EdgeStyle) -> DrawEdge {
    DrawEdge {
        from: from.to_string(),
        to: to.to_string(),
        label: label.to_string(),
        style,
    }
}
