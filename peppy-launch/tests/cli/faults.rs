//! Faults a running stack meets and what peppy promises about each
//! (docs/FAULTS.md): a consumer killed outright, a full disk under the
//! logs or a recording, a process out of file descriptors, a flood of
//! bad logins. Real processes, real mounts (a tmpfs in a private mount
//! namespace of `unshare -m`, gone with its last process), real limits
//! (`prlimit`).

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::seeds::{BUILD_AND_START, Launch};
use crate::support::{Run, debian_tool, peppy_launch_in, peppy_launch_with, root};
use crate::up::{alive_in, shell_node};

/// How long a restarted instance, or a stack after a fault, gets to be
/// back at work (a loaded machine of two cores).
const BACK: Duration = Duration::from_secs(60);

fn examples() -> String {
    root().join("examples").to_str().unwrap().to_string()
}

/// `peppy-launch ARGS` against the launch registered in `state`, with time
/// for the instances to answer.
fn inspect(state: &Path, args: &[&str]) -> Run {
    let mut args = args.to_vec();
    if matches!(args[0], "node" | "service") {
        args.extend(["--wait", "10"]);
    }
    peppy_launch_with(&root(), &args, &[("PEPPY_STATE_DIR", state)])
}

/// The process of `instance` in the launch registered in `state`.
fn pid_of(state: &Path, instance: &str) -> u64 {
    let info = inspect(state, &["node", "info", instance, "--format", "json"]);
    assert_eq!(info.code, 0, "{}", info.stderr);
    serde_json::from_str::<Value>(info.stdout.trim()).unwrap()["pid"]
        .as_u64()
        .unwrap_or_else(|| panic!("no pid for {instance}: {}", info.stdout))
}

/// The example camera viewer stack (two RealSense cameras, one viewer) in
/// `dir`; `viewer` is what goes on the viewer's instance (a restart
/// policy), `top` on the launcher (`security: true`).
fn camera_viewer(dir: &Path, top: &str, viewer: &str) -> String {
    let path = dir.join("camera_viewer.json5");
    std::fs::write(
        &path,
        format!(
            r#"{{ peppy_schema: "launcher/v1", {top}
                deployments: [
                  {{ source: {{ name: "realsense_d405", tag: "v1" }}, instances: [
                      {{ instance_id: "rs_left" }},
                      {{ instance_id: "rs_right", arguments: {{ width: 64, height: 48 }} }} ] }},
                  {{ source: {{ name: "camera_viewer:v1" }}, instances: [
                      {{ instance_id: "viewer", {viewer}
                         links: {{ cameras: ["rs_left", "rs_right"], overhead: {{ vacant: "none here" }} }} }} ] }} ] }}"#
        ),
    )
    .unwrap();
    path.to_str().unwrap().to_string()
}

/// Whether `l` is the viewer's first frame from `camera`.
fn first_frame_from(l: &str, camera: &str) -> bool {
    l.starts_with("[viewer]") && l.contains(&format!("first frame from {camera} ("))
}

/// The camera viewer stack of [`camera_viewer`] up, in its own registry
/// (`state`) and namespace, once the viewer has frames from both cameras.
fn viewer_stack(dir: &Path, state: &Path, namespace: &str, top: &str, viewer: &str) -> Launch {
    let launcher = camera_viewer(dir, top, viewer);
    let mut launch = Launch::up_with(
        &launcher,
        &["--repo", &examples(), "--namespace", namespace],
        &[("PEPPY_STATE_DIR", state)],
    );
    for camera in ["rs_left", "rs_right"] {
        launch.expect(
            &format!("with the viewer's first frame from {camera}"),
            BUILD_AND_START,
            |l| first_frame_from(l, camera),
        );
    }
    launch
}

