//! Managing running launches from another shell: `stop` ends one as Ctrl-C
//! does, `node stop|start|restart` acts on one instance through the
//! launch's control socket. A launch is found among this user's running
//! launches (`ps`): by pid, namespace, launcher path or launcher name, or
//! as the only one running.

use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use crate::cli::{NodeControlArgs, StopArgs};
use crate::control::{self, Request};
use crate::error::{Result, SetupError, UsageError};
use crate::runs::{self, LaunchRecord};

/// Why no launch (or instance) was chosen.
#[derive(Debug, thiserror::Error)]
pub enum ManageError {
    /// No launch runs.
    #[error("no launch is running (`peppy-launch ps` lists them)")]
    NothingRunning,
    /// None of the running launches is the one named.
    #[error("no running launch is `{which}`; running: {}", running.join("; "))]
    NoSuchLaunch {
        /// What was named.
        which: String,
        /// The launches running.
        running: Vec<String>,
    },
    /// Several launches fit; one must be named.
    #[error("{} launches are running; name one (pid, namespace or launcher): {}", several.len(), several.join("; "))]
    Several {
        /// The launches that fit.
        several: Vec<String>,
    },
    /// No running launch has the instance.
    #[error("no running launch has instance `{instance}`; running: {}", running.join("; "))]
    NoInstance {
        /// The instance named.
        instance: String,
        /// The launches running, with their instances.
        running: Vec<String>,
    },
    /// The launch did not end in time.
    #[error(
        "launch {pid} did not end within {waited:?} (`kill -INT {pid}` again kills its instances at once)"
    )]
    StillRunning {
        /// The launch's pid.
        pid: u32,
        /// How long `stop` waited.
        waited: Duration,
    },
    /// The launch refused the request or did not answer.
    #[error(transparent)]
    Control(#[from] control::ControlError),
}

fn label(r: &LaunchRecord) -> String {
    format!(
        "pid {} {} (namespace {})",
        r.pid,
        r.launcher.display(),
        r.namespace
    )
}

/// Whether `which` names the launch `r`: its pid, its namespace, its
/// launcher's path, or its launcher's name (file stem).
fn names(r: &LaunchRecord, which: &str) -> bool {
    if which.parse::<u32>().is_ok_and(|pid| pid == r.pid) || r.namespace == which {
        return true;
    }
    let path = Path::new(which);
    if path.exists() {
        let canonical = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        return r.launcher == canonical || r.launcher.parent() == Some(canonical.as_path());
    }
    r.launcher.file_stem().is_some_and(|s| s == which)
}

/// The one running launch `which` names (the only one when `None`).
fn select(
    running: &[LaunchRecord],
    which: Option<&str>,
) -> std::result::Result<LaunchRecord, ManageError> {
    if running.is_empty() {
        return Err(ManageError::NothingRunning);
    }
    let fits: Vec<&LaunchRecord> = running
        .iter()
        .filter(|r| which.is_none_or(|w| names(r, w)))
        .collect();
    match fits.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(ManageError::NoSuchLaunch {
            which: which.unwrap_or_default().to_string(),
            running: running.iter().map(label).collect(),
        }),
        several => Err(ManageError::Several {
            several: several.iter().map(|r| label(r)).collect(),
        }),
    }
}

fn usage(e: ManageError) -> crate::error::LaunchError {
    match e {
        ManageError::StillRunning { .. }
        | ManageError::Control(control::ControlError::Io { .. }) => SetupError::Manage(e).into(),
        other => UsageError::Manage(other).into(),
    }
}

