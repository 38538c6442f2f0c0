//! Quality-of-service profiles (SPEC 5).

use std::fmt;

use serde::{Deserialize, Serialize};

/// How a topic's messages travel (SPEC 5's table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QosProfile {
    /// Newest-only sensor streams: dropped under congestion, small queue.
    SensorData,
    /// The default.
    #[default]
    Standard,
    /// Every message delivered: the publisher waits out congestion and the
    /// consumer keeps every message until read.
    Reliable,
    /// Like `reliable`, at real-time priority.
    Critical,
}

/// Every profile name, for messages.
pub const QOS_NAMES: &[&str] = &["sensor_data", "standard", "reliable", "critical"];

impl QosProfile {
    /// Parses a profile name.
    pub fn parse(s: &str) -> Option<QosProfile> {
        Some(match s {
            "sensor_data" => QosProfile::SensorData,
            "standard" => QosProfile::Standard,
            "reliable" => QosProfile::Reliable,
            "critical" => QosProfile::Critical,
            _ => return None,
        })
    }

    /// The profile's name.
    pub fn as_str(self) -> &'static str {
        match self {
            QosProfile::SensorData => "sensor_data",
            QosProfile::Standard => "standard",
            QosProfile::Reliable => "reliable",
            QosProfile::Critical => "critical",
        }
    }
}

impl fmt::Display for QosProfile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
