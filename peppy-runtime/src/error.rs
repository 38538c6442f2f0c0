//! The runtime's errors.

use peppy_schema::{BindError, ParamError};

/// Everything a peppy runtime call can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Nobody answered: no server of that service was reachable.
    #[error("service `{service_name}`{} is unreachable: no server answered", for_instance(.instance_id))]
    ServiceUnreachable {
        /// The targeted instance, if pinned.
        instance_id: Option<String>,
        /// The service.
        service_name: String,
    },
    /// A server accepted the request but did not reply in time.
    #[error("service `{service_name}`{} accepted the request but did not reply in time", for_instance(.instance_id))]
    ServiceTimeout {
        /// The server instance.
        instance_id: Option<String>,
        /// The service.
        service_name: String,
    },
    /// The server's handler returned an error (its text is the reason).
    #[error("service `{service_name}` failed{}: {reason}", for_instance(.instance_id))]
    ServiceError {
        /// The server instance that answered (always known here; an
        /// `Option` as PeppyOS has it).
        instance_id: Option<String>,
        /// The service.
        service_name: String,
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
    /// An action goal's feedback stream ended (the goal is terminal). Not
    /// returned any more: a clean end is
    /// [`Error::ActionFeedbackChannelClosed`], as in PeppyOS; kept so code
    /// that names it compiles.
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
    /// to (the peppylib API takes the target explicitly: one of the slot's
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
    /// A message larger than a receiving node accepts
    /// ([`MAX_MESSAGE_BYTES`](crate::MAX_MESSAGE_BYTES)): refused
    /// here rather than sent to be dropped unseen by every reader.
    #[error(
        "a message of {bytes} bytes cannot be published on topic `{topic}`: \
         nodes receive messages of at most {limit} bytes"
    )]
    MessageTooLarge {
        /// The topic.
        topic: String,
        /// The encoded message's size.
        bytes: usize,
        /// The largest message a node receives.
        limit: usize,
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
    /// (the `testing` module).
    #[error("{0}")]
    Testing(String),
    /// An error of the node's own code, kept as it is (its text is shown;
    /// `source()` returns it).
    #[error("{0}")]
    Node(#[source] Box<dyn std::error::Error + Send + Sync>),

    // PeppyOS's variants, with its names and fields, for node code that
    // matches on them.
    /// An I/O failure (node code's `?` on a file read, or an
    /// `io::Error::other` a node builds to fail its instance).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The system clock reads before the Unix epoch.
    #[error("system clock unavailable: {0}")]
    SystemTime(#[from] std::time::SystemTimeError),
    /// A goal's feedback stream closed cleanly: the server finished
    /// (completed, cancelled or abandoned) the goal and every feedback
    /// message was read. `get_result` says how it ended.
    #[error("action feedback channel closed: the goal is over and its feedback was read")]
    ActionFeedbackChannelClosed,
    /// The server instance a goal was sent to went away (its process died,
    /// its host was lost) without closing the goal's feedback stream; the
    /// goal's result is `Abandoned`.
    #[error(
        "action `{action_name}`{} went away before closing the feedback stream",
        for_instance(.instance_id)
    )]
    ActionFeedbackProducerGone {
        /// The server instance.
        instance_id: Option<String>,
        /// The action.
        action_name: String,
    },
    /// Waiting for a goal's result ran out of time: the goal is still
    /// running (ask again), or its server stopped answering.
    #[error(
        "action `{action_name}`{} has timed out waiting for result",
        for_instance(.instance_id)
    )]
    ActionResultTimeout {
        /// The server instance.
        instance_id: Option<String>,
        /// The action.
        action_name: String,
    },
    /// No server answered the request for a goal's result.
    #[error(
        "action `{action_name}`{} is unreachable for result",
        for_instance(.instance_id)
    )]
    ActionResultUnreachable {
        /// The server instance.
        instance_id: Option<String>,
        /// The action.
        action_name: String,
    },
    /// The goal's server abandoned it without a result.
    #[error(
        "action `{action_name}`{} was abandoned by its worker before producing a result",
        for_instance(.instance_id)
    )]
    ActionGoalAbandoned {
        /// The server instance.
        instance_id: Option<String>,
        /// The action.
        action_name: String,
    },
    /// The goal finished, but its result was kept only for a while and is
    /// gone.
    #[error(
        "action `{action_name}`{} result expired before it could be fetched",
        for_instance(.instance_id)
    )]
    ActionResultExpired {
        /// The server instance.
        instance_id: Option<String>,
        /// The action.
        action_name: String,
    },
    /// A service's request stream closed while a request was awaited.
    #[error("service request stream closed unexpectedly")]
    ServiceRequestStreamClosed,
    /// A subscription ended before it yielded a message.
    #[error("subscription to `{topic_name}` closed without yielding a message")]
    SubscriptionClosed {
        /// The topic.
        topic_name: String,
    },
    /// A pairing call named a slot the node does not declare.
    #[error(
        "unknown pairing slot `{link_id}`: the node declares no depends_on.pairings entry with that link_id"
    )]
    UnknownPairingSlot {
        /// The slot asked for.
        link_id: String,
    },
    /// A wait for a peer ended because the node's runtime stopped.
    #[error("pairing slot closed (the runtime stopped while waiting for a peer)")]
    PairingSlotClosed,
    /// An observer call named a slot the node does not declare.
    #[error(
        "unknown observer slot `{link_id}`: the node declares no depends_on.pairing_observers entry with that link_id"
    )]
    UnknownObservationSlot {
        /// The slot asked for.
        link_id: String,
    },
    /// A request could not be built (an empty datastore key, say).
    #[error("invalid service request `{identifier}`: {reason}")]
    InvalidServiceRequest {
        /// What was asked.
        identifier: String,
        /// Why it is refused.
        reason: String,
    },
    /// A value could not be encoded.
    #[error("serialization error: {0}")]
    Serialization(String),
    /// A value could not be decoded.
    #[error("deserialization error: {0}")]
    Deserialization(String),
    /// The node's parameters were already taken.
    #[error("parameters have already been taken (take_parameters() can only be called once)")]
    ParametersAlreadyTaken,
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
