//! The Python side of code generation: a `peppygen` package for a node
//! whose `execution.language` is `python`, with the module tree, names and
//! call shapes of the Rust API, on the `peppy` runtime package
//! (`python/peppy-runtime` in this repository).
//!
//! The Rust generator runs first on the same node, so every naming rule
//! (two entries mapping to one module, two nested types with one name) is
//! checked once, in one place, with the same located errors.

mod messages;
mod modules;
mod pairings;
mod params;
mod peppylib_api;
mod source;
mod testing;

use std::path::PathBuf;

use peppy_schema::layout::{CATEGORY_NAMES, Layout, ModuleRole};
use peppy_schema::names::module;
use peppy_schema::{Cardinality, Diagnostics, NodeApi, Origin, ResolvedNode};

/// The module path (below `category`) the layout gave entry `index`.
fn parts(layout: &Layout, category: &str, index: usize) -> Vec<String> {
    layout
        .category(category)
        .entry(index)
        .expect("a layout without errors places every entry")
        .path
}

use source::{Source, py_string};

/// One generated file: its path below the package directory, and text.
pub type PythonFile = (PathBuf, String);

/// The files of package `peppygen` for `node`, paths relative to the
/// package directory, in a stable order. Errors are the located naming
/// errors the Rust generator reports for the same document.
pub fn python_package(node: &ResolvedNode) -> Result<Vec<PythonFile>, Diagnostics> {
    crate::generate(node)?;
    let document = node.node.file.path().file_name().map_or_else(
        || "peppy.json5".to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let identity = node.node.identity().to_string();
    let peppylib = node.node.api == NodeApi::Peppylib;
    let mut clashes = Diagnostics::new();
    let layout = peppy_schema::layout::layout(node, &mut clashes);
    // Reported by the Rust generator above already; an entry the layout
    // left out is never looked up below.
    if clashes.has_errors() {
        return Err(clashes);
    }
    let mut files = Files {
        peppylib,
        document: document.clone(),
        list: Vec::new(),
        slot_packages: Vec::new(),
    };
    let by_instance_default = node.node.legacy;

    let mut specs = Specs::default();
    let mut surface = testing::Surface::default();
    let taps = layout.category("emitted_topics").tap_names();
    for (i, p) in node.emitted_topics.iter().enumerate() {
        let path = files.provided(&layout, "emitted_topics", i, &p.decl.name, |out| {
            modules::emitted_topic(out, p, peppylib)
        });
        if let Some((_, tap)) = taps.iter().find(|(index, _)| *index == i) {
            surface.emitted.push((tap.clone(), path.clone()));
        }
        specs.emitted.push(path);
    }
    surface.emitted_aliases = interface_tap_aliases(node, &taps, &specs.emitted);
    for (i, t) in node.consumed_topics.iter().enumerate() {
        let parts = parts(&layout, "consumed_topics", i);
        let by_instance = t.slot.is_none() || by_instance_default;
        let path = files.entry(
            "consumed_topics",
            &parts,
            &format!("Topic `{}`, consumed.", t.name),
            |out| modules::consumed_topic(out, node, t, by_instance),
        );
        if let Some(slot) = &t.slot {
            surface.consumed.push((
                slot.link_id.clone(),
                t.name.clone(),
                path.clone(),
                testing::Kind::Topic,
            ));
        }
        specs.consumed.push(path);
    }
    for (i, p) in node.exposed_services.iter().enumerate() {
        let path = files.provided(&layout, "exposed_services", i, &p.decl.name, |out| {
            modules::exposed_service(out, p)
        });
        surface
            .services
            .push((path.clone(), p.decl.request.is_some()));
        specs.services.push(path);
    }
    for (i, c) in node.consumed_services.iter().enumerate() {
        let parts = parts(&layout, "consumed_services", i);
        let path = files.entry(
            "consumed_services",
            &parts,
            &format!(
                "Service `{}`, called through slot `{}`.",
                c.decl.name, c.slot.link_id
            ),
            |out| modules::consumed_service(out, node, c),
        );
        surface.consumed.push((
            c.slot.link_id.clone(),
            c.decl.name.clone(),
            path.clone(),
            testing::Kind::Service,
        ));
        specs.consumed_services.push(path);
    }
    for (i, p) in node.exposed_actions.iter().enumerate() {
        let path = files.provided(&layout, "exposed_actions", i, &p.decl.name, |out| {
            modules::exposed_action(out, p, peppylib)
        });
        surface.actions.push((path.clone(), p.decl.goal.is_some()));
        specs.actions.push(path);
    }
    for (i, c) in node.consumed_actions.iter().enumerate() {
        let parts = parts(&layout, "consumed_actions", i);
        let path = files.entry(
            "consumed_actions",
            &parts,
            &format!(
                "Action `{}`, called through slot `{}`.",
                c.decl.name, c.slot.link_id
            ),
            |out| modules::consumed_action(out, node, c),
        );
        surface.consumed.push((
            c.slot.link_id.clone(),
            c.decl.name.clone(),
            path.clone(),
            testing::Kind::Action,
        ));
        specs.consumed_actions.push(path);
    }
    for rp in &node.pairings {
        let slot = &rp.slot;
        let mut topics = Vec::new();
        for (uses, emitted) in [(&rp.emitted, true), (&rp.consumed, false)] {
            for u in uses {
                let decl = &u.topic.decl;
                let parts = [module(&slot.link_id), module(&decl.name)];
                let mut out = Source::default();
                pairings::paired_topic(&mut out, &document, slot, decl, emitted);
                let mut path = PathBuf::from(pairings::CATEGORY);
                for p in &parts {
                    path.push(p);
                }
                path.set_extension("py");
                files.list.push((path, out.finish()));
                let dotted = format!("{}.{}", pairings::CATEGORY, parts.join("."));
                topics.push((decl.name.clone(), dotted.clone(), emitted));
                specs.pairing_topics.push(dotted);
            }
        }
        surface.pairings.push((slot.clone(), topics));
    }
    files.layout_packages(&layout);
    files.packages();
    // After `packages`: the test surfaces write their own `__init__.py`s.
    files.list.extend(testing::files(node, &surface));

    let mut out = Source::default();
    params::parameters(&mut out, &node.node.execution.parameters.fields, &identity);
    files.list.push(("parameters.py".into(), out.finish()));
    if peppylib {
        files.list.push(("clock.py".into(), clock_module()));
    }
    files
        .list
        .push(("__init__.py".into(), init(node, &document, &specs)));
    files.list.sort();
    Ok(files.list)
}

/// Module paths (dotted, below `peppygen`) of each descriptor list.
#[derive(Default)]
struct Specs {
    emitted: Vec<String>,
    consumed: Vec<String>,
    services: Vec<String>,
    consumed_services: Vec<String>,
    actions: Vec<String>,
    consumed_actions: Vec<String>,
    /// Pairing topics, sent or received, slot by slot.
    pairing_topics: Vec<String>,
}

struct Files {
    /// Whether the node gets the peppylib API (`NodeApi::Peppylib`).
    peppylib: bool,
    document: String,
    list: Vec<PythonFile>,
    /// The `__init__.py` of each slot package (peppylib API), with the
    /// slot's bound-producer accessor.
    slot_packages: Vec<PythonFile>,
}

impl Files {
    /// Writes `<category>/<parts...>.py`; returns its dotted path.
    fn entry(
        &mut self,
        category: &str,
        parts: &[String],
        doc: &str,
        body: impl FnOnce(&mut Source),
    ) -> String {
        let mut out = Source::default();
        modules::header(&mut out, doc, &self.document, self.peppylib);
        body(&mut out);
        let mut path = PathBuf::from(category);
        for p in parts {
            path.push(p);
        }
        path.set_extension("py");
        self.list.push((path, out.finish()));
        format!("{category}.{}", parts.join("."))
    }

    /// A provided entry, where the layout put it, with a docstring saying
    /// where it comes from.
    fn provided(
        &mut self,
        layout: &Layout,
        category: &str,
        index: usize,
        name: &str,
        body: impl FnOnce(&mut Source),
    ) -> String {
        let placed = layout
            .category(category)
            .entry(index)
            .expect("a layout without errors places every entry");
        let doc = match placed.parent {
            Some(ModuleRole::Implements {
                link_id, contract, ..
            }) => format!("`{name}` of contract `{contract}`, implemented as slot `{link_id}`."),
            Some(ModuleRole::InterfaceTag(interface)) => {
                format!("`{name}` of interface `{interface}`.")
            }
            _ => format!("`{name}`."),
        };
        self.entry(category, &placed.path, &doc, body)
    }

    /// What the layout adds around the entries: each slot package (with
    /// its bound-producer accessor) and each conformed entry's module
    /// under its own name.
    fn layout_packages(&mut self, layout: &Layout) {
        for (category, c) in CATEGORY_NAMES.iter().zip(&layout.categories) {
            for (name, link_id, cardinality) in c.slots() {
                let init = PathBuf::from(category).join(name).join("__init__.py");
                let text = slot_package(category, link_id, cardinality);
                self.slot_packages.push((init, text));
            }
            for alias in &c.aliases {
                let path = PathBuf::from(category).join(format!("{}.py", alias.module));
                let relative = alias.path.join(".");
                let text = format!(
                    "\"\"\"`{}` of a conformed interface, under its own name.\"\"\"\n\
                     # Generated by peppy; `peppy-launch sync` rewrites it. Do not edit.\n\
                     from .{relative} import *  # noqa: F401,F403\n\
                     from .{relative} import SPEC  # noqa: F401\n",
                    alias.module
                );
                self.list.push((path, text));
            }
        }
    }

    /// An `__init__.py` in every directory that holds modules.
    fn packages(&mut self) {
        let mut dirs: Vec<PathBuf> = Vec::new();
        for (path, _) in &self.list {
            let mut dir = path.parent();
            while let Some(d) = dir {
                if d.as_os_str().is_empty() {
                    break;
                }
                if !dirs.contains(&d.to_path_buf()) {
                    dirs.push(d.to_path_buf());
                }
                dir = d.parent();
            }
        }
        for category in [
            "emitted_topics",
            "consumed_topics",
            "exposed_services",
            "consumed_services",
            "exposed_actions",
            "consumed_actions",
        ] {
            if !dirs.contains(&PathBuf::from(category)) {
                dirs.push(PathBuf::from(category));
            }
        }
        let slot_packages = std::mem::take(&mut self.slot_packages);
        for d in dirs {
            let init = d.join("__init__.py");
            if slot_packages.iter().any(|(p, _)| *p == init) {
                continue;
            }
            let text = format!("\"\"\"Generated by peppy: `{}`.\"\"\"\n", d.display());
            self.list.push((init, text));
        }
        self.list.extend(slot_packages);
    }
}

/// `peppygen/__init__.py`: the descriptor and the re-exports node code
/// starts from (`from peppygen import NodeBuilder, NodeRunner`).
fn init(node: &ResolvedNode, document: &str, specs: &Specs) -> String {
    let n = &node.node;
    let mut out = Source::default();
    out.docstring(&format!(
        "The typed API of node `{}`, generated from `{document}` by peppy.\n\n\
         `NodeBuilder().run(setup)` runs the node; the modules below hold its entries.",
        n.identity()
    ));
    out.line("# Generated by peppy; `peppy-launch sync` rewrites it. Do not edit.");
    let peppylib = n.api == NodeApi::Peppylib;
    if peppylib {
        out.line("from peppy import NodeRunner, QoSProfile, StandaloneConfig  # noqa: F401");
    } else {
        out.line("from peppy import NodeRunner, QoSProfile  # noqa: F401");
    }
    out.line("from peppy import node as _node");
    out.line("from peppy import spec as _s");
    out.blank();
    let all: Vec<&String> = specs
        .emitted
        .iter()
        .chain(&specs.consumed)
        .chain(&specs.services)
        .chain(&specs.consumed_services)
        .chain(&specs.actions)
        .chain(&specs.consumed_actions)
        .chain(&specs.pairing_topics)
        .collect();
    for m in &all {
        out.line(&format!("from .{} import SPEC as _{}", m, alias(m)));
    }
    out.line("from .parameters import Parameters");
    if peppylib {
        out.line("from . import clock  # noqa: F401");
    }
    out.blank();
    let slots: Vec<String> = n
        .dependencies
        .iter()
        .map(|d| {
            format!(
                "_s.SlotSpec({}, {}, {}, {}, {}, {})",
                py_string(&d.link_id),
                py_string(d.kind.as_str()),
                py_string(&d.target.name),
                py_string(&d.target.tag),
                if d.from_any { "True" } else { "False" },
                py_string(d.cardinality.as_str())
            )
        })
        .collect();
    let list = |ms: &[String]| -> String {
        let items: Vec<String> = ms.iter().map(|m| format!("_{},", alias(m))).collect();
        format!("({})", items.join(" "))
    };
    // `peppy-launch sync` records itself beside the package, so a node
    // started by hand (or its pytest) plans with the engine that wrote it.
    out.line("try:");
    out.line("    from ._engine import PEPPY_LAUNCH as _ENGINE");
    out.line("except ImportError:  # a package not written by `peppy-launch sync`");
    out.line("    _ENGINE = None");
    out.blank();
    out.line("DESCRIPTOR = _s.NodeDescriptor(");
    out.indent();
    out.line(&format!("name={},", py_string(&n.name)));
    out.line(&format!("tag={},", py_string(&n.tag)));
    out.line(&format!(
        "slots=({}),",
        slots.iter().map(|s| format!("{s},")).collect::<String>()
    ));
    out.line(&format!("emitted_topics={},", list(&specs.emitted)));
    out.line(&format!("consumed_topics={},", list(&specs.consumed)));
    out.line(&format!("exposed_services={},", list(&specs.services)));
    out.line(&format!("exposed_actions={},", list(&specs.actions)));
    out.line(&format!(
        "consumed_services={},",
        list(&specs.consumed_services)
    ));
    out.line(&format!(
        "consumed_actions={},",
        list(&specs.consumed_actions)
    ));
    if !node.pairings.is_empty() {
        let pairings: Vec<String> = node
            .pairings
            .iter()
            .map(|rp| {
                let p = &rp.slot;
                format!(
                    "_s.PairingSlotSpec({}, {}, {}, {}, {}, {}, {}, {}),",
                    py_string(&p.link_id),
                    py_string(&p.pairing.name),
                    py_string(&p.pairing.tag),
                    py_string(&p.role),
                    py_string(&p.counterpart),
                    if p.observer { "True" } else { "False" },
                    if p.optional { "True" } else { "False" },
                    py_string(p.cardinality.as_str())
                )
            })
            .collect();
        out.line(&format!("pairings=({}),", pairings.join(" ")));
        out.line(&format!("pairing_topics={},", list(&specs.pairing_topics)));
    }
    out.line("parameters=Parameters,");
    out.line(&format!("document={},", py_string(document)));
    // What a node started by hand hands `peppy-launch plan`, as a Rust
    // binary embeds it.
    out.line(&format!(
        "model={},",
        py_string(&peppy_schema::NodeModel::of(n).to_json())
    ));
    out.line("engine=_ENGINE,");
    out.dedent();
    out.line(")");
    out.line("\"\"\"What the runtime knows about this node.\"\"\"");
    out.blank();
    out.blank();
    out.line("class NodeBuilder(_node.NodeBuilder):");
    out.indent();
    out.docstring("Builds and runs this node: `NodeBuilder().run(setup)`.");
    out.blank();
    out.line("def __init__(self) -> None:");
    out.line("    super().__init__(DESCRIPTOR)");
    out.dedent();
    out.blank();
    out.blank();
    if peppylib {
        out.line(
            "__all__ = [\"DESCRIPTOR\", \"NodeBuilder\", \"NodeRunner\", \"Parameters\", \"QoSProfile\", \"StandaloneConfig\", \"clock\"]",
        );
    } else {
        out.line(
            "__all__ = [\"DESCRIPTOR\", \"NodeBuilder\", \"NodeRunner\", \"Parameters\", \"QoSProfile\"]",
        );
    }
    out.finish()
}

/// The `__init__.py` of a `node/v1` slot's package in a consumed category:
/// the slot's `bound_producer(node_runner)` or `bound_producers(node_runner)`
/// (see [`peppylib_api::accessor`]), as every module of the slot has it too.
fn slot_package(category: &str, link_id: &str, cardinality: Option<Cardinality>) -> String {
    let mut out = Source::default();
    out.docstring(&format!(
        "Generated by peppy: `{category}/{}`, the entries consumed through slot `{link_id}`.",
        module(link_id)
    ));
    out.line("# Generated by peppy; `peppy-launch sync` rewrites it. Do not edit.");
    out.line("from __future__ import annotations");
    out.blank();
    // Only what the accessor's signature names: generated code lints clean.
    match cardinality {
        Some(Cardinality::ZeroOrOne) => out.line("from typing import Optional"),
        Some(Cardinality::OneOrMore | Cardinality::ZeroOrMore) => {
            out.line("from typing import List")
        }
        _ => {}
    }
    if matches!(
        cardinality,
        Some(Cardinality::ZeroOrOne | Cardinality::OneOrMore | Cardinality::ZeroOrMore)
    ) {
        out.blank();
    }
    if cardinality.is_some() {
        out.line("from peppy.node import NodeRunner");
        out.line("from peppy.producer import ProducerRef");
        out.blank();
        out.blank();
    }
    peppylib_api::accessor(&mut out, link_id, cardinality);
    out.finish()
}

/// `peppygen/clock.py` of a `node/v1` node: the stack clock bound to the
/// node (`await clock.init(node_runner)`, then `clock.now_ns()`).
fn clock_module() -> String {
    let mut out = Source::default();
    out.docstring(
        "The stack clock: `await clock.init(node_runner)` once, then `clock.now_ns()`\n\
         (ns since the Unix epoch; the latest sim tick when the node follows sim time).\n\
         Both raise `RuntimeError` (`peppy.ClockNotReady`) before there is a time to give.",
    );
    out.line("# Generated by peppy; `peppy-launch sync` rewrites it. Do not edit.");
    out.line("from peppy.clock import init, now_ns");
    out.blank();
    out.line("__all__ = [\"init\", \"now_ns\"]");
    out.finish()
}

/// The taps an `emit`-API node's interface topics also answer to,
/// `<interface>_<topic>`, as the Python harness named them before it named
/// taps by the layout's rule: each where no tap takes the name and no other
/// topic (another tag of the interface) would share it.
fn interface_tap_aliases(
    node: &ResolvedNode,
    taps: &[(usize, String)],
    paths: &[String],
) -> Vec<(String, String)> {
    if node.node.api != NodeApi::Emit {
        return Vec::new();
    }
    let candidates: Vec<(usize, String)> = taps
        .iter()
        .filter_map(|(index, _)| {
            let p = &node.emitted_topics[*index];
            let Origin::Interface(id) = &p.origin else {
                return None;
            };
            let alias = module(&format!("{}_{}", module(&id.name), module(&p.decl.name)));
            Some((*index, alias))
        })
        .collect();
    candidates
        .iter()
        .filter(|(_, alias)| {
            !taps.iter().any(|(_, t)| t == alias)
                && candidates.iter().filter(|(_, a)| a == alias).count() == 1
        })
        .map(|(index, alias)| (alias.clone(), paths[*index].clone()))
        .collect()
}

/// A private alias for a module's `SPEC` in `__init__.py`.
fn alias(dotted: &str) -> String {
    dotted.replace('.', "__")
}
