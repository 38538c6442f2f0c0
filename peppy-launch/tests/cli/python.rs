//! Python nodes beside Rust ones: the runtime's own tests, and the mixed
//! example stacks under `up` (generated `peppygen`, `uv sync`, `uv run`).

use std::process::Command;
use std::time::Duration;

use crate::seeds::{BUILD_AND_START, Launch, first_frames};
use crate::support::root;

/// `uv` as `up` finds it (on PATH, or installed for peppy on first use).
fn uv() -> std::path::PathBuf {
    peppy_launch::uv().expect("uv")
}

/// The Python runtime's own tests (codec golden bytes, routing, services,
/// actions between Python nodes), run here so they cannot be skipped. Nodes
/// they start by hand ask this build's `peppy-launch plan` for their plans.
#[test]
fn python_runtime_tests_pass() {
    let project = root().join("python/peppy-runtime");
    let out = Command::new(uv())
        .args(["run", "--project"])
        .arg(&project)
        .args(["python", "-m", "unittest", "discover", "-s"])
        .arg(project.join("tests"))
        .env("PEPPY_LAUNCH", env!("CARGO_BIN_EXE_peppy-launch"))
        .current_dir(&project)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "python tests failed:\n{stderr}");
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("Ran ") && !l.starts_with("Ran 0 ")),
        "no python test ran:\n{stderr}"
    );
}

/// A Python camera (conforming to depth_camera:v1) pinned into the
/// reconstruction's right_cam slot: its frames reach that slot and no
/// other, and its service answers a Rust tool.
#[test]
fn a_python_camera_fills_its_pinned_slot_in_a_rust_stack() {
    let mut launch = Launch::up("examples/launchers/mixed_stack.json5", &[]);
    launch.expect("with py_right's frames at recon_1", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("right_cam: first frame from py_right (64x48)")
    });
    launch.expect("with recon_1's summary", Duration::from_secs(30), |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from")
    });
    launch.read_for(Duration::from_secs(2));
    let mut firsts = first_frames(&launch.seen, "recon_1");
    firsts.sort();
    assert_eq!(
        firsts,
        [
            ("backup_cams".to_string(), "zed_overhead".to_string()),
            ("left_cam".to_string(), "rs_left".to_string()),
            ("right_cam".to_string(), "py_right".to_string()),
        ],
        "each slot hears exactly its producers"
    );

    let call = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .args([
            "service",
            "call",
            "py_right",
            "video_stream_info",
            "--launcher",
            "examples/launchers/mixed_stack.json5",
            "--format",
            "json",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&call.stdout);
    assert!(
        call.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&call.stderr)
    );
    let reply: serde_json::Value = serde_json::from_str(stdout.lines().next().unwrap()).unwrap();
    assert_eq!(reply["response"]["width"], 64, "{reply}");
    assert_eq!(reply["response"]["encoding"], "mono8", "{reply}");
    launch.expect(
        "with the python camera's log of the call",
        Duration::from_secs(10),
        |l| l.starts_with("[py_right]") && l.contains("stream info asked by"),
    );
    assert_eq!(launch.stop(), 0);
}

/// The arm loop with a Python controller: it homes the Rust arm through
/// the move_arm action (feedback, then the result) and then drives it
/// through joint_commands, hearing joint_states back.
#[test]
fn a_python_controller_closes_the_rust_arm_loop() {
    let mut launch = Launch::up("examples/launchers/robot_arm_loop_py.json5", &[]);
    launch.expect("with the homing result", BUILD_AND_START, |l| {
        l.starts_with("[py_controller]") && l.contains("homed by arm: reached=True")
    });
    assert!(
        launch
            .seen
            .iter()
            .any(|l| l.starts_with("[py_controller]") && l.contains("rad to go")),
        "no homing feedback:\n{}",
        launch.seen.join("\n")
    );
    launch.expect("with the loop running", Duration::from_secs(30), |l| {
        l.starts_with("[py_controller]") && l.contains("cycle 20: arm at")
    });
    launch.expect(
        "with the arm hearing the python controller",
        Duration::from_secs(10),
        |l| l.starts_with("[arm]") && l.contains("from py_controller"),
    );
    assert_eq!(launch.stop(), 0);
}

