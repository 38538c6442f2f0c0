//! `gripper`: a legacy-form node (`schema_version: 1`), generated and run
//! exactly like a current one. It opens and closes, reporting its state.

peppy::include_generated!();

use std::sync::Arc;
use std::time::Duration;

use peppygen::emitted_topics::gripper_state;
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(_params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(200));
        let mut t = 0u32;
        while !runner.cancellation_token().is_cancelled() {
            tick.tick().await;
            let opening = (t % 20) as f32 * 4.0;
            let _ = gripper_state::emit(&runner, opening, opening < 10.0).await;
            t += 1;
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md).

    use std::time::Duration;

    use super::peppygen::Result;
    use super::peppygen::fixtures::harness::Harness;

    const TIMEOUT: Duration = Duration::from_secs(10);

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn it_opens_in_4_mm_steps_and_holds_only_while_nearly_closed() -> Result<()> {
        let (mut harness, _mocks) = Harness::start(super::setup).await?;
        let mut states = Vec::new();
        for _ in 0..4 {
            let state = harness
                .emitted
                .gripper_state
                .next_within(TIMEOUT)
                .await?
                .expect("the tap is open");
            states.push((state.opening_mm, state.holding));
        }
        assert_eq!(
            states,
            [(0.0, true), (4.0, true), (8.0, true), (12.0, false)]
        );
        harness.shutdown().await
    }
}
