//! # peppy
//!
//! Robot software as typed, independently built nodes that find and talk to
//! each other. A node declares what it emits, consumes, exposes and calls in
//! one `peppy.json5`; peppy turns that into a typed Rust API at compile time
//! and carries the messages over Zenoh.
//!
//! This facade is the one dependency a node author adds: it re-exports the
//! runtime ([`NodeBuilder`], [`NodeRunner`], ...) and the [`node`] attribute.
//!
//! ## Walkthrough
//!
//! `peppy.json5` next to `Cargo.toml`:
//!
//! ```json5
//! {
//!   peppy_schema: "node_v1",
//!   manifest: { name: "robot_arm", tag: "v1" },
//!   interfaces: { topics: {
//!     emits: [{ name: "joint_states", qos_profile: "sensor_data", message_format: {
//!       positions: { $type: "array", $items: "f64", $length: 3 },
//!       timestamp: "time",
//!     } }],
//!     consumes: [{ name: "joint_commands", message_format: { max_velocity: "f64" } }],
//!   } },
//!   execution: { language: "rust", run_cmd: ["./target/release/robot_arm"] },
//! }
//! ```
//!
//! `src/main.rs`:
//!
//! ```ignore
//! #[peppy::node("peppy.json5")] // relative to CARGO_MANIFEST_DIR
//! mod peppygen {}
//!
//! use peppygen::consumed_topics::joint_commands;
//! use peppygen::emitted_topics::joint_states;
//! use peppygen::{NodeBuilder, Parameters, Result};
//!
//! fn main() -> Result<()> {
//!     NodeBuilder::new().run(|_params: Parameters, runner| async move {
//!         tokio::spawn(async move {
//!             while let Ok((from, command)) =
//!                 joint_commands::on_next_message_received(&runner, None, None).await
//!             {
//!                 println!("{from} asks for {}", command.max_velocity);
//!                 let _ = joint_states::emit(&runner, [0.0; 3], std::time::SystemTime::now()).await;
//!             }
//!         });
//!         Ok(())
//!     })
//! }
//! ```
//!
//! Or generate from a build script (`peppy-build` as a build-dependency,
//! `fn main() { peppy_build::sync(); }` in `build.rs`)
//! and write `peppy::include_generated!();` instead of the attribute: the
//! module is the same.

#[cfg(feature = "macros")]
pub use peppy_macros::node;
pub use peppy_runtime as runtime;
pub use peppy_runtime::clock;
#[cfg(feature = "testing")]
pub use peppy_runtime::testing;
pub use peppy_runtime::{
    CancellationToken, Error, NodeBuilder, NodeRunner, NonEmptyProducers, OutgoingMessage, Payload,
    ProducerRef, QoSProfile, Result, SharedMemory, StandaloneConfig, Subscription, TopicPublisher,
};

/// Expands to the items it is given when peppy's test surfaces (the
/// `testing` feature) are built, and to nothing otherwise: the test
/// modules generated for `#[cfg(test)]` then compile in a node built with
/// `default-features = false` whose tests do not use them.
#[cfg(feature = "testing")]
#[doc(hidden)]
#[macro_export]
macro_rules! __with_testing {
    ($($item:item)*) => { $($item)* };
}

/// Without the `testing` feature: nothing (see the other definition).
#[cfg(not(feature = "testing"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __with_testing {
    ($($item:item)*) => {};
}

/// Declares `pub mod peppygen` holding the code `peppy_build::sync()` wrote
/// to `OUT_DIR/peppygen.rs` from the build script.
#[macro_export]
macro_rules! include_generated {
    () => {
        /// This node's typed API, generated from its `peppy.json5` by `peppy_build::sync()`.
        pub mod peppygen {
            include!(concat!(env!("OUT_DIR"), "/peppygen.rs"));
        }
    };
}

/// What generated code calls, by absolute paths (`::peppy::codegen::...`).
/// Not a stable API for hand-written code.
#[doc(hidden)]
pub mod codegen {
    pub use peppy_runtime::codegen::*;
    pub use peppy_runtime::{
        Error, NodeBuilder, NodeRunner, Payload, QoSProfile, Result, StandaloneConfig,
    };

    /// An action server's decision on a goal; the goal response format of
    /// every action (`{ accepted, error_message }`), fixed by the framework.
    #[derive(Debug, Clone, PartialEq, Eq, Default)]
    pub struct GoalResponse {
        /// Whether the goal was accepted.
        pub accepted: bool,
        /// Why it was rejected.
        pub error_message: Option<String>,
    }

    impl GoalResponse {
        /// A decision from its fields.
        pub fn new(accepted: bool, error_message: Option<String>) -> Self {
            GoalResponse {
                accepted,
                error_message,
            }
        }

        /// Accepts the goal.
        pub fn accept() -> Self {
            Self::new(true, None)
        }

