//! Stacks that outlive the terminal: the example stack launched with `up
//! --detach`, managed from other commands (`ps`, `node stop|start`, `run
//! --join`, `stop`), and a supervisor killed outright taking its
//! instances with it. Each test has its own launch registry, so `ps` and
//! `stop` see its launch alone.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::support::{Run, peppy_launch_with, root};

struct Shell {
    state: tempfile::TempDir,
}

impl Shell {
    fn new() -> Shell {
        Shell {
            state: tempfile::tempdir().unwrap(),
        }
    }

    fn run(&self, args: &[&str]) -> Run {
        peppy_launch_with(&root(), args, &[("PEPPY_STATE_DIR", self.state.path())])
    }

    fn ok(&self, args: &[&str]) -> Run {
        let run = self.run(args);
        assert_eq!(
            run.code, 0,
            "peppy-launch {args:?}:\n{}\n{}",
            run.stdout, run.stderr
        );
        run
    }
}

/// `ps`'s rows: instance id, pid (`None`: not running) and log.
fn instances(ps: &str) -> Vec<(String, Option<u32>, PathBuf)> {
    ps.lines()
        .filter_map(|line| {
            let cols: Vec<&str> = line.split_whitespace().collect();
            match cols.as_slice() {
                [id, node, pid, log] if node.contains(':') => {
                    Some((id.to_string(), pid.parse().ok(), PathBuf::from(log)))
                }
                _ => None,
            }
        })
        .collect()
}

