//! Building a node and finding the program to start.
//!
//! A node with `run_cmd` runs that argv. A Rust node without one is built
//! with cargo, and its executable is the one cargo reports in its JSON
//! build messages, so `CARGO_TARGET_DIR`, `--release`, `--profile` and
//! `--target` all land where cargo put the binary, never at a guessed path.
//! Without a build (`--no-build`), `cargo metadata` names the target
//! directory and the build command's flags name the profile.

use std::path::{Path, PathBuf};
use std::process::Stdio;

use peppy_schema::{Execution, Launch};
use serde::Deserialize;

use crate::build_progress::{BuildProgress, CARGO_PROGRESS_ENV, parse_cargo_progress};

/// A build of one node failed, or its program cannot be found.
#[derive(Debug, thiserror::Error)]
pub enum ExecutableError {
    /// The build command could not be started.
    #[error("cannot run the build of {node} (`{command}` in {dir}): {source}")]
    Spawn {
        /// The node (`name:tag`).
        node: String,
        /// The build command.
        command: String,
        /// Where it ran.
        dir: String,
        /// Why it could not start.
        #[source]
        source: std::io::Error,
    },
    /// The build command failed; its output follows.
    #[error("the build of {node} failed (`{command}` in {dir}):\n{output}")]
    Failed {
        /// The node (`name:tag`).
        node: String,
        /// The build command.
        command: String,
        /// Where it ran.
        dir: String,
        /// What it printed (cargo's JSON lines left out).
        output: String,
    },
    /// Cargo built no executable for the node's package, or several.
    #[error("cannot tell which executable runs {node}: {source}")]
    NoExecutable {
        /// The node (`name:tag`).
        node: String,
        /// What was found instead.
        source: FindError,
    },
    /// A tool the node's commands name (`uv`) is missing and could not be
    /// installed.
    #[error("cannot build or run {node}: {source}")]
    Tool {
        /// The node (`name:tag`).
        node: String,
        /// Why there is no such tool.
        source: crate::python_sync::UvError,
    },
    /// A Python node's generated `peppygen` package could not be written.
    #[error("cannot build or run {node}: generating its peppygen package: {source}")]
    Package {
        /// The node (`name:tag`).
        node: String,
        /// Why.
        source: crate::python_sync::PackageError,
    },
    /// The node's container cannot run here.
    #[error("cannot run `{node}`: {source}")]
    Container {
        /// The node (`name:tag`).
        node: String,
        /// Why.
        source: crate::container::ContainerError,
    },
}

