//! The runtime's errors.

use peppy_schema::{BindError, ParamError};

/// Everything a peppy runtime call can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Nobody answered: no server of that service was reachable.
    #[error("service `{service}`{} is unreachable: no server answered", for_instance(.instance))]
    ServiceUnreachable {
        /// The service.
        service: String,
        /// The targeted instance, if pinned.
        instance: Option<String>,
    },
    /// A server accepted the request but did not reply in time.
    #[error("service `{service}`{} accepted the request but did not reply in time", for_instance(.instance))]
    ServiceTimeout {
        /// The service.
        service: String,
        /// The server instance.
        instance: Option<String>,
    },
    /// The server's handler returned an error (its text is the reason).
    #[error("service `{service}` failed on `{instance}`: {reason}")]
    ServiceError {
        /// The service.
        service: String,
        /// The server instance.
        instance: String,
        /// The handler's error text.
        reason: String,
    },
    /// A message or reply could not be decoded.
    #[error("cannot decode {what}: {source}")]
    Decode {
        /// What was being decoded.
        what: String,
        /// Why.
        #[source]
        source: crate::wire::codec::DecodeError,
    },
    /// Start-up inputs are missing or invalid (flags, runtime config file, bindings).
    #[error("{0}")]
    Startup(String),
    /// Bindings were refused: the rules, codes and messages of
    /// `peppy-launch check`, with help spelled for the command line.
    #[error("invalid bindings:{}", bindings_list(.0))]
    Bindings(Vec<BindError>),
    /// Parameter values do not fit the node's parameter schema.
    #[error("invalid parameters:{}", params_list(.0))]
    Parameters(Vec<ParamError>),
    /// An action goal's feedback stream ended (the goal is terminal).
    #[error("the feedback stream of action `{action}` has ended")]
    FeedbackEnded {
        /// The action.
        action: String,
    },
    /// The node is shutting down.
    #[error("the node is shutting down")]
    ShuttingDown,
    /// A consumed entry was used that this node does not declare.
    #[error("`{0}` is not declared by this node")]
    Undeclared(String),
    /// The transport failed.
    #[error("zenoh: {0}")]
    Transport(String),
    /// A service or action was called on a producer its slot is not bound
    /// to (today's API takes the target explicitly: one of the slot's
    /// `bound_producer(s)`).
    #[error("`{target}` is not bound to slot `{slot}`{}", bound_list(.bound))]
    TargetNotBound {
        /// The slot called through.
        slot: String,
        /// The producer asked for.
        target: String,
        /// The producers the slot is bound to.
        bound: Vec<String>,
    },
    /// A message built for one topic was handed to another topic's
    /// publisher.
    #[error("a message of topic `{message}` cannot be published on topic `{publisher}`")]
    WrongTopic {
        /// The publisher's topic.
        publisher: String,
        /// The topic the message was built for.
        message: String,
    },
    /// The node's own setup code failed.
    #[error("{0}")]
    User(String),
    /// The stack clock has no time to give yet: [`clock::init`] was not
    /// called, or, following simulated time, no sim tick has arrived.
    ///
    /// [`clock::init`]: crate::clock::init
    #[error(
        "the stack clock is not ready: clock::init has not run for this node, or (following simulated time) no sim tick has arrived yet"
    )]
    ClockNotReady,
    /// A test harness's wait that ran out of time (naming what it waited
    /// for), or the node under test failing while the test waited
    /// ([`crate::testing`]).
    #[error("{0}")]
    Testing(String),
    /// An error of the node's own code, kept as it is (its text is shown;
    /// `source()` returns it).
    #[error("{0}")]
    Node(#[source] Box<dyn std::error::Error + Send + Sync>),
}

fn for_instance(instance: &Option<String>) -> String {
    instance
        .as_ref()
        .map(|i| format!(" on `{i}`"))
        .unwrap_or_default()
}

fn bound_list(bound: &[String]) -> String {
    if bound.is_empty() {
        " (it is bound to no producer)".to_string()
    } else {
        format!(" (it is bound to {})", bound.join(", "))
    }
}

fn bindings_list(errors: &[BindError]) -> String {
    errors
        .iter()
        .map(|e| {
            let help = e.command_line_help();
            if help.is_empty() {
                format!("\n  - {e} ({})", e.code())
            } else {
                format!("\n  - {e} ({})\n    help: {help}", e.code())
            }
        })
        .collect()
}

fn params_list(errors: &[ParamError]) -> String {
    errors
        .iter()
        .map(|e| match e.help() {
            Some(h) => format!("\n  - {e} ({h})"),
            None => format!("\n  - {e}"),
        })
        .collect()
}

impl From<zenoh::Error> for Error {
    fn from(e: zenoh::Error) -> Self {
        Error::Transport(e.to_string())
    }
}

/// An I/O failure in node code (`?` on a file read, an `io::Error::other`
/// a node builds to fail its instance) is the node's own error.
impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::User(e.to_string())
    }
}

impl From<String> for Error {
    fn from(s: String) -> Self {
        Error::User(s)
    }
}

impl From<&str> for Error {
    fn from(s: &str) -> Self {
        Error::User(s.to_string())
    }
}

/// `Result` with the runtime's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
