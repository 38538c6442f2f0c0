//! Which part of a stack one `up` starts. A launcher without `core_nodes`
//! runs whole on this machine. One with `core_nodes` runs one machine's
//! share per `up --core-node NAME` (its instances, and its router linked to
//! the others), or every share here with `--local`; either way each
//! instance carries its core node's name, which is what `from_core_node`
//! filters on.

use peppy_schema::{LauncherDoc, StackCheck};

use crate::cli::UpArgs;

/// Why `up`'s `--core-node` / `--local` do not fit the launcher.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlacementError {
    /// `--core-node` for a launcher that runs whole on one machine.
    #[error(
        "--core-node {core}: this launcher declares no core_nodes; it runs whole on one machine"
    )]
    NoCoreNodes {
        /// The core node given.
        core: String,
    },
    /// A launcher with core nodes, and neither `--core-node` nor `--local`.
    #[error(
        "this launcher places its instances on core nodes {}: start each machine's share with `up --core-node NAME` there, or all of it here with `up --local`",
        core_nodes.join(", ")
    )]
    ShareNotChosen {
        /// The launcher's core nodes.
        core_nodes: Vec<String>,
    },
    /// `--core-node` names none of the launcher's core nodes.
    #[error("--core-node {core}: the launcher's core nodes are {}", core_nodes.join(", "))]
    UnknownCoreNode {
        /// The core node given.
        core: String,
        /// The launcher's core nodes.
        core_nodes: Vec<String>,
    },
}

/// What this launch starts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Share {
    /// Indices into the plan's instances, in launcher order.
    pub(crate) instances: Vec<usize>,
    /// The core node of each of `instances`.
    pub(crate) core_of: Vec<String>,
    /// This launch's name for itself (records, messages).
    pub(crate) name: String,
    /// Where its router listens (empty: a free loopback port).
    pub(crate) listen: Vec<String>,
    /// What its router connects to.
    pub(crate) connect: Vec<String>,
}

/// Decides the share from the launcher and `up`'s flags.
pub(crate) fn share(stack: &StackCheck, args: &UpArgs) -> Result<Share, PlacementError> {
    share_of(
        &stack.launcher,
        stack.plan.instances.iter().map(|i| i.core_node.as_deref()),
        args.core_node.as_deref(),
        args.local,
        &args.listen,
        &args.connect,
    )
}

fn share_of<'a>(
    launcher: &LauncherDoc,
    placements: impl Iterator<Item = Option<&'a str>>,
    core_node: Option<&str>,
    local: bool,
    listen: &[String],
    connect: &[String],
) -> Result<Share, PlacementError> {
    let names: Vec<&str> = launcher
        .core_nodes
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let placements: Vec<Option<&str>> = placements.collect();
    let everything = |name: String, core_of: Vec<String>| Share {
        instances: (0..placements.len()).collect(),
        core_of,
        name,
        listen: listen.to_vec(),
        connect: connect.to_vec(),
    };
    match (names.is_empty(), core_node, local) {
        (true, Some(c), _) => Err(PlacementError::NoCoreNodes {
            core: c.to_string(),
        }),
        (true, None, _) => {
            let name = format!("launch-{:x}", std::process::id());
            Ok(everything(name.clone(), vec![name; placements.len()]))
        }
        (false, None, true) => {
            let core_of = placements
                .iter()
                .map(|p| launcher.core_node_of(*p).unwrap_or_default().to_string())
                .collect();
            Ok(everything("local".into(), core_of))
        }
        (false, None, false) => Err(PlacementError::ShareNotChosen {
            core_nodes: names.iter().map(|n| n.to_string()).collect(),
        }),
        (false, Some(c), _) => {
            let Some(decl) = launcher.core_node(c) else {
                return Err(PlacementError::UnknownCoreNode {
                    core: c.to_string(),
                    core_nodes: names.iter().map(|n| n.to_string()).collect(),
                });
            };
            let instances: Vec<usize> = placements
                .iter()
                .enumerate()
                .filter(|(_, p)| launcher.core_node_of(**p) == Some(c))
                .map(|(i, _)| i)
                .collect();
            Ok(Share {
                core_of: vec![c.to_string(); instances.len()],
                instances,
                name: c.to_string(),
                // The command line wins over the launcher.
                listen: if listen.is_empty() {
                    decl.listen.clone()
                } else {
                    listen.to_vec()
                },
                connect: if connect.is_empty() {
                    decl.connect.clone()
                } else {
                    connect.to_vec()
                },
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn launcher(core_nodes: &str) -> LauncherDoc {
        let text = format!(
            r#"{{ peppy_schema: "launcher_v1", {core_nodes}
                deployments: [{{ source: {{ name: "cam:v1" }}, instances: [
                    {{ instance_id: "a" {a} }}, {{ instance_id: "b" }} ] }}] }}"#,
            a = if core_nodes.is_empty() {
                ""
            } else {
                r#", core_node: "robot""#
            },
        );
        LauncherDoc::parse("stack.json5", &text).unwrap().0
    }

    fn run(
        l: &LauncherDoc,
        placed: &[Option<&str>],
        core: Option<&str>,
        local: bool,
    ) -> Result<Share, PlacementError> {
        share_of(l, placed.iter().copied(), core, local, &[], &[])
    }

    #[test]
    fn a_launcher_without_core_nodes_runs_whole() {
        let l = launcher("");
        let s = run(&l, &[None, None], None, false).unwrap();
        assert_eq!(s.instances, [0, 1]);
        assert!(s.core_of[0].starts_with("launch-"));
        assert_eq!(
            run(&l, &[None, None], Some("robot"), false),
            Err(PlacementError::NoCoreNodes {
                core: "robot".into()
            })
        );
    }

    #[test]
    fn each_machine_starts_its_share_and_unplaced_instances_go_home() {
        let l = launcher(
            r#"core_nodes: { workstation: { connect: ["tcp/192.0.2.1:7447"] }, robot: { listen: ["tcp/0.0.0.0:7447"] } },"#,
        );
        let placed = [Some("robot"), None];
        let robot = run(&l, &placed, Some("robot"), false).unwrap();
        assert_eq!(
            (robot.instances.as_slice(), robot.listen.as_slice()),
            (&[0][..], &["tcp/0.0.0.0:7447".to_string()][..])
        );
        // `b` has no core_node: it runs on the first core node declared.
        let ws = run(&l, &placed, Some("workstation"), false).unwrap();
        assert_eq!(ws.instances, [1]);
        assert_eq!(ws.core_of, ["workstation"]);
        assert_eq!(ws.connect, ["tcp/192.0.2.1:7447"]);
        let local = run(&l, &placed, None, true).unwrap();
        assert_eq!(local.core_of, ["robot", "workstation"]);
        let e = run(&l, &placed, None, false).unwrap_err().to_string();
        assert!(
            e.contains("--core-node NAME") && e.contains("--local"),
            "{e}"
        );
        let e = run(&l, &placed, Some("lab"), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("workstation, robot"), "{e}");
        // The command line wins over the launcher's endpoints.
        let cli = share_of(
            &l,
            placed.iter().copied(),
            Some("robot"),
            false,
            &["tcp/127.0.0.1:9".into()],
            &[],
        )
        .unwrap();
        assert_eq!(cli.listen, ["tcp/127.0.0.1:9"]);
    }
}
