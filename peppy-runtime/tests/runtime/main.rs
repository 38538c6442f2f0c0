//! The runtime over real Zenoh sessions on loopback: an in-process router on
//! an explicit port (no multicast scouting), a fresh namespace per test,
//! hand-written message types, and every wait bounded; and the wire's
//! golden vectors, shared with the Python runtime (`golden`).

mod actions;
mod bindings;
mod clock;
mod faults;
mod golden;
mod host_faults;
mod pairings;
mod process;
mod routing;
mod services;
mod shutdown;
mod support;
mod topics;
