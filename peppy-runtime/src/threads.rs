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
//! it one (zenoh-runtime 1.10.2 parses the variable into a `lazy_static`,
//! `ZRUNTIME_PARAM`, that has no setter). A process that sets
//! `ZENOH_RUNTIME` itself keeps its own layout.
//!
//! Writing the environment is only sound while no other thread can read it
//! (`std::env::set_var`). A library cannot know that from its caller, so
//! [`share_zenoh_threads`] asks the kernel: it writes the variable only
//! when the calling thread is the process's only one (`Threads:` in
//! `/proc/self/status`, which counts every thread, a C library's too), and
//! then nothing can start a thread before the write but the caller itself.
//! A process with other threads (a test harness, a program that started its
//! own before the node) keeps Zenoh's default layout: slower, never unsound.

/// The environment variable Zenoh reads its runtime layout from.
pub const ZENOH_RUNTIME_ENV: &str = "ZENOH_RUNTIME";

/// Zenoh's runtime layout for a node (RON, as `ZENOH_RUNTIME` takes it):
/// receiving, accepting and network work handed over to the application
/// runtime's one thread; transmitting on its own.
pub const NODE_LAYOUT: &str =
    "(app: (worker_threads: 1), rx: (handover: app), acc: (handover: app), net: (handover: app))";

/// What [`share_zenoh_threads`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sharing {
    /// `ZENOH_RUNTIME` now holds [`NODE_LAYOUT`].
    Set,
    /// `ZENOH_RUNTIME` was already set: that layout stays.
    AlreadySet,
    /// Other threads run in this process (or, where there is no
    /// `/proc/self/status`, their number is unknown): the environment is
    /// left alone and Zenoh keeps its default layout.
    OtherThreads,
}

/// Gives Zenoh the node layout, [`NODE_LAYOUT`], unless `ZENOH_RUNTIME` is
/// already set or other threads run. Processes this one starts inherit it.
///
/// Call it first thing in `main`, before the program starts a thread of its
/// own and before its first use of Zenoh (which reads the layout once).
/// Called later, it changes nothing and says why.
/// [`NodeBuilder::run`](crate::NodeBuilder::run) calls it first thing.
pub fn share_zenoh_threads() -> Sharing {
    if std::env::var_os(ZENOH_RUNTIME_ENV).is_some() {
        return Sharing::AlreadySet;
    }
    if !alone() {
        return Sharing::OtherThreads;
    }
    // SAFETY: `set_var` must not race a read of the environment on another
    // thread. The kernel counts this thread as the process's only one, and
    // no thread but this one could start another before the write returns.
    unsafe { std::env::set_var(ZENOH_RUNTIME_ENV, NODE_LAYOUT) };
    Sharing::Set
}

/// Whether the calling thread is the only thread of the process.
#[cfg(target_os = "linux")]
fn alone() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| threads_in_status(&status))
        == Some(1)
}

/// Without `/proc` the count is unknown, so the answer is no.
#[cfg(not(target_os = "linux"))]
fn alone() -> bool {
    false
}

/// The `Threads:` count of a `/proc/<pid>/status` text.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
fn threads_in_status(status: &str) -> Option<u64> {
    status
        .lines()
        .find_map(|line| line.strip_prefix("Threads:"))
        .and_then(|count| count.trim().parse().ok())
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

    #[test]
    fn the_thread_count_is_read_from_the_status_text() {
        let status = "Name:\tnode\nUmask:\t0022\nThreads:\t7\nSigQ:\t0/63\n";
        assert_eq!(threads_in_status(status), Some(7));
        assert_eq!(threads_in_status("Name:\tnode\n"), None);
    }

    /// A test runs beside libtest's main thread, and this one keeps a
    /// second thread up during the call besides.
    #[test]
    fn with_other_threads_the_environment_is_left_alone() {
        let (stop, parked) = std::sync::mpsc::channel::<()>();
        let other = std::thread::spawn(move || parked.recv());
        let before = std::env::var_os(ZENOH_RUNTIME_ENV);
        let expected = if before.is_some() {
            Sharing::AlreadySet
        } else {
            Sharing::OtherThreads
        };
        assert_eq!(share_zenoh_threads(), expected);
        assert_eq!(std::env::var_os(ZENOH_RUNTIME_ENV), before);
        drop(stop);
        let _ = other.join();
    }
}
