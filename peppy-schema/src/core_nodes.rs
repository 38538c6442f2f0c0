//! Placement: the machines (core nodes) a launcher spreads its instances
//! over. `core_nodes` names them, as a list (`["robot", "workstation"]`) or
//! as an object giving each its Zenoh endpoints
//! (`{ robot: { listen: ["tcp/0.0.0.0:7447"] }, workstation: { connect:
//! ["tcp/robot.local:7447"] } }`); an instance says where it runs with
//! `core_node: "robot"`.

use serde::Serialize;

use crate::diag::{Code, Diagnostics, did_you_mean, list};
use crate::json::{Node, Value};
use crate::names::check_name;
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
pub(crate) fn parse_core_nodes(r: &mut Reader<'_>, node: &Node) -> Vec<CoreNode> {
    let path = "core_nodes";
    let mut out: Vec<CoreNode> = Vec::new();
    match &node.value {
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let p = index(path, i);
                if let Some(name) = r.string(item, &p)
                    && let Some(core) = named(r, name, item.span, &p)
                {
                    push_unique(r, &mut out, core);
                }
            }
        }
        Value::Object(members) => {
            for m in members {
                let p = join(path, &m.key);
                let Some(core) = named(r, m.key.clone(), m.key_span, &p) else {
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
fn named(r: &mut Reader<'_>, name: String, span: Span, path: &str) -> Option<CoreNode> {
    match check_name(&name) {
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

#[cfg(test)]
mod tests {
    use super::*;

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