/// Why the executable of a Rust node without `run_cmd` cannot be told.
#[derive(Debug, thiserror::Error)]
pub enum FindError {
    /// Cargo names no binary of the node's package.
    #[error("{tool} names no binary of the package in this directory; give the node a `run_cmd`")]
    NoBinary {
        /// Where cargo said so: `` `cargo build` `` or `` `cargo metadata` ``.
        tool: &'static str,
    },
    /// The package has several binaries, none named like the node.
    #[error(
        "the package has several binaries ({}) and none is named `{node_name}`; give the node a `run_cmd`",
        binaries.iter().map(|b| format!("`{b}`")).collect::<Vec<_>>().join(", ")
    )]
    SeveralBinaries {
        /// The binaries' target names.
        binaries: Vec<String>,
        /// The node's name.
        node_name: String,
    },
    /// `cargo metadata` could not be started.
    #[error("cannot run `cargo metadata`: {0}")]
    MetadataSpawn(#[source] std::io::Error),
    /// `cargo metadata` failed.
    #[error("`cargo metadata` failed: {stderr}")]
    MetadataFailed {
        /// What it printed on stderr, trimmed.
        stderr: String,
    },
    /// `cargo metadata` printed what is not its JSON.
    #[error("cannot read `cargo metadata`: {0}")]
    MetadataUnreadable(#[source] serde_json::Error),
    /// No package of the workspace has its manifest in the node's directory.
    #[error("no cargo package has its manifest in {}", dir.display())]
    NoPackage {
        /// The node's directory.
        dir: PathBuf,
    },
    /// `--no-build`, and the binary is not there.
    #[error("{} is not built yet; run without --no-build", exe.display())]
    NotBuilt {
        /// Where the binary would be.
        exe: PathBuf,
    },
}

/// `cargo build` argv with JSON messages on stdout (diagnostics still
/// rendered for people on stderr).
fn with_json_messages(cmd: &[String]) -> Vec<String> {
    let mut argv = cmd.to_vec();
    if !argv.iter().any(|a| a.starts_with("--message-format")) {
        argv.push("--message-format=json-render-diagnostics".into());
    }
    argv
}

/// Runs `cmd` in `dir`, showing its progress as `label`; returns its
/// stdout. A cargo build (`cargo`) is asked for its unit counts.
async fn run_build(
    node: &str,
    label: &str,
    dir: &Path,
    cmd: &[String],
    cargo: bool,
) -> Result<String, ExecutableError> {
    use tokio::io::AsyncReadExt as _;
    let command = cmd.join(" ");
    let spawn_failed = |source| ExecutableError::Spawn {
        node: node.to_string(),
        command: command.clone(),
        dir: dir.display().to_string(),
        source,
    };
    let mut build = tokio::process::Command::new(&cmd[0]);
    build
        .args(&cmd[1..])
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true);
    for (key, _) in std::env::vars_os() {
        if key.to_str().is_some_and(describes_own_package) {
            build.env_remove(&key);
        }
    }
    if cargo {
        build.envs(CARGO_PROGRESS_ENV);
    }
    if let Some(shared) = crate::shared_build::for_build(cmd, dir) {
        build.env("CARGO_BUILD_BUILD_DIR", shared);
    }
    let mut child = build.spawn().map_err(spawn_failed)?;
    let progress = BuildProgress::start(label.to_string());
    let mut out_pipe = child.stdout.take().expect("stdout is piped");
    let stdout = tokio::spawn(async move {
        let mut bytes = Vec::new();
        let _ = out_pipe.read_to_end(&mut bytes).await;
        bytes
    });
    // Cargo's progress lines end in `\r`, everything else in `\n`: each
    // segment is either a count for the display or text kept for a failure.
    let mut err_pipe = child.stderr.take().expect("stderr is piped");
    let (mut kept, mut pending, mut chunk) = (String::new(), Vec::new(), [0u8; 8192]);
    while let Ok(n @ 1..) = err_pipe.read(&mut chunk).await {
        pending.extend_from_slice(&chunk[..n]);
        while let Some(end) = pending.iter().position(|b| matches!(b, b'\r' | b'\n')) {
            let segment: Vec<u8> = pending.drain(..=end).collect();
            let line = String::from_utf8_lossy(&segment[..end]);
            match parse_cargo_progress(&line) {
                Some((done, total, current)) => progress.units(done, total, current),
                None if !line.trim().is_empty() => {
                    kept.push_str(&line);
                    kept.push('\n');
                }
                None => {}
            }
        }
    }
    kept.push_str(&String::from_utf8_lossy(&pending));
    let status = child.wait().await.map_err(spawn_failed)?;
    let stdout = String::from_utf8_lossy(&stdout.await.unwrap_or_default()).into_owned();
    progress.finish(status.success());
    if !status.success() {
        // Cargo's JSON lines are for us; people read the rendered stderr.
        let mut text: String = stdout
            .lines()
            .filter(|l| !l.starts_with('{'))
            .map(|l| format!("{l}\n"))
            .collect();
        text.push_str(&kept);
        return Err(ExecutableError::Failed {
            node: node.to_string(),
            command,
            dir: dir.display().to_string(),
            output: text,
        });
    }
    Ok(stdout)
}

/// The build one node needs before it starts (a cargo-located node's asks
/// cargo for JSON messages), if any.
pub(crate) fn build_of(execution: &Execution) -> Option<Vec<String>> {
    let cmd = execution.build_command()?;
    Some(match execution.launch() {
        Launch::CargoBinary => with_json_messages(&cmd),
        _ => cmd,
    })
}

