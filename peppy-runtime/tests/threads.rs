//! `share_zenoh_threads` in processes whose threads are known. Without
//! libtest's harness `main` is the process's only thread, as a node's is,
//! so the layout is written; with a second thread up it is left alone.
//! Each case runs in a child process of its own, without `ZENOH_RUNTIME`.

use std::process::Command;

use peppy_runtime::threads::{NODE_LAYOUT, Sharing, ZENOH_RUNTIME_ENV, share_zenoh_threads};

/// Selects the case a child process runs.
const CASE_ENV: &str = "PEPPY_THREADS_TEST_CASE";

fn main() {
    match std::env::var(CASE_ENV).as_deref() {
        Ok("alone") => alone(),
        Ok("threaded") => threaded(),
        _ => {
            for case in ["alone", "threaded"] {
                let status = Command::new(std::env::current_exe().unwrap())
                    .env(CASE_ENV, case)
                    .env_remove(ZENOH_RUNTIME_ENV)
                    .status()
                    .unwrap();
                assert!(status.success(), "case `{case}`: {status}");
                println!("threads: {case} ... ok");
            }
        }
    }
}

/// The only thread: the layout is written once, then kept.
fn alone() {
    if !cfg!(target_os = "linux") {
        // No thread count to read: the environment is never written.
        assert_eq!(share_zenoh_threads(), Sharing::OtherThreads);
        return;
    }
    assert_eq!(share_zenoh_threads(), Sharing::Set);
    assert_eq!(std::env::var(ZENOH_RUNTIME_ENV).unwrap(), NODE_LAYOUT);
    assert_eq!(share_zenoh_threads(), Sharing::AlreadySet);
}

/// Another thread up: nothing is written.
fn threaded() {
    let (stop, parked) = std::sync::mpsc::channel::<()>();
    let other = std::thread::spawn(move || parked.recv());
    assert_eq!(share_zenoh_threads(), Sharing::OtherThreads);
    assert_eq!(std::env::var_os(ZENOH_RUNTIME_ENV), None);
    drop(stop);
    let _ = other.join();
}
