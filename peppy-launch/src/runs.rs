//! The launches running on this machine. `up` and `run` write a record of
//! each launch into its run directory ([`RECORD_FILE`], beside the
//! instances' runtime configs, logs and pid files) and a copy into a per-user registry,
//! removed when the launch ends. `ps`, `logs` and the inspection commands
//! find a stack through them: by its launcher, its namespace, or as the
//! only one running.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The registry directory: `$PEPPY_STATE_DIR`, else
/// `$XDG_STATE_HOME/peppy`, else `~/.local/state/peppy`.
pub(crate) fn state_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("PEPPY_STATE_DIR").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    if let Some(dir) = std::env::var_os("XDG_STATE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir).join("peppy");
    }
    match std::env::var_os("HOME").filter(|d| !d.is_empty()) {
        Some(home) => PathBuf::from(home).join(".local/state/peppy"),
        None => std::env::temp_dir().join(format!("peppy-{}", unsafe { libc::getuid() })),
    }
}

fn registry() -> PathBuf {
    state_dir().join("launches")
}

/// One launch: where it runs and how to reach it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct LaunchRecord {
    /// The `peppy-launch` process.
    pub(crate) pid: u32,
    /// The launcher file (absolute), or the node for a `run`.
    pub(crate) launcher: PathBuf,
    /// The stack's namespace.
    pub(crate) namespace: String,
    /// The launch's core node.
    pub(crate) core_node: String,
    /// Endpoints that reach the stack's Zenoh network from this machine.
    pub(crate) connect: Vec<String>,
    /// The run directory (logs, pid files, runtime configs).
    pub(crate) run_dir: PathBuf,
    /// Milliseconds since the Unix epoch.
    pub(crate) started_at_ms: u64,
    /// Instance ids with their node `name:tag`, in start order.
    pub(crate) instances: Vec<(String, String)>,
    /// With security on: the login of the launching user's tools (which is
    /// why records are readable by that user only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) login: Option<peppy_runtime::Login>,
    /// With security on: the read-only login of `record` and `view`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) recorder_login: Option<peppy_runtime::Login>,
    /// The launch's control socket (`stop`, `node stop|start|restart`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) control: Option<PathBuf>,
}

impl LaunchRecord {
    /// The log of `instance`.
    pub(crate) fn log_of(&self, instance: &str) -> PathBuf {
        self.run_dir.join(format!("{instance}.log"))
    }

    /// The current process of `instance`, if it runs.
    pub(crate) fn pid_of(&self, instance: &str) -> Option<u32> {
        let text = std::fs::read_to_string(self.run_dir.join(format!("{instance}.pid"))).ok()?;
        text.trim().parse().ok().filter(|&pid| pid_alive(pid))
    }
}

/// Whether a process with this pid exists.
pub(crate) fn pid_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks that the process exists.
    pid > 0 && (unsafe { libc::kill(pid, 0) } == 0 || last_errno() == libc::EPERM)
}

fn last_errno() -> i32 {
    std::io::Error::last_os_error().raw_os_error().unwrap_or(0)
}

/// A launch's record, registered while it runs: the registry entry stays
/// locked (`flock`) for the launch's life, so an entry whose lock is free
/// belongs to a launch that ended, however it ended, even if its pid has
/// been reused since.
#[derive(Debug)]
pub(crate) struct Registration {
    entry: PathBuf,
    _lock: std::fs::File,
}

impl Drop for Registration {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.entry);
    }
}

/// A registered launch and its record, kept current as instances join it.
pub(crate) struct Registered {
    registration: Registration,
    record: LaunchRecord,
}

impl Registered {
    /// Registers `record` ([`register`]).
    pub(crate) fn new(record: LaunchRecord) -> Result<Registered, RegistryError> {
        Ok(Registered {
            registration: register(&record)?,
            record,
        })
    }

    /// The record as registered.
    pub(crate) fn record(&self) -> &LaunchRecord {
        &self.record
    }

