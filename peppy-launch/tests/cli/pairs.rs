//! Pairings from the command line (docs/PAIRINGS.md): the example pair of
//! a Rust leader and a Python follower under `up`, a follower killed and
//! restarted, `check` and `graph` of the pair, `run --link` against a held
//! and a free slot, `node info` and `topic echo --pair`, and the pair
//! across two network namespaces with security on.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use serde_json::Value;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{Run, peppy_launch_with, root};

/// How long a pair takes to form, dissolve or form again once its sides
/// run.
const PAIRING: Duration = Duration::from_secs(60);

fn examples() -> String {
    root().join("examples").to_str().unwrap().to_string()
}

/// The example pair, its follower restarted when it fails.
const RESTARTING_PAIR: &str = r#"{ peppy_schema: "launcher/v1",
    deployments: [
      { source: { name: "joint_leader:v1" },
        instances: [{ instance_id: "leader", links: { follower: "follower" } }] },
      { source: { name: "py_joint_follower:v1" },
        instances: [{ instance_id: "follower", restart: "on-failure" }] } ] }"#;

/// Writes [`RESTARTING_PAIR`] into `dir`; its path.
fn restarting_pair(dir: &Path) -> String {
    let path = dir.join("restarting_pair.json5");
    std::fs::write(&path, RESTARTING_PAIR).unwrap();
    path.to_str().unwrap().to_string()
}

/// A command against the test's own launch registry, with time for the
/// instances to answer.
fn inspect(state: &Path, args: &[&str]) -> Run {
    let mut args = args.to_vec();
    if matches!(args[0], "node" | "topic") {
        args.extend(["--wait", "10"]);
    }
    peppy_launch_with(&root(), &args, &[("PEPPY_STATE_DIR", state)])
}

/// The one running launch of the registry: its namespace and router.
fn reach(state: &Path) -> (String, String) {
    let ps = inspect(state, &["ps", "--format", "json"]);
    assert_eq!(ps.code, 0, "{}", ps.stderr);
    let launches: Value = serde_json::from_str(ps.stdout.trim()).unwrap();
    let launch = &launches[0];
    (
        launch["namespace"].as_str().unwrap().to_string(),
        launch["connect"][0].as_str().unwrap().to_string(),
    )
}

/// Whether a `[leader]` line says its slot paired with the follower (the
/// runtime's log, or the node's own line).
fn leader_paired(l: &str) -> bool {
    l.starts_with("[leader]")
        && (l.contains("paired slot=follower peer=follower peer_slot=leader")
            || l.contains("paired with follower/leader"))
}