/// The supervisor's pid, from `up --detach`'s last words.
fn supervisor_pid(stderr: &str) -> u32 {
    let at = stderr
        .find("in the background as pid ")
        .unwrap_or_else(|| panic!("no pid in: {stderr}"));
    stderr[at + "in the background as pid ".len()..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// Whether `pid` is one of this stack's processes still: alive, and the
/// program it was (a pid taken by another program since does not count).
fn runs(pid: u32, program: &str) -> bool {
    std::fs::read(format!("/proc/{pid}/cmdline"))
        .is_ok_and(|c| String::from_utf8_lossy(&c).contains(program))
}

fn wait_until(what: &str, within: Duration, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + within;
    while !done() {
        assert!(Instant::now() < deadline, "{what} within {within:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The viewer's `viewing rs_left:N rs_right:M` reports, in order.
fn reports(log: &Path) -> Vec<(u64, u64)> {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    text.lines()
        .filter_map(|line| {
            let rest = line.split("viewing ").nth(1)?;
            let mut left = None;
            let mut right = None;
            for part in rest.split_whitespace() {
                let (camera, count) = part.split_once(':')?;
                match camera {
                    "rs_left" => left = count.parse().ok(),
                    "rs_right" => right = count.parse().ok(),
                    _ => {}
                }
            }
            // A camera that has sent nothing yet is not in the report.
            Some((left.unwrap_or(0), right.unwrap_or(0)))
        })
        .collect()
}

/// Waits for the viewer's next report after the `seen` first ones.
fn next_report(log: &Path, seen: usize) -> (u64, u64) {
    let mut report = None;
    wait_until("the viewer reports", Duration::from_secs(20), || {
        report = reports(log).get(seen).copied();
        report.is_some()
    });
    report.unwrap()
}

#[test]
fn a_detached_stack_is_managed_from_other_commands_and_stopped_whole() {
    let shell = Shell::new();
    let launcher = root().join("examples/launchers/camera_viewer.json5");
    let launcher = launcher.to_str().unwrap();
    let up = shell.ok(&["up", "--detach", launcher]);
    assert!(up.stderr.contains("started `viewer`"), "{}", up.stderr);
    let supervisor = supervisor_pid(&up.stderr);
    assert!(runs(supervisor, "peppy-launch"));

    let ps = shell.ok(&["ps"]);
    let listed = instances(&ps.stdout);
    let ids: Vec<&str> = listed.iter().map(|(id, _, _)| id.as_str()).collect();
    assert_eq!(ids, ["rs_left", "rs_right", "viewer"], "{}", ps.stdout);
    assert!(
        listed.iter().all(|(_, pid, _)| pid.is_some()),
        "{}",
        ps.stdout
    );
    let viewer_log = listed[2].2.clone();

    // Both cameras stream to the viewer.
    let mut first = 0;
    loop {
        let (left, right) = next_report(&viewer_log, first);
        first += 1;
        if left > 0 && right > 0 {
            break;
        }
    }
    // One camera stopped: the viewer's count of its frames stops, the
    // other's goes on.
    let stopped = shell.ok(&["node", "stop", "rs_left"]);
    assert!(
        stopped.stdout.contains("`rs_left` stopped"),
        "{}",
        stopped.stdout
    );
    let held = instances(&shell.ok(&["ps"]).stdout);
    assert_eq!(held[0].1, None, "ps shows it stopped: {held:?}");
    let first = reports(&viewer_log).len();
    let after = next_report(&viewer_log, first);
    let later = next_report(&viewer_log, first + 1);
    assert_eq!(later.0, after.0, "no frame of rs_left once stopped");
    assert!(
        later.1 > after.1,
        "rs_right goes on: {after:?} then {later:?}"
    );

    // Started again: its frames come back.
    let started = shell.ok(&["node", "start", "rs_left"]);
    assert!(
        started.stdout.contains("started as pid"),
        "{}",
        started.stdout
    );
    let seen = reports(&viewer_log).len();
    let mut resumed = next_report(&viewer_log, seen);
    let mut n = seen;
    while resumed.0 <= later.0 {
        n += 1;
        resumed = next_report(&viewer_log, n);
    }

    // A second viewer joins the launch, linked to one camera.
    let joined = shell.ok(&[
        "run",
        root()
            .join("examples/nodes/camera_viewer")
            .to_str()
            .unwrap(),
        "--join",
        "-",
        "--instance-id",
        "side_viewer",
        "--link",
        "cameras@rs_right",
        "--vacant-link",
        "overhead=one camera is enough",
    ]);
    assert!(
        joined.stdout.contains("started in the launch"),
        "{}",
        joined.stdout
    );
    let listed = instances(&shell.ok(&["ps"]).stdout);
    let side = listed
        .iter()
        .find(|(id, _, _)| id == "side_viewer")
        .expect("ps lists the joined instance");
    wait_until(
        "the joined viewer sees rs_right",
        Duration::from_secs(20),
        || std::fs::read_to_string(&side.2).is_ok_and(|l| l.contains("first frame from rs_right")),
    );
    // It takes the launch's direct links, as the instances `up` started.
    let plan = |log: &PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(log.with_extension("json")).unwrap()).unwrap()
    };
    let links = plan(&viewer_log)["direct_links"].clone();
    assert!(links.is_string(), "{links}");
    assert_eq!(plan(&side.2)["direct_links"], links);
    // A link to what the stack does not run is refused before anything starts.
    let refused = shell.run(&[
        "run",
        root()
            .join("examples/nodes/camera_viewer")
            .to_str()
            .unwrap(),
        "--join",
        "-",
        "--link",
        "cameras@no_such_camera",
        "--vacant-link",
        "overhead=none",
    ]);
    assert_eq!(refused.code, 2, "{}", refused.stderr);
    assert!(
        refused.stderr.contains("which the launch does not run"),
        "{}",
        refused.stderr
    );

    // Everything ends: the supervisor and every instance, joined one too.
    let pids: Vec<u32> = listed.iter().filter_map(|(_, pid, _)| *pid).collect();
    assert_eq!(pids.len(), 4, "{listed:?}");
    let stop = shell.ok(&["stop"]);
    assert!(stop.stderr.contains("stopped pid"), "{}", stop.stderr);
    assert!(!runs(supervisor, "peppy-launch"));
    for pid in pids {
        assert!(
            !runs(pid, "realsense_d405") && !runs(pid, "camera_viewer"),
            "pid {pid} outlived the launch"
        );
    }
    assert!(instances(&shell.ok(&["ps"]).stdout).is_empty());
}

#[test]
fn a_killed_supervisor_leaves_no_instance_behind() {
    let shell = Shell::new();
    let launcher = root().join("examples/launchers/camera_viewer.json5");
    let up = shell.ok(&["up", "-d", launcher.to_str().unwrap()]);
    let supervisor = supervisor_pid(&up.stderr);
    let pids: Vec<u32> = instances(&shell.ok(&["ps"]).stdout)
        .iter()
        .filter_map(|(_, pid, _)| *pid)
        .collect();
    assert_eq!(pids.len(), 3);
    // SAFETY: kill only sends a signal to the test's own launch.
    unsafe {
        libc::kill(supervisor as libc::pid_t, libc::SIGKILL);
    }
    wait_until(
        "every instance dies with its supervisor",
        Duration::from_secs(10),
        || {
            pids.iter()
                .all(|&pid| !runs(pid, "realsense_d405") && !runs(pid, "camera_viewer"))
        },
    );
    // An instance dies with the supervisor's thread that started it, which
    // may be before the supervisor's last thread lets go of the launch's
    // registry entry: the launch is listed until then.
    wait_until(
        "the killed launch leaves the registry",
        Duration::from_secs(10),
        || instances(&shell.ok(&["ps"]).stdout).is_empty(),
    );
    let none = shell.run(&["stop"]);
    assert_eq!(none.code, 2, "{}", none.stderr);
    assert!(
        none.stderr.contains("no launch is running"),
        "{}",
        none.stderr
    );
}
