//! One stack over several core nodes: the two-machine example started as
//! two `up --core-node` launches whose routers link, here on loopback
//! (the network-namespace version stands in for two hosts).

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::Stdio;
use std::time::Duration;

use crate::seeds::{BUILD_AND_START, Launch, first_frames};
use crate::support::{peppy_launch, peppy_launch_with, root};

/// A free port below the kernel's ephemeral range (32768 and up), so no
/// other test's `bind(0)` can take it while the launch builds its nodes.
pub(crate) fn free_port() -> u16 {
    use std::sync::atomic::{AtomicU16, Ordering};
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let base = 20_000 + (std::process::id() % 400) as u16 * 25;
    loop {
        let port = base + NEXT.fetch_add(1, Ordering::Relaxed) % 25;
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
}

/// Creates the stack's keys in the registry `state`, as `peppy-launch keys`
/// does on a user's first machine.
pub(crate) fn stack_keys(state: &Path, launcher: &str) {
    let run = peppy_launch_with(&root(), &["keys", launcher], &[("PEPPY_STATE_DIR", state)]);
    assert_eq!(run.code, 0, "{}", run.stderr);
}

/// Cameras on `robot`, the reconstruction on `workstation`: the pinned
/// slots bind across the link, each receiving only its camera, and the
/// from_any slot the ZED; each side names its core node at start. The
/// launcher's robot listens beyond loopback, so the stack is secured: the
/// routers link over mutual TLS with the stack's keys, and a workstation
/// holding another stack's keys is refused.
#[test]
fn the_multi_camera_stack_over_two_core_nodes() {
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let launcher = "examples/launchers/two_machines.json5";
    stack_keys(st, launcher);
    let robot_at = format!("tcp/127.0.0.1:{}", free_port());
    let robot_tls = robot_at.replace("tcp/", "tls/");
    let mut robot = Launch::up_with(
        launcher,
        &["--core-node", "robot", "--listen", &robot_at],
        &[("PEPPY_STATE_DIR", st)],
    );
    robot.expect("with the robot's share", BUILD_AND_START, |l| {
        l.contains(&format!(
            "core node robot: rs_left, rs_right, zed_overhead (router on {robot_tls}, tcp/127.0.0.1:"
        ))
    });

    // Another stack's keys: its certificate is not signed by this stack's
    // authority, and the robot's router refuses the link.
    let other = tempfile::tempdir().unwrap();
    stack_keys(other.path(), launcher);
    let workstation_at = format!("tcp/127.0.0.1:{}", free_port());
    let args = [
        "--core-node",
        "workstation",
        "--listen",
        &workstation_at,
        "--connect",
        &robot_at,
    ];
    let mut stranger = Launch::up_with(launcher, &args, &[("PEPPY_STATE_DIR", other.path())]);
    stranger.expect("with the stranger's share", BUILD_AND_START, |l| {
        l.contains("core node workstation: recon_1")
            && l.contains(&format!("linked to {robot_tls}"))
    });
    stranger.read_for(Duration::from_secs(8));
    robot.read_for(Duration::from_secs(1));
    assert!(
        !stranger
            .seen
            .iter()
            .any(|l| l.contains("core node robot joined") || l.contains("left_cam<-")),
        "a router with another stack's certificate linked:\n{}",
        stranger.seen.join("\n")
    );
    assert!(
        !robot
            .seen
            .iter()
            .any(|l| l.contains("core node workstation joined")),
        "{}",
        robot.seen.join("\n")
    );
    assert_eq!(stranger.stop(), 0);

    let mut workstation = Launch::up_with(launcher, &args, &[("PEPPY_STATE_DIR", st)]);
    workstation.expect("with the workstation's share", BUILD_AND_START, |l| {
        l.contains("core node workstation: recon_1")
            && l.contains(&format!("linked to {robot_tls}"))
    });
    workstation.expect("with the robot joining", Duration::from_secs(30), |l| {
        l.contains("core node robot joined")
    });
    workstation.expect("with recon_1's summary", Duration::from_secs(60), |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from")
    });
    workstation.read_for(Duration::from_secs(1));
    let mut firsts = first_frames(&workstation.seen, "recon_1");
    firsts.sort();
    assert_eq!(
        firsts,
        [
            ("backup_cams".to_string(), "zed_overhead".to_string()),
            ("left_cam".to_string(), "rs_left".to_string()),
            ("right_cam".to_string(), "rs_right".to_string()),
        ],
        "each slot hears exactly its producers across the link"
    );
    assert!(
        !robot.seen.iter().any(|l| l.contains("started `recon_1`")),
        "the robot starts only its share"
    );
    assert!(
        !robot
            .seen
            .iter()
            .chain(&workstation.seen)
            .any(|l| l.contains("denied:")),
        "a bound flow was refused"
    );
    assert_eq!(workstation.stop(), 0);
    assert_eq!(robot.stop(), 0);
}

