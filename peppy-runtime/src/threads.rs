//! The threads a node runs Zenoh on.
//!
//! By default Zenoh runs its work on five runtimes of its own (receive,
//! transmit, accept, network, application), six threads beside the node's
//! tokio runtime, and a message received crosses from the thread that read
//! the socket to the one that routes it before it reaches the node. On a
//! small computer each crossing is a wake-up of a parked thread, and the
//! wake-ups are most of a small message's latency. A node started by
//! [`NodeBuilder::run`](crate::NodeBuilder::run) runs Zenoh's receiving,
//! accepting and network work on one thread, and its transmitting on
//! another: measured on two cores, a 64-byte round trip between two
//! processes took about a fifth less time (docs/PERFORMANCE.md, "Zenoh's
//! threads").
//!
//! Transmitting keeps its own thread: a message sent with congestion
//! control `Block` waits, on the sending thread, for the transmitting task
//! to free a batch, and Zenoh sends from its receiving tasks too (replies,
//! declarations). On one runtime, a receiving task waiting so could hold
//! the only thread the transmitting task can run on. The node's own tasks
//! keep their own runtime: on Zenoh's, a task that sends a large message
//! would wait the same way, and one that computes without yielding would
//! stop the node's sockets being read.
//!
//! Zenoh reads its layout once, from the `ZENOH_RUNTIME` environment
//! variable, when it first starts a runtime; there is no other way to give
//! it one. A process that sets `ZENOH_RUNTIME` itself keeps its own layout.

/// The environment variable Zenoh reads its runtime layout from.
pub const ZENOH_RUNTIME_ENV: &str = "ZENOH_RUNTIME";

/// Zenoh's runtime layout for a node (RON, as `ZENOH_RUNTIME` takes it):
/// receiving, accepting and network work handed over to the application
/// runtime's one thread; transmitting on its own.
pub const NODE_LAYOUT: &str =
    "(app: (worker_threads: 1), rx: (handover: app), acc: (handover: app), net: (handover: app))";

/// Gives Zenoh the node layout, [`NODE_LAYOUT`], unless `ZENOH_RUNTIME` is
/// already set. Processes this one starts inherit it.
///
/// Call it before the program starts any thread of its own, and before
/// its first use of Zenoh: Zenoh reads the layout once, and setting an
/// environment variable while another thread reads the environment is
/// undefined behaviour. [`NodeBuilder::run`](crate::NodeBuilder::run) calls
/// it first thing.
pub fn share_zenoh_threads() {
    if std::env::var_os(ZENOH_RUNTIME_ENV).is_none() {
        // SAFETY: the documented precondition: no other thread of this
        // program runs yet (Zenoh starts its threads on first use, after
        // reading this variable).
        unsafe { std::env::set_var(ZENOH_RUNTIME_ENV, NODE_LAYOUT) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_node_layout_keeps_transmitting_on_its_own_thread() {
        for runtime in ["rx", "acc", "net"] {
            assert!(
                NODE_LAYOUT.contains(&format!("{runtime}: (handover: app)")),
                "{NODE_LAYOUT}"
            );
        }
        assert!(!NODE_LAYOUT.contains("tx:"), "{NODE_LAYOUT}");
    }
}
