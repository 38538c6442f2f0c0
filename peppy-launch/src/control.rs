//! A launch's control socket: `node stop|start|restart` from another
//! shell, for a launch in a terminal and a detached one alike
//! (`peppy-launch stop` is a signal: it does what Ctrl-C does).
//!
//! Every `up` and `run` listens on a Unix socket in a directory only its
//! user can enter (`$XDG_RUNTIME_DIR/peppy-control` or the temporary
//! directory's `peppy-control-<uid>`, mode 0700), named by the launch's
//! pid; its launch record names it. A request is one JSON line, the reply
//! one JSON line. The socket is the launching user's alone: what it can
//! do (stop the launch, stop and start its instances) is what that user's
//! Ctrl-C and `kill` can do already.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read as _, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use tokio::io::{AsyncBufReadExt, AsyncReadExt as _, AsyncWriteExt};
use tokio::sync::{mpsc, oneshot};

use crate::supervise::{InstanceCommand, StopSignals};

/// One request.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub(crate) enum Request {
    /// Start an instance in the launch and supervise it as its own.
    Add {
        /// The instance, ready to start.
        addition: Box<Addition>,
    },
    /// Stop one instance; the launch goes on, and it can be started again.
    NodeStop {
        /// The instance.
        instance: String,
    },
    /// Start a stopped instance again.
    NodeStart {
        /// The instance.
        instance: String,
    },
    /// Stop an instance and start it again.
    NodeRestart {
        /// The instance.
        instance: String,
    },
}

/// One reply.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Reply {
    /// Whether the request was carried out.
    pub(crate) ok: bool,
    /// What happened, for the person who asked.
    pub(crate) message: String,
}

impl Reply {
    fn ok(message: impl Into<String>) -> Reply {
        Reply {
            ok: true,
            message: message.into(),
        }
    }

    fn refused(message: impl Into<String>) -> Reply {
        Reply {
            ok: false,
            message: message.into(),
        }
    }
}

/// The longest request line read: an addition carries a whole plan
/// (every parameter, slot and pair of the instance).
const MAX_REQUEST: usize = 1 << 20;

/// How long a client may take to send its request.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

/// The private directory control sockets live in.
fn socket_dir() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR")
        .map(PathBuf::from)
        .filter(|d| d.is_dir())
    {
        Some(dir) => dir.join("peppy-control"),
        // SAFETY: getuid cannot fail.
        None => std::env::temp_dir().join(format!("peppy-control-{}", unsafe { libc::getuid() })),
    }
}

/// Makes `dir` (or takes it as it is) if it is this user's and no one
/// else's: whoever can enter it can reach the sockets in it.
fn private_dir(dir: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    match std::fs::DirBuilder::new().mode(0o700).create(dir) {
        Ok(()) => return Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(e),
    }
    let meta = std::fs::symlink_metadata(dir)?;
    // SAFETY: getuid cannot fail.
    let me = unsafe { libc::getuid() };
    if !meta.is_dir() || meta.uid() != me || meta.mode() & 0o077 != 0 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::PermissionDenied,
            format!(
                "{} is not a directory of this user's alone (mode 0700)",
                dir.display()
            ),
        ));
    }
    Ok(())
}

/// A bound control socket, removed on drop.
#[derive(Debug)]
pub(crate) struct Listener {
    path: PathBuf,
    listener: Option<tokio::net::UnixListener>,
}

impl Listener {
    /// Binds this launch's socket; `None` (with the reason) when it cannot
    /// be, and the launch runs without remote control.
    pub(crate) fn bind() -> Result<Listener, std::io::Error> {
        let dir = socket_dir();
        private_dir(&dir)?;
        let path = dir.join(format!("{}.sock", std::process::id()));
        // A socket left by an earlier process of this pid (the pid was
        // reused after a crash): nobody listens on it any more.
        let _ = std::fs::remove_file(&path);
        let listener = tokio::net::UnixListener::bind(&path)?;
        Ok(Listener {
            path,
            listener: Some(listener),
        })
    }

