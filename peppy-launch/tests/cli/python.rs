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

/// A Python node in PeppyOS's `peppylib` API and layout
/// (`examples/nodes/py_peppylib_camera`: `node/v1`, `.peppy/libs`,
/// `uv sync --no-editable`, run from its own `.venv`) under `up`: the Rust
/// viewer hears its frames, which the stack clock stamps, and its shutdown
/// hook runs on Ctrl-C before it exits 0.
#[test]
fn a_python_node_in_the_peppylib_api_and_libs_layout_runs_under_up() {
    let mut launch = Launch::up("examples/launchers/py_peppylib_camera.json5", &[]);
    launch.expect("with the viewer hearing py_cam", BUILD_AND_START, |l| {
        l.starts_with("[viewer]") && l.contains("first frame from py_cam")
    });
    let stamped = launch.expect("with a stamped frame", Duration::from_secs(30), |l| {
        l.starts_with("[py_cam] frame ") && l.contains(" stamped ")
    });
    let ns: u64 = stamped
        .split_whitespace()
        .rev()
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("a stamp in ns: {stamped}"));
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    assert!(
        now.abs_diff(ns) < 60_000_000_000,
        "{ns} is the wall clock ({now})"
    );
    let (code, seen) = launch.stop_seen();
    assert_eq!(code, 0, "{}", seen.join("\n"));
    assert!(
        seen.iter()
            .any(|l| l.starts_with("[py_cam] py_peppylib_camera: stopping after")),
        "the shutdown hook ran:\n{}",
        seen.join("\n")
    );
    assert!(
        seen.iter().any(|l| l == "peppy-launch: `py_cam` stopped"),
        "{}",
        seen.join("\n")
    );
}

/// This process's `PATH` without any directory holding a `peppy-launch`.
fn path_without_peppy_launch() -> std::ffi::OsString {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let kept: Vec<_> = std::env::split_paths(&path)
        .filter(|dir| !dir.join("peppy-launch").exists())
        .collect();
    std::env::join_paths(kept).unwrap()
}

/// Every file below `dir`, with its modification time.
fn mtimes(dir: &std::path::Path) -> Vec<(std::path::PathBuf, std::time::SystemTime)> {
    let mut out: Vec<_> = walkdir::WalkDir::new(dir)
        .into_iter()
        .map(Result::unwrap)
        .filter(|e| e.file_type().is_file())
        .map(|e| {
            (
                e.path().to_path_buf(),
                e.metadata().unwrap().modified().unwrap(),
            )
        })
        .collect();
    out.sort();
    out
}

/// The installed copy of `relative` (below site-packages) in `node`'s `.venv`.
fn installed(node: &std::path::Path, relative: &str) -> String {
    let lib = node.join(".venv/lib");
    let python = std::fs::read_dir(&lib)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("python")
        })
        .expect("a python directory in .venv/lib");
    std::fs::read_to_string(python.join("site-packages").join(relative)).unwrap()
}

/// A Python node that runs in a container, with no pyproject.toml
/// (PeppyOS builds it into an image whose definition copies
/// `.peppy/libs/*`), is synced into the `.peppy/libs` layout too.
#[test]
fn a_container_node_is_synced_into_the_libs_layout() {
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("engine");
    std::fs::create_dir_all(&node).unwrap();
    let example = root().join("examples/nodes/py_peppylib_camera/peppy.json5");
    let text = std::fs::read_to_string(example).unwrap();
    let commands = "build_cmd: [\"uv\", \"sync\", \"--no-editable\"],\n    run_cmd: [\"./.venv/bin/python\", \"-m\", \"py_peppylib_camera\"],";
    assert!(text.contains(commands), "{text}");
    let text = text.replace(commands, "container: { def_file: \"apptainer.def\" },");
    std::fs::write(node.join("peppy.json5"), text).unwrap();
    let repo = root().join("examples");
    let run = crate::support::peppy_launch(
        dir.path(),
        &[
            "sync",
            node.to_str().unwrap(),
            "--repo",
            repo.to_str().unwrap(),
        ],
    );
    assert_eq!(run.code, 0, "{}", run.stderr);
    let libs = node.join(".peppy/libs");
    for file in [
        "peppygen/peppygen/__init__.py",
        "peppylib/peppylib/__init__.py",
    ] {
        assert!(libs.join(file).is_file(), "{file}: {}", run.stdout);
    }
    assert!(
        !node.join("peppygen").exists(),
        "nothing beside peppy.json5"
    );
}

