//! Generated code over real Zenoh: nodes generated from the peppy-build
//! fixtures (with `#[peppy::node]`) talk through an in-process router on a
//! loopback port, one namespace per test (topics, services, actions,
//! parameters); codec round trips of every generated message shape; and
//! node code against every generated API shape (`api`).

#![deny(warnings)]

mod actions;
mod api;
mod harness;
mod nodes;
mod pairings;
mod params;
mod peppyos_api;
mod python;
mod roundtrip;
mod services;
mod support;
mod topics;
