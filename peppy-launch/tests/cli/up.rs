//! `peppy-launch up` with real child processes: shell nodes that behave and
//! misbehave (ignore signals, crash, spawn grandchildren, flood stdout).

use std::io::Read;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A node directory whose `run_cmd` is `sh -c script`.
pub(crate) fn shell_node(dir: &Path, name: &str, script: &str) {
    std::fs::create_dir_all(dir.join(name)).unwrap();
    let doc = serde_json::json!({
        "peppy_schema": "node_v1",
        "manifest": { "name": name, "tag": "v1" },
        "execution": { "language": "shell", "run_cmd": ["sh", "-c", script] },
    });
    std::fs::write(dir.join(name).join("peppy.json5"), doc.to_string()).unwrap();
}

fn launcher(dir: &Path, deployments: &[(&str, &str, &str)]) {
    let deployments: Vec<serde_json::Value> = deployments
        .iter()
        .map(|(node, id, restart)| {
            serde_json::json!({ "source": { "local": node }, "instances": [{ "instance_id": id, "restart": restart }] })
        })
        .collect();
    let doc = serde_json::json!({ "peppy_schema": "launcher_v1", "deployments": deployments });
    std::fs::write(dir.join("stack.json5"), doc.to_string()).unwrap();
}

fn launch(dir: &Path, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .arg("stack.json5")
        .args(extra)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_REPOSITORIES")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn wait_for_file(path: &Path, within: Duration) -> String {
    let deadline = Instant::now() + within;
    loop {
        if let Ok(s) = std::fs::read_to_string(path)
            && !s.trim().is_empty()
        {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "{} did not appear within {within:?}",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn alive(pid: &str) -> bool {
    Path::new(&format!("/proc/{}", pid.trim())).exists() && {
        // A zombie is dead for our purposes only once reaped; check its state.
        let stat =
            std::fs::read_to_string(format!("/proc/{}/stat", pid.trim())).unwrap_or_default();
        stat.split_whitespace().nth(2).is_none_or(|s| s != "Z")
    }
}

/// Whether process `pid` is alive and still the one that ran in `dir`: the
/// machine's pids wrap (32768 here), and a busy test run may hand a dead
/// instance's pid to another process at once.
pub(crate) fn alive_in(pid: &str, dir: &Path) -> bool {
    alive(pid)
        && std::fs::read_link(format!("/proc/{}/cwd", pid.trim()))
            .is_ok_and(|cwd| cwd == dir || cwd.canonicalize().ok() == dir.canonicalize().ok())
}

fn interrupt(child: &Child) {
    assert!(
        Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
}

/// Waits for the launcher to exit; returns its exit code, stderr, and how long it took.
fn finish(mut child: Child, within: Duration) -> (i32, String, Duration) {
    let start = Instant::now();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > within {
            let _ = child.kill();
            panic!("peppy-launch did not exit within {within:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (
        status.code().unwrap_or(-1),
        reader.join().unwrap(),
        start.elapsed(),
    )
}

#[test]
fn an_invalid_launcher_starts_nothing() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "marker", "touch started; sleep 60");
    let doc = r#"{ peppy_schema: "launcher_v1", deployments: [
        { source: { local: "marker" }, instances: [{ instance_id: "m", bindings: { nope: "ghost" } }] } ] }"#;
    std::fs::write(dir.path().join("stack.json5"), doc).unwrap();
    let (code, stderr, _) = finish(launch(dir.path(), &[]), Duration::from_secs(20));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("UnknownBindingTarget"), "{stderr}");
    assert!(stderr.contains("nothing was built or started"));
    std::thread::sleep(Duration::from_millis(200));
    assert!(
        !dir.path().join("marker/started").exists(),
        "no instance may start"
    );
    assert!(
        !dir.path().join(".peppy").exists(),
        "no run directory either"
    );
}

