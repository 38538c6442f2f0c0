//! Where every generated entry of a node lives: the module tree of each
//! category (`emitted_topics`, `consumed_topics`, ...), decided once from
//! the resolved node and its [`NodeApi`], and read by both code
//! generators (Rust and Python), so neither lays out modules of its own nor
//! asks which spelling the document had.
//!
//! Two layouts exist, as the two generated APIs name their modules:
//! - [`NodeApi::Emit`]: own entries by name; a conformed interface's under
//!   `<interface>::<tag>::<name>`, and also by name when no other entry of
//!   the category takes it; consumed entries flat, `<link_id>_<name>`.
//! - [`NodeApi::Peppylib`] (PeppyOS's module paths): own entries by name; a
//!   contract's members under the `implements` slot's link_id; consumed
//!   entries under their slot's link_id, whose module holds the slot's
//!   bound-producer accessor.
//!
//! Two names one scope would hold are a located error, named as PeppyOS
//! names it for a `peppylib` node (`ModuleNameCollision`).

use std::collections::HashMap;

use crate::diag::{Code, Diagnostic, Diagnostics};
use crate::entries::{Declared, EntryKind};
use crate::loc::Loc;
use crate::model::{Cardinality, Identity, NodeApi};
use crate::names::{consumed_module, module};
use crate::resolve::{Origin, Provided, ResolvedCall, ResolvedNode};

/// The six entry categories, in the order they are generated.
pub const CATEGORY_NAMES: [&str; 6] = [
    "emitted_topics",
    "consumed_topics",
    "exposed_services",
    "consumed_services",
    "exposed_actions",
    "consumed_actions",
];

/// One category's modules.
#[derive(Debug, Clone)]
pub struct CategoryLayout {
    /// Topics, services or actions.
    pub kind: EntryKind,
    /// Whether the node provides these (emits, exposes) or consumes them.
    pub provided: bool,
    /// The category's top-level modules, in the order they are written.
    pub modules: Vec<ModuleNode>,
    /// Conformed entries also reachable under their own name (the `emit`
    /// API), in order.
    pub aliases: Vec<Alias>,
}

/// A generated module: an entry's, or one that groups entries.
#[derive(Debug, Clone)]
pub struct ModuleNode {
    /// The module name (already a valid module name).
    pub name: String,
    /// What it holds.
    pub role: ModuleRole,
    /// Its child modules, in order.
    pub children: Vec<ModuleNode>,
}

/// What a generated module holds.
#[derive(Debug, Clone)]
pub enum ModuleRole {
    /// One entry: its index in the node's list of the category.
    Entry(usize),
    /// A conformed interface's entries, by tag (`emit` API).
    Interface(String),
    /// One tag of a conformed interface (`emit` API).
    InterfaceTag(Identity),
    /// A contract's members, under its `implements` slot (`peppylib` API).
    Implements {
        /// The slot's link_id.
        link_id: String,
        /// The contract.
        contract: Identity,
        /// Where the `implements` entry is.
        loc: Loc,
    },
    /// The entries consumed through one slot (`peppylib` API): the module
    /// (and each entry's) holds the slot's bound-producer accessor.
    Slot {
        /// The slot's link_id.
        link_id: String,
        /// Its cardinality, when the node declares the slot.
        cardinality: Option<Cardinality>,
        /// Where the slot is declared (else its first entry).
        loc: Loc,
    },
}

/// A conformed entry re-exported under its own name.
#[derive(Debug, Clone)]
pub struct Alias {
    /// The module name it gets.
    pub module: String,
    /// The entry's name.
    pub name: String,
    /// The interface it comes from.
    pub interface: Identity,
    /// The full path of its module below the category.
    pub path: Vec<String>,
}

