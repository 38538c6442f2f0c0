//! `gripper`: a legacy-form node (`schema_version: 1`), generated and run
//! exactly like a current one. It opens and closes, reporting its state.

peppy::include_generated!();

use std::time::Duration;

use peppygen::emitted_topics::gripper_state;
use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(|_params: Parameters, runner| async move {
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
    })
}