/// `sync` on a node whose pyproject.toml takes `peppygen` and `peppylib`
/// from `.peppy/libs`: two projects there (nothing beside peppy.json5), a
/// second `sync` touches no file, `uv sync --no-editable` installs them
/// (`peppylib` re-exporting the one `peppy` runtime), and a change of the
/// documents reaches the installed package at the next `uv sync`.
#[test]
fn sync_writes_the_libs_projects_and_uv_reinstalls_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("cam");
    let example = root().join("examples/nodes/py_peppylib_camera");
    std::fs::create_dir_all(node.join("src/py_peppylib_camera")).unwrap();
    for file in [
        "peppy.json5",
        "pyproject.toml",
        "src/py_peppylib_camera/__init__.py",
        "src/py_peppylib_camera/__main__.py",
    ] {
        std::fs::copy(example.join(file), node.join(file)).unwrap();
    }
    let repo = root().join("examples");
    let sync = || {
        let run = crate::support::peppy_launch(
            dir.path(),
            &[
                "sync",
                node.to_str().unwrap(),
                "--repo",
                repo.to_str().unwrap(),
            ],
        );
        assert_eq!(run.code, 0, "{}", run.stderr);
        run.stdout
    };
    let first = sync();
    assert!(
        first.contains(".peppy/libs (") && !first.contains("(0 file(s)"),
        "{first}"
    );
    assert!(
        !node.join("peppygen").exists(),
        "nothing beside peppy.json5"
    );
    let libs = node.join(".peppy/libs");
    for file in [
        "peppygen/pyproject.toml",
        "peppygen/peppygen/__init__.py",
        "peppygen/peppygen/clock.py",
        "peppygen/peppygen/emitted_topics/camera/video_stream.py",
        "peppylib/pyproject.toml",
        "peppylib/peppylib/__init__.py",
        "peppylib/peppylib/clock.py",
    ] {
        assert!(libs.join(file).is_file(), "{file}");
    }
    let project = std::fs::read_to_string(libs.join("peppygen/pyproject.toml")).unwrap();
    let runtime = std::fs::canonicalize(root().join("python/peppy-runtime")).unwrap();
    assert!(
        project.contains(&format!("\"peppy-runtime @ file://{}\"", runtime.display())),
        "{project}"
    );
    let before = mtimes(&libs);
    let second = sync();
    assert!(second.contains("(0 file(s) changed)"), "{second}");
    assert_eq!(mtimes(&libs), before, "a second sync rewrites nothing");

    let uv_sync = || {
        let out = Command::new(uv())
            .args(["sync", "--no-editable"])
            .current_dir(&node)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    uv_sync();
    let probe = Command::new(node.join(".venv/bin/python"))
        .args([
            "-c",
            "import peppy, peppylib, peppygen\n\
             assert peppylib.clock is peppy.clock and peppylib.CancellationToken is peppy.CancellationToken\n\
             print(peppylib.clock.synchronize.__module__, peppygen.DESCRIPTOR.name)",
        ])
        .current_dir(&node)
        .output()
        .unwrap();
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        "peppy.clock py_peppylib_camera",
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );
    assert!(!installed(&node, "peppygen/parameters.py").contains("gain"));

    let doc = std::fs::read_to_string(node.join("peppy.json5")).unwrap();
    let doc = doc.replace(
        "frames_per_second: { $type: \"u8\", $default: 15 },",
        "frames_per_second: { $type: \"u8\", $default: 15 },\n      gain: { $type: \"u8\", $default: 1 },",
    );
    std::fs::write(node.join("peppy.json5"), doc).unwrap();
    let third = sync();
    assert!(!third.contains("(0 file(s)"), "{third}");
    uv_sync();
    assert!(
        installed(&node, "peppygen/parameters.py").contains("gain"),
        "the regenerated package was reinstalled"
    );
}