/// Builds the node in `dir` (unless `build` is false), showing progress
/// as `label`, and returns the argv that starts it.
pub(crate) async fn prepare(
    node: &str,
    label: &str,
    node_name: &str,
    dir: &Path,
    execution: &Execution,
    build: bool,
) -> Result<Vec<String>, ExecutableError> {
    let cargo = matches!(execution.launch(), Launch::CargoBinary);
    let tool = |source| ExecutableError::Tool {
        node: node.to_string(),
        source,
    };
    let stdout = match (build, build_of(execution)) {
        (true, Some(cmd)) => {
            let cmd = crate::python_sync::with_uv(&cmd).map_err(tool)?;
            Some(run_build(node, label, dir, &cmd, cargo).await?)
        }
        _ => None,
    };
    match execution.launch() {
        Launch::Command(argv) => crate::python_sync::with_uv(argv).map_err(tool),
        Launch::Container(container) => {
            let plan = crate::container::plan(dir, container, node).map_err(|source| {
                ExecutableError::Container {
                    node: node.to_string(),
                    source,
                }
            })?;
            let (builds, run) = crate::container::commands(&plan, container);
            if build && !crate::container::built(&plan) {
                crate::container::make_image_dir(&plan).map_err(|source| {
                    ExecutableError::Container {
                        node: node.to_string(),
                        source: crate::container::ContainerError::Image(source),
                    }
                })?;
                for cmd in builds {
                    let cmd = crate::python_sync::with_uv(&cmd).map_err(tool)?;
                    run_build(node, label, dir, &cmd, false).await?;
                }
                crate::container::finish_build(&plan).map_err(|source| {
                    ExecutableError::Container {
                        node: node.to_string(),
                        source: crate::container::ContainerError::Image(source),
                    }
                })?;
            }
            crate::python_sync::with_uv(&run).map_err(tool)
        }
        Launch::CargoBinary => {
            let exe = match stdout {
                Some(messages) => from_build_messages(&messages, dir, node_name),
                None => {
                    let cmd = execution.build_command().unwrap_or_default();
                    from_metadata(dir, &cmd, node_name).await
                }
            }
            .map_err(|source| ExecutableError::NoExecutable {
                node: node.to_string(),
                source,
            })?;
            Ok(vec![exe.display().to_string()])
        }
    }
}

#[derive(Deserialize)]
struct Message {
    reason: String,
    #[serde(default)]
    manifest_path: Option<PathBuf>,
    #[serde(default)]
    target: Option<Target>,
    #[serde(default)]
    executable: Option<PathBuf>,
}

#[derive(Deserialize)]
struct Target {
    name: String,
    kind: Vec<String>,
}

/// The package manifest of a node directory, canonical for comparison.
fn manifest_of(dir: &Path) -> PathBuf {
    let m = dir.join("Cargo.toml");
    std::fs::canonicalize(&m).unwrap_or(m)
}

/// Picks the node's binary among `(target name, path)` candidates: the only
/// one, or the one named like the node.
fn pick(
    candidates: Vec<(String, PathBuf)>,
    node_name: &str,
    tool: &'static str,
) -> Result<PathBuf, FindError> {
    match candidates.len() {
        0 => Err(FindError::NoBinary { tool }),
        1 => Ok(candidates.into_iter().next().expect("one").1),
        _ => {
            let binaries: Vec<String> = candidates.iter().map(|(n, _)| n.clone()).collect();
            candidates
                .into_iter()
                .find(|(n, _)| n == node_name)
                .map(|(_, p)| p)
                .ok_or_else(|| FindError::SeveralBinaries {
                    binaries,
                    node_name: node_name.to_string(),
                })
        }
    }
}

