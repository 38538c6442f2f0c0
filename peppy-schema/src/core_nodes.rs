//! Placement: the machines (core nodes) a launcher spreads its instances
//! over. `core_nodes` names them, as a list (`["robot", "workstation"]`) or
//! as an object giving each its Zenoh endpoints
//! (`{ robot: { listen: ["tcp/0.0.0.0:7447"] }, workstation: { connect:
//! ["tcp/robot.local:7447"] } }`); an instance says where it runs with
//! `core_node: "robot"`.

use serde::Serialize;

use crate::diag::{Code, Diagnostics, did_you_mean, list};
use crate::json::{Node, Value};
use crate::read::{Loc, Reader, index, join};
use crate::source::Span;

/// One machine of a stack.
#[derive(Debug, Clone, Serialize)]
pub struct CoreNode {
    /// Its name: the `<core>` segment of its instances' keys and what
    /// `from_core_node` filters on.
    pub name: String,
    /// Where its router listens.
    pub listen: Vec<String>,
    /// Routers (or other core nodes) its router connects to.
    pub connect: Vec<String>,
    /// Where the name is written.
    #[serde(skip)]
    pub loc: Loc,
}

/// Reads `core_nodes`, reporting every mistake; the core nodes that are
/// valid are returned either way.
pub(crate) fn parse_core_nodes(
    r: &mut Reader<'_>,
    node: &Node,
    spelling: crate::Spelling,
) -> Vec<CoreNode> {
    // `launcher_v1` named core nodes before `--place link@self` took
    // `self` and names were bounded by a machine's: it keeps its names.
    let rule = match spelling {
        crate::Spelling::SlashIds => crate::names::check_core_node_name,
        crate::Spelling::UnderscoreIds => crate::names::check_name,
    };
    let path = "core_nodes";
    let mut out: Vec<CoreNode> = Vec::new();
    match &node.value {
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let p = index(path, i);
                if let Some(name) = r.string(item, &p)
                    && let Some(core) = named(r, rule, name, item.span, &p)
                {
                    push_unique(r, &mut out, core);
                }
            }
        }
        Value::Object(members) => {
            for m in members {
                let p = join(path, &m.key);
                let Some(core) = named(r, rule, m.key.clone(), m.key_span, &p) else {
                    continue;
                };
                if let Some(core) = endpoints(r, &m.value, &p, core) {
                    push_unique(r, &mut out, core);
                }
            }
        }
        other => r.error(
            Code::WrongType,
            node.span,
            path,
            format!(
                "expected a list of core node names or an object of core nodes for `core_nodes`, found {}",
                other.kind()
            ),
        ),
    }
    let empty = match &node.value {
        Value::Array(items) => items.is_empty(),
        Value::Object(members) => members.is_empty(),
        _ => false,
    };
    if empty {
        r.error(
            Code::InvalidValue,
            node.span,
            path,
            "`core_nodes` is empty: name the machines, or leave the key out to run everything on one",
        );
    }
    out
}

/// A core node named `name`, written at `span`.
fn named(
    r: &mut Reader<'_>,
    rule: fn(&str) -> Result<(), String>,
    name: String,
    span: Span,
    path: &str,
) -> Option<CoreNode> {
    match rule(&name) {
        Ok(()) => Some(CoreNode {
            loc: r.loc(span, path),
            name,
            listen: Vec::new(),
            connect: Vec::new(),
        }),
        Err(why) => {
            r.error(
                Code::InvalidName,
                span,
                path,
                format!("invalid core node name `{name}`: {why}"),
            );
            None
        }
    }
}

fn push_unique(r: &mut Reader<'_>, out: &mut Vec<CoreNode>, core: CoreNode) {
    if out.iter().any(|c| c.name == core.name) {
        let d = core
            .loc
            .error(
                Code::DuplicateCoreNode,
                format!("core node `{}` is declared twice", core.name),
            )
            .with_help("each machine is named once in `core_nodes`");
        r.diags.push(d);
    } else {
        out.push(core);
    }
}

/// `{ listen: [...], connect: [...] }` of one core node.
fn endpoints(r: &mut Reader<'_>, node: &Node, path: &str, mut core: CoreNode) -> Option<CoreNode> {
    let obj = r.object(node, path, &["listen", "connect"])?;
    let mut ok = true;
    for (key, into) in [("listen", &mut core.listen), ("connect", &mut core.connect)] {
        let Some(list_node) = obj.get(key) else {
            continue;
        };
        let p = obj.path_of(key);
        let Some(items) = r.array(list_node, &p) else {
            ok = false;
            continue;
        };
        for (i, item) in items.iter().enumerate() {
            let ip = index(&p, i);
            match r.string(item, &ip) {
                Some(e) if is_endpoint(&e) => into.push(e),
                Some(e) => {
                    r.error_help(
                        Code::InvalidValue,
                        item.span,
                        &ip,
                        format!("`{e}` is not a Zenoh endpoint"),
                        "write `<protocol>/<address>:<port>`, e.g. `tcp/192.0.2.10:7447`",
                    );
                    ok = false;
                }
                None => ok = false,
            }
        }
    }
    ok.then_some(core)
}

/// `<protocol>/<address>` with no whitespace, e.g. `tcp/0.0.0.0:7447`.
fn is_endpoint(e: &str) -> bool {
    matches!(e.split_once('/'), Some((proto, addr))
        if !proto.is_empty()
            && proto.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
            && !addr.is_empty())
        && !e.chars().any(char::is_whitespace)
}

