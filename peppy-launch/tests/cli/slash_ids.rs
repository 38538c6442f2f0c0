//! The slashed-id spelling (PeppyOS v0.13 on) end to end: a `node/v1` node
//! linked by a `launcher/v1` file to `node_v1` nodes is checked, planned
//! and run like any stack, its slots filled exactly as linked; nodes in
//! PeppyOS's `peppylib` API sync, build and run beside `emit` API ones.

use std::time::Duration;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{peppy_launch, root};

const VIEWER: &str = "examples/launchers/camera_viewer.json5";

#[test]
fn check_prints_the_links_of_a_slashed_launcher_as_planned() {
    let run = peppy_launch(&root(), &["check", VIEWER]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    // A `node/v1` consumer's slots are named as it names them: contracts.
    for expected in [
        "cameras  <- rs_left, rs_right",
        "overhead <- (vacant: no overhead camera on this bench)",
    ] {
        assert!(
            run.stdout
                .lines()
                .any(|l| l.trim_start().starts_with(expected)),
            "no `{expected}` in:\n{}",
            run.stdout
        );
    }
}

#[test]
fn a_slashed_launcher_runs_with_its_slots_as_linked() {
    let mut launch = Launch::up(VIEWER, &[]);
    launch.expect(
        "naming the cameras slot's producers",
        BUILD_AND_START,
        |l| l.starts_with("[viewer]") && l.contains("cameras: linked to rs_left, rs_right"),
    );
    launch.expect(
        "saying the overhead slot is vacant",
        Duration::from_secs(30),
        |l| l.starts_with("[viewer]") && l.contains("overhead: vacant"),
    );
    for camera in ["rs_left (160x120)", "rs_right (64x48)"] {
        launch.expect("with a first frame", Duration::from_secs(30), |l| {
            l.starts_with("[viewer]") && l.contains(&format!("cameras: first frame from {camera}"))
        });
    }
}

#[test]
fn run_takes_link_flags_and_refuses_what_the_links_rules_refuse() {
    // One node started by hand, through the same engine. Keys and
    // vacancies are judged first, and alone: a vacancy on a slot that
    // cannot be empty says only that.
    let vacant = |args: &[&str]| {
        let mut all = vec!["run", "examples/nodes/camera_viewer"];
        all.extend_from_slice(args);
        peppy_launch(&root(), &all)
    };
    let run = vacant(&["--vacant-link", "cameras=none on the bench"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains(
            "slot `cameras` (cardinality one_or_more) cannot be vacant (LinkVacantInvalid)"
        ),
        "{}",
        run.stderr
    );
    assert!(!run.stderr.contains("`overhead`"), "{}", run.stderr);
    // Then what is left out: the optional slot must be linked or vacated.
    let run = vacant(&["--link", "cameras@rs_left"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("slot `overhead`")
            && run
                .stderr
                .contains("is not linked (BindingSlotUnfulfilled)"),
        "{}",
        run.stderr
    );
    assert!(
        run.stderr.contains("--vacant-link 'overhead=<why>'"),
        "{}",
        run.stderr
    );
}

const PEPPYLIB_CAMERA: &str = "examples/nodes/peppylib_camera";

/// `sync` of a node in the `.peppy/libs` layout is deterministic: the
/// example's committed crates are exactly what it writes (so a second run,
/// and this one, write nothing), and cargo then has nothing to rebuild.
#[test]
fn sync_writes_nothing_twice_and_cargo_rebuilds_nothing() {
    let crates = root().join(PEPPYLIB_CAMERA).join(".peppy/libs");
    let before = snapshot(&crates);
    for _ in 0..2 {
        let run = peppy_launch(&root(), &["sync", PEPPYLIB_CAMERA]);
        assert_eq!(run.code, 0, "{}", run.stderr);
        assert!(
            run.stdout.contains("peppylib_camera:v1: ")
                && run.stdout.contains("(0 file(s) changed)"),
            "the committed crates differ from what sync writes (run `peppy-launch sync {PEPPYLIB_CAMERA}` and commit):\n{}",
            run.stdout
        );
    }
    assert_eq!(snapshot(&crates), before, "sync touched a file");
    // Built once (cargo test built it already, or this does), a build after
    // sync finds every unit fresh.
    crate::support::cargo(&["build", "--quiet", "-p", "peppylib_camera"]);
    let out = crate::support::cargo(&["build", "-p", "peppylib_camera", "--message-format=json"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let units: Vec<&str> = stdout
        .lines()
        .filter(|l| l.contains("\"reason\":\"compiler-artifact\""))
        .filter(|l| {
            ["peppygen", "peppylib", "peppylib_camera"]
                .iter()
                .any(|c| l.contains(&format!("\"name\":\"{c}\"")))
        })
        .collect();
    // peppygen, peppylib, and peppylib_camera's library and binary.
    assert_eq!(units.len(), 4, "{stdout}");
    for unit in units {
        assert!(
            unit.contains("\"fresh\":true"),
            "rebuilt after sync: {unit}"
        );
    }
}

/// Every file below `dir` with its modification time and text.
fn snapshot(dir: &std::path::Path) -> Vec<(std::path::PathBuf, std::time::SystemTime, String)> {
    let mut files: Vec<_> = walk(dir)
        .into_iter()
        .map(|p| {
            let modified = std::fs::metadata(&p).and_then(|m| m.modified()).unwrap();
            let text = std::fs::read_to_string(&p).unwrap();
            (p, modified, text)
        })
        .collect();
    files.sort();
    files
}

fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

/// Both node APIs in one stack: the Rust and the Python camera in PeppyOS's
/// `peppylib` API and `.peppy/libs` layout and the RealSense (`node_v1`, the
/// `emit` API) all feed the viewer's held subscription; Ctrl-C runs the
/// cameras' shutdown hooks and every node stops cleanly.
#[test]
fn peppylib_api_nodes_run_beside_an_emit_api_node() {
    let mut launch = Launch::up("examples/launchers/peppylib_stack.json5", &[]);
    launch.expect("from the peppylib camera", BUILD_AND_START, |l| {
        l.starts_with("[peppylib_cam]") && l.contains("peppylib_camera: first frame (96x72)")
    });
    for camera in [
        "peppylib_cam (96x72)",
        "py_cam (64x48)",
        "rs_left (160x120)",
    ] {
        launch.expect("with a first frame", Duration::from_secs(30), |l| {
            l.starts_with("[viewer]") && l.contains(&format!("cameras: first frame from {camera}"))
        });
    }
    let (code, seen) = launch.stop_seen();
    assert_eq!(code, 0, "{}", seen.join("\n"));
    for (instance, hook) in [
        ("[peppylib_cam]", "peppylib_camera: stopping after"),
        ("[py_cam]", "py_peppylib_camera: stopping after"),
    ] {
        assert!(
            seen.iter()
                .any(|l| l.starts_with(instance) && l.contains(hook)),
            "the shutdown hook of {instance} did not run:\n{}",
            seen.join("\n")
        );
    }
}

/// `peppylib_camera` restarted when it fails.
const RESTARTING_CAMERA: &str = r#"{ peppy_schema: "launcher/v1",
    deployments: [
      { source: { name: "peppylib_camera:v1" },
        instances: [{ instance_id: "cam", restart: "on-failure" }] } ] }"#;

/// The datastore lives in the launch, the node's core node: a camera
/// SIGKILLed and restarted under `on-failure` reads back the count of its
/// starts it stored before (`peppylib_camera` counts them there), written by
/// itself.
#[test]
fn a_restarted_node_reads_back_what_it_stored_in_the_datastore() {
    use std::process::Command;

    let dir = tempfile::tempdir().unwrap();
    let launcher = dir.path().join("restarting_camera.json5");
    std::fs::write(&launcher, RESTARTING_CAMERA).unwrap();
    let state = tempfile::tempdir().unwrap();
    let examples = root().join("examples");
    let mut launch = Launch::up_with(
        launcher.to_str().unwrap(),
        &[
            "--repo",
            examples.to_str().unwrap(),
            "--namespace",
            "datastore-restart",
        ],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    launch.expect("with its first start counted", BUILD_AND_START, |l| {
        l == "[cam] peppylib_camera: start 1"
    });
    let info = crate::support::peppy_launch_with(
        &root(),
        &["node", "info", "cam", "--format", "json", "--wait", "10"],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    assert_eq!(info.code, 0, "{}", info.stderr);
    let pid = serde_json::from_str::<serde_json::Value>(info.stdout.trim()).unwrap()["pid"]
        .as_u64()
        .expect("the camera's pid");
    let mark = launch.seen.len();
    assert!(
        Command::new("kill")
            .args(["-KILL", &pid.to_string()])
            .status()
            .unwrap()
            .success()
    );
    launch.expect_since(
        mark,
        "with its second start counted",
        Duration::from_secs(60),
        |l| l == "[cam] peppylib_camera: start 2 (the count was last written by cam)",
    );
    assert_eq!(launch.stop(), 0);
}
