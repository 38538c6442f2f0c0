//! The peppy runtime under the names today's node code imports from
//! `peppylib`. Written by `peppy-launch sync`; every item is peppy's own, so
//! a node built this way talks to every other peppy node.
#![allow(missing_docs)]

pub use ::peppy::{
    Error as PeppyError, OutgoingMessage as Payload, ProducerRef, Result as PeppyResult,
    TopicPublisher,
};

/// Running a node: `NodeBuilder`, `NodeRunner`, the cancellation token.
pub mod runtime {
    pub use ::peppy::{CancellationToken, NodeBuilder, NodeRunner, StandaloneConfig};
}

/// Who sent a message and who a call goes to.
pub mod messaging {
    pub use ::peppy::{NonEmptyProducers, ProducerRef};
}

/// Delivery settings.
pub mod config {
    pub use ::peppy::QoSProfile;
}

/// The stack's clock: `synchronize`, `subscribe`, and sim time.
pub mod clock {
    pub use ::peppy::clock::*;
}