/// `up` of the example pair: both sides pair; the follower, SIGKILLed,
/// dissolves the pair (the leader says so), is restarted under
/// `on-failure`, and pairs again. Meanwhile `node info` shows the pair,
/// `topic echo --pair` follows both of its topics, and `run --link`
/// against the held follower slot is refused while a free follower pairs
/// with a leader started by `run`.
#[test]
fn a_pair_forms_dissolves_on_a_kill_and_forms_again_after_the_restart() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = restarting_pair(dir.path());
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let ex = examples();
    let mut launch = Launch::up_with(
        &launcher,
        &["--repo", &ex, "--namespace", "pairs-restart"],
        &[("PEPPY_STATE_DIR", st)],
    );
    launch.expect("with the leader paired", BUILD_AND_START, leader_paired);
    launch.expect("with the follower paired", PAIRING, |l| {
        l.starts_with("[follower]") && l.contains("paired with `leader/follower`")
    });
    launch.expect("with the follower's state at the leader", PAIRING, |l| {
        l.starts_with("[leader]") && l.contains("follower at ")
    });

    // node info: each side's pairing slot, paired with the other.
    let info = inspect(st, &["node", "info", "leader"]);
    assert_eq!(info.code, 0, "{}", info.stderr);
    assert!(
        info.stdout.contains(
            "pairings\n  follower  pairing joint_link:v1 plays leader: paired with follower/leader"
        ),
        "{}",
        info.stdout
    );
    let info = inspect(st, &["node", "info", "follower", "--format", "json"]);
    assert_eq!(info.code, 0, "{}", info.stderr);
    let info: Value = serde_json::from_str(info.stdout.trim()).unwrap();
    let slot = &info["pairings"][0];
    assert_eq!(
        (
            &slot["link_id"],
            &slot["role"],
            &slot["peer"]["instance_id"],
            &slot["peer"]["link_id"]
        ),
        (
            &Value::from("leader"),
            &Value::from("follower"),
            &Value::from("leader"),
            &Value::from("follower")
        ),
        "{info}"
    );

    // topic echo --pair: each topic from the side that emits it, decoded
    // with the pairing document's format.
    for (topic, from, field) in [
        ("joint_state", "follower", "setpoint_sequence"),
        ("joint_setpoint", "leader", "sequence"),
    ] {
        let echo = inspect(
            st,
            &[
                "topic",
                "echo",
                topic,
                "--pair",
                "leader.follower",
                "--repo",
                &ex,
                "--count",
                "3",
                "--timeout",
                "30",
                "--format",
                "json",
            ],
        );
        assert_eq!(echo.code, 0, "{topic}: {}", echo.stderr);
        let lines: Vec<Value> = echo
            .stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 3, "{}", echo.stdout);
        for m in &lines {
            assert_eq!(m["from"], from, "{m}");
            assert_eq!(m["owner"], "joint_link:v1", "{m}");
            assert!(m["message"][field].is_u64(), "{m}");
        }
    }
    let wrong = inspect(
        st,
        &[
            "topic",
            "echo",
            "nope",
            "--pair",
            "leader.follower",
            "--repo",
            &ex,
        ],
    );
    assert_eq!(wrong.code, 2, "{}", wrong.stderr);
    assert!(
        wrong
            .stderr
            .contains("has no topic `nope`; its topics: joint_setpoint, joint_state"),
        "{}",
        wrong.stderr
    );

    // run --link against the held follower slot: refused before starting,
    // naming who holds it.
    let (namespace, router) = reach(st);
    let refused = inspect(
        st,
        &[
            "run",
            "joint_leader:v1",
            "--repo",
            &ex,
            "--instance-id",
            "leader_2",
            "--link",
            "follower@follower",
            "--connect",
            &router,
            "--namespace",
            &namespace,
        ],
    );
    assert_eq!(refused.code, 2, "{}", refused.stderr);
    assert!(
        refused.stderr.contains(
            "pairing slot `follower` cannot link to `follower/leader` (joint_link:v1): it is already paired with `leader/follower`"
        ) && refused.stderr.contains("(PairingSlotAlreadyPaired)"),
        "{}",
        refused.stderr
    );
    assert!(!refused.stderr.contains("started `leader_2`"));

    // Against a free follower (started by `run`, waiting for a peer), a
    // leader started by `run --link` pairs.
    let run_state = tempfile::tempdir().unwrap();
    let rs = run_state.path();
    let on_stack = [
        "--repo",
        &ex,
        "--connect",
        &router,
        "--namespace",
        &namespace,
    ];
    let mut free = Launch::start(
        &[],
        &[
            &["run", "py_joint_follower:v1", "--instance-id", "follower_2"][..],
            &on_stack[..],
        ]
        .concat(),
        &[("PEPPY_STATE_DIR", rs)],
    );
    free.expect("with the free follower up", PAIRING, |l| {
        l.starts_with("[follower_2]") && l.contains("node up")
    });
    let mut second = Launch::start(
        &[],
        &[
            &[
                "run",
                "joint_leader:v1",
                "--instance-id",
                "leader_2",
                "--link",
                "follower@follower_2",
            ][..],
            &on_stack[..],
        ]
        .concat(),
        &[("PEPPY_STATE_DIR", rs)],
    );
    second.expect("with leader_2 paired", PAIRING, |l| {
        l.starts_with("[leader_2]") && l.contains("paired slot=follower peer=follower_2")
    });
    free.expect("with follower_2 paired", PAIRING, |l| {
        l.starts_with("[follower_2]") && l.contains("paired with `leader_2/follower`")
    });
    assert_eq!(second.stop(), 0);
    assert_eq!(free.stop(), 0);

    // SIGKILL the follower: the leader's pair ends, the launch restarts
    // the follower, and the pair forms again.
    let info = inspect(st, &["node", "info", "follower", "--format", "json"]);
    let pid = serde_json::from_str::<Value>(info.stdout.trim()).unwrap()["pid"]
        .as_u64()
        .expect("the follower's pid");
    let mark = launch.seen.len();
    assert!(
        Command::new("kill")
            .args(["-KILL", &pid.to_string()])
            .status()
            .unwrap()
            .success()
    );
    launch.expect_since(mark, "with the leader unpaired", PAIRING, |l| {
        l.starts_with("[leader]") && l.contains("unpaired") && l.contains("slot=follower")
    });
    launch.expect_since(mark, "with the follower restarted", PAIRING, |l| {
        l.contains("`follower`") && l.contains("restarting")
    });
    let restarted = launch.seen.len();
    launch.expect_since(
        restarted,
        "with the pair formed again",
        PAIRING,
        leader_paired,
    );
    launch.expect_since(restarted, "with states flowing again", PAIRING, |l| {
        l.starts_with("[leader]") && l.contains("follower at ")
    });
    assert_eq!(launch.stop(), 0);
}