/// A consumer killed outright (SIGKILL, as the OOM killer does) under
/// `restart: "on-failure"`: the launch says it was killed by signal 9 and
/// restarts it under its instance id; the new process receives frames
/// from both cameras again. The cameras are not touched (same processes,
/// never restarted), and Ctrl-C then stops the launch cleanly (exit 0).
#[test]
fn a_killed_consumer_is_restarted_and_consumes_again() {
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let mut launch = viewer_stack(
        dir.path(),
        st,
        "faults-killed-consumer",
        "",
        r#"restart: "on-failure","#,
    );
    let cameras = [pid_of(st, "rs_left"), pid_of(st, "rs_right")];
    let viewer = pid_of(st, "viewer");
    let mark = launch.seen.len();
    assert!(
        Command::new("kill")
            .args(["-KILL", &viewer.to_string()])
            .status()
            .unwrap()
            .success()
    );
    launch.expect_since(mark, "saying the viewer was killed", BACK, |l| {
        l.contains("`viewer` killed by signal 9; restarting")
    });
    for camera in ["rs_left", "rs_right"] {
        launch.expect_since(
            mark,
            &format!("with the restarted viewer's first frame from {camera}"),
            BACK,
            |l| first_frame_from(l, camera),
        );
    }
    let restarted = pid_of(st, "viewer");
    assert_ne!(restarted, viewer, "a new process");
    assert_eq!(
        [pid_of(st, "rs_left"), pid_of(st, "rs_right")],
        cameras,
        "the cameras run on in the same processes"
    );
    let (code, lines) = launch.stop_seen();
    let all = lines.join("\n");
    assert_eq!(code, 0, "{all}");
    for camera in ["rs_left", "rs_right"] {
        assert!(
            !lines
                .iter()
                .any(|l| l.contains(&format!("`{camera}`")) && l.contains("restarting")),
            "{camera} was restarted:\n{all}"
        );
    }
}

/// The command prefix that runs a program with a fresh tmpfs of `options`
/// mounted on `dir`, in a mount namespace of its own: the mount is seen by
/// that program and its children only, and goes with the last of them,
/// however the test ends. It execs the program, so signals reach it.
fn on_tmpfs(dir: &Path, options: &str, then: &str) -> Vec<String> {
    vec![
        "unshare".into(),
        "-m".into(),
        "sh".into(),
        "-c".into(),
        format!(r#"mount -t tmpfs -o {options} tmpfs "$1" && {then} shift && exec "$@""#),
        "sh".into(),
        dir.to_str().unwrap().into(),
    ]
}

/// Whether this machine can run [`on_tmpfs`] (the tools are there); said
/// loudly when not, a failure in CI.
fn can_mount() -> bool {
    debian_tool("unshare", "util-linux").is_some() && debian_tool("mount", "mount").is_some()
}

/// No mount of a test is seen outside its namespace.
fn assert_not_mounted(dir: &Path) {
    let mounts = std::fs::read_to_string("/proc/self/mountinfo").unwrap();
    let dir = dir.to_str().unwrap();
    assert!(
        !mounts.lines().any(|l| l.contains(dir)),
        "{dir} is mounted here:\n{mounts}"
    );
}

/// A node floods its log until the disk under the run directory (a tmpfs
/// of 256 KiB) is full. The node runs on, every line of it still reaches
/// the launch's output in order, the launch says once that the log
/// cannot be written and why, and Ctrl-C stops everything cleanly (exit 0).
#[test]
fn a_full_disk_for_logs_keeps_the_stack_running() {
    if !can_mount() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    // 20 000 lines of 60 bytes: more than 1 MB for a disk of 256 KiB.
    shell_node(
        dir.path(),
        "flood",
        "i=0; while [ $i -lt 20000 ]; do echo \"line $i 0123456789abcdef0123456789abcdef0123456789\"; i=$((i+1)); done; n=0; while true; do n=$((n+1)); echo beat $n; sleep 0.2; done",
    );
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher_v1", deployments: [
            { source: { local: "flood" }, instances: [{ instance_id: "flood" }] } ] }"#,
    )
    .unwrap();
    let runs = dir.path().join(".peppy");
    std::fs::create_dir(&runs).unwrap();
    let wrapper = on_tmpfs(&runs, "size=256k", "");
    let wrapper: Vec<&str> = wrapper.iter().map(String::as_str).collect();
    let launcher = dir.path().join("stack.json5");
    let mut launch = Launch::up_in(
        &wrapper,
        launcher.to_str().unwrap(),
        &["--namespace", "faults-full-log-disk"],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    let said = launch.expect("saying the log is not written", BACK, |l| {
        l.contains("cannot write the log of `flood`")
    });
    assert!(
        said.contains(&format!("{}/", runs.canonicalize().unwrap().display()))
            && said.contains("flood.log")
            && said.contains("No space left on device"),
        "{said}"
    );
    let first = launch.expect("with the node beating after its flood", BACK, |l| {
        l.starts_with("[flood] beat ")
    });
    let beat = |l: &str| {
        l.strip_prefix("[flood] beat ")
            .and_then(|n| n.trim().parse::<u32>().ok())
    };
    let first = beat(&first).unwrap();
    launch.expect("with the node still beating", BACK, |l| {
        beat(l).is_some_and(|n| n >= first + 3)
    });
    let flood: Vec<&String> = launch
        .seen
        .iter()
        .filter(|l| l.starts_with("[flood] line "))
        .collect();
    assert_eq!(flood.len(), 20_000, "every line reached the output");
    assert!(
        flood
            .iter()
            .enumerate()
            .all(|(i, l)| l.starts_with(&format!("[flood] line {i} "))),
        "in order"
    );
    let notes = launch
        .seen
        .iter()
        .filter(|l| l.contains("cannot write the log of"))
        .count();
    assert_eq!(notes, 1, "said once, not at every line");
    let (code, lines) = launch.stop_seen();
    assert_eq!(code, 0, "{}", lines.join("\n"));
    assert!(!lines.iter().any(|l| l.contains("panicked")));
    assert_not_mounted(&runs);
}

