//! `up --detach`: a launch that outlives its terminal.
//!
//! The command starts itself again as the launch's supervisor, in a
//! session of its own (no terminal: Ctrl-C and a closed terminal do not
//! reach it), its output going to a log file. The foreground process
//! shows that log as it grows (checks, builds, starts) and returns once
//! every instance has started, or with the launch's own failure when it
//! could not start. The supervisor then moves its log into its run
//! directory (`launch.log`) and runs until `peppy-launch stop`. Its
//! instances die with it (each has a parent-death signal), so a killed
//! supervisor leaves no orphan nodes.

use std::io::{Read, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::error::{LaunchError, Result, SetupError};

/// Set in the supervisor: where it says it has started every instance.
const STATUS_ENV: &str = "PEPPY_DETACHED_STATUS";
/// Set in the supervisor: its log, moved into its run directory once the
/// run directory is known.
const LOG_ENV: &str = "PEPPY_DETACHED_LOG";

/// The supervisor's side, read once (and taken out of the environment, so
/// the nodes it starts do not inherit it).
#[derive(Debug, Clone)]
pub(crate) struct Detached {
    status: PathBuf,
    log: Option<PathBuf>,
}

static DETACHED: std::sync::OnceLock<Option<Detached>> = std::sync::OnceLock::new();

/// Whether this process is a detached launch's supervisor. Call before any
/// thread starts (it edits the environment).
pub(crate) fn take_role() -> bool {
    DETACHED
        .get_or_init(|| {
            let status = std::env::var_os(STATUS_ENV)?;
            let log = std::env::var_os(LOG_ENV).map(PathBuf::from);
            // SAFETY: called first thing by `up`, before the runtime (or any
            // other thread) starts.
            unsafe {
                std::env::remove_var(STATUS_ENV);
                std::env::remove_var(LOG_ENV);
            }
            Some(Detached {
                status: PathBuf::from(status),
                log,
            })
        })
        .is_some()
}

/// In a detached launch's supervisor: every instance has started. Its log
/// moves into `run_dir` and the foreground process is told.
pub(crate) fn started(run_dir: &Path) {
    let Some(Some(detached)) = DETACHED.get() else {
        return;
    };
    if let Some(log) = &detached.log {
        let target = run_dir.join(LAUNCH_LOG);
        // The log stays open as this process's output; only its name moves.
        if std::fs::rename(log, &target).is_err()
            && let Err(e) = move_output(log, &target)
        {
            eprintln!(
                "peppy-launch: the launch's output stays in {} ({e})",
                log.display()
            );
        }
    }
    let tmp = detached.status.with_extension("tmp");
    let written = std::fs::write(&tmp, run_dir.display().to_string())
        .and_then(|()| std::fs::rename(&tmp, &detached.status));
    if let Err(e) = written {
        eprintln!(
            "peppy-launch: cannot tell the foreground process that the launch started ({}): {e}",
            detached.status.display()
        );
    }
}

/// Where the log cannot be renamed (another file system): what was
/// written so far is copied to `to`, which this process writes on from
/// now, and `from` goes.
fn move_output(from: &Path, to: &Path) -> std::io::Result<()> {
    use std::os::fd::AsRawFd;
    let new = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(to)?;
    std::io::copy(&mut std::fs::File::open(from)?, &mut &new)?;
    for fd in [libc::STDOUT_FILENO, libc::STDERR_FILENO] {
        // SAFETY: dup2 onto this process's own standard descriptors.
        if unsafe { libc::dup2(new.as_raw_fd(), fd) } < 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    std::fs::remove_file(from)
}

/// A detached launch's own output, in its run directory.
pub(crate) const LAUNCH_LOG: &str = "launch.log";

/// Why a detached launch was not started.
#[derive(Debug, thiserror::Error)]
pub enum DetachError {
    /// The supervisor process could not be started.
    #[error("cannot start the launch in the background: {0}")]
    Spawn(std::io::Error),
    /// Its log could not be made or read.
    #[error("cannot use {}: {source}", path.display())]
    Log {
        /// The log.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The foreground side of `up --detach`: starts the supervisor, shows its
/// output until it has started every instance (`Ok`) or ended (its exit
/// code, as [`LaunchError::Detached`]).
pub(crate) fn launch() -> Result {
    let dir = crate::runs::state_dir().join("detached");
    let me = std::process::id();
    let (log, status) = (
        dir.join(format!("{me}.log")),
        dir.join(format!("{me}.status")),
    );
    let log_error = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SetupError::Detach(DetachError::Log { path, source })
    };
    std::fs::create_dir_all(&dir).map_err(log_error(&dir))?;
    let _ = std::fs::remove_file(&status);
    let out = std::fs::File::create(&log).map_err(log_error(&log))?;
    let err = out.try_clone().map_err(log_error(&log))?;
    let exe = std::env::current_exe().map_err(|e| SetupError::Detach(DetachError::Spawn(e)))?;
    let mut command = std::process::Command::new(exe);
    command
        .args(std::env::args_os().skip(1))
        .env(STATUS_ENV, &status)
        .env(LOG_ENV, &log)
        .stdin(std::process::Stdio::null())
        .stdout(out)
        .stderr(err);
    // SAFETY: setsid is async-signal-safe; the child leaves this terminal's
    // session so its signals and hang-up do not reach the launch.
    unsafe {
        command.pre_exec(|| {
            if libc::setsid() < 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command
        .spawn()
        .map_err(|e| SetupError::Detach(DetachError::Spawn(e)))?;
    let mut reader = std::fs::File::open(&log).map_err(log_error(&log))?;
    let interrupted = interrupt_flag();
    let mut forwarded = false;
    loop {
        copy_new(&mut reader);
        if let Ok(run_dir) = std::fs::read_to_string(&status) {
            copy_new(&mut reader);
            let _ = std::fs::remove_file(&status);
            say_where(child.id(), Path::new(run_dir.trim()));
            return Ok(());
        }
        if let Ok(Some(ended)) = child.try_wait() {
            copy_new(&mut reader);
            let _ = std::fs::remove_file(&log);
            let code = ended.code().unwrap_or(1).clamp(1, 255) as u8;
            return Err(LaunchError::Detached { code });
        }
        if !forwarded && interrupted.load(std::sync::atomic::Ordering::Relaxed) {
            // Ctrl-C before the launch has started: stop it, as the
            // launch itself would have been stopped in the foreground.
            // SAFETY: kill only sends a signal to our own child.
            unsafe {
                libc::kill(child.id() as libc::pid_t, libc::SIGINT);
            }
            forwarded = true;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Copies what the supervisor wrote since the last call to stderr. Read
/// through the handle opened at the start (not by path, as `logs` reads):
/// the supervisor renames the file into its run directory meanwhile.
fn copy_new(reader: &mut std::fs::File) {
    let mut buf = Vec::new();
    if reader.read_to_end(&mut buf).is_ok() && !buf.is_empty() {
        let _ = std::io::stderr().write_all(&buf);
    }
}

fn say_where(pid: u32, run_dir: &Path) {
    let namespace = std::fs::read(run_dir.join(crate::runs::RECORD_FILE))
        .ok()
        .and_then(|b| serde_json::from_slice::<crate::runs::LaunchRecord>(&b).ok())
        .map(|r| r.namespace)
        .unwrap_or_default();
    eprintln!(
        "peppy-launch: the launch runs in the background as pid {pid} (namespace {namespace}); its output goes to {}",
        run_dir.join(LAUNCH_LOG).display()
    );
    eprintln!(
        "peppy-launch: `peppy-launch ps` lists it, `peppy-launch logs INSTANCE` shows an instance, `peppy-launch stop` ends it"
    );
}

/// A flag set by SIGINT, for the foreground process's wait.
fn interrupt_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [libc::SIGINT, libc::SIGTERM] {
        let set = flag.clone();
        // SAFETY: the action only stores to an atomic, which is
        // async-signal-safe.
        let _ = unsafe {
            signal_hook_registry::register(signal, move || {
                set.store(true, std::sync::atomic::Ordering::Relaxed);
            })
        };
    }
    flag
}