    /// The socket's path, for the launch record.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// An instance another command prepared (built, planned, checked) for
/// the launch to start and supervise as its own: `run --join`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Addition {
    /// Its plan; the launch writes it into its run directory.
    pub(crate) config: peppy_runtime::StartupConfig,
    /// Its node, `name:tag`.
    pub(crate) node: String,
    /// Where it runs.
    pub(crate) dir: PathBuf,
    /// Its program and arguments.
    pub(crate) argv: Vec<String>,
    /// Whether it runs on a peppy runtime (its hooks get their window).
    pub(crate) has_hooks: bool,
}

/// Where the launch says what came of an addition.
pub(crate) type AddReply = oneshot::Sender<Result<String, String>>;

/// What the control socket acts on: the launch's stop signals, each
/// running instance's command channel, and the launch's queue of
/// additions.
pub(crate) struct Controls {
    pub(crate) signals: StopSignals,
    /// Each instance's command channel, and the longest it may take to
    /// stop (its grace, SIGTERM's wait and a margin): how long a `node
    /// stop` is waited for.
    pub(crate) instances:
        std::sync::Mutex<BTreeMap<String, (mpsc::UnboundedSender<InstanceCommand>, Duration)>>,
    pub(crate) additions: mpsc::UnboundedSender<(Addition, AddReply)>,
}

impl Controls {
    /// Records a started instance: its command channel, and a stop bound
    /// that covers its grace.
    pub(crate) fn add(
        &self,
        id: &str,
        commands: mpsc::UnboundedSender<InstanceCommand>,
        grace: Duration,
    ) {
        // Grace, SIGTERM's wait, SIGKILL's, a restart's back-off and the
        // output drained: a reply comes well within this.
        let bound = grace + crate::supervise::TERM_TIMEOUT + Duration::from_secs(30);
        self.instances
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id.to_string(), (commands, bound));
    }

    fn channel(
        &self,
        id: &str,
    ) -> Result<(mpsc::UnboundedSender<InstanceCommand>, Duration), Vec<String>> {
        let instances = self.instances.lock().unwrap_or_else(|p| p.into_inner());
        instances
            .get(id)
            .cloned()
            .ok_or_else(|| instances.keys().cloned().collect())
    }
}

/// Serves requests on `listener` until the task is dropped.
pub(crate) async fn serve(mut listener: Listener, controls: Arc<Controls>) {
    let Some(socket) = listener.listener.take() else {
        return;
    };
    loop {
        let Ok((stream, _)) = socket.accept().await else {
            // Out of file descriptors, say: try again, without spinning.
            tokio::time::sleep(Duration::from_millis(100)).await;
            continue;
        };
        let controls = controls.clone();
        tokio::spawn(async move {
            let (read, mut write) = stream.into_split();
            let mut line = String::new();
            let mut reader = tokio::io::BufReader::new(read).take(MAX_REQUEST as u64);
            let reply =
                match tokio::time::timeout(REQUEST_TIMEOUT, reader.read_line(&mut line)).await {
                    Ok(Ok(_)) => match serde_json::from_str::<Request>(line.trim()) {
                        Ok(request) => handle(request, &controls).await,
                        Err(e) => Reply::refused(format!("not a control request: {e}")),
                    },
                    Ok(Err(e)) => Reply::refused(format!("cannot read the request: {e}")),
                    Err(_) => Reply::refused("no request within 5 s"),
                };
            let mut text = serde_json::to_string(&reply).unwrap_or_default();
            text.push('\n');
            let _ = write.write_all(text.as_bytes()).await;
        });
    }
    // `listener` is dropped with the task: the socket file goes with it.
}