/// A launcher with core nodes is never started half-decided, and placement
/// shows in `check` and `graph`.
#[test]
fn core_nodes_must_be_chosen_and_show_in_check_and_graph() {
    let launcher = "examples/launchers/two_machines.json5";
    let undecided = peppy_launch(&root(), &["up", launcher, "--no-build"]);
    assert_eq!(undecided.code, 2, "{}", undecided.stderr);
    assert!(
        undecided.stderr.contains("up --core-node NAME") && undecided.stderr.contains("--local"),
        "{}",
        undecided.stderr
    );
    let unknown = peppy_launch(
        &root(),
        &["up", launcher, "--no-build", "--core-node", "lab"],
    );
    assert_eq!(unknown.code, 2);
    assert!(
        unknown
            .stderr
            .contains("the launcher's core nodes are robot, workstation"),
        "{}",
        unknown.stderr
    );

    // A misplaced instance is a located error, and nothing starts on any
    // machine.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join(launcher))
        .unwrap()
        .replace(r#"core_node: "workstation""#, r#"core_node: "workstaton""#)
        .replace(
            "../nodes/",
            &format!("{}/", root().join("examples/nodes").display()),
        );
    let bad = dir.path().join("misplaced.json5");
    std::fs::write(&bad, text).unwrap();
    let repo = root().join("examples");
    for args in [
        vec!["check", bad.to_str().unwrap()],
        vec![
            "up",
            bad.to_str().unwrap(),
            "--core-node",
            "robot",
            "--no-build",
        ],
    ] {
        let run = peppy_launch(
            &root(),
            &[args, vec!["--repo", repo.to_str().unwrap()]].concat(),
        );
        assert_eq!(run.code, 2, "{}", run.stderr);
        assert!(
            run.stderr.contains("misplaced.json5:")
                && run.stderr.contains("instance `recon_1` is placed on core node `workstaton`, which `core_nodes` does not declare (UnknownCoreNode)"),
            "{}",
            run.stderr
        );
        assert!(
            !run.stderr.contains("started `"),
            "nothing starts: {}",
            run.stderr
        );
    }

    let check = peppy_launch(&root(), &["check", launcher]);
    assert_eq!(check.code, 0, "{}", check.stderr);
    assert!(
        check.stdout.contains("robot  (listen tcp/0.0.0.0:7447)"),
        "{}",
        check.stdout
    );
    assert!(check.stdout.contains("on workstation"), "{}", check.stdout);
    let json = peppy_launch(&root(), &["check", launcher, "--format", "json"]);
    let report: serde_json::Value = serde_json::from_str(&json.stdout).unwrap();
    assert_eq!(report["core_nodes"][0]["listen"][0], "tcp/0.0.0.0:7447");
    assert_eq!(report["plan"]["instances"][3]["core_node"], "workstation");
    let graph = peppy_launch(&root(), &["graph", launcher]);
    assert!(
        graph.stdout.contains("subgraph \"cluster_robot\""),
        "{}",
        graph.stdout
    );
}

/// The counts of one `reconstructing from` summary of recon_1, by slot.
fn left_count(line: &str) -> Option<u64> {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix("left_cam<-rs_left:"))
        .and_then(|n| n.parse().ok())
}