/// `peppy-launch stop [LAUNCH]`: SIGINT to the launch, as Ctrl-C in its
/// terminal, then waits until it has ended (a detached launch's output is
/// shown meanwhile).
pub(crate) fn stop(args: &StopArgs) -> Result {
    let launch = select(&runs::running(), args.launch.as_deref()).map_err(usage)?;
    eprintln!("peppy-launch: stopping {}", label(&launch));
    // SAFETY: kill only sends a signal; the pid is a launch of this user's
    // that the registry shows alive.
    unsafe {
        libc::kill(launch.pid as libc::pid_t, libc::SIGINT);
    }
    let mut log = std::fs::File::open(launch.run_dir.join(crate::detach::LAUNCH_LOG))
        .ok()
        .map(|mut f| {
            // Only what the launch says from now on.
            let _ = f.seek(SeekFrom::End(0));
            f
        });
    let deadline = Instant::now() + args.timeout;
    loop {
        if let Some(f) = log.as_mut() {
            let mut buf = Vec::new();
            if f.read_to_end(&mut buf).is_ok() && !buf.is_empty() {
                let _ = std::io::stderr().write_all(&buf);
            }
        }
        // The registry, not the pid: a pid may be another process's by now.
        let alive = runs::running()
            .iter()
            .any(|r| r.pid == launch.pid && r.started_at_ms == launch.started_at_ms);
        if !alive {
            eprintln!("peppy-launch: stopped pid {}", launch.pid);
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(usage(ManageError::StillRunning {
                pid: launch.pid,
                waited: args.timeout,
            }));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// `node stop|start|restart INSTANCE`: asks the launch running the
/// instance through its control socket.
pub(crate) fn node(args: &NodeControlArgs, request: fn(String) -> Request) -> Result {
    let running = runs::running();
    let candidates: Vec<LaunchRecord> = running
        .iter()
        .filter(|r| args.launch.as_deref().is_none_or(|w| names(r, w)))
        .filter(|r| r.instances.iter().any(|(id, _)| *id == args.instance))
        .cloned()
        .collect();
    let launch = match candidates.as_slice() {
        [one] => one.clone(),
        [] => {
            return Err(usage(ManageError::NoInstance {
                instance: args.instance.clone(),
                running: running
                    .iter()
                    .map(|r| {
                        let ids: Vec<&str> = r.instances.iter().map(|(i, _)| i.as_str()).collect();
                        format!("{}: {}", label(r), ids.join(", "))
                    })
                    .collect(),
            }));
        }
        several => {
            return Err(usage(ManageError::Several {
                several: several.iter().map(label).collect(),
            }));
        }
    };
    // A stop waits for the instance's shutdown hooks: the launch bounds it.
    let message = control::ask(
        launch.pid,
        launch.control.as_deref(),
        &request(args.instance.clone()),
        Duration::from_secs(3600),
    )
    .map_err(|e| usage(e.into()))?;
    println!("{message}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(pid: u32, launcher: &str, namespace: &str) -> LaunchRecord {
        LaunchRecord {
            pid,
            launcher: launcher.into(),
            namespace: namespace.into(),
            core_node: "c".into(),
            connect: Vec::new(),
            run_dir: "/nonexistent".into(),
            started_at_ms: 0,
            instances: vec![("cam".into(), "cam:v1".into())],
            login: None,
            control: None,
        }
    }

    #[test]
    fn a_launch_is_named_by_pid_namespace_or_launcher_name() {
        let running = [
            record(10, "/x/camera_viewer.json5", "viewer-ns"),
            record(11, "/x/robot.json5", "robot-ns"),
        ];
        assert_eq!(select(&running, Some("11")).unwrap().pid, 11);
        assert_eq!(select(&running, Some("viewer-ns")).unwrap().pid, 10);
        assert_eq!(select(&running, Some("robot")).unwrap().pid, 11);
        assert!(matches!(
            select(&running, None),
            Err(ManageError::Several { .. })
        ));
        assert!(matches!(
            select(&running, Some("nope")),
            Err(ManageError::NoSuchLaunch { .. })
        ));
        assert!(matches!(
            select(&[], None),
            Err(ManageError::NothingRunning)
        ));
        assert_eq!(select(&running[..1], None).unwrap().pid, 10);
    }
}
