//! Which part of a stack one `up` starts. A launcher without `core_nodes`
//! runs whole on this machine. One with `core_nodes` runs one machine's
//! share per `up --core-node NAME` (its instances, and its router linked to
//! the others), or every share here with `--local`; either way each
//! instance carries its core node's name, which is what `from_core_node`
//! filters on.

//!
//! `--place LINK@CORE_NODE` binds the launcher's core nodes (placeholders
//! in `launcher/v1`) to machines first ([`place`]): the machines become the
//! stack's core nodes, and everything after sees only them.

use peppy_schema::{LauncherDoc, Placement, StackCheck, did_you_mean};

use crate::cli::UpArgs;

/// The target of `--place LINK@self`: the machine running the command.
pub(crate) const SELF: &str = peppy_schema::names::SELF_CORE_NODE;

/// Why `--place` does not fit the launcher or is not understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlaceError {
    /// Not `LINK@CORE_NODE`.
    #[error(
        "--place {arg}: {why}; write `--place LINK@CORE_NODE`, e.g. `--place robot_onboard@self`"
    )]
    Grammar {
        /// The argument as given.
        arg: String,
        /// What is wrong with it.
        why: String,
    },
    /// `--place` for a launcher that declares no `core_nodes`.
    #[error(
        "--place {arg}: {launcher} declares no core_nodes, so there is nothing to place; it runs whole on one machine"
    )]
    NoCoreNodes {
        /// The argument as given.
        arg: String,
        /// The launcher file.
        launcher: String,
    },
    /// `--place` names a core node the launcher does not declare.
    #[error("--place {arg}: {launcher} declares no core node `{link}`{}; its core nodes are {}", suggestion.as_ref().map(|s| format!(" (did you mean `{s}`?)")).unwrap_or_default(), declared.join(", "))]
    UnknownLink {
        /// The argument as given.
        arg: String,
        /// The core node named.
        link: String,
        /// The closest declared name, if one is close.
        suggestion: Option<String>,
        /// The launcher file.
        launcher: String,
        /// Its core nodes.
        declared: Vec<String>,
    },
    /// One core node placed by two arguments.
    #[error(
        "--place {second}: core node `{link}` is already placed by --place {first}; place each core node once"
    )]
    PlacedTwice {
        /// The core node.
        link: String,
        /// The first argument placing it.
        first: String,
        /// The second.
        second: String,
    },
    /// Some core nodes placed, others not.
    #[error("{} not placed: with --place, every core node of the launcher is placed ({}), e.g. `--place {}@self`", unplaced.iter().map(|(l, at)| format!("core node `{l}` (declared at {at})")).collect::<Vec<_>>().join(", "), declared.join(", "), unplaced[0].0)]
    Unplaced {
        /// Each core node not placed, with where it is declared
        /// (`file:line:column`).
        unplaced: Vec<(String, String)>,
        /// Every core node of the launcher.
        declared: Vec<String>,
    },
    /// A machine name that cannot name a core node.
    #[error("--place {arg}: `{machine}` cannot name a core node: {why}")]
    BadMachine {
        /// The argument as given.
        arg: String,
        /// The machine named.
        machine: String,
        /// Why not.
        why: String,
    },
    /// `@self`, and this machine's name is unknown or unusable.
    #[error(
        "this machine's host name {host} cannot name a core node ({why}); name it with `up --core-node NAME`, or place on machines by name instead of `@self`"
    )]
    HostName {
        /// The host name, quoted, or `(unknown)`.
        host: String,
        /// Why it cannot be used.
        why: String,
    },
    /// `up --core-node NAME --place ...` with a NAME no machine can have.
    #[error("--core-node {name}: `{name}` cannot name a machine: {why}")]
    BadCoreNode {
        /// The name given.
        name: String,
        /// Why not.
        why: String,
    },
    /// `up --place` that places nothing on this machine.
    #[error("nothing is placed on this machine, `{core}`: the machines are {}; place a core node `@self`, or give `--core-node` one of the machines", machines.join(", "))]
    NothingHere {
        /// This machine's name.
        core: String,
        /// The machines the placement names.
        machines: Vec<String>,
    },
}

/// Whether `name` may name a machine: the core node name rule a
/// launcher's `core_nodes` follow.
fn check_machine(name: &str) -> Result<(), String> {
    peppy_schema::names::check_core_node_name(name)
}

/// This machine's name: its host name up to the first dot.
pub(crate) fn host_core_node() -> Result<String, PlaceError> {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its whole length, and gethostname
    // writes at most that many bytes.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return Err(PlaceError::HostName {
            host: "(unknown)".into(),
            why: std::io::Error::last_os_error().to_string(),
        });
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let host = String::from_utf8_lossy(&buf[..end]).into_owned();
    let name = host.split('.').next().unwrap_or_default().to_string();
    check_machine(&name).map_err(|why| PlaceError::HostName {
        host: format!("`{host}`"),
        why,
    })?;
    Ok(name)
}

