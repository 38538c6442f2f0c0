//! Looking into running example stacks with `node`, `topic`, `service`,
//! `action`, `graph --live`, `ps` and `logs`: real launches, real node
//! processes, the commands run as a user runs them. Each test has its own
//! namespace and launch registry (`PEPPY_STATE_DIR`), so they run in
//! parallel with each other and with the seed tests.

use std::path::Path;
use std::time::Duration;

use serde_json::Value;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{Run, peppy_launch_with, root};

/// Runs an inspection command against the test's registry, giving a busy
/// machine's instances time to answer (discovery ends as soon as every
/// instance of the launch has).
fn inspect(state: &Path, args: &[&str]) -> Run {
    let mut args = args.to_vec();
    if !matches!(args[0], "ps" | "logs") {
        args.extend(["--wait", "10"]);
    }
    peppy_launch_with(&root(), &args, &[("PEPPY_STATE_DIR", state)])
}

/// Runs a command that prints JSON lines; fails with its output otherwise.
fn json_lines(state: &Path, args: &[&str]) -> Vec<Value> {
    let run = inspect(state, args);
    assert_eq!(
        run.code, 0,
        "{args:?} failed:\n{}\n{}",
        run.stdout, run.stderr
    );
    run.stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

fn strings<'a>(values: impl IntoIterator<Item = &'a Value>, field: &str) -> Vec<String> {
    let mut v: Vec<String> = values
        .into_iter()
        .map(|x| x[field].as_str().unwrap_or_default().to_string())
        .collect();
    v.sort();
    v.dedup();
    v
}

/// The multi-camera stack seen from outside: every instance listed, frames
/// decoded per camera, a slot's view, the configured rate, a service
/// answered, the live graph, `ps` and `logs`.
#[test]
fn the_multi_camera_stack_seen_from_outside() {
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let mut launch = Launch::up_with(
        "examples/launchers/multi_camera.json5",
        &["--namespace", "inspect-multi-camera"],
        &[("PEPPY_STATE_DIR", st)],
    );
    launch.expect("with recon_1's summary", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from")
    });

    let list = json_lines(st, &["node", "list", "--format", "json"]);
    let instances = list[0].as_array().unwrap();
    assert_eq!(
        strings(instances, "instance_id"),
        ["recon_1", "rs_left", "rs_right", "zed_overhead"]
    );
    assert!(instances.iter().all(|i| i["pid"].as_u64().unwrap() > 0));
    let human = inspect(st, &["node", "list"]);
    assert!(human.stdout.starts_with("INSTANCE"), "{}", human.stdout);
    assert!(
        human.stdout.contains("realsense_d405:v1"),
        "{}",
        human.stdout
    );

    // Every camera's frames, decoded from the format text alone.
    let frames = json_lines(
        st,
        &[
            "topic",
            "echo",
            "video_stream",
            "--count",
            "120",
            "--timeout",
            "60",
            "--format",
            "json",
        ],
    );
    assert_eq!(
        strings(&frames, "from"),
        ["rs_left", "rs_right", "zed_overhead"]
    );
    let rs = frames.iter().find(|f| f["from"] == "rs_left").unwrap();
    assert_eq!(rs["message"]["width"], 160, "{rs}");
    assert_eq!(rs["message"]["frame"]["len"], 160 * 120, "{rs}");

    // A pinned slot sees only its camera.
    let left = json_lines(
        st,
        &[
            "topic",
            "echo",
            "video_stream",
            "--slot",
            "recon_1.left_cam",
            "--count",
            "5",
            "--timeout",
            "30",
            "--format",
            "json",
        ],
    );
    assert_eq!(strings(&left, "from"), ["rs_left"]);
    let human = inspect(
        st,
        &[
            "topic",
            "echo",
            "video_stream",
            "--from",
            "rs_right",
            "--once",
            "--timeout",
            "30",
        ],
    );
    assert!(
        human
            .stdout
            .starts_with("--- video_stream from rs_right (depth_camera:v1) #1\n"),
        "{}",
        human.stdout
    );
    assert!(
        human.stdout.contains("frame: <19200 bytes: "),
        "{}",
        human.stdout
    );

    // The configured 15 fps, within 10 %, over 6 s of frames.
    let reports = json_lines(
        st,
        &[
            "topic",
            "hz",
            "video_stream",
            "--from",
            "rs_left",
            "--count",
            "6",
            "--format",
            "json",
        ],
    );
    let rate = reports.last().unwrap()["producers"][0]["rate_hz"]
        .as_f64()
        .unwrap_or_else(|| panic!("no rate in the last report: {reports:?}"));
    assert!(
        (13.5..=16.5).contains(&rate),
        "rs_left at {rate} Hz: {reports:?}"
    );

    let info = json_lines(
        st,
        &[
            "service",
            "call",
            "rs_left",
            "video_stream_info",
            "--format",
            "json",
        ],
    );
    assert_eq!(info[0]["response"]["width"], 160, "{info:?}");
    assert_eq!(info[0]["response"]["height"], 120, "{info:?}");

    let unknown = inspect(st, &["topic", "echo", "video_streem"]);
    assert_eq!(unknown.code, 2);
    assert!(
        unknown.stderr.contains("topics: video_stream"),
        "{}",
        unknown.stderr
    );

    // The live graph: every instance and every bound flow.
    let out = tempfile::tempdir().unwrap();
    let html = out.path().join("live.html");
    let graph = inspect(st, &["graph", "--live", "--output", html.to_str().unwrap()]);
    assert_eq!(graph.code, 0, "{}", graph.stderr);
    let page = std::fs::read_to_string(&html).unwrap();
    for id in ["rs_left", "rs_right", "zed_overhead", "recon_1"] {
        assert!(page.contains(id), "{id} missing from the live graph");
    }
    for flow in [
        "left_cam · video_stream",
        "right_cam · video_stream",
        "backup_cams · video_stream",
    ] {
        assert!(page.contains(flow), "{flow} missing from the live graph");
    }
    let dot = inspect(st, &["graph", "--live"]);
    assert!(dot.stdout.starts_with("digraph"), "{}", dot.stdout);
    assert!(
        dot.stdout.contains("\"rs_left\" -> \"recon_1\""),
        "{}",
        dot.stdout
    );

    let ps = json_lines(st, &["ps", "--format", "json"]);
    let launch_record = &ps[0][0];
    assert_eq!(launch_record["namespace"], "inspect-multi-camera");
    assert!(
        launch_record["instances"]
            .as_array()
            .unwrap()
            .iter()
            .all(|i| i["pid"].as_u64().is_some())
    );
    let logs = inspect(st, &["logs", "recon_1", "--count", "1"]);
    assert_eq!(logs.code, 0, "{}", logs.stderr);
    assert_eq!(logs.stdout.lines().count(), 1, "{}", logs.stdout);

    assert_eq!(launch.stop(), 0);
    let after = inspect(st, &["ps"]);
    assert!(
        after.stdout.contains("no launch is running"),
        "{}",
        after.stdout
    );
}

