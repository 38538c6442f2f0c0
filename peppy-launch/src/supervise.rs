//! Running instances: each in its own process group with a parent-death
//! signal, restarted per its policy, and stopped in escalating steps.
//!
//! Stop sequence (SPEC 6.4): SIGINT to every instance's group, wait up to
//! the grace period, SIGTERM, wait 5 s, SIGKILL. The grace period is at
//! least the node's shutdown-hook window plus a margin (`up`'s
//! `start_instance`), since a node takes a second signal during its hooks
//! as "exit now". A second Ctrl-C kills at once. Every wait has a deadline.

use std::path::PathBuf;
use std::process::{ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppy_schema::RestartPolicy;
use tokio::process::{Child, Command};
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;

use crate::output::{Log, Output, pump};

/// How long after SIGTERM before SIGKILL.
pub(crate) const TERM_TIMEOUT: Duration = Duration::from_secs(5);
/// Restarts allowed in a row before the instance is given up.
const RESTART_BUDGET: u32 = 5;
/// A run at least this long resets the restart budget.
const HEALTHY_RUN: Duration = Duration::from_secs(30);

/// One instance to run.
#[derive(Debug, Clone)]
pub(crate) struct InstanceSpec {
    pub(crate) id: String,
    pub(crate) dir: PathBuf,
    pub(crate) argv: Vec<String>,
    pub(crate) env: Vec<(String, String)>,
    pub(crate) restart: RestartPolicy,
    pub(crate) log: PathBuf,
}

/// How an instance ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Ended {
    /// Exited with status 0 on its own.
    Finished,
    /// Stopped on request within the grace period.
    Stopped,
    /// Did not stop within the grace period and was killed.
    ForceKilled,
    /// Exited with a failure and was not restarted.
    Failed(String),
    /// Kept failing; the restart budget ran out.
    BudgetExhausted(String),
}

impl Ended {
    pub(crate) fn is_failure(&self) -> bool {
        matches!(self, Ended::Failed(_) | Ended::BudgetExhausted(_))
    }
}

/// A request for one instance from the launch's control socket; each
/// carries where to say what came of it.
#[derive(Debug)]
pub(crate) enum InstanceCommand {
    /// Stop it (as the launch would) and hold it stopped.
    Stop(oneshot::Sender<String>),
    /// Start it again if it is held stopped.
    Start(oneshot::Sender<String>),
    /// Stop it and start it again.
    Restart(oneshot::Sender<String>),
}

/// Stop requests shared by every instance.
#[derive(Clone, Default)]
pub(crate) struct StopSignals {
    /// The launch is stopping: no more restarts.
    pub(crate) stopping: CancellationToken,
    /// This instance's turn to stop, gracefully (its consumers have
    /// stopped already).
    pub(crate) stop: CancellationToken,
    /// Second Ctrl-C: kill now.
    pub(crate) kill: CancellationToken,
}

impl StopSignals {
    /// One instance's signals within the launch's: its own turn to stop,
    /// the launch's stopping and killing.
    pub(crate) fn instance(&self) -> StopSignals {
        StopSignals {
            stopping: self.stopping.clone(),
            stop: CancellationToken::new(),
            kill: self.kill.clone(),
        }
    }
}

fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exited with status {c}"),
        (None, Some(s)) => format!("killed by signal {s}"),
        _ => "exited".to_string(),
    }
}

fn signal_group(pid: u32, signal: libc::c_int) {
    // SAFETY: killpg only sends a signal; a stale group id fails with ESRCH.
    unsafe {
        libc::killpg(pid as libc::pid_t, signal);
    }
}