    /// Records that instance `id` of node `node` joined the launch, so
    /// `ps`, `logs` and `node stop` find it; a failure is said in a note.
    pub(crate) fn add_instance(&mut self, id: &str, node: &str, out: &crate::output::Output) {
        self.record
            .instances
            .push((id.to_string(), node.to_string()));
        let text = serde_json::to_vec_pretty(&self.record).expect("a launch record serializes");
        let in_run = self.record.run_dir.join(RECORD_FILE);
        let written = write_whole(&in_run, &text, false).and_then(|_| {
            // The new entry replaces the old one, locked before it is in
            // place, so the launch never looks ended to `ps`.
            let lock = write_whole(&self.registration.entry, &text, true)?;
            self.registration._lock = lock;
            Ok(())
        });
        if let Err(e) = written {
            out.note(&format!("`{id}` is not in the launch's record: {e}"));
        }
    }
}

/// The record's name in its run directory (instance ids hold no `.`, so no
/// instance's `<id>.json` runtime config can take it).
pub(crate) const RECORD_FILE: &str = "launch.record.json";

/// Takes the lock of a registry entry without waiting: `false` when a
/// running launch holds it.
fn try_lock(file: &std::fs::File) -> bool {
    use std::os::fd::AsRawFd as _;
    // SAFETY: flock on a file descriptor we own; no memory is involved.
    unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) == 0 }
}

