//! The one error of every command, and the one place exit codes are decided
//! (SPEC 6.4: 0 valid or clean, 1 a run failed, 2 usage or document errors).
//!
//! [`LaunchError`] says which kind of failure a command had (and so its exit
//! code); [`UsageError`], [`SetupError`] and [`InspectError`] say what
//! happened, with the data a person needs, and modules group their own
//! situations in enums of their own (a [`LocateError`], a [`KeysError`],
//! ...) that convert into these.

use std::path::PathBuf;
use std::time::Duration;

use crate::executable::ExecutableError;
use crate::find_launcher::LauncherLookupError;
use crate::inspect::SelectError;
use crate::node_init::InitError;
use crate::placement::{PlaceError, PlacementError};
use crate::python_sync::PackageError;
use crate::recording::RecordingError;
use crate::recording::view::ViewError;
use crate::repositories::RepoListError;
use crate::run_node::{LocateError, PairLinkRefused};
use crate::runs::LogsError;
use crate::security::keys::KeysError;
use crate::up::RouterError;

/// Exit codes.
pub mod exit {
    /// Everything valid, or a clean stop.
    pub const OK: u8 = 0;
    /// A build or an instance failed, or a restart budget ran out.
    pub const FAILED: u8 = 1;
    /// A document, binding or command line is invalid.
    pub const INVALID: u8 = 2;
    /// Stopped by Ctrl-C before it was done (128 + SIGINT, as shells do).
    pub const INTERRUPTED: u8 = 130;
}