#[test]
fn ctrl_c_stops_everything_even_a_node_that_ignores_signals() {
    let dir = tempfile::tempdir().unwrap();
    // Writes its own pid and a grandchild's, then ignores SIGINT and SIGTERM.
    shell_node(
        dir.path(),
        "stubborn",
        "trap '' INT TERM; sleep 1000 & echo $! > grandchild.pid; echo $$ > pid; while true; do sleep 1; done",
    );
    shell_node(dir.path(), "polite", "echo $$ > pid; exec sleep 1000");
    launcher(
        dir.path(),
        &[("stubborn", "stubborn", "no"), ("polite", "polite", "no")],
    );
    let child = launch(dir.path(), &["--grace", "1"]);
    let pid = wait_for_file(&dir.path().join("stubborn/pid"), Duration::from_secs(20));
    let grandchild = wait_for_file(
        &dir.path().join("stubborn/grandchild.pid"),
        Duration::from_secs(20),
    );
    let polite = wait_for_file(&dir.path().join("polite/pid"), Duration::from_secs(20));
    assert!(alive(&pid) && alive(&grandchild) && alive(&polite));
    interrupt(&child);
    let (code, stderr, took) = finish(child, Duration::from_secs(20));
    // SIGINT, 1 s grace, SIGTERM, 5 s, SIGKILL: about 6 s (slack for a loaded machine).
    assert!(took < Duration::from_secs(12), "stopping took {took:?}");
    assert_eq!(code, 0, "a user-requested stop is clean: {stderr}");
    assert!(
        stderr.contains("`stubborn` did not stop in time: force-killed"),
        "{stderr}"
    );
    assert!(stderr.contains("`polite` stopped"), "{stderr}");
    for p in [&pid, &grandchild, &polite] {
        assert!(!alive(p), "process {p} was left behind");
    }
}

#[test]
fn a_second_ctrl_c_kills_at_once() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(
        dir.path(),
        "stubborn",
        "trap '' INT TERM; echo $$ > pid; while true; do sleep 1; done",
    );
    launcher(dir.path(), &[("stubborn", "stubborn", "no")]);
    let child = launch(dir.path(), &["--grace", "30"]);
    let pid = wait_for_file(&dir.path().join("stubborn/pid"), Duration::from_secs(20));
    interrupt(&child);
    std::thread::sleep(Duration::from_millis(300));
    interrupt(&child);
    let (code, stderr, took) = finish(child, Duration::from_secs(20));
    assert!(
        took < Duration::from_secs(5),
        "a second Ctrl-C does not wait for the grace period: {took:?}"
    );
    assert_eq!(code, 0, "{stderr}");
    assert!(!alive(&pid));
}

#[test]
fn a_crashing_node_is_restarted_with_its_instance_id() {
    let dir = tempfile::tempdir().unwrap();
    // Crashes twice, then stays up; records the instance id it was given each time.
    shell_node(
        dir.path(),
        "flaky",
        r#"n=$(cat runs 2>/dev/null || echo 0); n=$((n+1)); echo $n > runs; grep -o '"instance_id": *"[^"]*"' "$PEPPY_RUNTIME_CONFIG" >> ids; if [ $n -lt 3 ]; then echo crash $n; exit 3; fi; echo up; exec sleep 1000"#,
    );
    launcher(dir.path(), &[("flaky", "flaky_1", "on-failure")]);
    let child = launch(dir.path(), &[]);
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::fs::read_to_string(dir.path().join("flaky/runs"))
        .unwrap_or_default()
        .trim()
        != "3"
    {
        assert!(Instant::now() < deadline, "not restarted twice");
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(200));
    interrupt(&child);
    let (code, stderr, _) = finish(child, Duration::from_secs(20));
    assert_eq!(code, 0, "{stderr}");
    let ids = std::fs::read_to_string(dir.path().join("flaky/ids")).unwrap();
    assert_eq!(ids.lines().count(), 3);
    assert!(ids.lines().all(|l| l.contains("\"flaky_1\"")), "{ids}");
    assert!(
        stderr.contains("`flaky_1` exited with status 3; restarting"),
        "{stderr}"
    );
    assert!(
        stderr.contains("[flaky_1] crash 1"),
        "output is prefixed: {stderr}"
    );
}