/// Whether the open `file` is the one at `path` (same device and inode).
fn same_file(file: &std::fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt as _;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Writes `text` to `path` through a temporary file and a rename, so a
/// reader never sees half a record; returns the written file, still open.
fn write_whole(path: &Path, text: &[u8], lock: bool) -> std::io::Result<std::fs::File> {
    use std::io::Write as _;
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    // A secured launch's record holds its tools' password.
    let mut file = crate::security::create_private(&tmp)?;
    file.write_all(text)?;
    if lock && !try_lock(&file) {
        return Err(std::io::Error::other("the registry entry is locked"));
    }
    std::fs::rename(&tmp, path)?;
    Ok(file)
}

/// Why a launch could not be registered (said in a note: the launch runs
/// all the same).
#[derive(Debug, thiserror::Error)]
pub(crate) enum RegistryError {
    /// The record could not be written into the run directory.
    #[error("cannot write {}: {source}", path.display())]
    Record {
        /// The record's file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The registry entry could not be written (or locked).
    #[error("cannot register the launch in {}: {source}", dir.display())]
    Register {
        /// The registry directory.
        dir: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// Writes `record` into its run directory and the registry. A launch that
/// cannot register still runs; only finding it later is harder, so the
/// failure is returned for a note, not an error.
pub(crate) fn register(record: &LaunchRecord) -> Result<Registration, RegistryError> {
    let text = serde_json::to_vec_pretty(record).expect("a launch record serializes");
    let in_run = record.run_dir.join(RECORD_FILE);
    write_whole(&in_run, &text, false).map_err(|source| RegistryError::Record {
        path: in_run.clone(),
        source,
    })?;
    let dir = registry();
    let entry = dir.join(format!("{}-{}.json", record.pid, record.started_at_ms));
    let lock = std::fs::create_dir_all(&dir)
        .and_then(|()| write_whole(&entry, &text, true))
        .map_err(|source| RegistryError::Register {
            dir: dir.clone(),
            source,
        })?;
    Ok(Registration { entry, _lock: lock })
}

/// The launches running now, oldest first. Entries of launches that ended
/// without cleaning up (killed, power cut) are removed.
pub(crate) fn running() -> Vec<LaunchRecord> {
    let Ok(entries) = std::fs::read_dir(registry()) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for entry in entries.flatten() {
        let path = entry.path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let Ok(file) = std::fs::File::open(&path) else {
            continue;
        };
        if try_lock(&file) {
            // Nobody holds it: the launch ended. Unlink only the file we
            // locked, never one a new launch renamed over the path since.
            if same_file(&file, &path) {
                let _ = std::fs::remove_file(&path);
            }
            continue;
        }
        if let Some(r) = read_record(&path) {
            out.push(r);
        }
    }
    out.sort_by_key(|r| (r.started_at_ms, r.pid));
    out
}

fn read_record(path: &Path) -> Option<LaunchRecord> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// The newest run of `launcher` recorded in its `.peppy/runs`, running or
/// not (the logs of a stopped run are still worth reading).
pub(crate) fn latest_run_of(launcher: &Path) -> Option<LaunchRecord> {
    let base = launcher.parent()?;
    let abs = std::fs::canonicalize(launcher).ok()?;
    let runs = std::fs::read_dir(base.join(".peppy").join("runs")).ok()?;
    runs.flatten()
        .filter_map(|d| read_record(&d.path().join(RECORD_FILE)))
        .filter(|r| r.launcher == abs)
        .max_by_key(|r| (r.started_at_ms, r.pid))
}

/// Milliseconds since the Unix epoch.
pub(crate) fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// `3 s`, `4 min 12 s`, `2 h 5 min`, `3 d 4 h`.
pub(crate) fn human_duration(d: std::time::Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {} s", s / 60, s % 60),
        3600..86400 => format!("{} h {} min", s / 3600, s % 3600 / 60),
        _ => format!("{} d {} h", s / 86400, s % 86400 / 3600),
    }
}

/// `peppy-launch ps`.
pub(crate) fn ps(args: &crate::cli::PsArgs) -> crate::error::Result {
    let launches = running();
    let now = now_ms();
    if args.format == crate::cli::Format::Json {
        let list: Vec<serde_json::Value> = launches
            .iter()
            .map(|r| {
                let mut v = serde_json::to_value(r).expect("a launch record serializes");
                // The tools' login stays in the record, never on stdout.
                if let Some(o) = v.as_object_mut() {
                    o.remove("login");
                }
                v["uptime_ms"] = now.saturating_sub(r.started_at_ms).into();
                v["instances"] = r
                    .instances
                    .iter()
                    .map(|(id, node)| {
                        serde_json::json!({ "instance": id, "node": node, "pid": r.pid_of(id) })
                    })
                    .collect();
                v
            })
            .collect();
        println!("{}", serde_json::Value::Array(list));
        return Ok(());
    }
    if launches.is_empty() {
        println!("no launch is running on this machine");
        return Ok(());
    }
    for r in &launches {
        let up = std::time::Duration::from_millis(now.saturating_sub(r.started_at_ms));
        println!(
            "{}  (pid {}, namespace {}, up {}, reach {})",
            r.launcher.display(),
            r.pid,
            r.namespace,
            human_duration(up),
            r.connect.join(", ")
        );
        let rows: Vec<Vec<String>> = r
            .instances
            .iter()
            .map(|(id, node)| {
                vec![
                    format!("  {id}"),
                    node.clone(),
                    r.pid_of(id).map_or("-".into(), |p| p.to_string()),
                    r.log_of(id).display().to_string(),
                ]
            })
            .collect();
        print!(
            "{}",
            crate::inspect::nodes::table(&["  INSTANCE", "NODE", "PID", "LOG"], &rows)
        );
    }
    Ok(())
}

/// Why `logs` cannot tell which log to read.
#[derive(Debug, thiserror::Error)]
pub enum LogsError {
    /// `--launcher` has never run here.
    #[error(
        "{} has no recorded run; start it with `peppy-launch up {}`",
        launcher.display(),
        launcher.display()
    )]
    NoRecordedRun {
        /// The launcher file.
        launcher: PathBuf,
    },
    /// No running launch has the instance.
    #[error(
        "no running launch has an instance `{instance}`; running instances: {} (for a stopped run, give --launcher)",
        if running.is_empty() { "none".to_string() } else { running.join(", ") }
    )]
    NotRunning {
        /// The instance asked for.
        instance: String,
        /// The instances of every running launch.
        running: Vec<String>,
    },
    /// Several running launches have an instance of that id.
    #[error("{launches} running launches have an instance `{instance}`; pick one with --launcher")]
    Ambiguous {
        /// The instance asked for.
        instance: String,
        /// How many launches have one.
        launches: usize,
    },
    /// The launch given has no such instance.
    #[error(
        "{} has no instance `{instance}`; its instances: {}",
        launcher.display(),
        instances.join(", ")
    )]
    NoSuchInstance {
        /// The launch's launcher.
        launcher: PathBuf,
        /// The instance asked for.
        instance: String,
        /// The launch's instances.
        instances: Vec<String>,
    },
}

