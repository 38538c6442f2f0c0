//! Placement by `--place LINK@CORE_NODE` and launchers found by name: a
//! launcher's core nodes (`launcher/v1` placeholders) bound to machines, which
//! then name the instances' keys; every misuse refused before anything
//! starts; `up NAME` finding the launcher through the repositories.

use std::path::Path;
use std::time::Duration;

use crate::machines::free_port;
use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{peppy_launch, root};

const TWO_MACHINES: &str = "examples/launchers/two_machines.json5";

fn write(root: &Path, rel: &str, text: &str) {
    let p = root.join(rel);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, text).unwrap();
}

fn examples() -> String {
    root().join("examples").display().to_string()
}

/// Runs `check` (or any command) from the checkout, expecting a refusal
/// (exit 2) whose message contains every one of `says`; nothing starts.
fn refused(args: &[&str], says: &[&str]) {
    let run = peppy_launch(&root(), args);
    assert_eq!(run.code, 2, "{args:?}:\n{}", run.stderr);
    for s in says {
        assert!(
            run.stderr.contains(s),
            "{args:?}: no `{s}` in:\n{}",
            run.stderr
        );
    }
    assert!(!run.stderr.contains("started `"), "{}", run.stderr);
}

#[test]
fn every_misplacement_is_refused_before_anything_starts() {
    let ex = examples();
    fn with<'a>(ex: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
        [&["check", TWO_MACHINES, "--repo", ex][..], extra].concat()
    }
    let check = |extra: &[&'static str]| with(&ex, extra);
    // The grammar: `LINK@CORE_NODE`, split at the first `@`.
    refused(
        &check(&["--place", "robot"]),
        &["--place robot: no `@` between the core node and the machine"],
    );
    refused(
        &check(&["--place", "@lab"]),
        &["--place @lab: the core node before `@` is empty"],
    );
    refused(
        &check(&["--place", "robot@"]),
        &["--place robot@: the machine after `@` is empty"],
    );
    refused(
        &check(&["--place", "robot@lab@2", "--place", "workstation@desk"]),
        &["--place robot@lab@2: `lab@2` cannot name a core node"],
    );
    // Only declared core nodes, with a suggestion.
    refused(
        &check(&["--place", "robt@self"]),
        &[
            "declares no core node `robt` (did you mean `robot`?); its core nodes are robot, workstation",
        ],
    );
    // Each once.
    refused(
        &check(&["--place", "robot@a", "--place", "robot@b"]),
        &["--place robot@b: core node `robot` is already placed by --place robot@a"],
    );
    // All of them.
    refused(
        &check(&["--place", "robot@self"]),
        &[
            "core node `workstation` (declared at ",
            "two_machines.json5:13:5) not placed",
            "e.g. `--place workstation@self`",
        ],
    );
    // Nothing to place on a launcher that runs whole on one machine.
    refused(
        &[
            "check",
            "examples/launchers/camera_viewer.json5",
            "--place",
            "robot@self",
        ],
        &["camera_viewer.json5 declares no core_nodes, so there is nothing to place"],
    );
    // `--local` and `--place` are two answers to one question.
    refused(
        &["up", TWO_MACHINES, "--local", "--place", "robot@self"],
        &["'--local' cannot be used with '--place <LINK@CORE_NODE>'"],
    );
    // `up` starts what is placed on this machine: something must be.
    refused(
        &[
            "up",
            TWO_MACHINES,
            "--repo",
            &ex,
            "--no-build",
            "--core-node",
            "bench",
            "--place",
            "robot@lab",
            "--place",
            "workstation@desk",
        ],
        &["nothing is placed on this machine, `bench`: the machines are lab, desk"],
    );
    refused(
        &[
            "up",
            TWO_MACHINES,
            "--core-node",
            "self",
            "--place",
            "robot@self",
            "--place",
            "workstation@desk",
        ],
        &["--core-node self: `self` cannot name a machine"],
    );
}