/// An instance's `core_node` must be one of the declared core nodes.
pub(crate) fn check_placement(
    core_nodes: &[CoreNode],
    instance: &str,
    placed: &(String, Loc),
    diags: &mut Diagnostics,
) {
    let (name, loc) = placed;
    if core_nodes.iter().any(|c| &c.name == name) {
        return;
    }
    let names: Vec<&str> = core_nodes.iter().map(|c| c.name.as_str()).collect();
    let help = if names.is_empty() {
        "declare the machines first: `core_nodes: [\"robot\", \"workstation\"]` at the top level"
            .to_string()
    } else {
        match did_you_mean(name, names.iter().copied()) {
            Some(s) => format!(
                "did you mean `{s}`? core nodes: {}",
                list(names.iter().copied())
            ),
            None => format!("core nodes: {}", list(names.iter().copied())),
        }
    };
    diags.push(
        loc.error(
            Code::UnknownCoreNode,
            format!("instance `{instance}` is placed on core node `{name}`, which `core_nodes` does not declare"),
        )
        .with_help(help),
    );
}

/// Where each of a launcher's core nodes runs, as `--place LINK@MACHINE`
/// says: the launcher's core node names (placeholders in `launcher/v1`)
/// each bound to a machine, several possibly to one.
///
/// Placing renames: the machines become the core nodes, so an instance's
/// `<core>` key segment, what `from_core_node` filters on, the security
/// policy and the per-core-node keys all name the machine it runs on, and
/// the placeholders sharing a machine share its one router.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Placement {
    /// `(placeholder, machine)`, in the order given.
    pub places: Vec<(String, String)>,
}

impl Placement {
    /// The machine `placeholder` is placed on.
    pub fn machine_of(&self, placeholder: &str) -> Option<&str> {
        self.places
            .iter()
            .find(|(p, _)| p == placeholder)
            .map(|(_, m)| m.as_str())
    }
}

impl crate::launcher::LauncherDoc {
    /// This launcher with its core nodes replaced by the machines
    /// `placement` puts them on. Each machine comes once, in the order its
    /// first placeholder is declared (so an instance without `core_node`
    /// still runs where the first placeholder is), with the `listen` and
    /// `connect` endpoints of all its placeholders, located at the first.
    /// A placeholder `placement` does not name keeps its own name.
    pub fn placed(&self, placement: &Placement) -> crate::launcher::LauncherDoc {
        let machine = |name: &str| placement.machine_of(name).unwrap_or(name).to_string();
        let mut core_nodes: Vec<CoreNode> = Vec::new();
        for c in &self.core_nodes {
            let name = machine(&c.name);
            match core_nodes.iter_mut().find(|m| m.name == name) {
                Some(m) => {
                    for e in &c.listen {
                        if !m.listen.contains(e) {
                            m.listen.push(e.clone());
                        }
                    }
                    for e in &c.connect {
                        if !m.connect.contains(e) {
                            m.connect.push(e.clone());
                        }
                    }
                }
                None => core_nodes.push(CoreNode { name, ..c.clone() }),
            }
        }
        let mut placed = self.clone();
        placed.core_nodes = core_nodes;
        for d in &mut placed.deployments {
            for inst in &mut d.instances {
                if let Some((name, _)) = &mut inst.core_node {
                    *name = machine(name);
                }
            }
        }
        placed
    }
}

impl crate::stack::StackCheck {
    /// This checked stack with its core nodes placed on machines
    /// ([`LauncherDoc::placed`](crate::launcher::LauncherDoc::placed)):
    /// the launcher and every planned instance's core node. The bindings
    /// need nothing else: they name instances, wherever those run.
    pub fn placed(mut self, placement: &Placement) -> crate::stack::StackCheck {
        self.launcher = self.launcher.placed(placement);
        for inst in &mut self.plan.instances {
            if let Some(name) = &mut inst.core_node
                && let Some(m) = placement.machine_of(name)
            {
                *name = m.to_string();
            }
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placing_renames_core_nodes_and_merges_those_sharing_a_machine() {
        let text = r#"{ peppy_schema: "launcher_v1",
            core_nodes: { arm: { listen: ["tcp/0.0.0.0:7447"] }, cam: { connect: ["tcp/192.0.2.1:7447"] }, gpu: {} },
            deployments: [{ source: { name: "cam:v1" }, instances: [
                { instance_id: "a", core_node: "cam" }, { instance_id: "b" },
                { instance_id: "c", core_node: "gpu" } ] }] }"#;
        let doc = crate::launcher::LauncherDoc::parse("stack.json5", text)
            .unwrap()
            .0;
        let placement = Placement {
            places: vec![
                ("cam".into(), "robot7".into()),
                ("arm".into(), "robot7".into()),
                ("gpu".into(), "atlas".into()),
            ],
        };
        let placed = doc.placed(&placement);
        let names: Vec<&str> = placed.core_nodes.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["robot7", "atlas"]);
        assert_eq!(placed.core_nodes[0].listen, ["tcp/0.0.0.0:7447"]);
        assert_eq!(placed.core_nodes[0].connect, ["tcp/192.0.2.1:7447"]);
        let cores: Vec<Option<&str>> = placed
            .instances()
            .map(|(_, i)| placed.core_node_of(i.core_node.as_ref().map(|(n, _)| n.as_str())))
            .collect();
        assert_eq!(cores, [Some("robot7"), Some("robot7"), Some("atlas")]);
        assert!(crate::launcher::stack_rules(&placed).is_empty());
    }

    #[test]
    fn endpoints_look_like_zenoh_endpoints() {
        for good in [
            "tcp/0.0.0.0:7447",
            "tcp/[::1]:7447",
            "udp/192.0.2.1:7447",
            "tls/robot.local:7447",
        ] {
            assert!(is_endpoint(good), "{good}");
        }
        for bad in ["", "tcp", "tcp/", "/x", "tcp/a b", "t*p/x"] {
            assert!(!is_endpoint(bad), "{bad}");
        }
    }
}
