//! The launches running on this machine. `up` and `run` write a record of
//! each launch into its run directory (`launch.json`, beside the instances'
//! runtime configs, logs and pid files) and a copy into a per-user registry,
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
}

impl LaunchRecord {
    /// Whether the launch's process still runs.
    pub(crate) fn is_alive(&self) -> bool {
        pid_alive(self.pid)
    }

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

/// A launch's record, registered while it runs.
#[derive(Debug)]
pub(crate) struct Registration {
    entry: PathBuf,
}

impl Drop for Registration {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.entry);
    }
}

/// Writes `record` into its run directory and the registry. A launch that
/// cannot register still runs; only finding it later is harder, so the
/// failure is returned for a note, not an error.
pub(crate) fn register(record: &LaunchRecord) -> Result<Registration, String> {
    let text = serde_json::to_vec_pretty(record).expect("a launch record serializes");
    let in_run = record.run_dir.join("launch.json");
    std::fs::write(&in_run, &text)
        .map_err(|e| format!("cannot write {}: {e}", in_run.display()))?;
    let dir = registry();
    let entry = dir.join(format!("{}.json", record.pid));
    std::fs::create_dir_all(&dir)
        .and_then(|()| std::fs::write(&entry, &text))
        .map_err(|e| format!("cannot register the launch in {}: {e}", dir.display()))?;
    Ok(Registration { entry })
}

/// The launches running now, oldest first. Records of launches that died
/// without cleaning up are removed.
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
        match read_record(&path) {
            Some(r) if r.is_alive() => out.push(r),
            Some(_) => {
                let _ = std::fs::remove_file(&path);
            }
            None => {}
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
        .filter_map(|d| read_record(&d.path().join("launch.json")))
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

/// The launch whose logs `logs` reads: the newest run of `--launcher`, or
/// the running launch that has the instance.
fn launch_with(args: &crate::cli::LogsArgs) -> crate::error::Result<LaunchRecord> {
    use crate::error::LaunchError;
    if let Some(l) = &args.launcher {
        return latest_run_of(l).ok_or_else(|| {
            LaunchError::Usage(format!(
                "{} has no recorded run; start it with `peppy-launch up {}`",
                l.display(),
                l.display()
            ))
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
        0 => {
            let known: Vec<&str> = launches
                .iter()
                .flat_map(|r| r.instances.iter().map(|(id, _)| id.as_str()))
                .collect();
            Err(LaunchError::Usage(format!(
                "no running launch has an instance `{}`; running instances: {} (for a stopped run, give --launcher)",
                args.instance,
                if known.is_empty() {
                    "none".to_string()
                } else {
                    known.join(", ")
                }
            )))
        }
        n => Err(LaunchError::Usage(format!(
            "{n} running launches have an instance `{}`; pick one with --launcher",
            args.instance
        ))),
    }
}

/// `peppy-launch logs INSTANCE [-f]`.
pub(crate) fn logs(args: &crate::cli::LogsArgs) -> crate::error::Result {
    use std::io::{Read as _, Seek as _, Write as _};

    use crate::error::LaunchError;
    let record = launch_with(args)?;
    let path = record.log_of(&args.instance);
    if !record.instances.iter().any(|(id, _)| id == &args.instance) {
        let ids: Vec<&str> = record.instances.iter().map(|(id, _)| id.as_str()).collect();
        return Err(LaunchError::Usage(format!(
            "{} has no instance `{}`; its instances: {}",
            record.launcher.display(),
            args.instance,
            ids.join(", ")
        )));
    }
    let mut file = std::fs::File::open(&path)
        .map_err(|e| LaunchError::Inspect(format!("cannot read {}: {e}", path.display())))?;
    let mut text = String::new();
    file.read_to_string(&mut text)
        .map_err(|e| LaunchError::Inspect(format!("cannot read {}: {e}", path.display())))?;
    let lines: Vec<&str> = text.lines().collect();
    let start = args.tail.map_or(0, |n| lines.len().saturating_sub(n));
    let mut printed = 0u64;
    let mut out = std::io::stdout().lock();
    for line in &lines[start..] {
        if args.stream.count.is_some_and(|n| printed >= n) {
            return Ok(());
        }
        let _ = writeln!(out, "{line}");
        printed += 1;
    }
    let _ = out.flush();
    drop(out);
    if !args.follow {
        return Ok(());
    }
    let deadline = args.stream.timeout.map(|t| std::time::Instant::now() + t);
    let mut pos = file.stream_position().unwrap_or(0);
    let mut partial = String::new();
    while args.stream.count.is_none_or(|n| printed < n) {
        if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
            break;
        }
        let len = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        if len < pos {
            // The log was truncated or replaced (a restart): read it anew.
            pos = 0;
        }
        if len > pos {
            let mut f = std::fs::File::open(&path).map_err(|e| {
                LaunchError::Inspect(format!("cannot read {}: {e}", path.display()))
            })?;
            f.seek(std::io::SeekFrom::Start(pos))
                .and_then(|_| f.read_to_string(&mut partial))
                .map_err(|e| {
                    LaunchError::Inspect(format!("cannot read {}: {e}", path.display()))
                })?;
            pos = len;
            while let Some(end) = partial.find('\n') {
                let line: String = partial.drain(..=end).collect();
                print!("{line}");
                printed += 1;
                if args.stream.count.is_some_and(|n| printed >= n) {
                    break;
                }
            }
            let _ = std::io::stdout().flush();
        } else {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
    match (args.stream.count, args.stream.timeout) {
        (Some(n), Some(t)) if printed < n => Err(LaunchError::Inspect(format!(
            "{printed} of {n} lines within {} s",
            t.as_secs_f64()
        ))),
        _ => Ok(()),
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
    fn own_process_is_alive_and_a_free_pid_is_not() {
        assert!(pid_alive(std::process::id()));
        assert!(!pid_alive(0));
        assert!(!pid_alive(u32::MAX));
    }
}