#[test]
fn check_and_graph_show_the_stack_on_its_machines() {
    let ex = examples();
    // Two core nodes on one machine: one core node, listening and
    // connecting as both say.
    let run = peppy_launch(
        &root(),
        &[
            "check",
            TWO_MACHINES,
            "--repo",
            &ex,
            "--place",
            "robot@rig",
            "--place",
            "workstation@rig",
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stdout.contains(
            "core nodes:\n  rig  (listen tcp/0.0.0.0:7447; connect tcp/robot.local:7447)\ninstances:"
        ),
        "{}",
        run.stdout
    );
    assert!(!run.stdout.contains("on robot"), "{}", run.stdout);
    let json = peppy_launch(
        &root(),
        &[
            "check",
            TWO_MACHINES,
            "--repo",
            &ex,
            "--format",
            "json",
            "--place",
            "robot@rig",
            "--place",
            "workstation@desk",
        ],
    );
    let report: serde_json::Value = serde_json::from_str(&json.stdout).unwrap();
    assert_eq!(report["core_nodes"][0]["name"], "rig");
    assert_eq!(report["plan"]["instances"][0]["core_node"], "rig");
    assert_eq!(report["plan"]["instances"][3]["core_node"], "desk");
    let graph = peppy_launch(
        &root(),
        &[
            "graph",
            TWO_MACHINES,
            "--repo",
            &ex,
            "--place",
            "robot@rig",
            "--place",
            "workstation@desk",
        ],
    );
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    for frame in ["cluster_rig", "cluster_desk"] {
        assert!(graph.stdout.contains(frame), "{}", graph.stdout);
    }
}

/// Three core nodes of a `launcher/v1` launcher on two machines of one host:
/// `sensors` and `compute` share machine `bench`, `display` is on `desk`.
/// Each `up` starts what is placed on it (`@self`, named by
/// `--core-node`), the two routers link, the viewer on `desk` receives
/// both cameras, and every instance's key names its machine.
#[test]
fn placed_core_nodes_run_on_their_machines() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("placed_viewer.json5");
    std::fs::write(
        &launcher,
        r#"{ peppy_schema: "launcher/v1",
            core_nodes: ["sensors", "compute", "display"],
            deployments: [
              { source: { name: "realsense_d405:v1" }, instances: [
                  { instance_id: "rs_left", core_node: "sensors" },
                  { instance_id: "rs_right", core_node: "compute", arguments: { width: 64, height: 48 } } ] },
              { source: { name: "camera_viewer:v1" }, instances: [
                  { instance_id: "viewer", core_node: "display",
                    links: { cameras: ["rs_left", "rs_right"], overhead: { vacant: "none here" } } } ] } ] }"#,
    )
    .unwrap();
    let (launcher, ex) = (launcher.to_str().unwrap(), examples());
    let bench_at = format!("tcp/127.0.0.1:{}", free_port());
    let mut bench = Launch::up(
        launcher,
        &[
            "--repo",
            &ex,
            "--core-node",
            "bench",
            "--place",
            "sensors@self",
            "--place",
            "compute@self",
            "--place",
            "display@desk",
            "--listen",
            &bench_at,
        ],
    );
    bench.expect("with bench's share", BUILD_AND_START, |l| {
        l.contains("core node bench: rs_left, rs_right (router on ")
    });
    let mut desk = Launch::up(
        launcher,
        &[
            "--repo",
            &ex,
            "--core-node",
            "desk",
            "--place",
            "sensors@bench",
            "--place",
            "compute@bench",
            "--place",
            "display@self",
            "--connect",
            &bench_at,
        ],
    );
    desk.expect("with desk's share", BUILD_AND_START, |l| {
        l.contains("core node desk: viewer (router on ")
    });
    desk.expect("with bench joining", Duration::from_secs(30), |l| {
        l.contains("core node bench joined")
    });
    for camera in ["rs_left (160x120)", "rs_right (64x48)"] {
        desk.expect("with a first frame", Duration::from_secs(60), |l| {
            l.starts_with("[viewer]") && l.contains(&format!("cameras: first frame from {camera}"))
        });
    }
    let namespace = desk
        .seen
        .iter()
        .find_map(|l| l.split("namespace ").nth(1))
        .and_then(|rest| rest.split(';').next())
        .expect("the launch names its namespace")
        .to_string();
    let list = peppy_launch(
        &root(),
        &[
            "node",
            "list",
            "--connect",
            &bench_at,
            "--namespace",
            &namespace,
        ],
    );
    assert_eq!(list.code, 0, "{}", list.stderr);
    let machine_of = |id: &str| {
        list.stdout
            .lines()
            .find(|l| l.split_whitespace().next() == Some(id))
            .and_then(|l| l.split_whitespace().nth(2))
            .map(str::to_string)
    };
    assert_eq!(
        machine_of("rs_left").as_deref(),
        Some("bench"),
        "{}",
        list.stdout
    );
    assert_eq!(
        machine_of("rs_right").as_deref(),
        Some("bench"),
        "{}",
        list.stdout
    );
    assert_eq!(
        machine_of("viewer").as_deref(),
        Some("desk"),
        "{}",
        list.stdout
    );
    assert!(
        !bench.seen.iter().any(|l| l.contains("started `viewer`")),
        "bench starts only its share"
    );
    assert_eq!(desk.stop(), 0);
    assert_eq!(bench.stop(), 0);
}

