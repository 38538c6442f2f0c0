//! # peppy
//!
//! Robot software as typed, independently built nodes that find and talk to
//! each other. A node declares what it emits, consumes, exposes and calls in
//! one `peppy.json5`; peppy turns that into a typed Rust API at compile time
//! and carries the messages over Zenoh.
//!
//! This facade is the one dependency a node author adds. It re-exports the
//! runtime ([`peppy_runtime`]) and, once code generation lands, the
//! `#[peppy::node]` attribute.
//!
//! Status: the document model (`peppy-schema`) and the launcher's `validate`
//! and `check` commands work today; code generation, the runtime and process
//! supervision are being built in that order.

pub use peppy_runtime as runtime;
