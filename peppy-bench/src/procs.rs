//! The parent's side of the child processes: spawn one, read its JSON
//! lines with a bound on every wait, stop it, read its memory.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Shutdown, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::Duration;

use serde_json::Value;

use crate::roles::Res;

/// A running child process of the benchmark, or a process started by
/// another program (a dora node, started by dora's daemon) that talks to
/// the benchmark over a loopback socket instead of stdin and stdout.
pub(crate) struct Proc {
    what: String,
    /// `None` for a process reached over a socket.
    child: Option<Child>,
    stdin: Option<Box<dyn Write + Send>>,
    /// The socket of a process reached over one: shut down to close it
    /// (its reading half is another handle of the same socket).
    link: Option<TcpStream>,
    lines: Receiver<String>,
    stderr: std::sync::Arc<std::sync::Mutex<String>>,
}

impl Proc {
    /// `peppy-bench child ARGS...`.
    pub(crate) fn child(args: &[String]) -> Res<Proc> {
        let exe = std::env::current_exe()?;
        let mut command = Command::new(exe);
        command.arg("child").args(args);
        Proc::spawn(command, &args.join(" "))
    }

    /// Any program, its stdout read as JSON lines.
    pub(crate) fn spawn(mut command: Command, what: &str) -> Res<Proc> {
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .env("NO_COLOR", "1")
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", command.get_program().display()))?;
        let (tx, lines) = channel();
        let stdout = child.stdout.take().expect("piped");
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let stderr = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let mut err = child.stderr.take().expect("piped");
        let keep = stderr.clone();
        std::thread::spawn(move || {
            let mut chunk = [0u8; 4096];
            while let Ok(n @ 1..) = err.read(&mut chunk) {
                if let Ok(mut s) = keep.lock() {
                    s.push_str(&String::from_utf8_lossy(&chunk[..n]));
                }
            }
        });
        Ok(Proc {
            what: what.to_string(),
            stdin: child
                .stdin
                .take()
                .map(|s| Box::new(s) as Box<dyn Write + Send>),
            child: Some(child),
            link: None,
            lines,
            stderr,
        })
    }

    /// A process reached over `stream`: its JSON lines come on it, and
    /// [`Proc::say`] writes to it.
    pub(crate) fn remote(stream: TcpStream, what: &str) -> Res<Proc> {
        let (tx, lines) = channel();
        let reader = stream.try_clone()?;
        std::thread::spawn(move || {
            for line in BufReader::new(reader).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        Ok(Proc {
            what: what.to_string(),
            child: None,
            stdin: Some(Box::new(stream.try_clone()?)),
            link: Some(stream),
            lines,
            stderr: Default::default(),
        })
    }

    /// The process id (0 for a process reached over a socket).
    pub(crate) fn pid(&self) -> u32 {
        self.child.as_ref().map_or(0, Child::id)
    }

    /// What it has printed on stderr so far.
    pub(crate) fn stderr(&self) -> String {
        self.stderr.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// The next stdout line that is a JSON object, within `bound`.
    pub(crate) fn next(&mut self, bound: Duration) -> Res<Value> {
        let deadline = std::time::Instant::now() + bound;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    if let Ok(v @ Value::Object(_)) = serde_json::from_str(&line) {
                        return Ok(v);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    return Err(format!(
                        "`{}` said nothing within {bound:?}; its stderr:\n{}",
                        self.what,
                        tail(&self.stderr())
                    )
                    .into());
                }
                Err(RecvTimeoutError::Disconnected) => {
                    let status = self.child.as_mut().and_then(|c| c.wait().ok());
                    return Err(format!(
                        "`{}` ended ({status:?}); its stderr:\n{}",
                        self.what,
                        tail(&self.stderr())
                    )
                    .into());
                }
            }
        }
    }

    /// Writes `line` to its stdin.
    pub(crate) fn say(&mut self, line: &str) -> Res<()> {
        use std::io::Write as _;
        let stdin = self.stdin.as_mut().ok_or("stdin already closed")?;
        writeln!(stdin, "{line}")
            .and_then(|()| stdin.flush())
            .map_err(|e| format!("`{}` stopped listening: {e}", self.what).into())
    }

    /// The next JSON line that has `key`.
    pub(crate) fn next_with(&mut self, key: &str, bound: Duration) -> Res<Value> {
        let deadline = std::time::Instant::now() + bound;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let v = self.next(left)?;
            if v.get(key).is_some() {
                return Ok(v);
            }
        }
    }

    /// Closes its stdin (a source stops then) and waits at most 10 s
    /// before killing it.
    pub(crate) fn stop(mut self) {
        self.stdin.take();
        self.wait_or_kill(Duration::from_secs(10));
    }

    /// Waits at most `bound` for it to end, then kills it. A process
    /// reached over a socket has said all it had to by then: its socket
    /// is closed, which ends it.
    pub(crate) fn wait_or_kill(&mut self, bound: Duration) {
        if let Some(link) = self.link.take() {
            self.stdin.take();
            let _ = link.shutdown(Shutdown::Both);
        }
        let Some(child) = self.child.as_mut() else {
            return;
        };
        let deadline = std::time::Instant::now() + bound;
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = child.kill();
        let _ = child.wait();
    }

    /// Asks it to stop as Ctrl-C would (SIGINT), then waits at most
    /// `bound` before killing it.
    pub(crate) fn interrupt(mut self, bound: Duration) {
        // Never `kill -INT 0` (the whole process group) for a process
        // reached over a socket.
        if let Some(child) = &self.child {
            let _ = Command::new("kill")
                .args(["-INT", &child.id().to_string()])
                .status();
        }
        self.wait_or_kill(bound);
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(link) = self.link.take() {
            let _ = link.shutdown(Shutdown::Both);
        }
        if let Some(child) = self.child.as_mut()
            && let Ok(None) = child.try_wait()
        {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// The last lines of a child's stderr, for an error.
fn tail(text: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(20)..].join("\n")
}

/// Resident memory of process `pid`, in MiB.
pub(crate) fn rss_mib(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kib: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kib / 1024.0)
}

/// A free TCP port on loopback, below the kernel's ephemeral range: a port
/// the kernel hands out for `:0` is also what it gives the next outgoing
/// connection, and with a dozen processes connecting at once one took a
/// source's port between this check and the source's bind.
pub(crate) fn free_port() -> Res<u16> {
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    const LOWEST: u32 = 10_000;
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let below = ephemeral_start().unwrap_or(32_768).max(LOWEST + 1_000);
    let span = below - LOWEST;
    // Spread over the span by process, so two benchmarks seldom collide.
    let start = std::process::id().wrapping_mul(7_919);
    for _ in 0..span.min(5_000) {
        let port = LOWEST + start.wrapping_add(NEXT.fetch_add(1, Relaxed)) % span;
        let Ok(port) = u16::try_from(port) else {
            continue;
        };
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return Ok(port);
        }
    }
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// The first port of the kernel's ephemeral range.
fn ephemeral_start() -> Option<u32> {
    std::fs::read_to_string("/proc/sys/net/ipv4/ip_local_port_range")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