#[test]
fn exit_codes_for_a_crash_and_an_exhausted_restart_budget() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "crash", "echo bye; exit 7");
    launcher(dir.path(), &[("crash", "crash", "no")]);
    let (code, stderr, _) = finish(launch(dir.path(), &[]), Duration::from_secs(20));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("`crash` failed: exited with status 7"),
        "{stderr}"
    );
    // The log file has the instance's output.
    let runs = dir.path().join(".peppy/runs");
    let run = std::fs::read_dir(&runs)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    assert_eq!(
        std::fs::read_to_string(run.join("crash.log")).unwrap(),
        "bye\n"
    );

    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "crash", "exit 7");
    launcher(dir.path(), &[("crash", "crash", "always")]);
    let (code, stderr, _) = finish(launch(dir.path(), &[]), Duration::from_secs(30));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("restart budget of 5 used up"), "{stderr}");

    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "done", "echo finished");
    launcher(dir.path(), &[("done", "done", "no")]);
    let (code, stderr, _) = finish(launch(dir.path(), &[]), Duration::from_secs(20));
    assert_eq!(code, 0, "all instances finished cleanly: {stderr}");
}

#[test]
fn a_start_failure_stops_what_was_started_and_names_the_instance() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "fine", "echo $$ > pid; exec sleep 1000");
    std::fs::create_dir_all(dir.path().join("broken")).unwrap();
    std::fs::write(
        dir.path().join("broken/peppy.json5"),
        r#"{ peppy_schema: "node_v1", manifest: { name: "broken", tag: "v1" }, execution: { language: "rust", run_cmd: ["./no-such-binary"] } }"#,
    )
    .unwrap();
    launcher(
        dir.path(),
        &[("fine", "fine", "no"), ("broken", "broken", "no")],
    );
    let (code, stderr, _) = finish(launch(dir.path(), &[]), Duration::from_secs(20));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("instance `broken` failed to start"),
        "{stderr}"
    );
    assert!(stderr.contains("broken.log"), "names its log: {stderr}");
    assert!(
        stderr.contains("`fine` stopped"),
        "the started instance was stopped: {stderr}"
    );
    // It may have been stopped before its shell wrote its pid. Its group
    // is killed once its main process is gone; on a loaded machine the
    // kernel may take a moment to finish it.
    if let Ok(pid) = std::fs::read_to_string(dir.path().join("fine/pid")) {
        let deadline = Instant::now() + Duration::from_secs(5);
        let fine = dir.path().join("fine");
        // The check sees a live process where it runs (this test's own).
        let here = std::env::current_dir().unwrap();
        assert!(alive_in(&std::process::id().to_string(), &here));
        while alive_in(&pid, &fine) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(
            !alive_in(&pid, &fine),
            "the started instance is gone: {stderr}"
        );
    }
}