impl CategoryLayout {
    /// Every placed entry, in the order written: its index in the node's
    /// list, its module path below the category, and the module that
    /// groups it.
    pub fn entries(&self) -> Vec<PlacedEntry<'_>> {
        fn walk<'a>(
            nodes: &'a [ModuleNode],
            path: &mut Vec<String>,
            parent: Option<&'a ModuleRole>,
            out: &mut Vec<PlacedEntry<'a>>,
        ) {
            for n in nodes {
                path.push(n.name.clone());
                match &n.role {
                    ModuleRole::Entry(index) => out.push(PlacedEntry {
                        index: *index,
                        path: path.clone(),
                        parent,
                    }),
                    role => walk(&n.children, path, Some(role), out),
                }
                path.pop();
            }
        }
        let mut out = Vec::new();
        walk(&self.modules, &mut Vec::new(), None, &mut out);
        out
    }

    /// Entry `index`, if it was placed.
    pub fn entry(&self, index: usize) -> Option<PlacedEntry<'_>> {
        self.entries().into_iter().find(|e| e.index == index)
    }

    /// The harness's tap name of each placed entry (`h.emitted.<name>`),
    /// by index: the entry's module path joined with `_`, except that an
    /// `emit`-API interface entry (`<interface>::<tag>::<topic>`) is named
    /// by its topic alone when no other entry's module ends so.
    pub fn tap_names(&self) -> Vec<(usize, String)> {
        let entries = self.entries();
        entries
            .iter()
            .map(|e| {
                let last = &e.path[e.path.len() - 1];
                let by_interface = matches!(e.parent, Some(ModuleRole::InterfaceTag(_)));
                let unique = entries
                    .iter()
                    .filter(|o| o.path.last() == Some(last))
                    .count()
                    == 1;
                let name = if by_interface && unique {
                    last.clone()
                } else {
                    e.path.join("_")
                };
                (e.index, name)
            })
            .collect()
    }

    /// Every slot module (`peppylib` API): its name, link_id and the
    /// slot's cardinality.
    pub fn slots(&self) -> impl Iterator<Item = (&str, &str, Option<Cardinality>)> {
        self.modules.iter().filter_map(|m| match &m.role {
            ModuleRole::Slot {
                link_id,
                cardinality,
                ..
            } => Some((m.name.as_str(), link_id.as_str(), *cardinality)),
            _ => None,
        })
    }
}

/// An entry where the layout put it.
#[derive(Debug, Clone)]
pub struct PlacedEntry<'a> {
    /// Its index in the node's list of the category.
    pub index: usize,
    /// Its module path below the category.
    pub path: Vec<String>,
    /// The module that groups it (an interface tag, an `implements` slot,
    /// a consumed slot), if any.
    pub parent: Option<&'a ModuleRole>,
}

/// The module tree of every category of a node.
#[derive(Debug, Clone)]
pub struct Layout {
    /// In [`CATEGORY_NAMES`] order.
    pub categories: Vec<CategoryLayout>,
}

impl Layout {
    /// The category named `name` (one of [`CATEGORY_NAMES`]).
    pub fn category(&self, name: &str) -> &CategoryLayout {
        let i = CATEGORY_NAMES
            .iter()
            .position(|c| *c == name)
            .unwrap_or_else(|| panic!("no category `{name}`"));
        &self.categories[i]
    }
}

/// Lays out `node`'s entries; clashes go to `diags` and leave the later
/// entry out.
pub fn layout(node: &ResolvedNode, diags: &mut Diagnostics) -> Layout {
    fn offered<T: Declared>(list: &[Provided<T>]) -> Vec<(&str, &Loc, &Origin)> {
        list.iter()
            .map(|p| (p.decl.name(), p.decl.decl_loc(), &p.origin))
            .collect()
    }
    fn called<T: Declared>(list: &[ResolvedCall<T>]) -> Vec<Consumed<'_>> {
        list.iter()
            .map(|c| Consumed {
                link_id: Some(&c.slot.link_id),
                name: c.decl.name(),
                loc: &c.loc,
            })
            .collect()
    }
    let mut provided = |kind: EntryKind, entries: Vec<(&str, &Loc, &Origin)>| match node.node.api {
        NodeApi::Emit => provided_by_interface(node, kind, &entries, diags),
        NodeApi::Peppylib => provided_by_link(node, kind, &entries, diags),
    };
    let emitted = provided(EntryKind::Topic, offered(&node.emitted_topics));
    let exposed_services = provided(EntryKind::Service, offered(&node.exposed_services));
    let exposed_actions = provided(EntryKind::Action, offered(&node.exposed_actions));
    let topics = node
        .consumed_topics
        .iter()
        .map(|t| Consumed {
            link_id: t.slot.as_ref().map(|s| s.link_id.as_str()),
            name: &t.name,
            loc: &t.loc,
        })
        .collect();
    Layout {
        categories: vec![
            emitted,
            consumed(node, EntryKind::Topic, topics, diags),
            exposed_services,
            consumed(
                node,
                EntryKind::Service,
                called(&node.consumed_services),
                diags,
            ),
            exposed_actions,
            consumed(
                node,
                EntryKind::Action,
                called(&node.consumed_actions),
                diags,
            ),
        ],
    }
}

