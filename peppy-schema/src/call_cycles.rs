//! Caller-driven cycles (PeppyOS's `ServiceActionContractCycle`): a stack
//! whose nodes call each other's services or actions round a loop can
//! deadlock, each handler waiting on the next, so a launch refuses it.
//!
//! Topics never count (receiving blocks nobody). A node slot's calls go to
//! that node; an interface (contract) slot's go to every node of the stack
//! that conforms to (implements) the interface, whichever instance a launch
//! links: a loop some linking would avoid is refused all the same, before
//! anything runs, as PeppyOS does. A node calling a service of an interface
//! it implements itself is a loop of one.

use std::collections::HashSet;

use crate::diag::{Code, Diagnostic};
use crate::model::SlotKind;
use crate::node::NodeDoc;

/// One call edge: `from` calls through slot `via` (its `depends_on` entry)
/// something `to` provides.
struct Edge {
    from: usize,
    to: usize,
    /// The slot's index in `from`'s dependencies.
    via: usize,
}

/// The first caller-driven cycle among `nodes` (each once), located at the
/// slot that closes it.
pub(crate) fn call_cycle(nodes: &[&NodeDoc]) -> Option<Diagnostic> {
    let edges = edges(nodes);
    let out_of = |n: usize| edges.iter().filter(move |e| e.from == n);
    // Depth-first search with an explicit path: the first back edge found
    // closes a cycle, read off the path.
    let mut done = vec![false; nodes.len()];
    for start in 0..nodes.len() {
        if done[start] {
            continue;
        }
        let mut path: Vec<(usize, Vec<&Edge>)> = vec![(start, out_of(start).collect())];
        let mut on_path: HashSet<usize> = HashSet::from([start]);
        while let Some((node, pending)) = path.last_mut() {
            let node = *node;
            let Some(edge) = pending.pop() else {
                done[node] = true;
                on_path.remove(&node);
                path.pop();
                continue;
            };
            if on_path.contains(&edge.to) {
                let from = path.iter().position(|(n, _)| *n == edge.to).unwrap_or(0);
                let members: Vec<usize> = path[from..].iter().map(|(n, _)| *n).collect();
                return Some(report(nodes, &members, edge));
            }
            if !done[edge.to] {
                on_path.insert(edge.to);
                path.push((edge.to, out_of(edge.to).collect()));
            }
        }
    }
    None
}

/// Every call edge of the stack.
fn edges(nodes: &[&NodeDoc]) -> Vec<Edge> {
    let mut out = Vec::new();
    for (from, caller) in nodes.iter().enumerate() {
        let calls: HashSet<&str> = caller
            .consumed_services
            .iter()
            .chain(&caller.consumed_actions)
            .map(|c| c.link_id.as_str())
            .collect();
        for (via, dep) in caller.dependencies.iter().enumerate() {
            if !calls.contains(dep.link_id.as_str()) {
                continue;
            }
            for (to, provider) in nodes.iter().enumerate() {
                let provides = match dep.kind {
                    SlotKind::Node => provider.identity() == dep.target,
                    SlotKind::Interface => {
                        provider.conforms_to.iter().any(|c| c.target == dep.target)
                    }
                };
                if provides {
                    out.push(Edge { from, to, via });
                }
            }
        }
    }
    out
}

fn report(nodes: &[&NodeDoc], members: &[usize], closing: &Edge) -> Diagnostic {
    let caller = nodes[closing.from];
    let dep = &caller.dependencies[closing.via];
    let kind = if caller
        .consumed_services
        .iter()
        .any(|c| c.link_id == dep.link_id)
    {
        "service"
    } else {
        "action"
    };
    let mut names: Vec<String> = members
        .iter()
        .map(|&m| nodes[m].identity().to_string())
        .collect();
    names.sort();
    let loop_text = if members.len() == 1 {
        format!("`{}` calls itself", names[0])
    } else {
        format!(
            "{} call each other round a loop",
            crate::diag::list(names.iter().map(String::as_str))
        )
    };
    dep.loc
        .error(
            Code::ServiceActionContractCycle,
            format!(
                "{loop_text}: slot `{}` of `{}` calls a {kind} of `{}`, closing it",
                dep.link_id,
                caller.identity(),
                dep.target
            ),
        )
        .with_help(
            "services and actions block their caller until answered, so a loop of calls can deadlock; let one side publish a topic instead, or split the node that closes the loop",
        )
}
