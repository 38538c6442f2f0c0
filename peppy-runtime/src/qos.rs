//! What each QoS profile means for Zenoh and for the consumer's queue.

use peppy_schema::QosProfile;
use zenoh::qos::{CongestionControl, Priority};

/// How a consumer's queue behaves when its reader falls behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum QueuePolicy {
    /// Keep the newest `n`, drop the oldest.
    KeepNewest(usize),
    /// Hold `n`, then block delivery (back-pressure to the sender).
    Block(usize),
}

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
        QosProfile::Reliable | QosProfile::Critical => QueuePolicy::Block(256),
    }
}