fn entry(name: String, index: usize) -> ModuleNode {
    ModuleNode {
        name,
        role: ModuleRole::Entry(index),
        children: Vec::new(),
    }
}

/// The node's own entries of a provided category, by name.
fn own_entries(
    kind: EntryKind,
    entries: &[(&str, &Loc, &Origin)],
    name_kind: NameKind,
    names: &mut Names,
    diags: &mut Diagnostics,
) -> Vec<ModuleNode> {
    let mut out = Vec::new();
    for (index, (name, loc, origin)) in entries.iter().enumerate() {
        if !matches!(origin, Origin::Node(_)) {
            continue;
        }
        let m = module(name);
        if names.claim(name_kind, &m, &format!("{kind} `{name}`"), loc, diags) {
            out.push(entry(m, index));
        }
    }
    out
}

/// The `emit` API's provided entries: own by name, conformed under
/// `<interface>::<tag>::<name>`, and by name when unambiguous.
fn provided_by_interface(
    node: &ResolvedNode,
    kind: EntryKind,
    entries: &[(&str, &Loc, &Origin)],
    diags: &mut Diagnostics,
) -> CategoryLayout {
    let mut names = Names::default();
    let mut modules = own_entries(kind, entries, NameKind::Module, &mut names, diags);
    let own_modules: Vec<String> = modules.iter().map(|m| m.name.clone()).collect();
    fn conformed<'e, 'a>(
        entries: &'e [(&'a str, &'a Loc, &'a Origin)],
        target: &'e Identity,
    ) -> impl Iterator<Item = (usize, &'e (&'a str, &'a Loc, &'a Origin))> {
        entries
            .iter()
            .enumerate()
            .filter(move |(_, (_, _, o))| matches!(o, Origin::Interface(id) if id == target))
    }
    // Interfaces with entries here, grouped by module name, in order.
    let mut groups: Vec<(String, Vec<&crate::InterfaceRef>)> = Vec::new();
    for c in &node.node.conforms_to {
        if conformed(entries, &c.target).next().is_none() {
            continue;
        }
        let m = module(&c.target.name);
        match groups.iter_mut().find(|(g, _)| *g == m) {
            Some((_, list)) => list.push(c),
            None => groups.push((m, vec![c])),
        }
    }
    let iface_modules: Vec<String> = groups.iter().map(|(m, _)| m.clone()).collect();
    let conformed_modules: Vec<String> = entries
        .iter()
        .filter(|(_, _, o)| matches!(o, Origin::Interface(_)))
        .map(|(name, _, _)| module(name))
        .collect();
    let mut aliases = Vec::new();
    for (iface_mod, refs) in &groups {
        let first = refs[0];
        let what = format!("interface `{}`", first.target.name);
        if !names.claim(NameKind::Module, iface_mod, &what, &first.loc, diags) {
            continue;
        }
        let mut tags = Names::default();
        let mut tag_modules = Vec::new();
        for r in refs {
            let tag_mod = module(&r.target.tag);
            let what = format!("interface `{}`", r.target);
            if !tags.claim(NameKind::Module, &tag_mod, &what, &r.loc, diags) {
                continue;
            }
            let mut scope = Names::default();
            let mut children = Vec::new();
            for (index, (name, loc, _)) in conformed(entries, &r.target) {
                let m = module(name);
                let what = format!("{kind} `{name}` of interface `{}`", r.target);
                if !scope.claim(NameKind::Module, &m, &what, loc, diags) {
                    continue;
                }
                let unambiguous = !own_modules.contains(&m)
                    && conformed_modules.iter().filter(|c| **c == m).count() == 1
                    && !iface_modules.contains(&m);
                if unambiguous {
                    aliases.push(Alias {
                        module: m.clone(),
                        name: name.to_string(),
                        interface: r.target.clone(),
                        path: vec![iface_mod.clone(), tag_mod.clone(), m.clone()],
                    });
                }
                children.push(entry(m, index));
            }
            tag_modules.push(ModuleNode {
                name: tag_mod,
                role: ModuleRole::InterfaceTag(r.target.clone()),
                children,
            });
        }
        modules.push(ModuleNode {
            name: iface_mod.clone(),
            role: ModuleRole::Interface(first.target.name.clone()),
            children: tag_modules,
        });
    }
    CategoryLayout {
        kind,
        provided: true,
        modules,
        aliases,
    }
}