/// Why a command did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// Documents, bindings or parameters are invalid. Their located
    /// diagnostics were already printed, for people or as JSON.
    #[error("invalid: {errors} error(s), reported above")]
    Invalid {
        /// How many errors were reported.
        errors: usize,
    },
    /// A command-line value is invalid, or names what does not exist.
    #[error(transparent)]
    Usage(#[from] UsageError),
    /// The node's start-up inputs (`--bind`, parameters, instance id) were
    /// refused by the same rules the node applies.
    #[error(transparent)]
    Startup(#[from] peppy_runtime::Error),
    /// A node's build failed or its program cannot be found.
    #[error(transparent)]
    Build(#[from] ExecutableError),
    /// The launch could not set itself up (runtime, run directory, ports,
    /// router, keys).
    #[error(transparent)]
    Setup(#[from] SetupError),
    /// An instance failed or used up its restart budget; the output above
    /// names it and its log.
    #[error("an instance failed")]
    InstanceFailed,
    /// A running stack did not give what an inspection command asked for:
    /// a call failed, a goal was rejected, fewer messages than `--count`
    /// arrived in time.
    #[error(transparent)]
    Inspect(#[from] InspectError),
    /// Ctrl-C stopped a command that had nothing to finish cleanly.
    #[error("interrupted")]
    Interrupted,
    /// `up --detach`: the launch ended before it had started every
    /// instance, with this exit code; its output above says why.
    #[error("the launch ended with exit code {code} before it started")]
    Detached {
        /// The launch's exit code.
        code: u8,
    },
}

/// `From` a module's own error into [`LaunchError`], through the kind of
/// failure it always is.
macro_rules! launch_error_from {
    ($($error:ty => $kind:ident),* $(,)?) => {$(
        impl From<$error> for LaunchError {
            fn from(e: $error) -> Self {
                LaunchError::$kind(e.into())
            }
        }
    )*};
}

launch_error_from!(
    LocateError => Usage,
    PairLinkRefused => Usage,
    PlacementError => Usage,
    PlaceError => Usage,
    LauncherLookupError => Usage,
    LogsError => Usage,
    SelectError => Usage,
    KeysError => Setup,
    ViewError => Setup,
    RouterError => Setup,
);

impl From<InitError> for LaunchError {
    /// A name or folder `init` refuses is a usage error; a file it cannot
    /// write is a setup failure.
    fn from(e: InitError) -> Self {
        match e {
            InitError::Write { .. } => LaunchError::Setup(SetupError::Init(e)),
            other => LaunchError::Usage(UsageError::Init(other)),
        }
    }
}

impl From<RecordingError> for LaunchError {
    /// A recording that cannot be created or written is a setup failure;
    /// a file (missing, or not a recording) or stack that does not fit, a
    /// usage error; a recording damaged midway, a failed run.
    fn from(e: RecordingError) -> Self {
        match e {
            RecordingError::Create { .. }
            | RecordingError::Write { .. }
            | RecordingError::Thread { .. }
            | RecordingError::WriterPanicked { .. } => LaunchError::Setup(SetupError::Recording(e)),
            RecordingError::Damaged { .. } | RecordingError::Unfit { .. } => {
                LaunchError::Inspect(InspectError::Recording(e))
            }
            other => LaunchError::Usage(UsageError::Recording(other)),
        }
    }
}

impl From<PackageError> for LaunchError {
    /// Invalid documents stay [`LaunchError::Invalid`] (their diagnostics
    /// are printed); a file that cannot be written is a setup failure.
    fn from(e: PackageError) -> Self {
        match e {
            PackageError::Invalid { errors } => LaunchError::Invalid { errors },
            other => LaunchError::Setup(SetupError::Package(other)),
        }
    }
}

/// A command line that cannot be carried out as given: a value is invalid,
/// or it names something (a node, a stack, an instance, a topic) that is
/// not there. Exit code 2.
#[derive(Debug, thiserror::Error)]
pub enum UsageError {
    /// `NODE` is not found ([`LocateError`]).
    #[error(transparent)]
    Locate(#[from] LocateError),
    /// `up`'s `--core-node` / `--local` do not fit the launcher.
    #[error(transparent)]
    Placement(#[from] PlacementError),
    /// `--place` does not fit the launcher or is not understood.
    #[error(transparent)]
    Place(#[from] PlaceError),
    /// A launcher named on the command line is not found.
    #[error(transparent)]
    LauncherLookup(#[from] LauncherLookupError),
    /// `logs` cannot tell which launch or instance it should read.
    #[error(transparent)]
    Logs(#[from] LogsError),
    /// An inspection command names a stack, an instance or an entry the
    /// running stacks do not have.
    #[error(transparent)]
    Select(#[from] SelectError),
    /// This process's `PEPPY_SHUTDOWN_GRACE_SECS`, which every node it
    /// starts inherits, is not a grace window.
    #[error("invalid PEPPY_SHUTDOWN_GRACE_SECS: {0}")]
    ShutdownGrace(peppy_schema::GraceError),
    /// `node init` refuses the name or the folder.
    #[error(transparent)]
    Init(InitError),
    /// `record` or `replay` refuses its file or arguments, or the stack
    /// cannot take the recording.
    #[error(transparent)]
    Recording(RecordingError),
    /// `stop` or `node stop|start|restart` names no running launch or
    /// instance, or the launch refused the request.
    #[error(transparent)]
    Manage(crate::manage::ManageError),
    /// `repo add` / `repo remove` name what the user's list cannot take.
    #[error(transparent)]
    RepoList(RepoListError),
    /// `plan` was given neither a node nor a model.
    #[error("give a NODE or --model")]
    NoNodeOrModel,
    /// `plan --model FILE` cannot be read.
    #[error("cannot read --model {}: {source}", path.display())]
    ReadModel {
        /// The file (`-` for standard input).
        path: PathBuf,
        /// Why it cannot be read.
        source: std::io::Error,
    },
    /// `plan --model FILE` is not a node model.
    #[error("--model {} is not a node model: {source}", path.display())]
    NotAModel {
        /// The file (`-` for standard input).
        path: PathBuf,
        /// Why it does not parse.
        source: serde_json::Error,
    },
    /// `--namespace` is not a valid name.
    #[error("invalid --namespace `{namespace}`: {why}")]
    Namespace {
        /// The namespace given.
        namespace: String,
        /// What the naming rules say.
        why: String,
    },
    /// `graph` was given neither a launcher nor `--live`.
    #[error("give a launcher file, or --live")]
    NothingToDraw,
    /// `graph -o FILE` names a file whose extension is no drawing format.
    #[error(
        "cannot draw `{}`: unknown extension `.{extension}` (use .svg, .html, .htm, .dot or .gv)",
        path.display()
    )]
    DrawingExtension {
        /// The output file.
        path: PathBuf,
        /// Its extension, lowercase.
        extension: String,
    },
    /// `keys` was given a launcher that runs on one machine.
    #[error(
        "{} runs on one machine (no `core_nodes`): its router links to no other, so it needs no keys",
        launcher.display()
    )]
    NoCoreNodes {
        /// The launcher file.
        launcher: PathBuf,
    },
    /// The endpoints an inspection command reaches a stack by do not make
    /// a Zenoh configuration.
    #[error(transparent)]
    Endpoints(peppy_runtime::Error),
    /// A message, request or goal with fields was not given.
    #[error("give the {origin} as JSON5; its format is {format}")]
    NoValue {
        /// What was missing (`message`, `request`, `goal`).
        origin: String,
        /// The format's canonical text.
        format: String,
    },
    /// `run --link` names a peer slot another instance holds.
    #[error(transparent)]
    PairLink(#[from] PairLinkRefused),
    /// `topic pub --rate` is out of range.
    #[error("--rate {rate} is out of range: give messages per second above 0, at most 100000")]
    Rate {
        /// The rate given.
        rate: f64,
    },
}

/// The launch could not set itself up. Exit code 1.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// A running launch did not stop in time, or its control socket did
    /// not answer.
    #[error(transparent)]
    Manage(crate::manage::ManageError),
    /// `up --detach` could not start the launch in the background.
    #[error(transparent)]
    Detach(crate::detach::DetachError),
    /// The user's repository list cannot be written, or a git repository
    /// cannot be fetched.
    #[error(transparent)]
    RepoList(RepoListError),
    /// `node init` could not write the node's files.
    #[error(transparent)]
    Init(InitError),
    /// `record` could not write its file.
    #[error(transparent)]
    Recording(RecordingError),
    /// `view` could not serve.
    #[error(transparent)]
    View(#[from] ViewError),
    /// The tokio runtime did not start.
    #[error("cannot start the tokio runtime: {0}")]
    Runtime(#[source] std::io::Error),
    /// A directory could not be created.
    #[error("cannot create {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The launch's run directory could not be created.
    #[error("cannot create the run directory {}: {source}", path.display())]
    RunDir {
        /// The run directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// No free loopback port was found for the router.
    #[error("cannot find a free local port: {0}")]
    FreePort(#[source] std::io::Error),
    /// The secured launch's credentials could not be generated.
    #[error("cannot generate credentials: {0}")]
    Credentials(#[source] std::io::Error),
    /// An instance of a secured launch has a user name the launch keeps
    /// for itself.
    #[error(
        "instance id `{instance}` is a user name a secured launch keeps for itself (`{operator}`, `peppy-router-*`): rename the instance",
        operator = crate::security::policy::OPERATOR
    )]
    ReservedInstanceId {
        /// The instance id.
        instance: String,
    },
    /// Security is on and the router would link to another router without
    /// the stack's keys.
    #[error(
        "security is on ({reason}), and this launch would link to {} with no keys to link with: only the core nodes of one launcher (`up --core-node NAME`) link securely; make both sides core nodes of one launcher, or run both with --insecure",
        connect.join(", ")
    )]
    NoKeysToLink {
        /// Why security is on.
        reason: String,
        /// The endpoints the router would connect to.
        connect: Vec<String>,
    },
    /// `plan`'s output could not be written as JSON.
    #[error("cannot write the plan as JSON: {0}")]
    PlanJson(#[source] serde_json::Error),
    /// The launch's router did not open ([`RouterError`]).
    #[error(transparent)]
    Router(#[from] RouterError),
    /// The stack's keys are missing or could not be made ([`KeysError`]).
    #[error(transparent)]
    Keys(#[from] KeysError),
    /// A Python node's generated package could not be written
    /// ([`PackageError`]).
    #[error(transparent)]
    Package(PackageError),
    /// The describe query of an inspection command failed.
    #[error("cannot query {stack}: {source}")]
    Query {
        /// The stack, as the command found it (its launcher or namespace).
        stack: String,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// `graph --live` could not subscribe to the stack's topics.
    #[error("cannot sample the topics: {0}")]
    Sample(#[source] zenoh::Error),
    /// A streaming command could not subscribe to its selection.
    #[error("cannot subscribe to {selector}: {source}")]
    Subscribe {
        /// The key expression.
        selector: String,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// `topic pub` could not declare its publisher.
    #[error(transparent)]
    Publisher(peppy_runtime::Error),
}

/// A running stack did not give what an inspection command asked for.
/// Exit code 1.
#[derive(Debug, thiserror::Error)]
pub enum InspectError {
    /// The stack's router cannot be reached.
    #[error("cannot reach {stack}{}: {source}", unreachable_hint(*local_hub, *with_login))]
    Unreachable {
        /// The stack, as the command found it (its launcher or namespace).
        stack: String,
        /// Whether it was looked for on the local hub (no launch is
        /// registered on this machine).
        local_hub: bool,
        /// Whether the tools' login of a secured launch was presented.
        with_login: bool,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// No instance answered the describe query.
    #[error("no instance answered in {stack} within {wait:?}")]
    NoAnswer {
        /// The stack, as the command found it (its launcher or namespace).
        stack: String,
        /// How long the command waited (`--wait`).
        wait: Duration,
    },
    /// An instance described a format that does not read back.
    #[error("the instance described an unreadable format: {0}")]
    UnreadableFormat(#[source] peppy_schema::CanonicalError),
    /// A response, feedback or result does not decode with its described
    /// format.
    #[error("the {what} does not decode: {source}")]
    Undecodable {
        /// What was decoded (`response`, `feedback`, `result`).
        what: &'static str,
        /// Where and why decoding failed.
        source: peppy_runtime::wire::codec::DecodeError,
    },
    /// A service call, a goal or its result failed (unreachable, timed
    /// out, refused by the server).
    #[error(transparent)]
    Call(peppy_runtime::Error),
    /// The action server rejected the goal.
    #[error("`{instance}` rejected the goal: {}", reason.as_deref().unwrap_or("no reason given"))]
    Rejected {
        /// The server instance.
        instance: String,
        /// The server's reason, if it gave one.
        reason: Option<String>,
    },
    /// The server dropped the goal without a result.
    #[error("the server dropped the goal without a result")]
    Abandoned,
    /// The result expired before it was asked for.
    #[error("the result expired before it was asked for")]
    Expired,
    /// The goal was cancelled (by Ctrl-C or `--timeout`).
    #[error("goal {goal} was cancelled")]
    Cancelled {
        /// The goal id.
        goal: String,
    },
    /// Fewer items than `--count` arrived within `--timeout`.
    #[error("{got} of {wanted} {what} within {} s", within.as_secs_f64())]
    TooFew {
        /// How many arrived.
        got: u64,
        /// `--count`.
        wanted: u64,
        /// What was counted (`messages`, `reports`, `lines`).
        what: &'static str,
        /// `--timeout`.
        within: Duration,
    },
    /// `topic pub` could not publish.
    #[error("cannot publish: {0}")]
    Publish(#[source] zenoh::Error),
    /// `replay` stopped at a damaged part of its recording.
    #[error(transparent)]
    Recording(RecordingError),
    /// `logs` cannot read an instance's log.
    #[error("cannot read {}: {source}", path.display())]
    ReadLog {
        /// The log file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// What may explain an unreachable stack.
fn unreachable_hint(local_hub: bool, with_login: bool) -> &'static str {
    if local_hub {
        " (no launch is registered on this machine and nothing listens there)"
    } else if !with_login {
        " (a stack with security on admits only its launch's tools: run this on a machine of the stack, as the user who launched it)"
    } else {
        ""
    }
}

impl LaunchError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            LaunchError::Invalid { .. } | LaunchError::Usage(_) | LaunchError::Startup(_) => {
                exit::INVALID
            }
            LaunchError::Build(_)
            | LaunchError::Setup(_)
            | LaunchError::InstanceFailed
            | LaunchError::Inspect(_) => exit::FAILED,
            LaunchError::Interrupted => exit::INTERRUPTED,
            LaunchError::Detached { code } => *code,
        }
    }

    /// Whether the command already told the user everything (the
    /// diagnostics, or the failed instance's story), so printing the error
    /// again would only repeat it.
    pub fn already_reported(&self) -> bool {
        matches!(
            self,
            LaunchError::Invalid { .. }
                | LaunchError::InstanceFailed
                | LaunchError::Detached { .. }
        )
    }
}

/// What a command returns.
pub type Result<T = ()> = std::result::Result<T, LaunchError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_follow_the_kind_of_failure() {
        assert_eq!(LaunchError::Invalid { errors: 3 }.exit_code(), 2);
        assert_eq!(LaunchError::from(UsageError::NoNodeOrModel).exit_code(), 2);
        assert_eq!(
            LaunchError::Startup(peppy_runtime::Error::Startup("x".into())).exit_code(),
            2
        );
        let port = || SetupError::FreePort(std::io::Error::other("x"));
        assert_eq!(LaunchError::from(port()).exit_code(), 1);
        assert_eq!(LaunchError::InstanceFailed.exit_code(), 1);
        assert!(LaunchError::InstanceFailed.already_reported());
        assert!(!LaunchError::from(port()).already_reported());
        assert_eq!(LaunchError::from(InspectError::Expired).exit_code(), 1);
        assert_eq!(LaunchError::Interrupted.exit_code(), 130);
    }

    #[test]
    fn module_errors_keep_their_kind_of_failure() {
        let usage = LaunchError::from(LocateError::NotANode { node: "x y".into() });
        assert!(matches!(usage, LaunchError::Usage(UsageError::Locate(_))));
        assert_eq!(usage.exit_code(), 2);
        assert_eq!(
            usage.to_string(),
            "`x y` is neither a path nor a `name:tag`"
        );
        let keys = LaunchError::from(KeysError::ReadSecret {
            path: "/k/link.secret".into(),
            source: std::io::Error::from(std::io::ErrorKind::NotFound),
        });
        assert!(matches!(keys, LaunchError::Setup(SetupError::Keys(_))));
        assert_eq!(keys.exit_code(), 1);
        // Invalid documents found while generating a package were reported.
        let invalid = LaunchError::from(PackageError::Invalid { errors: 2 });
        assert!(matches!(invalid, LaunchError::Invalid { errors: 2 }));
        assert!(invalid.already_reported());
    }

    #[test]
    fn messages_carry_their_data() {
        use std::error::Error as _;
        let e = LaunchError::from(SetupError::Write {
            path: "/run/x.json".into(),
            source: std::io::Error::from(std::io::ErrorKind::PermissionDenied),
        });
        assert_eq!(e.to_string(), "cannot write /run/x.json: permission denied");
        assert!(e.source().is_some(), "the io error is kept as the source");
        let e = InspectError::TooFew {
            got: 2,
            wanted: 5,
            what: "messages",
            within: Duration::from_millis(1500),
        };
        assert_eq!(e.to_string(), "2 of 5 messages within 1.5 s");
        let e = SetupError::ReservedInstanceId {
            instance: "peppy-operator".into(),
        };
        assert_eq!(
            e.to_string(),
            "instance id `peppy-operator` is a user name a secured launch keeps for itself (`peppy-operator`, `peppy-router-*`): rename the instance"
        );
        let e = InspectError::Rejected {
            instance: "arm".into(),
            reason: None,
        };
        assert_eq!(e.to_string(), "`arm` rejected the goal: no reason given");
    }
}
