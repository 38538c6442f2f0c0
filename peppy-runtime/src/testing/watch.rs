//! How a test learns that the node under test failed: a setup that
//! returned an error or panicked ends every wait of the harness with that
//! failure instead of leaving the test to hang until its timeout.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio_util::sync::CancellationToken;

use crate::error::{Error, Result};

/// Shared by a harness, its mocks and its taps.
#[derive(Clone, Default)]
pub(crate) struct Watch {
    failed: CancellationToken,
    why: Arc<Mutex<Option<String>>>,
}

impl Watch {
    /// Records the node's failure and wakes every waiter.
    pub(crate) fn fail(&self, why: String) {
        let mut slot = self.why.lock().unwrap_or_else(|p| p.into_inner());
        slot.get_or_insert(why);
        self.failed.cancel();
    }

    /// The failure, as the error a waiter returns.
    fn error(&self) -> Error {
        let why = self.why.lock().unwrap_or_else(|p| p.into_inner()).clone();
        Error::Testing(format!(
            "the node under test failed: {}",
            why.unwrap_or_else(|| "(no reason recorded)".into())
        ))
    }

    /// Runs `work` until it ends, the node fails, or `timeout` passes; a
    /// timeout names `what` was waited for.
    pub(crate) async fn bound<T>(
        &self,
        what: &str,
        timeout: Duration,
        work: impl Future<Output = Result<T>>,
    ) -> Result<T> {
        // Work first: what already arrived is returned before a failure.
        tokio::select! {
            biased;
            r = tokio::time::timeout(timeout, work) => r.unwrap_or_else(|_| Err(timed_out(what, timeout))),
            () = self.failed.cancelled() => Err(self.error()),
        }
    }

    /// Runs `work` until it ends or the node fails.
    pub(crate) async fn unbounded<T>(&self, work: impl Future<Output = Result<T>>) -> Result<T> {
        tokio::select! {
            biased;
            r = work => r,
            () = self.failed.cancelled() => Err(self.error()),
        }
    }
}

/// The error of a harness wait that ran out of time.
pub(crate) fn timed_out(what: &str, timeout: Duration) -> Error {
    Error::Testing(format!(
        "timed out after {:.1} s waiting for {what}",
        timeout.as_secs_f64()
    ))
}