/// Two hosts joined by a veth link: the robot's share in one namespace,
/// the workstation's in the other. The pinned slots bind across the link;
/// pulling the link for 5 s is logged as the loss and the return of the
/// other core node on both sides, and frames flow again on every slot with
/// no process restarted.
#[test]
fn a_dropped_link_between_two_hosts_heals_by_itself() {
    let Some(hosts) = crate::netns::TwoHosts::new() else {
        return;
    };
    // Each host its own state directory; the stack's keys made on the
    // robot and copied to the workstation, as a user does.
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let workstation_state = tempfile::tempdir().unwrap();
    let st_b = workstation_state.path();
    let launcher = "examples/launchers/two_machines.json5";
    stack_keys(st, launcher);
    copy_stack_keys(st, st_b);
    let robot_at = format!("tcp/{}:7447", crate::netns::HOST_A);
    let mut robot = Launch::up_in(
        &hosts.on(&hosts.a),
        launcher,
        &["--core-node", "robot", "--listen", &robot_at],
        &[("PEPPY_STATE_DIR", st)],
    );
    robot.expect("with the robot's cameras", BUILD_AND_START, |l| {
        l.contains("started `zed_overhead`")
    });
    let mut workstation = Launch::up_in(
        &hosts.on(&hosts.b),
        launcher,
        &["--core-node", "workstation", "--connect", &robot_at],
        &[("PEPPY_STATE_DIR", st_b)],
    );
    workstation.expect("with the link over TLS", BUILD_AND_START, |l| {
        l.contains(&format!("linked to {}", robot_at.replace("tcp/", "tls/")))
    });
    workstation.expect("with the robot joining", BUILD_AND_START, |l| {
        l.contains("core node robot joined")
    });
    let before = workstation.expect(
        "with frames across the link",
        Duration::from_secs(60),
        |l| l.starts_with("[recon_1]") && left_count(l).is_some_and(|n| n > 0),
    );
    let mut firsts = first_frames(&workstation.seen, "recon_1");
    firsts.sort();
    assert_eq!(
        firsts,
        [
            ("backup_cams".to_string(), "zed_overhead".to_string()),
            ("left_cam".to_string(), "rs_left".to_string()),
            ("right_cam".to_string(), "rs_right".to_string()),
        ],
        "each slot hears exactly its producers across the link"
    );

    // A service on the other side answers across the link (a debug build on
    // a machine busy with the other tests may need more than a few
    // seconds)...
    let call = |timeout: &str| {
        crate::support::peppy_launch_in(
            &hosts.on(&hosts.b),
            &root(),
            &[
                "service",
                "call",
                "rs_left",
                "video_stream_info",
                "--format",
                "json",
                "--timeout",
                timeout,
                "-l",
                launcher,
            ],
            &[("PEPPY_STATE_DIR", st_b)],
        )
    };
    let answered = call("20");
    assert_eq!(answered.code, 0, "{}", answered.stderr);
    assert!(
        answered.stdout.contains(r#""width":160"#),
        "{}",
        answered.stdout
    );

    hosts.link(false);
    workstation.expect("with the loss of the robot", Duration::from_secs(30), |l| {
        l.contains("lost core node robot")
    });
    // The reconstruction's own check of its camera reports it unreachable
    // (not a hang)...
    workstation.expect("with left_cam unreachable", Duration::from_secs(20), |l| {
        l.starts_with("[recon_1]")
            && l.contains("left_cam stream info:")
            && l.contains("unreachable")
    });
    // ...and the command line cannot reach it either, at once.
    let started = std::time::Instant::now();
    let down = call("5");
    assert_eq!(down.code, 2, "{}", down.stderr);
    assert!(
        down.stderr.contains("no instance `rs_left` answers"),
        "{}",
        down.stderr
    );
    assert!(started.elapsed() < Duration::from_secs(10), "no hang");
    std::thread::sleep(Duration::from_secs(5));
    let during = workstation
        .seen
        .iter()
        .rev()
        .find_map(|l| left_count(l))
        .unwrap_or(0);
    hosts.link(true);
    let relinked = workstation.seen.len();
    // Zenoh relinks with a growing back-off: on a busy machine the first
    // retries may fall inside the outage, so the next one can be tens of
    // seconds away.
    // Under a full load (a node's build in another test) a fresh link can
    // flap a while before it holds.
    workstation.expect("with the robot back", Duration::from_secs(180), |l| {
        l.contains("core node robot is back")
    });
    // A busy machine may see the fresh TLS link drop once more before it
    // holds (Zenoh then links again by itself): allow for one more retry.
    workstation.expect("with frames again", Duration::from_secs(60), |l| {
        left_count(l).is_some_and(|n| n > during)
    });
    workstation.expect_since(
        relinked,
        "with left_cam answering again",
        Duration::from_secs(20),
        |l| l.starts_with("[recon_1]") && l.contains("left_cam is rs_left"),
    );
    robot.expect(
        "with the workstation lost and back",
        Duration::from_secs(30),
        |l| l.contains("core node workstation is back"),
    );
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l.contains("lost core node workstation")),
        "the robot logged the loss too"
    );
    for side in [&robot.seen, &workstation.seen] {
        assert!(
            !side
                .iter()
                .any(|l| l.contains("restarting") || l.contains("exited with")),
            "no process restarted:\n{}",
            side.join("\n")
        );
    }
    assert!(left_count(&before).is_some());
    assert_eq!(workstation.stop(), 0);
    assert_eq!(robot.stop(), 0);
}

