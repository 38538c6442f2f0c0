// Seed 002's robot_arm, in the legacy `schema_version: 1` form, with the
// seed's Rust code. (The seed passes a third `None`; SPEC 4's signature,
// which this project follows, takes `from_core_node` only.)
#![deny(warnings)]

#[peppy::node("tests/e2e/api/legacy_robot_arm.json5")]
mod peppygen {}

use peppygen::consumed_topics::joint_commands;
use peppygen::emitted_topics::joint_states;
use peppygen::{NodeBuilder, Parameters, Result};

fn node_main() -> Result<()> {
    NodeBuilder::new().run(|_args: Parameters, node_runner| async move {
        let node_runner_clone = node_runner.clone();
        tokio::spawn(async move {
            loop {
                let (instance_id, command) =
                    joint_commands::on_next_message_received(&node_runner_clone, None)
                        .await
                        .expect("failed to receive joint command");

                println!(
                    "received from {}: target={:?} max_vel={}",
                    instance_id, command.target_positions, command.max_velocity
                );

                // Drive the joints, then report state
                let _ = joint_states::emit(
                    &node_runner_clone,
                    command.target_positions,
                    [0.0, 0.0, 0.0],
                    std::time::SystemTime::now(),
                )
                .await;
            }
        });

        Ok(())
    })
}

#[test]
fn compiles_and_runs() {
    let _ = node_main;
}