/// Every Python example's own tests: `sync` writes its `peppygen` (with
/// the `mock` and `fixtures` packages), then pytest (the project's `dev`
/// group) boots the node's setup through the generated harness, planning
/// with the `peppy-launch` that synced it (neither `PATH` nor
/// `PEPPY_LAUNCH` names one).
#[test]
fn python_examples_pass_their_harness_tests() {
    let repo = root().join("examples");
    for example in [
        "py_arm_controller",
        "py_depth_camera",
        "py_peppylib_camera",
        "py_joint_follower",
    ] {
        let node = repo.join("nodes").join(example);
        let run = crate::support::peppy_launch(
            &root(),
            &[
                "sync",
                node.to_str().unwrap(),
                "--repo",
                repo.to_str().unwrap(),
            ],
        );
        assert_eq!(run.code, 0, "sync {example}: {}", run.stderr);
        let child = Command::new(uv())
            .args([
                "run",
                "--group",
                "dev",
                "pytest",
                "-q",
                "-p",
                "no:cacheprovider",
            ])
            .current_dir(&node)
            // The harness asks `peppy-launch plan` for the node's plan,
            // and finds the one that synced it with nothing set up: not
            // on PATH either.
            .env_remove("PEPPY_LAUNCH")
            .env("PATH", path_without_peppy_launch())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let out = crate::support::wait_bounded(
            child,
            crate::support::COMMAND_BOUND,
            &format!("pytest of {example}"),
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{example}'s tests failed:\n{stdout}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            stdout.contains(" passed") && !stdout.contains(" failed"),
            "{example}: {stdout}"
        );
    }
}

/// The shutdown grace window is read by one rule everywhere: with
/// `PEPPY_SHUTDOWN_GRACE_SECS=7200` in an instance's `env_vars`, the
/// launcher waits for a hook that takes 8 s instead of signalling the node
/// again after its own default, and the node stops cleanly.
#[test]
fn a_long_grace_window_is_waited_for_by_the_launcher() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("grace.json5");
    std::fs::write(
        &launcher,
        r#"{
  peppy_schema: "launcher/v1",
  deployments: [
    {
      source: { name: "py_peppylib_camera", tag: "v1" },
      instances: [{
        instance_id: "slow_cam",
        env_vars: { PEPPY_SHUTDOWN_GRACE_SECS: "7200" },
        arguments: { close_secs: 8.0 },
      }],
    },
  ],
}"#,
    )
    .unwrap();
    let examples = root().join("examples");
    let mut launch = Launch::up(
        launcher.to_str().unwrap(),
        &["--repo", examples.to_str().unwrap()],
    );
    launch.expect("with slow_cam streaming", BUILD_AND_START, |l| {
        l.starts_with("[slow_cam] frame ")
    });
    let stopping = std::time::Instant::now();
    let (code, seen) = launch.stop_seen();
    assert_eq!(code, 0, "{}", seen.join("\n"));
    assert!(
        stopping.elapsed() >= Duration::from_secs(8),
        "the hook's 8 s were waited for"
    );
    assert!(
        seen.iter()
            .any(|l| l.starts_with("[slow_cam] py_peppylib_camera: stopping after")),
        "the hook ran to its end:\n{}",
        seen.join("\n")
    );
    assert!(
        seen.iter().any(|l| l == "peppy-launch: `slow_cam` stopped"),
        "{}",
        seen.join("\n")
    );
}