/// `from_core_node: Some("robot")` keeps frames of the cameras on the
/// machine named `robot`: core nodes are names from the launcher (here all
/// run on this machine with `--local`).
#[test]
fn from_core_node_filters_by_the_core_node_name() {
    let dir = tempfile::tempdir().unwrap();
    let nodes = root().join("examples/nodes");
    let launcher = dir.path().join("placed.json5");
    std::fs::write(
        &launcher,
        format!(
            r#"{{ peppy_schema: "launcher_v1", core_nodes: ["robot", "workstation"],
                deployments: [
                  {{ source: {{ local: "{nodes}/realsense_d405" }}, instances: [
                      {{ instance_id: "cam_robot", core_node: "robot" }},
                      {{ instance_id: "cam_desk", core_node: "workstation" }} ] }},
                  {{ source: {{ local: "{nodes}/camera_mosaic" }}, instances: [
                      {{ instance_id: "robot_only", core_node: "workstation",
                         arguments: {{ only_core_node: "robot" }} }},
                      {{ instance_id: "every_cam", core_node: "workstation" }} ] }} ] }}"#,
            nodes = nodes.display()
        ),
    )
    .unwrap();
    let repo = root().join("examples");
    let mut launch = Launch::up(
        launcher.to_str().unwrap(),
        &["--local", "--repo", repo.to_str().unwrap()],
    );
    launch.expect("with every_cam's mosaic of both", BUILD_AND_START, |l| {
        l.starts_with("[every_cam]") && l.contains("mosaic of 2 tiles")
    });
    launch.expect("with robot_only's mosaic", Duration::from_secs(30), |l| {
        l.starts_with("[robot_only]") && l.contains("mosaic of")
    });
    launch.read_for(Duration::from_secs(2));
    let mosaics: Vec<&String> = launch
        .seen
        .iter()
        .filter(|l| l.starts_with("[robot_only]") && l.contains("mosaic of"))
        .collect();
    assert!(
        mosaics
            .iter()
            .all(|l| l.contains("mosaic of 1 tiles: cam_robot:")),
        "only the robot's camera: {mosaics:?}"
    );
    assert_eq!(launch.stop(), 0);
}

