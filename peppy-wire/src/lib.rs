//! The wire format: key expressions, attachments and the payload codec.
//! docs/WIRE.md describes it for implementers in other languages.
//!
//! This crate does no I/O and depends on nothing but `std` (and, with the
//! `dynamic` feature, the schema's format model), so everything that reads
//! bytes from a peer can be fuzzed and tested without a Zenoh session:
//! `peppy-runtime` re-exports it as `peppy_runtime::wire`.

pub mod attachment;
pub mod codec;
#[cfg(feature = "dynamic")]
pub mod dynamic;
pub mod keys;