/// The executable cargo's `compiler-artifact` messages report for the
/// package whose manifest is in `dir`.
fn from_build_messages(stdout: &str, dir: &Path, node_name: &str) -> Result<PathBuf, FindError> {
    let manifest = manifest_of(dir);
    let mut candidates = Vec::new();
    for line in stdout.lines().filter(|l| l.starts_with('{')) {
        let Ok(m) = serde_json::from_str::<Message>(line) else {
            continue;
        };
        let (Some(path), Some(target), Some(exe)) = (m.manifest_path, m.target, m.executable)
        else {
            continue;
        };
        let same = std::fs::canonicalize(&path).unwrap_or(path) == manifest;
        if m.reason == "compiler-artifact" && same && target.kind.iter().any(|k| k == "bin") {
            candidates.push((target.name, exe));
        }
    }
    pick(candidates, node_name, "`cargo build`")
}

#[derive(Deserialize)]
struct Metadata {
    target_directory: PathBuf,
    packages: Vec<Package>,
}

#[derive(Deserialize)]
struct Package {
    manifest_path: PathBuf,
    targets: Vec<Target>,
}

/// Where `cargo build` (with the flags of `build_cmd`) puts its binaries,
/// below the target directory: `[<triple>/]<profile dir>`.
fn profile_dir(build_cmd: &[String]) -> PathBuf {
    let mut profile = "debug".to_string();
    let mut triple = None;
    let mut args = build_cmd.iter().skip(2);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--release" | "-r" => profile = "release".into(),
            "--profile" => {
                if let Some(p) = args.next() {
                    profile = p.clone();
                }
            }
            "--target" => triple = args.next().cloned(),
            _ => {
                if let Some(p) = a.strip_prefix("--profile=") {
                    profile = p.to_string();
                } else if let Some(t) = a.strip_prefix("--target=") {
                    triple = Some(t.to_string());
                }
            }
        }
    }
    // Cargo's own names for its built-in profiles' directories.
    if profile == "dev" || profile == "test" {
        profile = "debug".into();
    } else if profile == "bench" {
        profile = "release".into();
    }
    match triple {
        Some(t) => Path::new(&t).join(profile),
        None => PathBuf::from(profile),
    }
}

/// Whether `key` is one of the variables `cargo run` sets to describe the
/// program it runs, here peppy-launch's own package. A node's build must not
/// inherit them: build scripts that watch them (ring's watches
/// `CARGO_PKG_NAME` and `OUT_DIR`) would rerun, and every crate above them
/// (rustls, zenoh's TLS link, zenoh) would be rebuilt for the first node
/// `up` builds after `cargo run -p peppy-launch`.
fn describes_own_package(key: &str) -> bool {
    key.starts_with("CARGO_PKG_")
        || key.starts_with("CARGO_MANIFEST_")
        || matches!(
            key,
            "CARGO_CRATE_NAME" | "CARGO_BIN_NAME" | "CARGO_PRIMARY_PACKAGE" | "OUT_DIR"
        )
}

