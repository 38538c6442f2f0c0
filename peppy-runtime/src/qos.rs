//! What each QoS profile means for Zenoh and for the consumer's queue.

use peppy_schema::QosProfile;
use zenoh::qos::{CongestionControl, Priority};

/// How a consumer's queue behaves when its reader falls behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum QueuePolicy {
    /// Keep the newest `n`, drop the oldest.
    KeepNewest(usize),
    /// Keep every message, up to `max_bytes` queued; warn once the
    /// backlog reaches `warn_at` messages. Never blocks delivery: Zenoh
    /// delivers every subscription and query of a session on the same
    /// threads, so blocking there for one slow reader would stall all the
    /// node's other topics and services.
    KeepAll {
        /// The backlog (in messages) that earns the first warning.
        warn_at: usize,
        /// The most payload bytes held unread before arrivals are dropped.
        max_bytes: usize,
    },
}

/// The most one reliable topic's inbox holds unread before the node drops
/// (and counts, in the log) what arrives next. A bound on memory for a
/// reader that has stopped for good; no reader that keeps reading gets
/// near it.
const KEEP_ALL_BYTES: usize = 1 << 30;

pub(crate) fn congestion(q: QosProfile) -> CongestionControl {
    match q {
        QosProfile::SensorData | QosProfile::Standard => CongestionControl::Drop,
        QosProfile::Reliable | QosProfile::Critical => CongestionControl::Block,
    }
}

pub(crate) fn priority(q: QosProfile) -> Priority {
    match q {
        QosProfile::SensorData => Priority::DataLow,
        QosProfile::Standard => Priority::Data,
        QosProfile::Reliable => Priority::DataHigh,
        QosProfile::Critical => Priority::RealTime,
    }
}

pub(crate) fn express(q: QosProfile) -> bool {
    matches!(q, QosProfile::SensorData | QosProfile::Critical)
}

pub(crate) fn queue(q: QosProfile) -> QueuePolicy {
    match q {
        QosProfile::SensorData => QueuePolicy::KeepNewest(5),
        QosProfile::Standard => QueuePolicy::KeepNewest(10),
        QosProfile::Reliable | QosProfile::Critical => QueuePolicy::KeepAll {
            warn_at: 256,
            max_bytes: KEEP_ALL_BYTES,
        },
    }
}
