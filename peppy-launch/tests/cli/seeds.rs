//! Every statement of the two seed pages, asserted by running the examples
//! with `peppy-launch`: real node binaries (built by their `build_cmd`),
//! real Zenoh, real processes. Node output is read from the launcher's
//! multiplexed stderr.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use crate::support::{copy_documents, peppy_launch, root};

/// Builds of every example node can take a while on a cold machine.
pub(crate) const BUILD_AND_START: Duration = Duration::from_secs(600);

/// A running `peppy-launch up` and its multiplexed output.
pub(crate) struct Launch {
    child: Child,
    lines: Receiver<String>,
    pub(crate) seen: Vec<String>,
}

impl Launch {
    pub(crate) fn up(launcher: &str, extra: &[&str]) -> Launch {
        Launch::up_with(launcher, extra, &[])
    }

    /// `up` with extra environment variables.
    pub(crate) fn up_with(launcher: &str, extra: &[&str], env: &[(&str, &Path)]) -> Launch {
        Launch::up_in(&[], launcher, extra, env)
    }

    /// `up` run through `wrapper` (e.g. `ip netns exec NS`), which must
    /// exec into `peppy-launch` so that signals reach it.
    pub(crate) fn up_in(
        wrapper: &[&str],
        launcher: &str,
        extra: &[&str],
        env: &[(&str, &Path)],
    ) -> Launch {
        let mut args = vec!["up", launcher];
        args.extend_from_slice(extra);
        Launch::start(wrapper, &args, env)
    }