/// Starts one process of `spec`, its output pumped to `out` and its log.
pub(crate) fn spawn(
    spec: &InstanceSpec,
    out: &Arc<Output>,
) -> std::io::Result<(Child, Vec<tokio::task::JoinHandle<()>>)> {
    let program = {
        let p = PathBuf::from(&spec.argv[0]);
        if p.components().count() > 1 && p.is_relative() {
            spec.dir.join(p)
        } else {
            p
        }
    };
    let mut cmd = Command::new(&program);
    cmd.args(&spec.argv[1..])
        .current_dir(&spec.dir)
        // Output is multiplexed line by line: a Python node's prints must
        // not sit in a pipe buffer until it fills.
        .env("PYTHONUNBUFFERED", "1")
        .envs(spec.env.iter().map(|(k, v)| (k, v)))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .kill_on_drop(false);
    // SAFETY: prctl is async-signal-safe; it only sets a flag on the child.
    unsafe {
        cmd.pre_exec(|| {
            #[cfg(target_os = "linux")]
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            crate::open_files::restore_in_child()
        });
    }
    // Opened before the process starts: an instance whose log cannot be
    // created (a full disk, no file descriptor left) must not run on,
    // unsupervised, after its start was reported as failed.
    let log = Log::open(&spec.log)
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot open its log: {e}")))?;
    let mut child = cmd.spawn().map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!("cannot start `{}`: {e}", program.display()),
        )
    })?;
    // `peppy-launch ps` reads the current process of each instance here.
    if let Some(pid) = child.id() {
        let _ = std::fs::write(spec.log.with_extension("pid"), format!("{pid}\n"));
    }
    let log = Arc::new(Mutex::new(log));
    let mut pumps = Vec::new();
    if let Some(o) = child.stdout.take() {
        pumps.push(tokio::spawn(pump(
            o,
            spec.id.clone(),
            out.clone(),
            log.clone(),
        )));
    }
    if let Some(e) = child.stderr.take() {
        pumps.push(tokio::spawn(pump(e, spec.id.clone(), out.clone(), log)));
    }
    Ok((child, pumps))
}

/// Stops one running child: SIGINT, grace, SIGTERM, 5 s, SIGKILL (or at
/// once on a kill request). Leaves nothing of its process group behind.
async fn stop_child(
    child: &mut Child,
    grace: Duration,
    signals: &StopSignals,
    out: &Output,
    id: &str,
) -> Ended {
    let Some(pid) = child.id() else {
        return Ended::Stopped;
    };
    let steps = [(libc::SIGINT, grace), (libc::SIGTERM, TERM_TIMEOUT)];
    for (signal, wait) in steps {
        if signals.kill.is_cancelled() {
            break;
        }
        signal_group(pid, signal);
        tokio::select! {
            _ = child.wait() => {
                signal_group(pid, libc::SIGKILL);
                return Ended::Stopped;
            }
            () = tokio::time::sleep(wait) => {}
            () = signals.kill.cancelled() => break,
        }
    }
    signal_group(pid, libc::SIGKILL);
    let _ = tokio::time::timeout(Duration::from_secs(5), child.wait()).await;
    out.note(&format!("`{id}` did not stop in time: force-killed"));
    Ended::ForceKilled
}

/// What woke a supervisor up.
enum Event {
    /// The instance's process exited.
    Exited(std::io::Result<ExitStatus>),
    /// The launch asked it to stop for good.
    LaunchStop,
    /// The control socket asked for something.
    Command(InstanceCommand),
}

