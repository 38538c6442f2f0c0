//! What launching costs: `peppy-launch up --no-build` of N already built
//! camera instances to their first message and to a message from every
//! one, and the resident memory of an idle node next to an idle raw Zenoh
//! process.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use crate::children::System;
use crate::procs::{Proc, free_port, rss_mib};
use crate::roles::{Res, now_ns};
use crate::stats::{Figure, Row};
use crate::workspace;

/// How the launched programs are built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Build {
    /// The debug build `up` makes, as a newcomer's first launch runs.
    Debug,
    /// The same profile with every crate optimised, in its own target
    /// directory: what a robot runs.
    Optimised,
}

impl Build {
    fn group(self) -> &'static str {
        match self {
            Build::Debug => "launch (already built, debug nodes)",
            Build::Optimised => "launch (already built, optimised nodes)",
        }
    }

    /// The target directory (`None`: the workspace's own).
    pub(crate) fn target_dir(self) -> Option<PathBuf> {
        match self {
            Build::Debug => None,
            Build::Optimised => Some(target().join("bench-optimised")),
        }
    }
}

/// Builds what the launches start, both ways, then measures.
pub(crate) fn launch(_quick: bool) -> Res<Vec<Row>> {
    let mut rows = Vec::new();
    let ms = |v: f64| Figure::Value {
        value: v,
        unit: "ms".into(),
    };
    // peppy's optimised launches, beside dora-rs's below.
    let mut optimised = Vec::new();
    for build in [Build::Debug, Build::Optimised] {
        let launcher = build_examples(build)?;
        for n in [10usize, 50] {
            let (first, all, rss) = launch_once(&launcher, build, n)?;
            if build == Build::Optimised {
                optimised.push((n, first, all));
            }
            rows.push(Row::new(
                build.group(),
                format!("{n} instances: up to first message"),
                None,
                Some(ms(first)),
            ));
            rows.push(Row::new(
                build.group(),
                format!("{n} instances: up to a message from each"),
                None,
                all.map(ms),
            ));
            if let Some(rss) = rss {
                rows.push(Row::new(
                    build.group(),
                    format!("{n} instances: resident memory of a camera node"),
                    None,
                    Some(Figure::Value {
                        value: rss,
                        unit: "MiB".into(),
                    }),
                ));
            }
        }
    }
    let mut idle = [None, None];
    for (i, system) in [System::Zenoh, System::Peppy].into_iter().enumerate() {
        let port = free_port()?;
        let system_flag = if system == System::Peppy {
            "peppy"
        } else {
            "zenoh"
        };
        let mut source = Proc::child(
            &[
                "source",
                "--system",
                system_flag,
                "--ns",
                &format!("idle-{port}"),
                "--endpoint",
                &format!("tcp/127.0.0.1:{port}"),
            ]
            .map(String::from),
        )?;
        source.next_with("ready", Duration::from_secs(30))?;
        std::thread::sleep(Duration::from_secs(2));
        idle[i] = rss_mib(source.pid()).map(|value| Figure::Value {
            value,
            unit: "MiB".into(),
        });
        source.stop();
    }
    if let Some(dora) = &crate::peers::peers().dora {
        let group = "launch, dora-rs vs peppy (already built, optimised nodes)";
        for (n, first, all) in optimised {
            let (d_first, d_all) = dora_launch(dora, n)?;
            rows.push(
                Row::new(
                    group,
                    format!("{n} instances: up to first message"),
                    Some(ms(d_first)),
                    Some(ms(first)),
                )
                .against(crate::transport::DORA_NAME),
            );
            rows.push(
                Row::new(
                    group,
                    format!("{n} instances: up to a message from each"),
                    d_all.map(ms),
                    all.map(ms),
                )
                .against(crate::transport::DORA_NAME),
            );
        }
    }
    let [zenoh, peppy] = idle;
    rows.push(
        Row::new(
            Build::Optimised.group(),
            "idle process: resident memory (release)".into(),
            zenoh,
            peppy,
        )
        .with_note("the benchmark's source: every topic, service and action of this table"),
    );
    Ok(rows)
}

/// `dora run` of `n` camera nodes (release builds, a frame every 33 ms)
/// and a sink: ms from the command to the sink's first frame, and to a
/// frame from each.
fn dora_launch(dora: &crate::peers::Dora, n: usize) -> Res<(f64, Option<f64>)> {
    use crate::peers::DoraNode;
    let mut nodes: Vec<DoraNode> = (0..n)
        .map(|i| DoraNode {
            id: format!("cam_{i}"),
            sink: false,
            inputs: vec![("tick".into(), "dora/timer/millis/33".into(), None)],
            outputs: vec!["frame".into()],
            args: None,
        })
        .collect();
    nodes.push(DoraNode {
        id: "sink".into(),
        sink: true,
        inputs: (0..n)
            .map(|i| (format!("cam_{i}"), format!("cam_{i}/frame"), None))
            .collect(),
        outputs: Vec::new(),
        args: Some(
            ["launch", "--expect", &n.to_string()]
                .map(String::from)
                .to_vec(),
        ),
    });
    let started = now_ns();
    let mut run = dora.run(&nodes)?;
    let seen = run
        .nodes
        .get_mut("sink")
        .ok_or("dora's sink never linked")?
        .next_with("heard", Duration::from_secs(150));
    run.stop();
    let seen = seen?;
    let since = |key: &str| {
        seen[key]
            .as_u64()
            .map(|t| t.saturating_sub(started) as f64 / 1e6)
    };
    let first = since("first_ns").ok_or("no frame from dora's cameras")?;
    Ok((first, since("all_ns")))
}

