//! Children's output: one line at a time, prefixed with a stable coloured
//! `[instance_id]` on stderr (plain when not a terminal or `NO_COLOR`), and
//! copied to one log file per instance.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use tokio::io::{AsyncBufReadExt, AsyncRead, BufReader};

/// The longest line kept whole; longer lines are split (a flood without
/// newlines must not grow memory without bound).
const MAX_LINE: usize = 64 * 1024;

const COLOURS: [&str; 6] = [
    "\x1b[36m", "\x1b[33m", "\x1b[35m", "\x1b[32m", "\x1b[34m", "\x1b[31m",
];

/// Where every instance's lines go.
pub(crate) struct Output {
    colour: bool,
    width: usize,
    stderr: Mutex<std::io::Stderr>,
}

impl Output {
    pub(crate) fn new(ids: &[&str]) -> Output {
        let colour = std::io::stderr().is_terminal()
            && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty());
        Output {
            colour,
            width: ids.iter().map(|i| i.len()).max().unwrap_or(0),
            stderr: Mutex::new(std::io::stderr()),
        }
    }

    fn prefix(&self, id: &str) -> String {
        let pad = " ".repeat(self.width.saturating_sub(id.len()));
        if self.colour {
            let c = COLOURS[id
                .bytes()
                .fold(0usize, |h, b| h.wrapping_mul(31).wrapping_add(b as usize))
                % COLOURS.len()];
            format!("{c}[{id}]\x1b[0m{pad} ")
        } else {
            format!("[{id}]{pad} ")
        }
    }

    /// One line from an instance.
    pub(crate) fn line(&self, id: &str, line: &str) {
        let text = format!("{}{line}\n", self.prefix(id));
        let mut err = self.stderr.lock().unwrap_or_else(|p| p.into_inner());
        let _ = err.write_all(text.as_bytes());
    }

    /// A message from the launcher itself.
    pub(crate) fn note(&self, message: &str) {
        let mut err = self.stderr.lock().unwrap_or_else(|p| p.into_inner());
        let _ = writeln!(err, "peppy-launch: {message}");
    }
}

/// Copies `stream` line by line to `out` (prefixed) and to `log`, until EOF.
/// Always drains the pipe, so a chatty child never blocks on a full pipe.
pub(crate) async fn pump(
    stream: impl AsyncRead + Unpin,
    id: String,
    out: std::sync::Arc<Output>,
    log: std::sync::Arc<Mutex<Log>>,
) {
    let mut reader = BufReader::with_capacity(64 * 1024, stream);
    let mut buf = Vec::with_capacity(1024);
    loop {
        buf.clear();
        let read = read_line_capped(&mut reader, &mut buf).await;
        match read {
            Ok(0) | Err(_) => break,
            Ok(_) => {
                while buf.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
                    buf.pop();
                }
                let line = String::from_utf8_lossy(&buf);
                out.line(&id, &line);
                log.lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .append(&buf, &id, &out);
            }
        }
    }
}

async fn read_line_capped<R: AsyncBufReadExt + Unpin>(
    reader: &mut R,
    buf: &mut Vec<u8>,
) -> std::io::Result<usize> {
    let mut total = 0;
    loop {
        let available = reader.fill_buf().await?;
        if available.is_empty() {
            return Ok(total);
        }
        let room = MAX_LINE - buf.len();
        let chunk = &available[..available.len().min(room)];
        match chunk.iter().position(|b| *b == b'\n') {
            Some(i) => {
                buf.extend_from_slice(&chunk[..=i]);
                reader.consume(i + 1);
                return Ok(total + i + 1);
            }
            None => {
                let n = chunk.len();
                buf.extend_from_slice(chunk);
                reader.consume(n);
                total += n;
                if buf.len() >= MAX_LINE {
                    return Ok(total);
                }
            }
        }
    }
}

/// An instance's log file, shared by its stdout and stderr pumps.
pub(crate) struct Log {
    file: std::fs::File,
    path: PathBuf,
    /// A write has failed (a full disk): said once, not at every line.
    failed: bool,
}

impl Log {
    /// Opens (appending) an instance's log file.
    pub(crate) fn open(path: &Path) -> std::io::Result<Log> {
        use std::os::unix::fs::OpenOptionsExt as _;
        // Readable by the launching user only: a node's log may hold what
        // its libraries print about its session, login included.
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .mode(0o600)
            .open(path)?;
        Ok(Log {
            file,
            path: path.to_path_buf(),
            failed: false,
        })
    }

    /// Appends one line. The instance runs on when its log cannot be
    /// written (its lines still reach `out`), but a log with lines missing
    /// is said to be so: `logs` would otherwise show it as whole.
    fn append(&mut self, line: &[u8], id: &str, out: &Output) {
        let written = self
            .file
            .write_all(line)
            .and_then(|()| self.file.write_all(b"\n"));
        if let Err(e) = written
            && !self.failed
        {
            self.failed = true;
            out.note(&format!(
                "cannot write the log of `{id}` ({}): {e}; its output still shows here, and lines are missing from the log",
                self.path.display()
            ));
        }
    }
}
