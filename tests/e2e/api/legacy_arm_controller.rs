// Seed 002's arm_controller, in the legacy `schema_version: 1` form, with
// the seed's Rust code (two arguments to `on_next_message_received`, per
// SPEC 4).
#![deny(warnings)]

#[peppy::node("tests/e2e/api/legacy_arm_controller.json5")]
mod peppygen {}

use peppygen::consumed_topics::robot_arm_joint_states;
use peppygen::emitted_topics::joint_commands;
use peppygen::{NodeBuilder, Parameters, Result};

fn node_main() -> Result<()> {
    NodeBuilder::new().run(|_args: Parameters, node_runner| async move {
        let node_runner_clone = node_runner.clone();
        tokio::spawn(async move {
            loop {
                // Linked topic: module name is <local_node_id>_<topic_name>
                let (_instance_id, state) =
                    robot_arm_joint_states::on_next_message_received(&node_runner_clone, None)
                        .await
                        .expect("failed to receive joint state");

                // Compute next target based on current state
                let target = compute_next_target(&state.positions);

                let _ = joint_commands::emit(
                    &node_runner_clone,
                    target,
                    1.0, // max_velocity
                )
                .await;
            }
        });

        Ok(())
    })
}

fn compute_next_target(current: &[f64; 3]) -> [f64; 3] {
    // Trajectory planning logic
    [current[0] + 0.1, current[1], current[2]]
}

#[test]
fn compiles_and_runs() {
    let _ = node_main;
}