/// The workspace's target directory.
pub(crate) fn target() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| workspace().join("target"), PathBuf::from)
}

/// `cargo build -p peppy-launch -p realsense_d405`; the launcher's path.
pub(crate) fn build_examples(build: Build) -> Res<PathBuf> {
    eprintln!("peppy-bench: building peppy-launch and realsense_d405 ({build:?})…");
    let mut cargo = Command::new(crate::cargo());
    cargo
        .args(["build", "-p", "peppy-launch", "-p", "realsense_d405"])
        .current_dir(workspace());
    if build == Build::Optimised {
        // The dev profile (the one `up` looks in), optimised like release.
        cargo.args([
            "--config",
            "profile.dev.opt-level=3",
            "--config",
            "profile.dev.package.\"*\".opt-level=3",
            "--config",
            "profile.dev.debug-assertions=false",
            "--config",
            "profile.dev.overflow-checks=false",
        ]);
    }
    if let Some(dir) = build.target_dir() {
        cargo.env("CARGO_TARGET_DIR", dir);
    }
    if !cargo.status()?.success() {
        return Err("the build of peppy-launch and realsense_d405 failed".into());
    }
    Ok(build
        .target_dir()
        .unwrap_or_else(target)
        .join("debug")
        .join("peppy-launch"))
}

/// A launcher of `n` `realsense_d405` instances (`cam_0`, ...), each given
/// `arguments` (a JSON5 object's fields; empty for the defaults), written
/// in `dir`.
pub(crate) fn cameras_launcher(dir: &Path, n: usize, arguments: &str) -> Res<PathBuf> {
    let node = workspace().join("examples/nodes/realsense_d405");
    let instances: Vec<String> = (0..n)
        .map(|i| format!("{{ instance_id: \"cam_{i}\", arguments: {{ {arguments} }} }}"))
        .collect();
    let file = dir.join("cameras.json5");
    std::fs::write(
        &file,
        format!(
            "{{ peppy_schema: \"launcher_v1\", deployments: [{{ source: {{ local: {:?} }}, instances: [{}] }}] }}",
            node.display().to_string(),
            instances.join(", ")
        ),
    )?;
    Ok(file)
}

/// One launch of `n` cameras: ms to the first message, to one from each,
/// and the median camera's resident memory (MiB) once all are heard.
fn launch_once(launcher: &Path, build: Build, n: usize) -> Res<(f64, Option<f64>, Option<f64>)> {
    let dir = tempfile::tempdir()?;
    let file = cameras_launcher(dir.path(), n, "")?;
    let (router, watch_port) = (free_port()?, free_port()?);
    let ns = format!("launch-{n}-{router}");
    let watch_at = format!("tcp/127.0.0.1:{watch_port}");
    let mut watch = Proc::child(
        &[
            "watch",
            "--listen",
            &watch_at,
            "--ns",
            &ns,
            "--expect",
            &n.to_string(),
        ]
        .map(String::from),
    )?;
    watch.next_with("ready", Duration::from_secs(30))?;
    let started = now_ns();
    let mut command = Command::new(launcher);
    command.args([
        "up",
        &file.display().to_string(),
        "--no-build",
        "--namespace",
        &ns,
        "--listen",
        &format!("tcp/127.0.0.1:{router}"),
        "--connect",
        &watch_at,
    ]);
    // `up --no-build` finds the nodes in the target directory they were built in.
    if let Some(dir) = build.target_dir() {
        command.env("CARGO_TARGET_DIR", dir);
    }
    let up = Proc::spawn(command, "peppy-launch up")?;
    let seen = watch.next_with("heard", Duration::from_secs(150));
    // The instances' pids, from `started `cam_0` (...) as pid N`.
    let pids: Vec<u32> = up
        .stderr()
        .lines()
        .filter_map(|l| l.rsplit_once(" as pid ")?.1.trim().parse().ok())
        .collect();
    let mut rss: Vec<f64> = pids.iter().filter_map(|p| rss_mib(*p)).collect();
    rss.sort_by(f64::total_cmp);
    let stderr = up.stderr();
    up.interrupt(Duration::from_secs(30));
    let seen = seen.map_err(|e| format!("{e}\npeppy-launch said:\n{stderr}"))?;
    let since = |key: &str| {
        seen[key]
            .as_u64()
            .map(|t| t.saturating_sub(started) as f64 / 1e6)
    };
    let first =
        since("first_ns").ok_or_else(|| format!("no message from the launch:\n{stderr}"))?;
    Ok((first, since("all_ns"), rss.get(rss.len() / 2).copied()))
}