#[test]
fn a_stdout_flood_neither_blocks_the_child_nor_ctrl_c() {
    let dir = tempfile::tempdir().unwrap();
    // 50 MB of output, then a marker file: reached only if the pipe is drained.
    shell_node(
        dir.path(),
        "flood",
        "yes 0123456789abcdef0123456789abcdef0123456789abcdef | head -c 50000000; touch flooded; exec sleep 1000",
    );
    launcher(dir.path(), &[("flood", "flood", "no")]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .arg("stack.json5")
        .current_dir(dir.path())
        .env("NO_COLOR", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_file_exists(&dir.path().join("flood/flooded"), Duration::from_secs(60));
    interrupt(&child);
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(15),
            "Ctrl-C did not stop the launch"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(0));
    let runs = dir.path().join(".peppy/runs");
    let run = std::fs::read_dir(&runs)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let logged = std::fs::metadata(run.join("flood.log")).unwrap().len();
    assert!(
        logged >= 50_000_000,
        "the whole flood reached the log: {logged} bytes"
    );
}

fn wait_for_file_exists(path: &Path, within: Duration) {
    let deadline = Instant::now() + within;
    while !path.exists() {
        assert!(
            Instant::now() < deadline,
            "{} did not appear within {within:?}",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn run_starts_one_node_with_checked_bindings_and_typed_parameters() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("echo")).unwrap();
    let doc = serde_json::json!({
        "peppy_schema": "node_v1",
        "manifest": { "name": "echo", "tag": "v1", "depends_on": { "nodes": [{ "name": "cam", "tag": "v1", "link_id": "source" }] } },
        "execution": {
            "language": "shell",
            "run_cmd": ["sh", "-c", "cat \"$PEPPY_RUNTIME_CONFIG\"; echo; echo END"],
            "parameters": { "rate": { "$type": "f64", "$default": 10 }, "label": "string" },
        },
    });
    std::fs::write(dir.path().join("echo/peppy.json5"), doc.to_string()).unwrap();
    shell_node(dir.path(), "cam", "sleep 1");
    std::fs::write(
        dir.path().join("peppy_repositories.json5"),
        r#"[{ type: "fs", path: "." }]"#,
    )
    .unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
            .arg("run")
            .args(args)
            .current_dir(dir.path())
            .env("NO_COLOR", "1")
            .output()
            .unwrap()
    };
    let unbound = run(&["echo", "label=x"]);
    assert_eq!(unbound.status.code(), Some(2));
    let text = String::from_utf8_lossy(&unbound.stderr);
    assert!(
        text.contains("slot `source`") && text.contains("--bind source@"),
        "{text}"
    );

    let missing = run(&["echo", "--bind", "source@cam_1"]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&missing.stderr).contains("missing required parameter `label`")
    );

    let ok = run(&[
        "echo",
        "--instance-id",
        "echo_1",
        "--bind",
        "source@cam_1",
        "--namespace",
        "lab",
        "label=123",
        "--connect",
        "tcp/127.0.0.1:9",
    ]);
    let text = String::from_utf8_lossy(&ok.stderr);
    assert_eq!(ok.status.code(), Some(0), "{text}");
    let json: String = text
        .lines()
        .filter_map(|l| l.strip_prefix("[echo_1] "))
        .take_while(|l| *l != "END")
        .collect::<Vec<_>>()
        .join("\n");
    let config: serde_json::Value =
        serde_json::from_str(&json).unwrap_or_else(|e| panic!("{e}: {json}"));
    assert_eq!(config["instance_id"], "echo_1");
    assert_eq!(config["namespace"], "lab");
    assert_eq!(
        config["slots"],
        serde_json::json!([{
            "link_id": "source",
            "kind": "node",
            "target": { "name": "cam", "tag": "v1" },
            "binding": { "kind": "pinned", "producer": "cam_1" },
            "filter": { "kind": "pin", "producers": "cam_1" },
        }])
    );
    assert_eq!(
        config["parameters"],
        serde_json::json!({ "rate": 10, "label": "123" })
    );
    assert_eq!(
        config["zenoh"]["connect"],
        serde_json::json!(["tcp/127.0.0.1:9"])
    );
}