async fn handle(request: Request, controls: &Controls) -> Reply {
    let (instance, command): (String, fn(oneshot::Sender<String>) -> InstanceCommand) =
        match request {
            Request::Add { addition } => return add(*addition, controls).await,
            Request::NodeStop { instance } => (instance, InstanceCommand::Stop),
            Request::NodeStart { instance } => (instance, InstanceCommand::Start),
            Request::NodeRestart { instance } => (instance, InstanceCommand::Restart),
        };
    if controls.signals.stopping.is_cancelled() {
        return Reply::refused("the launch is stopping");
    }
    let (channel, bound) = match controls.channel(&instance) {
        Ok(found) => found,
        Err(known) => {
            return Reply::refused(format!(
                "no instance `{instance}` in this launch (it has: {})",
                known.join(", ")
            ));
        }
    };
    let (tx, rx) = oneshot::channel();
    if channel.send(command(tx)).is_err() {
        return Reply::refused(format!(
            "`{instance}` has ended; it is no longer supervised"
        ));
    }
    match tokio::time::timeout(bound, rx).await {
        Ok(Ok(message)) => Reply::ok(message),
        Ok(Err(_)) => Reply::refused(format!("`{instance}` ended before it could answer")),
        Err(_) => Reply::refused(format!("`{instance}` did not answer within {bound:?}")),
    }
}

/// How long a launch may take to start an added instance.
const ADD_TIMEOUT: Duration = Duration::from_secs(60);

async fn add(addition: Addition, controls: &Controls) -> Reply {
    if controls.signals.stopping.is_cancelled() {
        return Reply::refused("the launch is stopping");
    }
    let id = addition.config.instance_id.clone();
    if controls.channel(&id).is_ok() {
        return Reply::refused(format!(
            "the launch has an instance `{id}` already; give another `--instance-id`"
        ));
    }
    let (tx, rx) = oneshot::channel();
    if controls.additions.send((addition, tx)).is_err() {
        return Reply::refused("the launch is ending");
    }
    match tokio::time::timeout(ADD_TIMEOUT, rx).await {
        Ok(Ok(Ok(message))) => Reply::ok(message),
        Ok(Ok(Err(why))) => Reply::refused(why),
        Ok(Err(_)) => Reply::refused("the launch ended before it started the instance"),
        Err(_) => Reply::refused(format!("`{id}` was not started within {ADD_TIMEOUT:?}")),
    }
}

/// Why a control request got no reply.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// The launch has no control socket (it predates them, or could not
    /// bind one).
    #[error("launch {pid} cannot be controlled: it has no control socket")]
    NoSocket {
        /// The launch's pid.
        pid: u32,
    },
    /// The socket did not answer.
    #[error("launch {pid} did not answer on {}: {source}", path.display())]
    Io {
        /// The launch's pid.
        pid: u32,
        /// The socket.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The launch refused the request.
    #[error("{0}")]
    Refused(String),
}

/// Sends `request` to the launch whose socket is `path` and returns its
/// reply's message, waiting at most `bound` for it.
pub(crate) fn ask(
    pid: u32,
    path: Option<&Path>,
    request: &Request,
    bound: Duration,
) -> Result<String, ControlError> {
    let path = path.ok_or(ControlError::NoSocket { pid })?;
    let io = |source| ControlError::Io {
        pid,
        path: path.to_path_buf(),
        source,
    };
    let mut stream = std::os::unix::net::UnixStream::connect(path).map_err(io)?;
    stream.set_read_timeout(Some(bound)).map_err(io)?;
    stream
        .set_write_timeout(Some(REQUEST_TIMEOUT))
        .map_err(io)?;
    let mut text = serde_json::to_string(request).unwrap_or_default();
    text.push('\n');
    stream.write_all(text.as_bytes()).map_err(io)?;
    let mut line = String::new();
    BufReader::new(&stream)
        .take(64 * 1024)
        .read_line(&mut line)
        .map_err(io)?;
    let reply: Reply = serde_json::from_str(line.trim()).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not a reply: {e}"),
        ))
    })?;
    if reply.ok {
        Ok(reply.message)
    } else {
        Err(ControlError::Refused(reply.message))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_one_json_line_each() {
        let stop = serde_json::to_string(&Request::NodeStop {
            instance: "cam".into(),
        })
        .unwrap();
        assert_eq!(stop, r#"{"op":"node_stop","instance":"cam"}"#);
        assert!(matches!(
            serde_json::from_str::<Request>(r#"{"op":"node_start","instance":"a"}"#).unwrap(),
            Request::NodeStart { instance } if instance == "a"
        ));
        assert!(serde_json::from_str::<Request>(r#"{"op":"rm -rf"}"#).is_err());
    }
}