/// The arm alone: `topic pub` drives it (its joint states follow), a wrong
/// field is refused where it is, and `action send-goal` shows feedback and
/// the result.
#[test]
fn driving_the_arm_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("arm.json5");
    std::fs::write(
        &launcher,
        format!(
            r#"{{ peppy_schema: "launcher_v1", deployments: [
                {{ source: {{ local: "{}" }}, instances: [{{ instance_id: "arm" }}] }} ] }}"#,
            root().join("examples/nodes/robot_arm").display()
        ),
    )
    .unwrap();
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let mut launch = Launch::up_with(
        launcher.to_str().unwrap(),
        &["--namespace", "inspect-arm"],
        &[("PEPPY_STATE_DIR", st)],
    );
    launch.expect("with the arm up", BUILD_AND_START, |l| {
        l.starts_with("[arm]") && l.contains("node up")
    });
    let position = |st: &Path| {
        let s = json_lines(
            st,
            &[
                "topic",
                "echo",
                "joint_states",
                "--once",
                "--timeout",
                "20",
                "--format",
                "json",
            ],
        );
        s[0]["message"]["positions"][0].as_f64().unwrap()
    };
    let before = position(st);

    let wrong = inspect(
        st,
        &[
            "topic",
            "pub",
            "joint_commands",
            "{ target_positions: [0.8, 0, 0], max_velocty: 2 }",
        ],
    );
    assert_eq!(wrong.code, 2, "{}", wrong.stderr);
    assert!(
        wrong
            .stderr
            .contains("message:1:34: error: unknown field `max_velocty`"),
        "{}",
        wrong.stderr
    );
    let short = inspect(
        st,
        &[
            "topic",
            "pub",
            "joint_commands",
            "{ target_positions: [0.8, 0], max_velocity: 2 }",
        ],
    );
    assert_eq!(short.code, 2);
    assert!(
        short
            .stderr
            .contains("message:1:21: error: expected exactly 3 items, found 2"),
        "{}",
        short.stderr
    );

    let sent = inspect(
        st,
        &[
            "topic",
            "pub",
            "joint_commands",
            "{ target_positions: [0.8, 0, 0], max_velocity: 2 }",
            "--rate",
            "20",
            "--count",
            "40",
        ],
    );
    assert_eq!(sent.code, 0, "{}", sent.stderr);
    launch.expect("with the command", Duration::from_secs(20), |l| {
        l.starts_with("[arm]") && l.contains("target [0.8, 0.0, 0.0] max 2")
    });
    std::thread::sleep(Duration::from_millis(500));
    let after = position(st);
    assert!(
        after > before + 0.3,
        "the arm moved from {before} to {after}"
    );

    let actions = json_lines(st, &["action", "list", "--format", "json"]);
    assert_eq!(actions[0][0]["instance"], "arm", "{actions:?}");
    assert_eq!(actions[0][0]["action"], "move_arm", "{actions:?}");
    assert_eq!(actions[0][0]["feedback"], "{remaining:f64}", "{actions:?}");
    let services = inspect(st, &["service", "list"]);
    assert!(
        services.stdout.starts_with("no instance serves a service"),
        "{}",
        services.stdout
    );
    let info = inspect(st, &["node", "info", "arm"]);
    assert!(
        info.stdout
            .contains("joint_commands  (external, any owner)"),
        "{}",
        info.stdout
    );

    let goal = json_lines(
        st,
        &[
            "action",
            "send-goal",
            "arm",
            "move_arm",
            "{ target_positions: [0.2, 0, 0], max_velocity: 4 }",
            "--format",
            "json",
        ],
    );
    assert!(
        goal.iter().any(|l| l["feedback"]["remaining"].is_number()),
        "{goal:?}"
    );
    let result = &goal.last().unwrap()["result"];
    assert_eq!(result["reached"], true, "{goal:?}");
    assert!(
        (result["final_positions"][0].as_f64().unwrap() - 0.2).abs() < 1e-6,
        "{goal:?}"
    );

    let rejected = inspect(
        st,
        &[
            "action",
            "send-goal",
            "arm",
            "move_arm",
            "{ target_positions: [0, 0, 0], max_velocity: -1 }",
        ],
    );
    assert_eq!(rejected.code, 1);
    assert!(
        rejected
            .stderr
            .contains("rejected the goal: max_velocity must be positive"),
        "{}",
        rejected.stderr
    );
    assert_eq!(launch.stop(), 0);
}