/// The `peppylib` API's provided entries: own by name, a contract's
/// members under the `implements` slot's link_id, no aliases.
fn provided_by_link(
    node: &ResolvedNode,
    kind: EntryKind,
    entries: &[(&str, &Loc, &Origin)],
    diags: &mut Diagnostics,
) -> CategoryLayout {
    let mut names = Names::default();
    let mut modules = own_entries(kind, entries, NameKind::PeppylibModule, &mut names, diags);
    for slot in &node.node.conforms_to {
        // `node/v1`'s `implements` entries always carry their link_id.
        let Some(link_id) = &slot.link_id else {
            continue;
        };
        let members: Vec<(usize, &(&str, &Loc, &Origin))> = entries
            .iter()
            .enumerate()
            .filter(|(_, (_, _, o))| matches!(o, Origin::Interface(id) if *id == slot.target))
            .collect();
        if members.is_empty() {
            continue;
        }
        let link_mod = module(link_id);
        let what = format!("implements slot `{link_id}` (contract `{}`)", slot.target);
        if !names.claim(NameKind::PeppylibModule, &link_mod, &what, &slot.loc, diags) {
            continue;
        }
        let mut scope = Names::default();
        let mut children = Vec::new();
        for (index, (name, loc, _)) in members {
            let m = module(name);
            let what = format!("{kind} `{name}` of implements slot `{link_id}`");
            if scope.claim(NameKind::PeppylibModule, &m, &what, loc, diags) {
                children.push(entry(m, index));
            }
        }
        modules.push(ModuleNode {
            name: link_mod,
            role: ModuleRole::Implements {
                link_id: link_id.clone(),
                contract: slot.target.clone(),
                loc: slot.loc.clone(),
            },
            children,
        });
    }
    CategoryLayout {
        kind,
        provided: true,
        modules,
        aliases: Vec::new(),
    }
}

/// A consumed entry, as the layout needs it.
struct Consumed<'a> {
    link_id: Option<&'a str>,
    name: &'a str,
    loc: &'a Loc,
}

impl Consumed<'_> {
    /// What it is, for a clash.
    fn what(&self, kind: EntryKind) -> String {
        match self.link_id {
            Some(link) => format!("consumed {kind} `{}` of slot `{link}`", self.name),
            None => format!("external consumed {kind} `{}`", self.name),
        }
    }
}

/// A consumed category: flat `<link_id>_<name>` modules (`emit` API), or
/// under each slot's link_id (`peppylib` API), slots in the order of their
/// first entry.
fn consumed(
    node: &ResolvedNode,
    kind: EntryKind,
    entries: Vec<Consumed<'_>>,
    diags: &mut Diagnostics,
) -> CategoryLayout {
    let mut names = Names::default();
    let mut modules: Vec<ModuleNode> = Vec::new();
    let api = node.node.api;
    let name_kind = NameKind::module_of(api);
    // Each slot's module and its entries' scope, in first-entry order.
    let mut slots: Vec<(String, Option<Names>)> = Vec::new();
    for (index, e) in entries.iter().enumerate() {
        let (link_id, NodeApi::Peppylib) = (e.link_id, api) else {
            // Flat: `<link_id>_<name>`, or an external topic's `<name>`.
            let m = consumed_module(e.link_id, e.name);
            if names.claim(name_kind, &m, &e.what(kind), e.loc, diags) {
                modules.push(entry(m, index));
            }
            continue;
        };
        let Some(link_id) = link_id else {
            // Not written in `node/v1` (every consumed entry names a slot);
            // laid out flat, like `node_v1`'s external topics.
            let m = module(e.name);
            if names.claim(name_kind, &m, &e.what(kind), e.loc, diags) {
                modules.push(entry(m, index));
            }
            continue;
        };
        let slot = match slots.iter().position(|(l, _)| l == link_id) {
            Some(i) => i,
            None => {
                let dependency = node.node.dependency(link_id);
                let loc = dependency.map_or_else(|| e.loc.clone(), |d| d.loc.clone());
                let link_mod = module(link_id);
                let claimed = names.claim(
                    name_kind,
                    &link_mod,
                    &format!("slot `{link_id}`"),
                    &loc,
                    diags,
                );
                if claimed {
                    modules.push(ModuleNode {
                        name: link_mod,
                        role: ModuleRole::Slot {
                            link_id: link_id.to_string(),
                            cardinality: dependency.map(|d| d.cardinality),
                            loc,
                        },
                        children: Vec::new(),
                    });
                }
                slots.push((link_id.to_string(), claimed.then(Names::default)));
                slots.len() - 1
            }
        };
        let Some(scope) = slots[slot].1.as_mut() else {
            continue;
        };
        let m = module(e.name);
        if scope.claim(name_kind, &m, &e.what(kind), e.loc, diags) {
            let parent = modules
                .iter_mut()
                .rev()
                .find(|n| matches!(&n.role, ModuleRole::Slot { link_id: l, .. } if l == link_id))
                .expect("the slot's module was pushed with its scope");
            parent.children.push(entry(m, index));
        }
    }
    CategoryLayout {
        kind,
        provided: false,
        modules,
        aliases: Vec::new(),
    }
}