#[test]
fn a_killed_launcher_leaves_no_orphans() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "orphan", "echo $$ > pid; exec sleep 1000");
    launcher(dir.path(), &[("orphan", "orphan", "no")]);
    let mut child = launch(dir.path(), &[]);
    let pid = wait_for_file(&dir.path().join("orphan/pid"), Duration::from_secs(20));
    assert!(alive(&pid));
    // SIGKILL: the launcher gets no chance to stop anything itself.
    child.kill().unwrap();
    child.wait().unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while alive(&pid) {
        assert!(
            Instant::now() < deadline,
            "the node outlived its launcher (parent-death signal)"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_crashed_instance_leaves_no_grandchild_behind() {
    let dir = tempfile::tempdir().unwrap();
    // The node starts a grandchild in its own process group, then crashes.
    shell_node(
        dir.path(),
        "leaky",
        "sleep 1000 & echo $! > grandchild; sleep 0.2; exit 3",
    );
    shell_node(dir.path(), "steady", "exec sleep 1000");
    launcher(
        dir.path(),
        &[("leaky", "leaky", "no"), ("steady", "steady", "no")],
    );
    let child = launch(dir.path(), &[]);
    let pid = wait_for_file(
        &dir.path().join("leaky/grandchild"),
        Duration::from_secs(20),
    );
    // The launch is still up (`steady` runs): the crash alone must clear the group.
    let deadline = Instant::now() + Duration::from_secs(10);
    while alive(&pid) {
        assert!(
            Instant::now() < deadline,
            "the crashed instance's grandchild {} is still running",
            pid.trim()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    interrupt(&child);
    let (code, stderr, _) = finish(child, Duration::from_secs(20));
    assert_eq!(code, 1, "a failed instance makes the launch fail: {stderr}");
    assert!(
        stderr.contains("`leaky` failed: exited with status 3"),
        "{stderr}"
    );
}

#[test]
fn bad_grace_values_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    shell_node(dir.path(), "n", "exec sleep 1000");
    launcher(dir.path(), &[("n", "n", "no")]);
    for bad in [
        "--grace=-1",
        "--grace=NaN",
        "--grace=inf",
        "--grace=1e300",
        "--grace=soon",
    ] {
        let (code, stderr, _) = finish(launch(dir.path(), &[bad]), Duration::from_secs(20));
        assert_eq!(code, 2, "{bad}: {stderr}");
        assert!(stderr.contains("--grace"), "{bad}: {stderr}");
        assert!(!stderr.contains("panicked"), "{bad}: {stderr}");
    }
    // Nothing was started.
    assert!(!dir.path().join(".peppy").exists());
}

/// A Rust node without `run_cmd` whose program writes `mark` to `ran`.
fn tiny_cargo_node(dir: &Path, mark: &str) {
    let node = dir.join("tiny");
    std::fs::create_dir_all(node.join("src")).unwrap();
    std::fs::write(
        node.join("Cargo.toml"),
        "[package]\nname = \"tiny\"\nversion = \"0.1.0\"\nedition = \"2021\"\n\n[workspace]\n",
    )
    .unwrap();
    std::fs::write(
        node.join("src/main.rs"),
        format!("fn main() {{ std::fs::write(\"ran\", \"{mark}\").unwrap(); }}\n"),
    )
    .unwrap();
    std::fs::write(
        node.join("peppy.json5"),
        r#"{ peppy_schema: "node_v1", manifest: { name: "tiny", tag: "v1" },
             execution: { language: "rust" } }"#,
    )
    .unwrap();
}

#[test]
fn a_cargo_node_runs_what_cargo_built_wherever_the_target_dir_is() {
    let dir = tempfile::tempdir().unwrap();
    let elsewhere = tempfile::tempdir().unwrap();
    launcher(dir.path(), &[("tiny", "tiny", "no")]);
    let up = |extra: &[&str]| {
        let child = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
            .arg("stack.json5")
            .args(extra)
            .current_dir(dir.path())
            .env("NO_COLOR", "1")
            .env("CARGO_TARGET_DIR", elsewhere.path())
            .env_remove("PEPPY_REPOSITORIES")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (code, stderr, _) = finish(child, Duration::from_secs(120));
        assert_eq!(code, 0, "{stderr}");
        std::fs::read_to_string(dir.path().join("tiny/ran")).unwrap()
    };
    tiny_cargo_node(dir.path(), "one");
    assert_eq!(up(&[]), "one");
    assert!(elsewhere.path().join("debug/tiny").is_file());
    assert!(!dir.path().join("tiny/target").exists());
    // Edited and launched again: the fresh build runs, not a stale binary.
    tiny_cargo_node(dir.path(), "two");
    assert_eq!(up(&[]), "two");
    // Without a build, the binary is found where cargo put it.
    tiny_cargo_node(dir.path(), "three");
    assert_eq!(up(&["--no-build"]), "two");
}

/// The names of a process's threads.
fn thread_names(pid: u32) -> Vec<String> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
        .map(|n| n.trim().to_string())
        .collect()
}

/// A node started alone (its `main` the only thread when `NodeBuilder::run`
/// begins) runs Zenoh's receiving, accepting and network work on its one
/// `app` thread; a layout its caller set in `ZENOH_RUNTIME` is kept.
#[cfg(target_os = "linux")]
#[test]
fn a_node_runs_zenoh_on_the_node_layout_unless_told_otherwise() {
    let program = crate::support::example_binary("arm_controller");
    for (layout, wanted, unwanted) in [
        (
            None,
            &["app-0"][..],
            &["acc-0", "net-0", "rx-0", "app-1"][..],
        ),
        (
            Some("(app: (worker_threads: 2))"),
            &["app-0", "app-1", "acc-0", "net-0"][..],
            &[][..],
        ),
    ] {
        let mut command = Command::new(&program);
        command
            .args(["--instance-id", "c1", "--listen", "tcp/127.0.0.1:0"])
            .args(["--bind", "robot_arm@arm"])
            .env_remove("PEPPY_RUNTIME_CONFIG")
            .env_remove("ZENOH_RUNTIME")
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        if let Some(layout) = layout {
            command.env("ZENOH_RUNTIME", layout);
        }
        let mut child = command.spawn().unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut names = thread_names(child.id());
        while !wanted.iter().all(|w| names.iter().any(|n| n == w)) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
            names = thread_names(child.id());
        }
        // Zenoh starts some of its threads on first use: look again once the
        // node has been up a while.
        std::thread::sleep(Duration::from_millis(500));
        names = thread_names(child.id());
        let _ = child.kill();
        let _ = child.wait();
        for w in wanted {
            assert!(names.contains(&w.to_string()), "{layout:?}: {names:?}");
        }
        for u in unwanted {
            assert!(!names.contains(&u.to_string()), "{layout:?}: {names:?}");
        }
    }
}