/// Runs an already started instance until it ends for good (restarting it
/// per its policy) or a stop is requested. Commands from the control
/// socket stop it and hold it stopped, start it again, or restart it.
pub(crate) async fn supervise(
    spec: InstanceSpec,
    mut child: Child,
    mut pumps: Vec<tokio::task::JoinHandle<()>>,
    grace: Duration,
    signals: StopSignals,
    out: Arc<Output>,
    mut commands: mpsc::UnboundedReceiver<InstanceCommand>,
) -> Ended {
    let mut failures_in_a_row = 0u32;
    let mut started = Instant::now();
    // Taken now: once `wait` has returned, the child no longer knows its pid.
    let mut group = child.id();
    loop {
        let event = tokio::select! {
            s = child.wait() => Event::Exited(s),
            () = signals.stop.cancelled() => Event::LaunchStop,
            Some(command) = commands.recv() => Event::Command(command),
        };
        // Who asked for the start that follows, if anyone did.
        let requested = match event {
            Event::Exited(status) => {
                // The instance's main process is gone: clear anything it
                // left in its group.
                if let Some(pid) = group {
                    signal_group(pid, libc::SIGKILL);
                }
                drain(&mut pumps).await;
                let (ok, what) = match status {
                    Ok(s) => (s.success(), describe(s)),
                    Err(e) => (false, format!("could not be waited for: {e}")),
                };
                let restart = match spec.restart {
                    RestartPolicy::Always => true,
                    RestartPolicy::OnFailure => !ok,
                    RestartPolicy::No => false,
                };
                if !restart || signals.stop.is_cancelled() || signals.stopping.is_cancelled() {
                    return if ok {
                        out.note(&format!("`{}` {what}", spec.id));
                        Ended::Finished
                    } else {
                        out.note(&format!(
                            "`{}` failed: {what} (log: {})",
                            spec.id,
                            spec.log.display()
                        ));
                        Ended::Failed(what)
                    };
                }
                if started.elapsed() >= HEALTHY_RUN {
                    failures_in_a_row = 0;
                }
                failures_in_a_row += 1;
                if failures_in_a_row > RESTART_BUDGET {
                    out.note(&format!(
                        "`{}` {what}; restart budget of {RESTART_BUDGET} used up, giving up (log: {})",
                        spec.id,
                        spec.log.display()
                    ));
                    return Ended::BudgetExhausted(what);
                }
                let backoff = Duration::from_millis(250 * 2u64.pow(failures_in_a_row - 1))
                    .min(Duration::from_secs(8));
                out.note(&format!(
                    "`{}` {what}; restarting in {backoff:.1?} ({failures_in_a_row}/{RESTART_BUDGET})",
                    spec.id
                ));
                tokio::select! {
                    () = tokio::time::sleep(backoff) => {}
                    () = signals.stop.cancelled() => return if ok { Ended::Finished } else { Ended::Failed(what) },
                    () = signals.stopping.cancelled() => return if ok { Ended::Finished } else { Ended::Failed(what) },
                }
                None
            }
            Event::LaunchStop => {
                let ended = stop_child(&mut child, grace, &signals, &out, &spec.id).await;
                drain(&mut pumps).await;
                return ended;
            }
            Event::Command(InstanceCommand::Start(reply)) => {
                let _ = reply.send(format!("`{}` is running already", spec.id));
                continue;
            }
            Event::Command(InstanceCommand::Stop(reply)) => {
                let how = stop_child(&mut child, grace, &signals, &out, &spec.id).await;
                drain(&mut pumps).await;
                // `ps` shows it stopped.
                let _ = std::fs::remove_file(spec.log.with_extension("pid"));
                out.note(&format!(
                    "`{}` stopped on request (`node start` starts it again)",
                    spec.id
                ));
                let _ = reply.send(match how {
                    Ended::ForceKilled => {
                        format!("`{}` did not stop in time: force-killed", spec.id)
                    }
                    _ => format!("`{}` stopped", spec.id),
                });
                let Some(reply) = held(&spec.id, &signals, &mut commands).await else {
                    return Ended::Stopped;
                };
                Some(reply)
            }
            Event::Command(InstanceCommand::Restart(reply)) => {
                stop_child(&mut child, grace, &signals, &out, &spec.id).await;
                drain(&mut pumps).await;
                Some(reply)
            }
        };
        match spawn(&spec, &out) {
            Ok((c, p)) => {
                child = c;
                group = child.id();
                pumps = p;
                started = Instant::now();
                if let Some(reply) = requested {
                    // Started on request: a fresh restart budget.
                    failures_in_a_row = 0;
                    let message =
                        format!("`{}` started as pid {}", spec.id, group.unwrap_or_default());
                    out.note(&format!("{message} (on request)"));
                    let _ = reply.send(message);
                }
            }
            Err(e) => {
                let message = format!("`{}` could not be restarted: {e}", spec.id);
                out.note(&message);
                if let Some(reply) = requested {
                    let _ = reply.send(message);
                }
                return Ended::Failed(e.to_string());
            }
        }
    }
}

/// An instance held stopped by `node stop`: the reply channel of the
/// `node start` (or `restart`) that starts it again, or `None` once the
/// launch stops.
async fn held(
    id: &str,
    signals: &StopSignals,
    commands: &mut mpsc::UnboundedReceiver<InstanceCommand>,
) -> Option<oneshot::Sender<String>> {
    loop {
        tokio::select! {
            () = signals.stop.cancelled() => return None,
            () = signals.stopping.cancelled() => return None,
            command = commands.recv() => match command {
                Some(InstanceCommand::Start(reply) | InstanceCommand::Restart(reply)) => {
                    return Some(reply);
                }
                Some(InstanceCommand::Stop(reply)) => {
                    let _ = reply.send(format!("`{id}` is stopped already"));
                }
                None => {
                    // No one can start it again: wait for the launch's stop.
                    tokio::select! {
                        () = signals.stop.cancelled() => {}
                        () = signals.stopping.cancelled() => {}
                    }
                    return None;
                }
            },
        }
    }
}

/// Waits (bounded) for an instance's output to be fully copied.
async fn drain(pumps: &mut Vec<tokio::task::JoinHandle<()>>) {
    for p in pumps.drain(..) {
        let _ = tokio::time::timeout(Duration::from_secs(2), p).await;
    }
}
