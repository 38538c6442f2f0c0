//! # peppy-runtime
//!
//! What generated peppy code calls at run time: one Zenoh session per node,
//! typed topics and services, and consumer-side routing of the launcher's
//! bindings.
//!
//! A node's `main` is one call:
//!
//! ```ignore
//! NodeBuilder::<Parameters>::new().run(|params, runner| async move {
//!     // spawn tasks that emit, consume and serve; watch
//!     // runner.cancellation_token() to stop cleanly
//!     Ok(())
//! })
//! ```
//!
//! Start-up inputs come from the launcher (`PEPPY_RUNTIME_CONFIG`) or, in a
//! plain `cargo run`, from flags: `--instance-id ID`, `--bind KEY@INSTANCE`,
//! `--params FILE.json`, `--namespace NS`, `--connect` / `--listen ENDPOINT`
//! and `key=value` parameter overrides.
//!
//! A stop cancels [`NodeRunner::cancellation_token`] first, then runs the
//! node's shutdown hooks ([`NodeRunner::on_shutdown`]) within one grace
//! window while messaging is still up, then closes messaging. Once the
//! token fires, waits for incoming messages, requests and goals return
//! [`Error::ShuttingDown`] at once; outgoing calls work until messaging
//! closes. A call refused that way returns the error after a short pause,
//! so loops that ignore it park instead of spinning (see docs/RUNNING.md,
//! "Stopping").
//!
//! The stack clock (wall or simulated time) is in [`clock`].
//!
//! The wire format (key expressions, attachments, payload encoding) is in
//! [`wire`] and docs/WIRE.md.

mod acks;
mod actions;
pub mod clock;
pub mod core_functions;
pub mod datastore;
pub mod describe;
#[cfg(unix)]
mod direct;
#[cfg(not(unix))]
#[path = "direct/elsewhere.rs"]
mod direct;
mod error;
pub mod info;
mod intake;
mod members;
mod node;
mod pairing;
mod producer_ref;
mod producers;
mod publisher;
mod qos;
mod request;
mod services;
mod shm;
mod slots;
pub mod spec;
pub mod stack;
mod startup;
mod stop;
mod subscription;
mod target;
// Mocks, the fixture session and the harness's plumbing: only for a node's
// tests (generated `peppygen` asks for them under its own `testing`
// feature), so no node binary compiles them.
#[cfg(feature = "testing")]
pub mod testing;
pub mod threads;
pub mod tool;
mod topics;
pub mod wire;

pub use actions::{
    CancelState, DEFAULT_RESULT_RETENTION, GoalClient, GoalContext, GoalServer, IncomingGoal,
    Outcome,
};
pub use error::{Error, Result};
pub use node::{NodeBuilder, NodeRunner};
pub use pairing::{
    NonEmptyObservedSources, ObservedSource, ObservedSubscription, PairedSubscription, PeerInfo,
};
pub use peppy_schema::QosProfile as QoSProfile;
pub use producer_ref::{NonEmptyProducers, ProducerRef};
pub use publisher::{OutgoingMessage, PairedPublisher, TopicPublisher};
pub use services::{Caller, Reply};
pub use shm::{SHM_ENV, SharedMemory};
pub use startup::{
    DEFAULT_NAMESPACE, DEFAULT_SHUTDOWN_GRACE, Endpoints, Login, RUNTIME_CONFIG_ENV,
    SHUTDOWN_GRACE_ENV, STANDALONE_CORE, StandaloneConfig, StartupConfig, startup_from_flags,
};
pub use subscription::Subscription;
pub use tokio_util::sync::CancellationToken;
pub use topics::MAX_MESSAGE_BYTES;
pub use topics::{Payload, Senders};

/// What generated code calls. Not a stable API for hand-written code.
#[doc(hidden)]
pub mod codegen {
    pub use crate::__peppy_codec as codec;
    pub use crate::actions::{
        CancelState, GoalClient, GoalContext, GoalServer, IncomingGoal, Outcome, next_goal,
        send_goal, send_goal_to,
    };
    pub use crate::pairing::{
        NonEmptyObservedSources, ObservedSource, ObservedSubscription, PairedSubscription,
        PeerInfo, declare_paired_publisher, non_empty_observed_sources, observed_source,
        observed_sources, paired, subscribe_observed, subscribe_paired, wait_paired,
    };
    pub use crate::producer_ref::{NonEmptyProducers, ProducerRef};
    pub use crate::publisher::{
        OutgoingMessage, PairedPublisher, TopicPublisher, declare_publisher,
    };
    pub use crate::services::{Caller, Reply, call, call_to, handle_next};
    pub use crate::slots::{
        bound_producer, bound_producers, non_empty_bound_producers, optional_bound_producer,
        sole_bound_producer,
    };
    pub use crate::spec::*;
    pub use crate::subscription::{Subscription, subscribe};
    pub use crate::topics::{
        Senders, emit, next_message, next_message_from, next_payload, next_payload_from,
    };
    pub use crate::wire::codec::{
        Counted, Decode, DecodeError, Decoder, Encode, Writer, from_bytes, to_bytes,
    };
    pub use crate::wire::struct_codec::{MessageData, min_counted_size_of, min_size_of};
    pub use peppy_schema::QosProfile;
    pub use serde;
    pub use serde_json;
    pub use zenoh;
}