/// Reads the `--place` arguments against the launcher: each
/// `LINK@CORE_NODE` split at its first `@`, `self` replaced by
/// `this_machine()` (asked only then), every declared core node placed
/// exactly once.
pub(crate) fn read_places(
    launcher: &LauncherDoc,
    args: &[String],
    this_machine: &mut dyn FnMut() -> Result<String, PlaceError>,
) -> Result<Placement, PlaceError> {
    let declared: Vec<String> = launcher.core_nodes.iter().map(|c| c.name.clone()).collect();
    let file = launcher.file.path().display().to_string();
    let mut placement = Placement::default();
    let mut given: Vec<&String> = Vec::new();
    for arg in args {
        let grammar = |why: &str| PlaceError::Grammar {
            arg: arg.clone(),
            why: why.to_string(),
        };
        let Some((link, machine)) = arg.split_once('@') else {
            return Err(grammar("no `@` between the core node and the machine"));
        };
        if link.is_empty() {
            return Err(grammar("the core node before `@` is empty"));
        }
        if machine.is_empty() {
            return Err(grammar("the machine after `@` is empty"));
        }
        if declared.is_empty() {
            return Err(PlaceError::NoCoreNodes {
                arg: arg.clone(),
                launcher: file,
            });
        }
        if !declared.iter().any(|d| d == link) {
            return Err(PlaceError::UnknownLink {
                arg: arg.clone(),
                link: link.to_string(),
                suggestion: did_you_mean(link, declared.iter().map(String::as_str))
                    .map(str::to_string),
                launcher: file,
                declared,
            });
        }
        if let Some(i) = placement.places.iter().position(|(l, _)| l == link) {
            return Err(PlaceError::PlacedTwice {
                link: link.to_string(),
                first: given[i].clone(),
                second: arg.clone(),
            });
        }
        let machine = if machine == SELF {
            this_machine()?
        } else {
            check_machine(machine).map_err(|why| PlaceError::BadMachine {
                arg: arg.clone(),
                machine: machine.to_string(),
                why,
            })?;
            machine.to_string()
        };
        placement.places.push((link.to_string(), machine));
        given.push(arg);
    }
    let unplaced: Vec<(String, String)> = launcher
        .core_nodes
        .iter()
        .filter(|c| placement.machine_of(&c.name).is_none())
        .map(|c| {
            let lc = c.loc.file.line_col(c.loc.span.start);
            (
                c.name.clone(),
                format!("{}:{}:{}", c.loc.file.path().display(), lc.line, lc.column),
            )
        })
        .collect();
    if !placement.places.is_empty() && !unplaced.is_empty() {
        return Err(PlaceError::Unplaced { unplaced, declared });
    }
    Ok(placement)
}

/// A checked stack with `--place` applied: its core nodes are the machines
/// from here on. Without `--place`, the stack as it is (each core node a
/// machine of its own name).
pub(crate) fn place(
    stack: StackCheck,
    args: &[String],
    this_machine: &mut dyn FnMut() -> Result<String, PlaceError>,
) -> Result<StackCheck, PlaceError> {
    if args.is_empty() {
        return Ok(stack);
    }
    let placement = read_places(&stack.launcher, args, this_machine)?;
    Ok(stack.placed(&placement))
}

/// `up`'s name for this machine under `--place`: `--core-node`, else the
/// host name.
pub(crate) fn up_machine(args: &UpArgs) -> Result<String, PlaceError> {
    match &args.core_node {
        Some(name) => {
            check_machine(name)
                .map(|()| name.clone())
                .map_err(|why| PlaceError::BadCoreNode {
                    name: name.clone(),
                    why,
                })
        }
        None => host_core_node(),
    }
}

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

    fn places(l: &LauncherDoc, args: &[&str]) -> Result<Placement, PlaceError> {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        let mut asked = 0;
        let got = read_places(l, &args, &mut || {
            asked += 1;
            Ok("bench".into())
        });
        assert!(asked <= 1, "this machine's name is asked for once at most");
        got
    }

    #[test]
    fn places_split_at_the_first_at_and_self_is_this_machine() {
        let l = launcher(r#"core_nodes: ["robot", "desk"],"#);
        let p = places(&l, &["robot@self", "desk@atlas"]).unwrap();
        assert_eq!(
            p.places,
            [
                ("robot".to_string(), "bench".to_string()),
                ("desk".to_string(), "atlas".to_string())
            ]
        );
        assert!(places(&l, &[]).unwrap().places.is_empty());
        assert!(matches!(
            places(&l, &["robot@a@b", "desk@c"]),
            Err(PlaceError::BadMachine { machine, .. }) if machine == "a@b"
        ));
        assert!(matches!(
            places(&l, &["desk@c"]),
            Err(PlaceError::Unplaced { unplaced, .. }) if unplaced[0].0 == "robot"
        ));
        assert!(matches!(
            places(&l, &["rbot@c"]),
            Err(PlaceError::UnknownLink { suggestion: Some(s), .. }) if s == "robot"
        ));
        assert!(matches!(
            places(&launcher(""), &["robot@c"]),
            Err(PlaceError::NoCoreNodes { .. })
        ));
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
