//! What calls do once the node stops: they return [`Error::ShuttingDown`],
//! and a call *made* on an already stopped node pauses first. A serving loop
//! that ignores the error (`loop { let _ = next(..).await; }`) then parks
//! instead of spinning, so the node's runtime can drop it and stop promptly.

use std::time::Duration;

use crate::error::Error;

/// How long a call made on an already stopped node waits before it
/// returns [`Error::ShuttingDown`].
pub(crate) const REFUSAL_PAUSE: Duration = Duration::from_millis(100);

/// [`Error::ShuttingDown`], after [`REFUSAL_PAUSE`].
pub(crate) async fn refused() -> Error {
    tokio::time::sleep(REFUSAL_PAUSE).await;
    Error::ShuttingDown
}