/// `up NAME`: the example stack found by its name through the examples'
/// repository, and run.
#[test]
fn up_by_name_runs_the_launcher_the_repositories_list() {
    let ex = examples();
    let mut launch = Launch::up("camera_viewer", &["--repo", &ex]);
    launch.expect("with a first frame", BUILD_AND_START, |l| {
        l.starts_with("[viewer]") && l.contains("cameras: first frame from rs_left")
    });
    assert_eq!(launch.stop(), 0);
    // From inside the examples, their peppy_repositories.json5 is enough.
    let check = peppy_launch(&root().join("examples"), &["check", "camera_viewer"]);
    assert_eq!(check.code, 0, "{}", check.stderr);
    assert!(
        check
            .stdout
            .contains("launcher: launchers/camera_viewer.json5"),
        "{}",
        check.stdout
    );
}

#[test]
fn a_launcher_name_must_find_exactly_one_file() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two, indexed) = (
        dir.path().join("one"),
        dir.path().join("two"),
        dir.path().join("indexed"),
    );
    let empty = r#"{ peppy_schema: "launcher/v1", deployments: [] }"#;
    write(&one, "stacks/demo.json5", empty);
    write(&two, "elsewhere/demo.json5", empty);
    write(
        &indexed,
        "peppy_repository.json5",
        r#"{ peppy_schema: "repository/v1", launchers: { gone: { path: "stacks/gone.json5" } } }"#,
    );
    let (one, two, indexed) = (
        one.to_str().unwrap(),
        two.to_str().unwrap(),
        indexed.to_str().unwrap(),
    );
    // Found and read (it deploys nothing, which its reader refuses).
    refused(
        &["check", "demo", "--repo", one],
        &["one/stacks/demo.json5:1:45: error: `deployments` is empty"],
    );
    refused(
        &["check", "demo", "--repo", one, "--repo", two],
        &[
            "launcher `demo` is ambiguous:",
            "stacks/demo.json5` and `",
            "elsewhere/demo.json5` answer to it; give the path of the one you mean",
        ],
    );
    refused(
        &["up", "dmeo", "--repo", one],
        &["no repository provides launcher `dmeo` (did you mean `demo`?); searched `"],
    );
    refused(
        &["graph", "gone", "--repo", indexed],
        &[
            "launcher `gone` is listed at `",
            "stacks/gone.json5`, which does not exist; write the repository's index again",
        ],
    );
    // A path is never looked up.
    refused(&["check", "./demo", "--repo", one], &["demo"]);
    // A word where a command goes that names no launcher either: a
    // mistyped command, named as one (`up` written, it is a launcher's name).
    refused(
        &["chek", "--repo", one],
        &[
            "`chek` is no command, and no repository provides launcher `chek`",
            "did you mean `peppy-launch check`?",
        ],
    );
    refused(
        &["stauts", "--repo", one],
        &[
            "`stauts` is no command, and no repository provides launcher `stauts`",
            "`peppy-launch --help` lists the commands",
        ],
    );
    let written = peppy_launch(&root(), &["up", "chek", "--repo", one]);
    assert!(
        written
            .stderr
            .contains("no repository provides launcher `chek`")
            && !written.stderr.contains("is no command"),
        "{}",
        written.stderr
    );
    // A word that names a launcher still runs it (`demo` is found and read).
    refused(&["demo", "--repo", one], &["`deployments` is empty"]);
}