/// A stack of one shell node, `marker`, running `script` (which touches
/// `marker/ran`), in a fresh directory: the directory, a state directory,
/// and the run directory (`.peppy`) made for a test's tmpfs.
fn marker_stack(script: &str) -> (tempfile::TempDir, tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "marker", script);
    std::fs::write(
        dir.path().join("stack.json5"),
        r#"{ peppy_schema: "launcher_v1", deployments: [
            { source: { local: "marker" }, instances: [{ instance_id: "marker" }] } ] }"#,
    )
    .unwrap();
    let runs = dir.path().join(".peppy");
    std::fs::create_dir(&runs).unwrap();
    (dir, state, runs)
}

/// A launch whose run directory is on a disk full before it starts
/// starts nothing: it fails (exit 1) naming the file it could not write
/// and the reason, and the node never runs.
#[test]
fn a_launch_on_a_full_disk_starts_nothing_and_says_why() {
    if !can_mount() {
        return;
    }
    let (dir, state, runs) = marker_stack("touch ran; exec sleep 1000");
    // Filled to the last byte before the launch starts (the filling
    // itself fails with ENOSPC, as it should).
    let wrapper = on_tmpfs(
        &runs,
        "size=64k",
        r#"{ head -c 1000000 /dev/zero > "$1/fill" 2>/dev/null; true; } &&"#,
    );
    let wrapper: Vec<&str> = wrapper.iter().map(String::as_str).collect();
    let run = peppy_launch_in(
        &wrapper,
        dir.path(),
        &["up", "stack.json5", "--namespace", "faults-full-disk"],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    assert_eq!(run.code, 1, "{}", run.stderr);
    assert!(
        run.stderr
            .lines()
            .any(|l| l.contains("cannot write ")
                && l.contains("/marker.json: No space left on device")),
        "{}",
        run.stderr
    );
    assert!(!run.stderr.contains("started `marker`"), "{}", run.stderr);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(!dir.path().join("marker/ran").exists(), "the node ran");
    assert_not_mounted(&runs);
}

/// However few files the disk under the run directory can hold (a tmpfs
/// of 2 to 7 inodes: not the run directory, not the runtime config, not
/// the log, ...), an instance whose start is reported as failed never ran,
/// and one that ran was reported started. (The log used to be opened
/// after the process started: a log that could not be created left the
/// process running, unsupervised, though its start was reported failed.)
#[test]
fn an_instance_whose_log_cannot_be_created_never_runs() {
    if !can_mount() {
        return;
    }
    let (dir, state, runs) = marker_stack("touch ran");
    let ran = dir.path().join("marker/ran");
    let mut log_refused = false;
    for inodes in 2..=7 {
        let _ = std::fs::remove_file(&ran);
        let wrapper = on_tmpfs(&runs, &format!("size=1m,nr_inodes={inodes}"), "");
        let wrapper: Vec<&str> = wrapper.iter().map(String::as_str).collect();
        let run = peppy_launch_in(
            &wrapper,
            dir.path(),
            &["up", "stack.json5", "--namespace", "faults-no-inodes"],
            &[("PEPPY_STATE_DIR", state.path())],
        );
        let why = format!("{inodes} inodes: {}", run.stderr);
        assert!(!run.stderr.contains("panicked"), "{why}");
        match run.code {
            0 => {
                assert!(ran.exists(), "{why}");
                assert!(run.stderr.contains("started `marker`"), "{why}");
            }
            1 => {
                assert!(
                    !ran.exists(),
                    "the node ran though it failed to start; {why}"
                );
                assert!(run.stderr.contains("No space left on device"), "{why}");
                log_refused |= run.stderr.contains(
                    "instance `marker` failed to start: cannot open its log: No space left on device",
                );
            }
            code => panic!("exit code {code}; {why}"),
        }
    }
    assert!(log_refused, "no inode count left the log alone uncreatable");
    assert_not_mounted(&runs);
}

/// A recording on a full disk: `-o /dev/full` fails at once, and a file on
/// a disk that fills while the stack is recorded (a tmpfs of 32 KiB) ends
/// the recording (exit 1) within a bounded time, saying `No space left on
/// device` and naming the file, without a panic. `--max-size` stops a
/// recording once its file reaches the size, cleanly (exit 0), and the
/// file replays.
#[test]
fn record_on_a_full_disk_stops_with_the_reason() {
    if !can_mount() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let stack = viewer_stack(dir.path(), st, "faults-record-full", "", "");
    let record = |wrapper: &[&str], args: &[&str]| {
        let mut all = vec!["record", "--wait", "10"];
        all.extend_from_slice(args);
        let started = Instant::now();
        let run = peppy_launch_in(wrapper, &root(), &all, &[("PEPPY_STATE_DIR", st)]);
        assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
        (run, started.elapsed())
    };

    let (full, _) = record(&[], &["-o", "/dev/full", "--force"]);
    assert_eq!(full.code, 1, "{}", full.stderr);
    assert!(
        full.stderr
            .contains("writing /dev/full failed: No space left on device"),
        "{}",
        full.stderr
    );

    let small = dir.path().join("small");
    std::fs::create_dir(&small).unwrap();
    let file = small.join("cameras.mcap");
    let wrapper = on_tmpfs(&small, "size=32k", "");
    let wrapper: Vec<&str> = wrapper.iter().map(String::as_str).collect();
    let (filled, took) = record(&wrapper, &["-o", file.to_str().unwrap()]);
    assert_eq!(filled.code, 1, "{}", filled.stderr);
    assert!(
        filled.stderr.contains(&format!(
            "writing {} failed: No space left on device",
            file.display()
        )),
        "{}",
        filled.stderr
    );
    assert!(
        filled.stderr.contains("stopped: the writer stopped"),
        "{}",
        filled.stderr
    );
    // The stack was being recorded when the disk filled.
    assert!(
        filled.stderr.contains("/rs_left/video_stream "),
        "{}",
        filled.stderr
    );
    // The disk fills in seconds; the limit is for a loaded machine.
    assert!(took < Duration::from_secs(120), "took {took:?}");
    assert_not_mounted(&small);

    let capped = dir.path().join("capped.mcap");
    let (run, _) = record(&[], &["-o", capped.to_str().unwrap(), "--max-size", "16K"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(
        run.stderr.contains("stopped: the file reached --max-size"),
        "{}",
        run.stderr
    );
    let size = std::fs::metadata(&capped).unwrap().len();
    assert!(size >= 16 * 1024, "{size} bytes");
    let recorded = count_after(&run.stderr, "recorded ");
    assert!(recorded > 0, "{}", run.stderr);
    assert_eq!(stack.stop(), 0);

    // Into a bare Zenoh peer standing in for a stack: every message the
    // recorder counted is in the file and published.
    let port = crate::machines::free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let (_rt, _peer) = crate::recording::bare_stack(&endpoint);
    let replayed = peppy_launch_with(
        dir.path(),
        &[
            "replay",
            capped.to_str().unwrap(),
            "--connect",
            &endpoint,
            "--namespace",
            "faults-replay-capped",
            "--wait",
            "1",
        ],
        &[("PEPPY_STATE_DIR", dir.path())],
    );
    assert_eq!(replayed.code, 0, "{}", replayed.stderr);
    assert!(
        !replayed.stderr.contains("ends early"),
        "{}",
        replayed.stderr
    );
    assert_eq!(
        count_after(&replayed.stderr, "replayed "),
        recorded,
        "{}",
        replayed.stderr
    );
}

/// N of the `<word>N messages` line of `stderr` (`recorded `, `replayed `).
fn count_after(stderr: &str, word: &str) -> u64 {
    stderr
        .lines()
        .find_map(|l| l.strip_prefix(word)?.split_once(" messages"))
        .and_then(|(n, _)| n.parse().ok())
        .unwrap_or_else(|| panic!("no `{word}N messages` line in:\n{stderr}"))
}

/// `up` in a process allowed 128 open files, with 60 instances to start
/// (each holds four: its log, two pipes, a pidfd): the launch itself
/// starts, starts instances until the limit, then fails (exit 1, an
/// instance failed) naming the instance it could not start and `Too many
/// open files`, and stops every instance it had started. No panic.
#[test]
fn too_many_open_files_is_a_located_start_failure() {
    if debian_tool("prlimit", "util-linux").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "idle", "exec sleep 1000");
    let instances: Vec<Value> = (0..60)
        .map(|i| serde_json::json!({ "instance_id": format!("n{i:02}") }))
        .collect();
    let doc = serde_json::json!({
        "peppy_schema": "launcher_v1",
        "deployments": [{ "source": { "local": "idle" }, "instances": instances }],
    });
    std::fs::write(dir.path().join("stack.json5"), doc.to_string()).unwrap();
    let run = peppy_launch_in(
        &["prlimit", "--nofile=128:128", "--"],
        dir.path(),
        &["up", "stack.json5", "--namespace", "faults-nofile"],
        &[("PEPPY_STATE_DIR", state.path())],
    );
    let err = &run.stderr;
    assert_eq!(run.code, 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // `started `nXX` (idle:v1) as pid P`, in start order.
    let started: Vec<(String, String)> = err
        .lines()
        .filter_map(|l| l.strip_prefix("peppy-launch: started `"))
        .filter_map(|l| {
            let (id, rest) = l.split_once('`')?;
            Some((id.to_string(), rest.rsplit_once("as pid ")?.1.to_string()))
        })
        .collect();
    assert!(
        !started.is_empty() && started.len() < 60,
        "the launch starts, and runs out while starting instances: {err}"
    );
    let next = format!("n{:02}", started.len());
    let failure = err
        .lines()
        .find(|l| l.contains("Too many open files"))
        .unwrap_or_else(|| panic!("{err}"));
    // Its runtime config, its log or its process: whichever ran out, the
    // instance is named.
    assert!(
        failure.contains(&format!("`{next}`")) || failure.contains(&format!("/{next}.json")),
        "the failure names {next}: {err}"
    );
    assert!(
        err.contains("stopping the instances already started"),
        "{err}"
    );
    let idle = dir.path().join("idle");
    for (id, pid) in &started {
        assert!(err.contains(&format!("`{id}` stopped")), "{id}: {err}");
        // Its group is killed once it is stopped; the kernel may take a
        // moment to finish it on a loaded machine.
        let deadline = Instant::now() + Duration::from_secs(10);
        while alive_in(pid, &idle) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(!alive_in(pid, &idle), "{id} (pid {pid}) is still running");
    }
}

/// The number of open file descriptors of process `pid`.
fn open_files(pid: u64) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .count()
}

/// 200 connection attempts at a secured stack's router at once, none with
/// a valid login: 100 zenoh clients presenting an instance's user with a
/// wrong password, 50 an unknown user, 25 raw connections sending garbage
/// and 25 sending nothing. Every login is refused, the router drops every
/// raw connection itself, the launcher's open files come back to what
/// they were (nothing leaks), and the stack still serves: rs_left answers
/// its service and the viewer still receives frames.
#[test]
fn a_flood_of_bad_logins_leaves_a_secured_stack_serving() {
    let dir = tempfile::tempdir().unwrap();
    let state = tempfile::tempdir().unwrap();
    let st = state.path();
    let mut launch = viewer_stack(dir.path(), st, "faults-bad-logins", "security: true,", "");
    let record = crate::security::record(st);
    let launcher_pid = record["pid"].as_u64().unwrap();
    let endpoint = record["connect"][0].as_str().unwrap().to_string();
    let address = endpoint
        .strip_prefix("tcp/")
        .unwrap_or_else(|| panic!("a TCP endpoint: {endpoint}"))
        .to_string();
    let (user, _) = crate::security::login_of(&record, "rs_left");
    // Counted once the stack has settled after its start.
    launch.read_for(Duration::from_secs(2));
    let before = open_files(launcher_pid);

    let rt = crate::security::runtime();
    let (refused, dropped) = rt.block_on(async {
        use tokio::io::{AsyncReadExt as _, AsyncWriteExt as _};
        let mut logins = tokio::task::JoinSet::new();
        for i in 0..150 {
            let (endpoint, user) = (endpoint.clone(), user.clone());
            logins.spawn(async move {
                let user = if i < 100 {
                    user
                } else {
                    format!("intruder{i}")
                };
                match crate::security::attacker(&endpoint, Some((&user, "not-the-password"))).await
                {
                    Ok(session) => {
                        let _ = session.close().await;
                        false
                    }
                    Err(_) => true,
                }
            });
        }
        let mut raw = tokio::task::JoinSet::new();
        for i in 0..50 {
            let address = address.clone();
            raw.spawn(async move {
                let mut stream = tokio::net::TcpStream::connect(&address).await.ok()?;
                if i % 2 == 0 {
                    let garbage: Vec<u8> = (0..300u32).map(|b| (b * 7 + i) as u8).collect();
                    let _ = stream.write_all(&garbage).await;
                }
                // Until the router hangs up: it must not hold a connection
                // that never logs in.
                let mut buf = [0u8; 4096];
                loop {
                    match stream.read(&mut buf).await {
                        Ok(0) | Err(_) => return Some(()),
                        Ok(_) => {}
                    }
                }
            });
        }
        let bound = Duration::from_secs(60);
        let logins = tokio::time::timeout(bound, logins.join_all())
            .await
            .expect("the logins were answered within 60 s");
        let raw = tokio::time::timeout(bound, raw.join_all())
            .await
            .expect("the router hung up on every raw connection within 60 s");
        (
            logins.iter().filter(|r| **r).count(),
            raw.iter().filter(|r| r.is_some()).count(),
        )
    });
    assert_eq!(refused, 150, "every bad login is refused");
    assert_eq!(dropped, 50, "every raw connection was made and dropped");
    let mark = launch.seen.len();

    // The launch's descriptors come back once the router has let go of
    // every attempt (a few may be in use for other reasons at any moment).
    let deadline = Instant::now() + BACK;
    let mut now = open_files(launcher_pid);
    while now > before + 8 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(200));
        now = open_files(launcher_pid);
    }
    assert!(
        now <= before + 8,
        "the launcher holds {now} files, {before} before the flood"
    );

    let info = inspect(
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
    assert_eq!(info.code, 0, "{}", info.stderr);
    assert!(info.stdout.contains(r#""width":160"#), "{}", info.stdout);
    launch.expect_since(mark, "with the viewer still receiving", BACK, |l| {
        l.starts_with("[viewer]") && l.contains("viewing rs_left:")
    });
    let (code, lines) = launch.stop_seen();
    assert_eq!(code, 0, "{}", lines.join("\n"));
    assert!(!lines.iter().any(|l| l.contains("panicked")));
}

/// docs/FAULTS.md promises what peppy survives and names the test that
/// shows each promise: at least 26 scenarios, and every test it names
/// exists where its prefix says (a renamed or removed test would leave a
/// promise nobody checks).
#[test]
fn the_fault_catalogue_names_only_tests_that_exist() {
    let repo = root();
    let catalogue = std::fs::read_to_string(repo.join("docs/FAULTS.md")).unwrap();
    let scenarios = catalogue.lines().filter(|l| l.starts_with("### ")).count();
    assert!(scenarios >= 26, "{scenarios} scenarios");
    let mut named = 0;
    let prefixes = ["`cli::", "`runtime::", "`schema::", "`e2e::", "`unit: "];
    let quoted = catalogue.match_indices('`').filter_map(|(at, _)| {
        let rest = &catalogue[at..];
        prefixes.iter().any(|p| rest.starts_with(p)).then(|| {
            let rest = &rest[1..];
            &rest[..rest.find('`').unwrap_or(rest.len())]
        })
    });
    // The legend's bare prefixes (`cli::`) name no test.
    for quoted in quoted.filter(|q| !q.ends_with("::")) {
        let (file, name) = if let Some(rest) = quoted.strip_prefix("unit: ") {
            let Some((path, name)) = rest.rsplit_once("::") else {
                panic!("`{quoted}`: a unit test is `unit: path::name`");
            };
            (repo.join(path), name)
        } else {
            let parts: Vec<&str> = quoted.split("::").collect();
            let dir = match parts.first() {
                Some(&"cli") => "peppy-launch/tests/cli",
                Some(&"runtime") => "peppy-runtime/tests/runtime",
                Some(&"schema") => "peppy-schema/tests/schema",
                _ => "tests/e2e",
            };
            let [_, module, name] = parts[..] else {
                panic!("`{quoted}`: a test is `prefix::module::name`");
            };
            (repo.join(dir).join(format!("{module}.rs")), name)
        };
        let text = std::fs::read_to_string(&file)
            .unwrap_or_else(|e| panic!("`{quoted}`: {}: {e}", file.display()));
        assert!(
            text.contains(&format!("fn {name}(")),
            "docs/FAULTS.md names `{quoted}`, which {} does not hold",
            file.display()
        );
        named += 1;
    }
    assert!(
        named >= scenarios,
        "{named} tests named for {scenarios} scenarios"
    );
}