        /// Rejects the goal; the caller sees `reason`.
        pub fn reject(reason: impl Into<String>) -> Self {
            Self::new(false, Some(reason.into()))
        }
    }

    /// An action server's decision on a goal, in PeppyOS's current API,
    /// for an action that declares no goal response:
    /// `GoalDecision::accept()` or `GoalDecision::reject(reason)`
    /// (`GoalDecision::Reject { reason: None }` rejects without one). An
    /// action that declares a goal response gets a `GoalDecision` of its
    /// own, whose `accept` takes the response.
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub enum GoalDecision {
        /// Accept the goal: it is handed to the server to work on.
        Accept,
        /// Reject the goal; the caller sees `reason`.
        Reject {
            /// Why the goal was rejected.
            reason: Option<String>,
        },
    }

    impl GoalDecision {
        /// Accepts the goal.
        pub fn accept() -> Self {
            GoalDecision::Accept
        }

        /// Rejects the goal; the caller sees `reason`.
        pub fn reject(reason: impl Into<String>) -> Self {
            GoalDecision::Reject {
                reason: Some(reason.into()),
            }
        }
    }

    /// Serde helpers for parameter types serde does not cover the way peppy
    /// documents them: `time` as seconds since the Unix epoch, and
    /// fixed-length arrays of any length.
    pub mod params {
        use std::time::{Duration, SystemTime, UNIX_EPOCH};

        use peppy_runtime::codegen::serde::de::Error as _;
        use peppy_runtime::codegen::serde::{Deserialize, Deserializer, Serialize, Serializer};

        fn to_secs(t: &SystemTime) -> f64 {
            match t.duration_since(UNIX_EPOCH) {
                Ok(d) => d.as_secs_f64(),
                Err(e) => -e.duration().as_secs_f64(),
            }
        }

        fn from_secs<E: peppy_runtime::codegen::serde::de::Error>(s: f64) -> Result<SystemTime, E> {
            let invalid = || {
                E::custom(format!(
                    "time {s} is not a point in time this platform can hold"
                ))
            };
            let d = Duration::try_from_secs_f64(s.abs()).map_err(|_| invalid())?;
            let t = if s >= 0.0 {
                UNIX_EPOCH.checked_add(d)
            } else {
                UNIX_EPOCH.checked_sub(d)
            };
            t.ok_or_else(invalid)
        }

        /// A `time` parameter: seconds since the Unix epoch.
        pub mod time {
            use super::*;

            /// Serializes as seconds since the epoch.
            pub fn serialize<S: Serializer>(t: &SystemTime, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_f64(to_secs(t))
            }

            /// Deserializes from seconds since the epoch.
            pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<SystemTime, D::Error> {
                from_secs(f64::deserialize(d)?)
            }
        }

        /// An array of `time` parameters.
        pub mod time_vec {
            use super::*;

            /// Serializes as seconds since the epoch, each.
            pub fn serialize<S: Serializer>(t: &[SystemTime], s: S) -> Result<S::Ok, S::Error> {
                s.collect_seq(t.iter().map(to_secs))
            }

            /// Deserializes from seconds since the epoch, each.
            pub fn deserialize<'de, D: Deserializer<'de>>(
                d: D,
            ) -> Result<Vec<SystemTime>, D::Error> {
                Vec::<f64>::deserialize(d)?
                    .into_iter()
                    .map(from_secs)
                    .collect()
            }
        }

        /// A fixed-length array of `time` parameters.
        pub mod time_array {
            use super::*;

            /// Serializes as seconds since the epoch, each.
            pub fn serialize<S: Serializer, const N: usize>(
                t: &[SystemTime; N],
                s: S,
            ) -> Result<S::Ok, S::Error> {
                super::array::serialize(&t.map(|t| to_secs(&t)), s)
            }

            /// Deserializes exactly `N` times.
            pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(
                d: D,
            ) -> Result<[SystemTime; N], D::Error> {
                let secs: [f64; N] = super::array::deserialize(d)?;
                let mut out = [UNIX_EPOCH; N];
                for (o, s) in out.iter_mut().zip(secs) {
                    *o = from_secs(s)?;
                }
                Ok(out)
            }
        }

        /// A fixed-length array parameter, of any length.
        pub mod array {
            use super::*;

            /// Serializes as a sequence.
            pub fn serialize<S: Serializer, T: Serialize, const N: usize>(
                items: &[T; N],
                s: S,
            ) -> Result<S::Ok, S::Error> {
                s.collect_seq(items)
            }

            /// Deserializes a sequence of exactly `N` items.
            pub fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(
                d: D,
            ) -> Result<[T; N], D::Error> {
                let items = Vec::<T>::deserialize(d)?;
                let len = items.len();
                items.try_into().map_err(|_| {
                    D::Error::invalid_length(len, &format!("an array of {N}").as_str())
                })
            }
        }
    }
}