/// A Python node emitting `joint_commands` in another format than the Rust
/// arm reads: the arm drops it with the warning two Rust nodes get, naming
/// both formats (the Python node answers for its format's text).
#[test]
fn a_python_emitter_with_another_format_is_dropped_with_the_warning() {
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("py_bad");
    std::fs::create_dir_all(&node).unwrap();
    let runtime = root().join("python/peppy-runtime");
    let doc = serde_json::json!({
        "peppy_schema": "node_v1",
        "manifest": { "name": "py_bad_controller", "tag": "v1" },
        "interfaces": { "topics": { "emits": [{
            "name": "joint_commands",
            "qos_profile": "reliable",
            "message_format": {
                "target_positions": { "$type": "array", "$items": "f32", "$length": 3 },
                "max_velocity": "f64",
            },
        }] } },
        "execution": {
            "language": "python",
            "run_cmd": ["uv", "run", "--quiet", "--project", runtime, "python", "bad.py"],
        },
    });
    std::fs::write(node.join("peppy.json5"), doc.to_string()).unwrap();
    std::fs::write(
        node.join("bad.py"),
        "import asyncio\n\
         from peppygen import NodeBuilder\n\
         from peppygen.emitted_topics import joint_commands\n\n\
         async def send(node_runner):\n\
         \x20   while True:\n\
         \x20       await joint_commands.emit(node_runner, [0.1, 0.2, 0.3], 1.0)\n\
         \x20       await asyncio.sleep(0.05)\n\n\
         async def setup(params, node_runner):\n\
         \x20   return [asyncio.create_task(send(node_runner))]\n\n\
         NodeBuilder().run(setup)\n",
    )
    .unwrap();
    let launcher = dir.path().join("stack.json5");
    let text = serde_json::json!({
        "peppy_schema": "launcher_v1",
        "deployments": [
            { "source": { "local": root().join("examples/nodes/robot_arm") }, "instances": [{ "instance_id": "arm" }] },
            { "source": { "local": node }, "instances": [{ "instance_id": "py_bad" }] },
        ],
    });
    std::fs::write(&launcher, text.to_string()).unwrap();

    let mut launch = Launch::up(launcher.to_str().unwrap(), &[]);
    let warning = launch.expect("with the arm's warning", BUILD_AND_START, |l| {
        l.starts_with("[arm]") && l.contains("dropping topic `joint_commands` from `py_bad`")
    });
    assert!(
        warning.contains("it sends {target_positions:[f32;3],max_velocity:f64}"),
        "the python node's format is named: {warning}"
    );
    assert!(
        warning.contains("this node expects {target_positions:[f64;3],max_velocity:f64}"),
        "{warning}"
    );
    launch.read_for(Duration::from_secs(2));
    assert!(
        !launch
            .seen
            .iter()
            .any(|l| l.contains("command 1 from py_bad")),
        "a mismatched message reached the arm:\n{}",
        launch.seen.join("\n")
    );
    assert_eq!(
        launch
            .seen
            .iter()
            .filter(|l| l.contains("dropping topic `joint_commands`"))
            .count(),
        1,
        "one warning per producer"
    );
    assert_eq!(launch.stop(), 0);
}

/// Seed 002's Python nodes, documents and code as the page prints them
/// (tests/seeds/python): the arm and the controller close the loop once a
/// first command starts it (the page's loop waits for one).
#[test]
fn seed_002_python_loop_runs_as_written() {
    let launcher = "tests/seeds/python/arm_loop.json5";
    let mut launch = Launch::up(launcher, &[]);
    launch.expect("with the controller up", BUILD_AND_START, |l| {
        l.starts_with("[controller]") && l.contains("node up")
    });
    launch.expect("with the arm up", Duration::from_secs(30), |l| {
        l.starts_with("[arm]") && l.contains("node up")
    });
    let kick = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .args([
            "topic",
            "pub",
            "joint_commands",
            "{ target_positions: [0, 0, 0], max_velocity: 1.0 }",
            "--launcher",
            launcher,
        ])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(
        kick.status.success(),
        "{}",
        String::from_utf8_lossy(&kick.stderr)
    );
    for target in ["[0.1, 0.0, 0.0]", "[0.2, 0.0, 0.0]"] {
        launch.expect(
            &format!("with the arm at {target}"),
            Duration::from_secs(30),
            |l| {
                l.starts_with("[arm]")
                    && l.contains(&format!(
                        "received from controller: target={target} max_vel=1.0"
                    ))
            },
        );
    }
    assert_eq!(launch.stop(), 0);
}

/// Seed 000's Python consumer fragment, as printed, keeps state per
/// producer for two Rust cameras under free-form keys.
#[test]
fn seed_000_python_consumer_keys_frames_by_producer() {
    let mut launch = Launch::up("tests/seeds/python/cameras.json5", &[]);
    launch.expect("with frames from both cameras", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from rs_back, rs_front")
    });
    assert_eq!(launch.stop(), 0);
}