/// The launch whose logs `logs` reads: the newest run of `--launcher`, or
/// the running launch that has the instance.
fn launch_with(args: &crate::cli::LogsArgs) -> Result<LaunchRecord, LogsError> {
    if let Some(l) = &args.launcher {
        // `-l NAME`: the launcher of that name in the repositories, when
        // it can be found; else the name is reported as never run.
        let l = &crate::find_launcher::locate(l, &[]).unwrap_or_else(|_| l.clone());
        return latest_run_of(l).ok_or_else(|| LogsError::NoRecordedRun {
            launcher: l.clone(),
        });
    }
    let launches = running();
    let mut with: Vec<LaunchRecord> = launches
        .iter()
        .filter(|r| r.instances.iter().any(|(id, _)| id == &args.instance))
        .cloned()
        .collect();
    match with.len() {
        1 => Ok(with.remove(0)),
        0 => Err(LogsError::NotRunning {
            instance: args.instance.clone(),
            running: launches
                .iter()
                .flat_map(|r| r.instances.iter().map(|(id, _)| id.clone()))
                .collect(),
        }),
        n => Err(LogsError::Ambiguous {
            instance: args.instance.clone(),
            launches: n,
        }),
    }
}

/// `peppy-launch logs INSTANCE [-f]`.
pub(crate) fn logs(args: &crate::cli::LogsArgs) -> crate::error::Result {
    use crate::error::InspectError;
    let record = launch_with(args)?;
    if !record.instances.iter().any(|(id, _)| id == &args.instance) {
        return Err(LogsError::NoSuchInstance {
            launcher: record.launcher.clone(),
            instance: args.instance.clone(),
            instances: record.instances.iter().map(|(id, _)| id.clone()).collect(),
        }
        .into());
    }
    let path = record.log_of(&args.instance);
    let unreadable = |source| InspectError::ReadLog {
        path: path.clone(),
        source,
    };
    let mut log = LogReader::default();
    let lines = log.read_new(&path).map_err(unreadable)?;
    let start = args.tail.map_or(0, |n| lines.len().saturating_sub(n));
    let mut out = LinePrinter {
        printed: 0,
        limit: args.stream.count,
    };
    out.print(&lines[start..]);
    if !args.follow {
        out.print(&log.rest().into_iter().collect::<Vec<_>>());
        return Ok(());
    }
    let deadline = args.stream.timeout.map(|t| std::time::Instant::now() + t);
    while !out.done() && deadline.is_none_or(|d| std::time::Instant::now() < d) {
        let lines = log.read_new(&path).map_err(unreadable)?;
        if lines.is_empty() {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
        out.print(&lines);
    }
    out.print(&log.rest().into_iter().collect::<Vec<_>>());
    match (args.stream.count, args.stream.timeout) {
        (Some(n), Some(t)) if out.printed < n => Err(InspectError::TooFew {
            got: out.printed,
            wanted: n,
            what: "lines",
            within: t,
        }
        .into()),
        _ => Ok(()),
    }
}

/// Prints lines up to `--count`.
struct LinePrinter {
    printed: u64,
    limit: Option<u64>,
}

impl LinePrinter {
    fn done(&self) -> bool {
        self.limit.is_some_and(|n| self.printed >= n)
    }

    fn print(&mut self, lines: &[String]) {
        use std::io::Write as _;
        let mut out = std::io::stdout().lock();
        for line in lines {
            if self.done() {
                break;
            }
            let _ = writeln!(out, "{line}");
            self.printed += 1;
        }
        let _ = out.flush();
    }
}

/// Reads a growing log by whole lines: bytes after the last newline wait
/// for the rest of their line, so a line (or a UTF-8 character) written
/// half-way is never split; invalid UTF-8 is shown, not fatal.
#[derive(Debug, Default)]
pub(crate) struct LogReader {
    pos: u64,
    partial: Vec<u8>,
}

impl LogReader {
    /// A reader of what `path` gets from now on (nothing, when it does
    /// not exist yet).
    pub(crate) fn at_end(path: &Path) -> LogReader {
        LogReader {
            pos: std::fs::metadata(path).map_or(0, |m| m.len()),
            partial: Vec::new(),
        }
    }

    /// A last line that has no newline yet (a log that ended mid-line).
    pub(crate) fn rest(&mut self) -> Option<String> {
        (!self.partial.is_empty())
            .then(|| String::from_utf8_lossy(&std::mem::take(&mut self.partial)).into_owned())
    }

    /// The complete lines written since the last call.
    pub(crate) fn read_new(&mut self, path: &Path) -> std::io::Result<Vec<String>> {
        use std::io::{Read as _, Seek as _};
        let mut file = std::fs::File::open(path)?;
        if file.metadata()?.len() < self.pos {
            // Truncated or replaced: read it anew.
            self.pos = 0;
            self.partial.clear();
        }
        file.seek(std::io::SeekFrom::Start(self.pos))?;
        let mut bytes = Vec::new();
        let n = file.read_to_end(&mut bytes)?;
        self.pos += n as u64;
        self.partial.extend_from_slice(&bytes);
        let Some(end) = self.partial.iter().rposition(|&b| b == b'\n') else {
            return Ok(Vec::new());
        };
        let complete: Vec<u8> = self.partial.drain(..=end).collect();
        Ok(complete[..complete.len() - 1]
            .split(|&b| b == b'\n')
            .map(|l| String::from_utf8_lossy(l).into_owned())
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_like_a_person_writes_them() {
        use std::time::Duration;
        assert_eq!(human_duration(Duration::from_secs(3)), "3 s");
        assert_eq!(human_duration(Duration::from_secs(252)), "4 min 12 s");
        assert_eq!(human_duration(Duration::from_secs(7500)), "2 h 5 min");
        assert_eq!(
            human_duration(Duration::from_secs(3 * 86400 + 4 * 3600)),
            "3 d 4 h"
        );
    }

    #[test]
    fn a_growing_log_is_read_by_whole_lines() {
        use std::io::Write as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.log");
        let mut f = std::fs::File::create(&path).unwrap();
        let mut log = LogReader::default();
        f.write_all(b"one\ntw").unwrap();
        assert_eq!(log.read_new(&path).unwrap(), ["one"]);
        f.write_all(b"o \xc3").unwrap();
        assert!(log.read_new(&path).unwrap().is_empty());
        f.write_all(b"\xa9\n\xff\n").unwrap();
        assert_eq!(log.read_new(&path).unwrap(), ["two \u{e9}", "\u{fffd}"]);
        std::fs::write(&path, b"new\nlast").unwrap();
        assert_eq!(log.read_new(&path).unwrap(), ["new"]);
        assert_eq!(log.rest().as_deref(), Some("last"));
        assert_eq!(log.rest(), None);
    }

    #[test]
    fn an_entry_is_running_while_its_registration_lives() {
        let state = tempfile::tempdir().unwrap();
        let run_dir = tempfile::tempdir().unwrap();
        // SAFETY (edition 2024 marks set_var unsafe): this is the only test
        // in this binary that reads or writes PEPPY_STATE_DIR.
        unsafe { std::env::set_var("PEPPY_STATE_DIR", state.path()) };
        let record = LaunchRecord {
            pid: 4_000_000,
            launcher: "/x/stack.json5".into(),
            namespace: "ns".into(),
            core_node: "c".into(),
            connect: vec!["tcp/127.0.0.1:1".into()],
            run_dir: run_dir.path().into(),
            started_at_ms: 1,
            instances: vec![("a".into(), "n:v1".into())],
            login: None,
            recorder_login: None,
            control: None,
        };
        let registration = register(&record).unwrap();
        assert_eq!(running(), vec![record.clone()]);
        assert!(run_dir.path().join(RECORD_FILE).exists());
        // A launch killed without cleaning up leaves an entry nobody locks.
        let live = state.path().join("launches/4000000-1.json");
        let stale = state.path().join("launches/4000001-1.json");
        std::fs::copy(&live, &stale).unwrap();
        assert_eq!(
            running(),
            vec![record.clone()],
            "an unlocked entry is stale"
        );
        assert!(!stale.exists(), "and removed");
        drop(registration);
        assert!(running().is_empty());
        assert!(!live.exists());
        unsafe { std::env::remove_var("PEPPY_STATE_DIR") };
    }

    #[test]
    fn own_process_is_alive_and_a_free_pid_is_not() {
        assert!(pid_alive(std::process::id()));
        assert!(!pid_alive(0));
        assert!(!pid_alive(u32::MAX));
    }
}
