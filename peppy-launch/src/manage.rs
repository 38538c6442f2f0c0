//! Managing running launches from another shell: `stop` ends one as Ctrl-C
//! does, `node stop|start|restart` acts on one instance through the
//! launch's control socket. A launch is found among this user's running
//! launches (`ps`): by pid, namespace, launcher path or launcher name, or
//! as the only one running.

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
    /// `run --join` of a secured launch: its instances' logins come from
    /// its launcher.
    #[error(
        "launch {pid} is secured: its instances come from its launcher (`run --join` cannot give one a login)"
    )]
    Secured {
        /// The launch's pid.
        pid: u32,
    },
    /// `run --join` with a `--namespace` that is not the launch's.
    #[error("launch {pid} runs in namespace `{launch}`, not `{given}`")]
    OtherNamespace {
        /// The launch's pid.
        pid: u32,
        /// Its namespace.
        launch: String,
        /// The one given.
        given: String,
    },
    /// The stack runs an instance of that id already.
    #[error(
        "the stack runs an instance `{instance}` ({node}) already; give another `--instance-id`"
    )]
    TakenId {
        /// The instance id.
        instance: String,
        /// Its node.
        node: String,
    },
    /// A slot is linked to an instance the stack does not run.
    #[error("slot `{slot}` is linked to `{producer}`, which the launch does not run (it runs: {})", running.join(", "))]
    NotInLaunch {
        /// The slot.
        slot: String,
        /// The producer named.
        producer: String,
        /// The instances the stack runs.
        running: Vec<String>,
    },
    /// A slot is linked to an instance of another node than it takes.
    #[error("slot `{slot}` takes {wants}, but `{producer}` is {is}")]
    WrongProducer {
        /// The slot.
        slot: String,
        /// The producer named.
        producer: String,
        /// What the slot takes.
        wants: String,
        /// What the producer is.
        is: String,
    },
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
        if r.launcher == canonical || r.launcher.parent() == Some(canonical.as_path()) {
            return true;
        }
    }
    // A name, also where a folder of that name happens to be here.
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
    // A detached launch's own output, from now on.
    let log_path = launch.run_dir.join(crate::detach::LAUNCH_LOG);
    let mut log = runs::LogReader::at_end(&log_path);
    let show = |lines: Vec<String>| {
        for line in lines {
            eprintln!("{line}");
        }
    };
    let deadline = Instant::now() + args.timeout;
    loop {
        show(log.read_new(&log_path).unwrap_or_default());
        // The registry, not the pid: a pid may be another process's by now.
        let alive = runs::running()
            .iter()
            .any(|r| r.pid == launch.pid && r.started_at_ms == launch.started_at_ms);
        if !alive {
            show(log.read_new(&log_path).unwrap_or_default());
            show(log.rest().into_iter().collect());
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

/// The running launch `run --join WHICH` adds to (`-`: the only one).
pub(crate) fn joinable(which: &str, namespace: Option<&str>) -> Result<LaunchRecord> {
    let which = (which != "-").then_some(which);
    let launch = select(&runs::running(), which).map_err(usage)?;
    if launch.login.is_some() {
        return Err(usage(ManageError::Secured { pid: launch.pid }));
    }
    if let Some(given) = namespace
        && given != launch.namespace
    {
        return Err(usage(ManageError::OtherNamespace {
            pid: launch.pid,
            launch: launch.namespace.clone(),
            given: given.to_string(),
        }));
    }
    if launch.control.is_none() {
        return Err(usage(
            control::ControlError::NoSocket { pid: launch.pid }.into(),
        ));
    }
    Ok(launch)
}

/// Checks a joining instance's slots against what the stack runs, as a
/// launcher's links are checked: every producer a slot is linked to is
/// an instance of the stack (this launch, and the launches sharing its
/// namespace and network), of the node a node slot takes, or of a node
/// that implements the contract a contract slot takes.
pub(crate) fn check_links(
    launch: &LaunchRecord,
    config: &peppy_runtime::StartupConfig,
    repos: &[std::path::PathBuf],
) -> Result {
    let live: Vec<(String, String)> = runs::running()
        .into_iter()
        .filter(|r| r.namespace == launch.namespace && r.connect == launch.connect)
        .flat_map(|r| r.instances)
        .collect();
    let launcher_dir = launch
        .launcher
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    if let Some((_, node)) = live.iter().find(|(id, _)| *id == config.instance_id) {
        return Err(usage(ManageError::TakenId {
            instance: config.instance_id.clone(),
            node: node.clone(),
        }));
    }
    let mut index = None;
    for slot in &config.slots {
        for producer in crate::core_view::producers(&slot.binding) {
            let Some((_, node)) = live.iter().find(|(id, _)| id == producer) else {
                return Err(usage(ManageError::NotInLaunch {
                    slot: slot.link_id.clone(),
                    producer: producer.clone(),
                    running: live.iter().map(|(id, n)| format!("{id} ({n})")).collect(),
                }));
            };
            let wants = slot.target.to_string();
            let fits = match slot.kind {
                peppy_schema::SlotKind::Node => *node == wants,
                peppy_schema::SlotKind::Interface => {
                    let index = index.get_or_insert_with(|| {
                        crate::repositories::index(repos, &launcher_dir).unwrap_or_default()
                    });
                    match peppy_schema::Identity::parse(node).and_then(|id| index.node(&id)) {
                        Some(entry) => entry
                            .doc
                            .conforms_to
                            .iter()
                            .any(|c| c.target == slot.target),
                        None => {
                            eprintln!(
                                "peppy-launch: cannot check that `{producer}` ({node}) implements {wants}: no repository searched from {} provides {node}",
                                launcher_dir.display()
                            );
                            true
                        }
                    }
                }
            };
            if !fits {
                let wants = match slot.kind {
                    peppy_schema::SlotKind::Node => format!("node {wants}"),
                    peppy_schema::SlotKind::Interface => format!("an implementation of {wants}"),
                };
                return Err(usage(ManageError::WrongProducer {
                    slot: slot.link_id.clone(),
                    producer: producer.clone(),
                    wants,
                    is: node.clone(),
                }));
            }
        }
    }
    Ok(())
}

/// Asks `launch` to start and supervise `addition`.
pub(crate) fn add(launch: &LaunchRecord, addition: control::Addition) -> Result {
    let message = control::ask(
        launch.pid,
        launch.control.as_deref(),
        &Request::Add {
            addition: Box::new(addition),
        },
        Duration::from_secs(90),
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
            recorder_login: None,
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