/// `check` lists each side's pairing slot with its peer and role, and
/// `graph` draws the pair, for the example stack and the restarting one.
#[test]
fn check_and_graph_show_the_pair() {
    let dir = tempfile::tempdir().unwrap();
    let ex = examples();
    for launcher in [
        restarting_pair(dir.path()),
        root()
            .join("examples/launchers/paired_joint.json5")
            .to_str()
            .unwrap()
            .to_string(),
    ] {
        let check = inspect(dir.path(), &["check", &launcher, "--repo", &ex]);
        assert_eq!(check.code, 0, "{}", check.stderr);
        let all = format!("{}{}", check.stdout, check.stderr);
        for row in [
            "follower <> follower/leader  (pairing joint_link:v1, plays leader)",
            "leader <> leader/follower  (pairing joint_link:v1, plays follower)",
        ] {
            assert!(all.contains(row), "{launcher}: no `{row}` in\n{all}");
        }
        let graph = inspect(dir.path(), &["graph", &launcher, "--repo", &ex]);
        assert_eq!(graph.code, 0, "{}", graph.stderr);
        assert!(
            graph
                .stdout
                .contains(r#""follower" -> "leader" [label="leader <> follower (joint_link)"]"#),
            "{}",
            graph.stdout
        );
    }
}

/// The example pair across two hosts (network namespaces joined by a veth
/// link), secured: the leader on `rig`, the Python follower on `desk`,
/// placed by name; they pair over TLS and exchange states and setpoints,
/// and nothing is denied.
#[test]
fn the_pair_links_two_hosts_secured() {
    let Some(hosts) = crate::netns::TwoHosts::new() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("placed_pair.json5");
    std::fs::write(
        &launcher,
        r#"{ peppy_schema: "launcher/v1",
            core_nodes: ["lead", "follow"],
            deployments: [
              { source: { name: "joint_leader:v1" }, instances: [
                  { instance_id: "leader", core_node: "lead", links: { follower: "follower" } } ] },
              { source: { name: "py_joint_follower:v1" }, instances: [
                  { instance_id: "follower", core_node: "follow" } ] } ] }"#,
    )
    .unwrap();
    let (launcher, ex) = (launcher.to_str().unwrap(), examples());
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let keys = peppy_launch_with(
        &root(),
        &[
            "keys",
            launcher,
            "--place",
            "lead@rig",
            "--place",
            "follow@desk",
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    assert_eq!(keys.code, 0, "{}", keys.stderr);
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
            "lead@self",
            "--place",
            "follow@desk",
            "--listen",
            &rig_at,
        ],
        &[("PEPPY_STATE_DIR", st)],
    );
    rig.expect("with the leader", BUILD_AND_START, |l| {
        l.contains("core node rig: leader (router on tls/")
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
            "lead@rig",
            "--place",
            "follow@self",
            "--connect",
            &rig_at,
        ],
        &[("PEPPY_STATE_DIR", st_b)],
    );
    desk.expect("with the link over TLS", BUILD_AND_START, |l| {
        l.contains(&format!("linked to {}", rig_at.replace("tcp/", "tls/")))
    });
    desk.expect("with the follower paired across", PAIRING, |l| {
        l.starts_with("[follower]") && l.contains("paired with `leader/follower`")
    });
    rig.expect("with the leader paired across", PAIRING, leader_paired);
    // Messages both ways: the leader hears states answering its setpoints.
    rig.expect("with states answering setpoints", PAIRING, |l| {
        l.starts_with("[leader]")
            && l.contains("follower at ")
            && l.split("setpoint ")
                .nth(1)
                .and_then(|n| n.trim().parse::<u64>().ok())
                .is_some_and(|n| n > 0)
    });
    assert!(
        !rig.seen
            .iter()
            .chain(&desk.seen)
            .any(|l| l.contains("denied:")),
        "a pair's flow was refused:\n{}\n{}",
        rig.seen.join("\n"),
        desk.seen.join("\n")
    );
    assert_eq!(desk.stop(), 0);
    assert_eq!(rig.stop(), 0);
}