    /// Any long-running `peppy-launch ARGS` (`up`, `run`), read like `up`.
    pub(crate) fn start(wrapper: &[&str], args: &[&str], env: &[(&str, &Path)]) -> Launch {
        let mut child = crate::support::peppy_launch_command(wrapper)
            .args(args)
            .envs(env.iter().copied())
            .current_dir(root())
            .env("NO_COLOR", "1")
            .env_remove("PEPPY_REPOSITORIES")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Launch {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// The first line so far, or waits for one, matching `pred`; fails with
    /// everything seen so far.
    pub(crate) fn expect(
        &mut self,
        what: &str,
        within: Duration,
        pred: impl Fn(&str) -> bool,
    ) -> String {
        if let Some(line) = self.seen.iter().find(|l| pred(l)) {
            return line.clone();
        }
        let deadline = Instant::now() + within;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if pred(&line) {
                        return line;
                    }
                }
                Err(_) => panic!(
                    "no line {what} within {within:?}; output:\n{}",
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Like [`expect`](Self::expect), but only lines from `seen[since..]`
    /// on (mark a moment with `seen.len()`).
    pub(crate) fn expect_since(
        &mut self,
        since: usize,
        what: &str,
        within: Duration,
        pred: impl Fn(&str) -> bool,
    ) -> String {
        if let Some(line) = self.seen[since.min(self.seen.len())..]
            .iter()
            .find(|l| pred(l))
        {
            return line.clone();
        }
        let deadline = Instant::now() + within;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if pred(&line) {
                        return line;
                    }
                }
                Err(_) => panic!(
                    "no new line {what} within {within:?}; output:\n{}",
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Reads for `time` more, returning the lines.
    pub(crate) fn read_for(&mut self, time: Duration) -> Vec<String> {
        let deadline = Instant::now() + time;
        let mut out = Vec::new();
        while let Ok(line) = self
            .lines
            .recv_timeout(deadline.saturating_duration_since(Instant::now()))
        {
            self.seen.push(line.clone());
            out.push(line);
        }
        out
    }

    /// Ctrl-C; returns the exit code. No instance may need SIGKILL: the
    /// ZED's service loop ignores every error (`loop { let _ = ... }`) and
    /// must still stop on SIGINT.
    pub(crate) fn stop(self) -> i32 {
        self.stop_seen().0
    }

    /// [`Launch::stop`], also giving every line seen, the stop's included.
    pub(crate) fn stop_seen(mut self) -> (i32, Vec<String>) {
        assert!(
            Command::new("kill")
                .args(["-INT", &self.child.id().to_string()])
                .status()
                .unwrap()
                .success()
        );
        let deadline = Instant::now() + Duration::from_secs(30);
        let code = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s.code().unwrap_or(-1);
            }
            assert!(Instant::now() < deadline, "the launch did not stop");
            while let Ok(line) = self.lines.try_recv() {
                self.seen.push(line);
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        // The output pumps end with the child; collect what is left.
        while let Ok(line) = self.lines.recv_timeout(Duration::from_secs(2)) {
            self.seen.push(line);
        }
        assert!(
            !self.seen.iter().any(|l| l.contains("force-killed")),
            "an instance had to be killed:\n{}",
            self.seen.join("\n")
        );
        (code, std::mem::take(&mut self.seen))
    }
}

/// A test that fails before `stop` must not leave its stack running (and
/// loading the machine for the other tests): the launch is stopped, then
/// killed; its instances die with it (parent-death signal).
impl Drop for Launch {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_some() {
            return;
        }
        let _ = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if self.child.try_wait().ok().flatten().is_some() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// "left_cam: first frame from rs_left (...)" lines of one instance.
pub(crate) fn first_frames(lines: &[String], instance: &str) -> Vec<(String, String)> {
    let prefix = format!("[{instance}]");
    lines
        .iter()
        .filter(|l| l.starts_with(&prefix))
        .filter_map(|l| {
            let rest = l[prefix.len()..].trim_start();
            let (slot, tail) = rest.split_once(": first frame from ")?;
            Some((
                slot.to_string(),
                tail.split_whitespace().next()?.to_string(),
            ))
        })
        .collect()
}

/// Seed 000: pinned interface slots get exactly their producer; a free-form
/// key puts zed_overhead into the from_any slot; left_cam's service answers.
#[test]
fn multi_camera_left_right_and_backup() {
    let mut launch = Launch::up("examples/launchers/multi_camera.json5", &[]);
    launch.expect("with recon_1's summary", BUILD_AND_START, |l| {
        l.starts_with("[recon_1]") && l.contains("reconstructing from")
    });
    launch.expect(
        "with left_cam's stream info",
        Duration::from_secs(30),
        |l| l.contains("left_cam is rs_left: 160x120 @ 15 fps, mono8"),
    );
    launch.read_for(Duration::from_secs(2));
    let mut firsts = first_frames(&launch.seen, "recon_1");
    firsts.sort();
    assert_eq!(
        firsts,
        [
            ("backup_cams".to_string(), "zed_overhead".to_string()),
            ("left_cam".to_string(), "rs_left".to_string()),
            ("right_cam".to_string(), "rs_right".to_string()),
        ],
        "each slot hears exactly its producers"
    );
    assert_eq!(launch.stop(), 0);
}

/// Seed 000: three instances of one node under free-form keys all reach the
/// single from_any slot, told apart by their instance ids.
#[test]
fn three_realsense_cameras_under_free_form_keys() {
    let mut launch = Launch::up("examples/launchers/three_realsense.json5", &[]);
    launch.expect("with mosaic_1's first frame", BUILD_AND_START, |l| {
        l.contains("extras: first frame")
    });
    launch.expect("with a mosaic of 3 tiles", Duration::from_secs(30), |l| {
        l.contains("mosaic of 3 tiles")
    });
    let mut producers: Vec<String> = first_frames(&launch.seen, "mosaic_1")
        .into_iter()
        .map(|(_, p)| p)
        .collect();
    producers.sort();
    assert_eq!(producers, ["rs_back_left", "rs_back_right", "rs_front"]);
    assert_eq!(launch.stop(), 0);
}

/// Seed 000: swapping the RealSense pair for the simulator needs no change
/// to the consumer: same node, same bindings.
#[test]
fn simulated_cameras_swap_in_without_consumer_changes() {
    let a = std::fs::read_to_string(root().join("examples/launchers/multi_camera.json5")).unwrap();
    let b =
        std::fs::read_to_string(root().join("examples/launchers/multi_camera_sim.json5")).unwrap();
    let consumer = |s: &str| s[s.find("video_reconstruction").unwrap()..].to_string();
    assert_eq!(
        consumer(&a),
        consumer(&b),
        "the consumer's deployment is identical"
    );
    let mut launch = Launch::up("examples/launchers/multi_camera_sim.json5", &[]);
    launch.expect("with rs_left running the simulator", BUILD_AND_START, |l| {
        l.contains("started `rs_left` (mujoco_depth_camera_sim:v1)")
    });
    launch.expect("with recon_1's summary", Duration::from_secs(60), |l| {
        l.contains("reconstructing from")
            && l.contains("left_cam<-rs_left")
            && l.contains("right_cam<-rs_right")
            && l.contains("backup_cams<-zed_overhead")
    });
    assert_eq!(launch.stop(), 0);
}

/// Seed 002: the arm loop runs both ways (linked topic one way, external
/// topic the other) with neither node depending on the other's code.
#[test]
fn robot_arm_loop_runs_both_ways() {
    let mut launch = Launch::up("examples/launchers/robot_arm_loop.json5", &[]);
    arm_loop_runs(&mut launch);
    assert_eq!(launch.stop(), 0);
}

/// What the arm loop prints when it works: the homing action, then both
/// topic directions.
pub(crate) fn arm_loop_runs(launch: &mut Launch) {
    // First the controller homes the arm with its move_arm action: goal,
    // feedback, result.
    launch.expect("with the homing goal", BUILD_AND_START, |l| {
        l.starts_with("[arm]") && l.contains("move_arm goal") && l.contains("from controller")
    });
    launch.expect("with homing feedback", Duration::from_secs(30), |l| {
        l.starts_with("[controller]") && l.contains("rad to go")
    });
    launch.expect("with the homing result", Duration::from_secs(30), |l| {
        l.contains("homed by arm: reached=true")
    });
    launch.expect("with the controller's 40th cycle", BUILD_AND_START, |l| {
        l.starts_with("[controller]") && l.contains("cycle 40:")
    });
    launch.expect(
        "with the arm's 40th command",
        Duration::from_secs(30),
        |l| l.starts_with("[arm]") && l.contains("command 40 from controller"),
    );
}

/// SPEC 6.4 with real nodes: a producer that crashes under `on-failure` is
/// restarted with the same instance id and its consumer keeps receiving.
#[test]
fn a_crashing_producer_is_restarted_and_still_consumed() {
    let dir = tempfile::tempdir().unwrap();
    let launcher = format!(
        r#"{{ peppy_schema: "launcher_v1", deployments: [
            {{ source: {{ local: "{nodes}/mujoco_depth_camera_sim" }}, instances: [
                {{ instance_id: "sim_cam", restart: "on-failure", arguments: {{ fail_after_frames: 20, frames_per_second: 40 }} }} ] }},
            {{ source: {{ local: "{nodes}/camera_mosaic" }}, instances: [{{ instance_id: "mosaic", bindings: {{ cam: "sim_cam" }} }}] }},
        ] }}"#,
        nodes = root().join("examples/nodes").display()
    );
    let path = dir.path().join("crash.json5");
    std::fs::write(&path, launcher).unwrap();
    let repo = root().join("examples");
    let mut launch = Launch::up(path.to_str().unwrap(), &["--repo", repo.to_str().unwrap()]);
    launch.expect("with a dropout", BUILD_AND_START, |l| {
        l.contains("[sim_cam]") && l.contains("simulated dropout after 20 frames")
    });
    launch.expect("with a restart", Duration::from_secs(30), |l| {
        l.contains("`sim_cam` exited with status 3; restarting")
    });
    // More than one run's worth of frames reach the consumer.
    launch.expect(
        "with frames from the restarted producer",
        Duration::from_secs(60),
        |l| {
            l.starts_with("[mosaic]")
                && l.split_whitespace().any(|w| {
                    w.strip_prefix("sim_cam:")
                        .and_then(|n| n.parse::<u32>().ok())
                        .is_some_and(|n| n > 25)
                })
        },
    );
    assert_eq!(launch.stop(), 0);
}

/// Seed 000: a node named like the interface does not conform.
#[test]
fn a_non_conforming_node_is_refused() {
    let run = peppy_launch(
        &root(),
        &["check", "examples/launchers/wrong_interface.json5"],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("(BindingInterfaceNotConformed)"),
        "{}",
        run.stderr
    );
    assert!(run.stderr.contains("`impostor` deploys `depth_camera:v1`, which does not conform to interface `depth_camera:v1`"));
}

/// Seed 000: sha256 pins on both sides are accepted when they match and
/// refused once the interface document changes.
#[test]
fn sha256_pins_on_both_sides() {
    let dir = tempfile::tempdir().unwrap();
    copy_documents(&root().join("examples"), dir.path());
    let interface = dir.path().join("interfaces/depth_camera.json5");
    let sha = peppy_schema::sha256_hex(&std::fs::read(&interface).unwrap());
    let pin = |file: &str, from: &str, to: String| {
        let p = dir.path().join(file);
        let s = std::fs::read_to_string(&p).unwrap();
        assert!(s.contains(from), "{file} has {from}");
        std::fs::write(&p, s.replacen(from, &to, 1)).unwrap();
    };
    pin(
        "nodes/realsense_d405/peppy.json5",
        r#"{ name: "depth_camera", tag: "v1" }"#,
        format!(r#"{{ name: "depth_camera", tag: "v1", sha256: "{sha}" }}"#),
    );
    pin(
        "nodes/video_reconstruction/peppy.json5",
        r#"{ name: "depth_camera", tag: "v1", link_id: "left_cam" }"#,
        format!(r#"{{ name: "depth_camera", tag: "v1", link_id: "left_cam", sha256: "{sha}" }}"#),
    );
    let ok = peppy_launch(dir.path(), &["check", "launchers/multi_camera.json5"]);
    assert_eq!(ok.code, 0, "matching pins are accepted: {}", ok.stderr);

    let mut text = std::fs::read_to_string(&interface).unwrap();
    text.push_str("// a later edit\n");
    std::fs::write(&interface, text).unwrap();
    let refused = peppy_launch(dir.path(), &["check", "launchers/multi_camera.json5"]);
    assert_eq!(refused.code, 2);
    let pins = refused
        .stderr
        .lines()
        .filter(|l| l.contains("(InterfacePinMismatch)"))
        .count();
    assert_eq!(
        pins, 2,
        "both sides refuse the changed document: {}",
        refused.stderr
    );
    assert!(
        refused.stderr.contains(&sha),
        "the message names the pinned revision"
    );
}