/// Where a name was claimed: what claimed it and where it is declared.
#[derive(Clone)]
struct Claim {
    what: String,
    loc: Option<Loc>,
}

/// Names claimed within one scope (a module's types, or its child
/// modules); a second claim of a name is a located error.
#[derive(Default)]
pub struct Names {
    claims: HashMap<String, Claim>,
}

impl Names {
    /// A scope whose `fixed` names belong to the generator.
    pub fn with_fixed(fixed: &[&str]) -> Self {
        let mut names = Names::default();
        for f in fixed {
            names.claims.insert(
                (*f).to_string(),
                Claim {
                    what: format!("the generated `{f}`"),
                    loc: None,
                },
            );
        }
        names
    }

    /// Claims `name` for `what` declared at `loc`. On a clash, pushes a
    /// located error (`kind` says what kind of name) and returns `false`.
    pub fn claim(
        &mut self,
        kind: NameKind,
        name: &str,
        what: &str,
        loc: &Loc,
        diags: &mut Diagnostics,
    ) -> bool {
        if let Some(first) = self.claims.get(name) {
            diags.push(clash(kind, name, what, loc, first));
            return false;
        }
        self.claims.insert(
            name.to_string(),
            Claim {
                what: what.to_string(),
                loc: Some(loc.clone()),
            },
        );
        true
    }
}

/// What kind of generated name clashed.
#[derive(Debug, Clone, Copy)]
pub enum NameKind {
    /// A generated struct.
    Type,
    /// A generated module.
    Module,
    /// A generated module of a node on PeppyOS's `peppylib` API, where
    /// PeppyOS names the clash `ModuleNameCollision`.
    PeppylibModule,
}

impl NameKind {
    /// The module kind for a node on `api`.
    pub fn module_of(api: NodeApi) -> NameKind {
        match api {
            NodeApi::Peppylib => NameKind::PeppylibModule,
            NodeApi::Emit => NameKind::Module,
        }
    }
}

fn clash(kind: NameKind, name: &str, what: &str, loc: &Loc, first: &Claim) -> Diagnostic {
    let where_first = first
        .loc
        .as_ref()
        .map(|l| format!(" (declared at {})", short_location(l)))
        .unwrap_or_default();
    match kind {
        NameKind::Type => loc
            .error(
                Code::InvalidFieldName,
                format!(
                    "generated type name `{name}` of {what} collides with {}{where_first}",
                    first.what
                ),
            )
            .with_help(
                "nested structs are named after their parent and field (`header` -> `MessageHeader`, parameter group `video.encoder` -> `VideoEncoder`, array items `...Item`); rename one of the two",
            ),
        NameKind::Module | NameKind::PeppylibModule => loc
            .error(
                match kind {
                    NameKind::PeppylibModule => Code::ModuleNameCollision,
                    _ => Code::ConflictingDefinition,
                },
                format!(
                    "module name clash: {what} would be generated as module `{name}`, which {} already uses{where_first}",
                    first.what
                ),
            )
            .with_help(
                "module names are the names lowercased with every other character as `_`; rename one of the two",
            ),
    }
}

/// `file.json5:line:col` with the file name only (stable across machines).
pub fn short_location(loc: &Loc) -> String {
    let path = loc.file.path();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    let lc = loc.file.line_col(loc.span.start);
    format!("{name}:{}:{}", lc.line, lc.column)
}
