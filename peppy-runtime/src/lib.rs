//! # peppy-runtime
//!
//! What generated peppy code calls at run time: one Zenoh session per node,
//! typed topics, services and actions, and consumer-side routing of the
//! launcher's bindings.
//!
//! Status: not implemented yet. This crate holds its place in the workspace
//! so that the facade and the generator can depend on it; it exports nothing
//! that pretends to work.