/// The runtime config an instance of `dir`'s launch got, with the
/// launcher's environment set to `env`; stops the launch after reading it
/// and returns the config and the launch's stderr.
fn launched_config(dir: &Path, env: &[(&str, &str)]) -> (serde_json::Value, String) {
    shell_node(
        dir,
        "probe",
        "cat \"$PEPPY_RUNTIME_CONFIG\" > config.tmp && mv config.tmp config.json; exec sleep 1000",
    );
    launcher(dir, &[("probe", "probe", "no")]);
    let child = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .arg("stack.json5")
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_REPOSITORIES")
        .env_remove("PEPPY_LOCAL_LINK")
        .env_remove("PEPPY_DIRECT_LINKS")
        .envs(env.iter().copied())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let text = wait_for_file(&dir.join("probe/config.json"), Duration::from_secs(30));
    let config: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
    // While the launch runs, its socket directory is there, private.
    if let Some(router) = config["zenoh"]["connect"][0]
        .as_str()
        .and_then(|e| e.strip_prefix("unixsock-stream/"))
    {
        let dir = Path::new(router).parent().unwrap();
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(dir).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o700, "{}", dir.display());
        assert!(Path::new(router).exists(), "the router's socket {router}");
    }
    interrupt(&child);
    let (_, stderr, _) = finish(child, Duration::from_secs(30));
    (config, stderr)
}

#[test]
fn instances_of_one_launch_link_over_unix_sockets_removed_at_its_end() {
    let dir = tempfile::tempdir().unwrap();
    let (config, stderr) = launched_config(dir.path(), &[]);
    let endpoint = |key: &str| config["zenoh"][key][0].as_str().unwrap_or("").to_string();
    let (connect, listen) = (endpoint("connect"), endpoint("listen"));
    assert!(
        connect.starts_with("unixsock-stream/") && connect.ends_with("/router.sock"),
        "{config}\n{stderr}"
    );
    assert!(
        listen.starts_with("unixsock-stream/") && listen.ends_with("/i0.sock"),
        "{config}"
    );
    let sockets = Path::new(connect.strip_prefix("unixsock-stream/").unwrap())
        .parent()
        .unwrap()
        .to_path_buf();
    // Direct links go in the same private directory.
    assert_eq!(
        config["direct_links"].as_str().map(Path::new),
        Some(sockets.as_path()),
        "{config}"
    );
    assert!(
        !sockets.exists(),
        "the launch left {} behind",
        sockets.display()
    );
}

#[test]
fn peppy_local_link_tcp_keeps_instances_on_loopback_tcp() {
    let dir = tempfile::tempdir().unwrap();
    let (config, stderr) = launched_config(dir.path(), &[("PEPPY_LOCAL_LINK", "tcp")]);
    let connect = config["zenoh"]["connect"][0].as_str().unwrap_or("");
    assert!(connect.starts_with("tcp/127.0.0.1:"), "{config}\n{stderr}");
    assert_eq!(config["zenoh"]["listen"], serde_json::json!([]));
    assert!(config.get("direct_links").is_none(), "{config}");
}