/// The executable of the package in `dir`, without building it.
async fn from_metadata(
    dir: &Path,
    build_cmd: &[String],
    node_name: &str,
) -> Result<PathBuf, FindError> {
    let output = tokio::process::Command::new("cargo")
        .args(["metadata", "--no-deps", "--format-version", "1"])
        .current_dir(dir)
        .stdin(Stdio::null())
        .output()
        .await
        .map_err(FindError::MetadataSpawn)?;
    if !output.status.success() {
        return Err(FindError::MetadataFailed {
            stderr: String::from_utf8_lossy(&output.stderr).trim().to_string(),
        });
    }
    let meta: Metadata =
        serde_json::from_slice(&output.stdout).map_err(FindError::MetadataUnreadable)?;
    let manifest = manifest_of(dir);
    let package = meta
        .packages
        .into_iter()
        .find(|p| {
            std::fs::canonicalize(&p.manifest_path).unwrap_or(p.manifest_path.clone()) == manifest
        })
        .ok_or_else(|| FindError::NoPackage {
            dir: dir.to_path_buf(),
        })?;
    let bin_dir = meta.target_directory.join(profile_dir(build_cmd));
    let candidates = package
        .targets
        .into_iter()
        .filter(|t| t.kind.iter().any(|k| k == "bin"))
        .map(|t| {
            let path = bin_dir.join(&t.name);
            (t.name, path)
        })
        .collect();
    let exe = pick(candidates, node_name, "`cargo metadata`")?;
    if exe.is_file() {
        Ok(exe)
    } else {
        Err(FindError::NotBuilt { exe })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn argv(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn a_node_build_forgets_what_cargo_run_said_about_the_launcher() {
        for own in [
            "CARGO_PKG_NAME",
            "CARGO_PKG_VERSION_MAJOR",
            "CARGO_MANIFEST_DIR",
            "CARGO_MANIFEST_PATH",
            "CARGO_CRATE_NAME",
            "CARGO_BIN_NAME",
            "CARGO_PRIMARY_PACKAGE",
            "OUT_DIR",
        ] {
            assert!(describes_own_package(own), "{own}");
        }
        // The user's own cargo settings stay.
        for theirs in [
            "CARGO",
            "CARGO_HOME",
            "CARGO_TARGET_DIR",
            "CARGO_TERM_COLOR",
            "CARGO_BUILD_JOBS",
            "PATH",
        ] {
            assert!(!describes_own_package(theirs), "{theirs}");
        }
    }

    #[test]
    fn the_profile_directory_follows_the_build_flags() {
        assert_eq!(profile_dir(&argv("cargo build")), Path::new("debug"));
        assert_eq!(
            profile_dir(&argv("cargo build -p x --release")),
            Path::new("release")
        );
        assert_eq!(
            profile_dir(&argv("cargo build --profile fast")),
            Path::new("fast")
        );
        assert_eq!(
            profile_dir(&argv("cargo build --profile=dev")),
            Path::new("debug")
        );
        assert_eq!(
            profile_dir(&argv("cargo build -r --target=aarch64-unknown-linux-gnu")),
            Path::new("aarch64-unknown-linux-gnu/release")
        );
    }

    #[test]
    fn json_messages_are_requested_once() {
        assert_eq!(
            with_json_messages(&argv("cargo build -p x")),
            argv("cargo build -p x --message-format=json-render-diagnostics")
        );
        assert_eq!(
            with_json_messages(&argv("cargo build --message-format=json")),
            argv("cargo build --message-format=json")
        );
    }

    #[test]
    fn the_executable_comes_from_the_artifact_of_the_node_package() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("Cargo.toml"), "").unwrap();
        let manifest = dir.path().join("Cargo.toml");
        let artifact = |pkg: &Path, name: &str, kind: &str, exe: &str| {
            serde_json::json!({
                "reason": "compiler-artifact",
                "manifest_path": pkg,
                "target": { "name": name, "kind": [kind] },
                "executable": if kind == "bin" { serde_json::json!(exe) } else { serde_json::Value::Null },
            })
            .to_string()
        };
        let stdout = [
            artifact(
                Path::new("/elsewhere/Cargo.toml"),
                "dep",
                "bin",
                "/t/debug/dep",
            ),
            artifact(&manifest, "cam", "lib", ""),
            r#"{"reason":"build-finished","success":true}"#.to_string(),
            "not json".to_string(),
            artifact(&manifest, "cam", "bin", "/custom/target/debug/cam"),
        ]
        .join("\n");
        assert_eq!(
            from_build_messages(&stdout, dir.path(), "cam").unwrap(),
            Path::new("/custom/target/debug/cam")
        );
        let two = format!(
            "{stdout}\n{}",
            artifact(&manifest, "tool", "bin", "/custom/target/debug/tool")
        );
        assert_eq!(
            from_build_messages(&two, dir.path(), "cam").unwrap(),
            Path::new("/custom/target/debug/cam")
        );
        let err = from_build_messages(&two, dir.path(), "other").unwrap_err();
        assert!(
            matches!(&err, FindError::SeveralBinaries { binaries, .. } if binaries.len() == 2),
            "{err}"
        );
        assert!(err.to_string().contains("(`cam`, `tool`)"), "{err}");
        let err = from_build_messages("", dir.path(), "cam").unwrap_err();
        assert!(
            matches!(
                err,
                FindError::NoBinary {
                    tool: "`cargo build`"
                }
            ),
            "{err}"
        );
        assert!(err.to_string().contains("run_cmd"), "{err}");
    }
}