/// A process killed when the test ends, however it ends.
struct Reaped(std::process::Child);

impl Drop for Reaped {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The robot-arm loop split over two hosts that meet at a router of their
/// own (`peppy-launch router`, standing in for `zenohd`) rather than
/// linking directly: the controller homes the arm with its action across
/// the link, then both topic directions flow.
#[test]
fn the_arm_loop_across_two_hosts_through_a_router() {
    let Some(hosts) = crate::netns::TwoHosts::new() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let nodes = root().join("examples/nodes");
    let launcher = dir.path().join("arm_two_hosts.json5");
    std::fs::write(
        &launcher,
        format!(
            r#"{{ peppy_schema: "launcher_v1", core_nodes: ["robot", "workstation"],
                deployments: [
                  {{ source: {{ local: "{nodes}/robot_arm" }}, instances: [
                      {{ instance_id: "arm", core_node: "robot" }} ] }},
                  {{ source: {{ local: "{nodes}/arm_controller" }}, instances: [
                      {{ instance_id: "controller", core_node: "workstation",
                         bindings: {{ robot_arm: "arm" }} }} ] }} ] }}"#,
            nodes = nodes.display()
        ),
    )
    .unwrap();
    let router_at = format!("tcp/{}:7448", crate::netns::HOST_A);
    // Reaped on any failure from here on, which also frees namespace `a`.
    let mut router = Reaped(
        crate::support::peppy_launch_command(&hosts.on(&hosts.a))
            .args(["router", "--listen", &router_at])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let stderr = router.0.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut first = String::new();
        let _ = BufReader::new(stderr).read_line(&mut first);
        let _ = tx.send(first);
    });
    let first = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the router says where it listens");
    assert!(
        first.contains("router") && first.contains(&router_at),
        "{first}"
    );

    let state = tempfile::tempdir().unwrap();
    let env = [("PEPPY_STATE_DIR", state.path())];
    let repo = root().join("examples");
    let (launcher, repo) = (launcher.to_str().unwrap(), repo.to_str().unwrap());
    let mut robot = Launch::up_in(
        &hosts.on(&hosts.a),
        launcher,
        &[
            "--core-node",
            "robot",
            "--connect",
            &router_at,
            "--repo",
            repo,
            // A bare router holds no stack keys to link over TLS with.
            "--insecure",
        ],
        &env,
    );
    let mut workstation = Launch::up_in(
        &hosts.on(&hosts.b),
        launcher,
        &[
            "--core-node",
            "workstation",
            "--connect",
            &router_at,
            "--repo",
            repo,
            // A bare router holds no stack keys to link over TLS with.
            "--insecure",
        ],
        &env,
    );
    workstation.expect("with the arm homed by the action", BUILD_AND_START, |l| {
        l.contains("homed by arm: reached=true")
    });
    workstation.expect(
        "with the controller's 40th cycle",
        Duration::from_secs(60),
        |l| l.starts_with("[controller]") && l.contains("cycle 40:"),
    );
    robot.expect(
        "with the arm's 40th command",
        Duration::from_secs(60),
        |l| l.starts_with("[arm]") && l.contains("command 40 from controller"),
    );
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l.contains("core node workstation joined")),
        "the robot sees the workstation through the router"
    );
    assert_eq!(workstation.stop(), 0);
    assert_eq!(robot.stop(), 0);
}

/// Copies the stacks' keys of one host's state directory to another's, as
/// a user copies them between machines.
pub(crate) fn copy_stack_keys(from: &std::path::Path, to: &std::path::Path) {
    assert!(
        std::process::Command::new("cp")
            .args(["-rp"])
            .arg(from.join("stacks"))
            .arg(to)
            .status()
            .unwrap()
            .success()
    );
}