#[test]
fn peppy_direct_links_off_keeps_topics_on_zenoh_alone() {
    let dir = tempfile::tempdir().unwrap();
    let (config, stderr) = launched_config(dir.path(), &[("PEPPY_DIRECT_LINKS", "off")]);
    let connect = config["zenoh"]["connect"][0].as_str().unwrap_or("");
    assert!(connect.ends_with("/router.sock"), "{config}\n{stderr}");
    assert!(config.get("direct_links").is_none(), "{config}");
}

/// With a container runtime on PATH, a container node is built into an
/// image under the cache (once per definition) and run in it. The runtime
/// here is a stand-in script that records what it is asked.
#[test]
fn a_container_node_runs_in_its_image_where_apptainer_is_installed() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let (bin, cache, calls) = (
        dir.path().join("bin"),
        dir.path().join("cache"),
        dir.path().join("calls"),
    );
    std::fs::create_dir_all(&bin).unwrap();
    let fake = bin.join("apptainer");
    std::fs::write(
        &fake,
        format!(
            "#!/bin/sh\necho \"$@\" >> {calls}\ncase \"$1\" in\n  build) for last; do :; done; image=\"$3\"; : > \"$image\";;\n  run) echo \"running in $2\";;\nesac\n",
            calls = calls.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::create_dir_all(dir.path().join("boxed")).unwrap();
    std::fs::write(
        dir.path().join("boxed/peppy.json5"),
        r#"{ peppy_schema: "node_v1", manifest: { name: "boxed", tag: "v1" },
             execution: { language: "shell", container: { def_file: "boxed.def" } } }"#,
    )
    .unwrap();
    std::fs::write(
        dir.path().join("boxed/boxed.def"),
        "Bootstrap: docker\nFrom: nvcr.io/nvidia/isaac-sim:4.5.0\n%runscript\n    exec /isaac-sim/python.sh\n",
    )
    .unwrap();
    launcher(dir.path(), &[("boxed", "b", "no")]);
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    // `peppy-launch args...` in the test's directory: its exit code and stderr.
    let peppy_launch = |args: &[&str], env: &[(&str, &std::ffi::OsStr)]| {
        let child = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
            .args(args)
            .current_dir(dir.path())
            .env("NO_COLOR", "1")
            .env_remove("PEPPY_CONTAINERS")
            .env_remove("PEPPY_REPOSITORIES")
            .envs(env.iter().copied())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (code, stderr, _) = finish(child, Duration::from_secs(60));
        (code, stderr)
    };
    for round in 0..2 {
        let (code, stderr) = peppy_launch(
            &["stack.json5"],
            &[
                ("PATH", path.as_ref()),
                ("PEPPY_CACHE_DIR", cache.as_os_str()),
            ],
        );
        assert_eq!(code, 0, "round {round}: {stderr}");
        assert!(
            stderr.contains("`boxed:v1` runs in its container image"),
            "{stderr}"
        );
        assert!(stderr.contains("[b] running in"), "{stderr}");
    }
    let calls = std::fs::read_to_string(&calls).unwrap();
    let lines: Vec<&str> = calls.lines().collect();
    assert_eq!(lines.len(), 3, "one build, two runs: {calls}");
    assert!(
        lines[0].starts_with("build --force ") && lines[0].ends_with("boxed/boxed.def"),
        "{calls}"
    );
    // Built beside its place, moved in once whole.
    let built = lines[0].split_whitespace().nth(2).unwrap();
    let image = built
        .strip_suffix(".partial")
        .expect("built as a partial file");
    assert!(
        image.starts_with(cache.join("containers").to_str().unwrap()),
        "{calls}"
    );
    assert_eq!(lines[1], format!("run {image}"));
    assert_eq!(lines[2], lines[1]);

    // Without a runtime (or told so), what only the image has is named.
    let (code, stderr) = peppy_launch(
        &["check", "stack.json5"],
        &[("PEPPY_CONTAINERS", "native".as_ref())],
    );
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("natively it would run `/isaac-sim/python.sh`, which its image (nvcr.io/nvidia/isaac-sim:4.5.0) brings and this machine lacks"),
        "{stderr}"
    );
}
