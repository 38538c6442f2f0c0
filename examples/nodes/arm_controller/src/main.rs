//! `arm_controller`: plans the next joint target from the arm's state and
//! commands it. `joint_states` comes through the linked `robot_arm` slot
//! (module `robot_arm_joint_states`); `joint_commands` goes out to whoever
//! listens: the arm hears it as an external topic.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::sync::Arc;
use std::time::Duration;

use peppygen::consumed_actions::robot_arm_move_arm;
use peppygen::consumed_topics::robot_arm_joint_states;
use peppygen::emitted_topics::joint_commands;
use peppygen::{NodeBuilder, NodeRunner, Parameters, QoSProfile, Result};

/// Sends the arm home with its `move_arm` action, following its progress.
async fn home(runner: &NodeRunner, max_velocity: f64) -> Result<()> {
    let goal = robot_arm_move_arm::GoalRequest::new([0.5, 0.0, 0.0], max_velocity);
    let mut handle = loop {
        match robot_arm_move_arm::ActionHandle::fire_goal(
            runner,
            Duration::from_secs(2),
            goal.clone(),
            QoSProfile::Standard,
        )
        .await
        {
            Ok(h) => break h,
            // The arm may start after us.
            Err(_) if !runner.cancellation_token().is_cancelled() => {
                tokio::time::sleep(Duration::from_millis(300)).await
            }
            Err(e) => return Err(e),
        }
    };
    if !handle.data.accepted {
        println!(
            "homing refused: {}",
            handle.data.error_message.unwrap_or_default()
        );
        return Ok(());
    }
    while let Ok(feedback) = handle.on_next_feedback_message().await {
        println!("homing: {:.2} rad to go", feedback.remaining);
    }
    let result = handle.get_result(Duration::from_secs(30)).await?;
    match result.outcome {
        robot_arm_move_arm::ResultOutcome::Completed(r) => {
            println!(
                "homed by {}: reached={} at {:?}",
                result.instance_id, r.reached, r.final_positions
            )
        }
        other => println!("homing ended: {other:?}"),
    }
    Ok(())
}

/// Sweeps the first joint back and forth between -1 and 1 rad, turning
/// around at either end.
fn next_target(current: &[f64; 3], step: f64, direction: &mut f64) -> [f64; 3] {
    if current[0] >= 1.0 - 1e-9 {
        *direction = -1.0;
    } else if current[0] <= -1.0 + 1e-9 {
        *direction = 1.0;
    }
    let mut t = *current;
    t[0] = (current[0] + *direction * step).clamp(-1.0, 1.0);
    t
}

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    tokio::spawn(async move {
        if let Err(e) = home(&runner, params.max_velocity).await {
            eprintln!("homing failed: {e}");
        }
        let mut cycle = 0u64;
        let mut direction = 1.0;
        while let Ok((arm, state)) =
            robot_arm_joint_states::on_next_message_received(&runner, None).await
        {
            cycle += 1;
            let target = next_target(&state.positions, params.step, &mut direction);
            if cycle == 1 || cycle.is_multiple_of(20) {
                println!(
                    "cycle {cycle}: {arm} at {:?} -> target {:?}",
                    state.positions, target
                );
            }
            if let Err(e) = joint_commands::emit(&runner, target, params.max_velocity).await {
                eprintln!("emit failed: {e}");
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md):
    //! the mock plays the arm, its `move_arm` action and its joint states.

    use std::time::{Duration, SystemTime};

    use super::peppygen::fixtures::harness::{Config, Harness};
    use super::peppygen::mock::deps::robot_arm::Mock as Arm;
    use super::peppygen::mock::deps::robot_arm::{joint_states, move_arm};
    use super::peppygen::{Parameters, Result};

    const TIMEOUT: Duration = Duration::from_secs(10);

    fn config() -> Config {
        Config {
            parameters: Some(Parameters {
                step: 0.25,
                max_velocity: 2.0,
            }),
            ..Config::default()
        }
    }

    /// Publishes the arm at `positions` and returns the command it gets.
    async fn command_for(
        harness: &mut super::peppygen::fixtures::harness::Harness,
        arm: &Arm,
        positions: [f64; 3],
    ) -> Result<([f64; 3], f64)> {
        arm.joint_states
            .publish(&joint_states::Message {
                positions,
                velocities: [0.0; 3],
                timestamp: SystemTime::now(),
            })
            .await?;
        let command = harness
            .emitted
            .joint_commands
            .next_within(TIMEOUT)
            .await?
            .expect("the tap is open");
        Ok((command.target_positions, command.max_velocity))
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn it_homes_the_arm_then_sweeps_the_first_joint() -> Result<()> {
        let (mut harness, mocks) = Harness::start_with(config(), super::setup).await?;
        let arm = mocks.deps.robot_arm;
        let goal = arm.move_arm.next_goal(TIMEOUT).await?;
        assert_eq!(goal.request.target_positions, [0.5, 0.0, 0.0]);
        assert_eq!(goal.request.max_velocity, 2.0);
        let goal = goal.accept().await?;
        goal.publish_feedback(&move_arm::FeedbackMessage { remaining: 0.5 })
            .await?;
        goal.complete(&move_arm::ResultResponseData {
            reached: true,
            final_positions: [0.5, 0.0, 0.0],
        })
        .await?;

        // Homed, it steps joint 0 by `step` from wherever the arm is...
        assert_eq!(
            command_for(&mut harness, &arm, [0.5, 0.2, -0.1]).await?,
            ([0.75, 0.2, -0.1], 2.0)
        );
        // ...turns around at the end of the range...
        assert_eq!(
            command_for(&mut harness, &arm, [1.0, 0.0, 0.0]).await?,
            ([0.75, 0.0, 0.0], 2.0)
        );
        // ...and keeps that direction until the other end.
        assert_eq!(
            command_for(&mut harness, &arm, [0.5, 0.0, 0.0]).await?,
            ([0.25, 0.0, 0.0], 2.0)
        );
        harness.shutdown().await
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_refused_homing_still_leaves_it_commanding_the_arm() -> Result<()> {
        let (mut harness, mocks) = Harness::start_with(config(), super::setup).await?;
        let arm = mocks.deps.robot_arm;
        arm.move_arm
            .next_goal(TIMEOUT)
            .await?
            .reject("the arm is braked")
            .await?;
        assert_eq!(
            command_for(&mut harness, &arm, [0.0; 3]).await?,
            ([0.25, 0.0, 0.0], 2.0)
        );
        harness.shutdown().await
    }
}
