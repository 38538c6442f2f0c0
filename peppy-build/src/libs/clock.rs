//! `clock::init(&runner)` once in setup, then `clock::now_ns()`: the OS
//! clock, or under `framework.use_sim_time` the simulator's latest tick.
pub use ::peppy::clock::{init, now_ns};
