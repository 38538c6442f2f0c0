//! Generated code over real Zenoh: nodes generated from the peppy-build
//! fixtures (with `#[peppy::node]`) talk through an in-process router on a
//! loopback port, one namespace per test (topics, services, actions,
//! parameters); plus codec round trips of every generated message shape.

#![deny(warnings)]

mod actions;
mod nodes;
mod params;
mod roundtrip;
mod services;
mod support;
mod topics;