/// Two hosts (network namespaces joined by a veth link) and a launcher's
/// two core nodes placed on them by name. The router listens beyond
/// loopback, so the stack runs secured: `keys --place` makes the keys of
/// the machines, copied to the other host, and the routers link over TLS
/// with certificates named by the machines.
#[test]
fn placed_core_nodes_link_two_hosts_secured() {
    let Some(hosts) = crate::netns::TwoHosts::new() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("placed_pair.json5");
    std::fs::write(
        &launcher,
        r#"{ peppy_schema: "launcher/v1",
            core_nodes: ["sensors", "display"],
            deployments: [
              { source: { name: "realsense_d405:v1" }, instances: [
                  { instance_id: "rs_left", core_node: "sensors" } ] },
              { source: { name: "camera_viewer:v1" }, instances: [
                  { instance_id: "viewer", core_node: "display",
                    links: { cameras: ["rs_left"], overhead: { vacant: "none here" } } } ] } ] }"#,
    )
    .unwrap();
    let (launcher, ex) = (launcher.to_str().unwrap(), examples());
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let keys = crate::support::peppy_launch_with(
        &root(),
        &[
            "keys",
            launcher,
            "--place",
            "sensors@rig",
            "--place",
            "display@desk",
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    assert_eq!(keys.code, 0, "{}", keys.stderr);
    assert!(
        keys.stderr.contains("keys for core nodes rig, desk"),
        "{}",
        keys.stderr
    );
    let desk_state = tempfile::tempdir().unwrap();
    let st_b = desk_state.path();
    crate::machines::copy_stack_keys(st, st_b);
    let rig_at = format!("tcp/{}:7447", crate::netns::HOST_A);
    let mut rig = Launch::up_in(
        &hosts.on(&hosts.a),
        launcher,
        &[
            "--repo",
            &ex,
            "--core-node",
            "rig",
            "--place",
            "sensors@self",
            "--place",
            "display@desk",
            "--listen",
            &rig_at,
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    rig.expect("with the camera", BUILD_AND_START, |l| {
        l.contains("core node rig: rs_left (router on tls/")
    });
    let mut desk = Launch::up_in(
        &hosts.on(&hosts.b),
        launcher,
        &[
            "--repo",
            &ex,
            "--core-node",
            "desk",
            "--place",
            "sensors@rig",
            "--place",
            "display@self",
            "--connect",
            &rig_at,
        ],
        &[("PEPPY_STATE_DIR", st_b)],
    );
    desk.expect("with the link over TLS", BUILD_AND_START, |l| {
        l.contains(&format!("linked to {}", rig_at.replace("tcp/", "tls/")))
    });
    desk.expect("with rig joining", Duration::from_secs(30), |l| {
        l.contains("core node rig joined")
    });
    desk.expect(
        "with a frame across the link",
        Duration::from_secs(60),
        |l| l.starts_with("[viewer]") && l.contains("cameras: first frame from rs_left"),
    );
    assert!(
        !rig.seen
            .iter()
            .chain(&desk.seen)
            .any(|l| l.contains("denied:")),
        "a bound flow was refused"
    );
    assert_eq!(desk.stop(), 0);
    assert_eq!(rig.stop(), 0);
}
