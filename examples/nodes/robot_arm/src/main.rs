//! `robot_arm`: drives three joints (simulated) toward the latest command
//! and reports their state at 20 Hz. It hears `joint_commands` from any
//! controller as an external consumed topic: it does not depend on the
//! controller, which is what lets the controller depend on it.

peppy::include_generated!();

use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use peppygen::consumed_topics::joint_commands;
use peppygen::emitted_topics::joint_states;
use peppygen::exposed_actions::move_arm;
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

#[derive(Clone, Copy, Default)]
struct Joints {
    position: [f64; 3],
    velocity: [f64; 3],
    target: [f64; 3],
    max_velocity: f64,
}

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(_params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    let joints = Arc::new(Mutex::new(Joints {
        max_velocity: 1.0,
        ..Joints::default()
    }));

    let (listener, state) = (runner.clone(), joints.clone());
    tokio::spawn(async move {
        let mut count = 0u64;
        while let Ok((from, command)) =
            joint_commands::on_next_message_received(&listener, None, None).await
        {
            count += 1;
            if count == 1 || count.is_multiple_of(20) {
                println!(
                    "command {count} from {from}: target {:?} max {}",
                    command.target_positions, command.max_velocity
                );
            }
            let mut j = state.lock().unwrap_or_else(|p| p.into_inner());
            j.target = command.target_positions;
            j.max_velocity = command.max_velocity;
        }
    });

    // The move_arm action: accept goals with a positive speed, report the
    // remaining distance, finish when reached (or cancelled).
    let (server, state) = (runner.clone(), joints.clone());
    tokio::spawn(async move {
        let Ok(mut action) = move_arm::ActionHandle::expose(&server).await else {
            return;
        };
        while let Ok(Some(goal)) = action
            .handle_goal_next_request(|request| {
                if request.data.max_velocity > 0.0 {
                    Ok(move_arm::GoalResponse::accept())
                } else {
                    Ok(move_arm::GoalResponse::reject(
                        "max_velocity must be positive",
                    ))
                }
            })
            .await
        {
            let state = state.clone();
            tokio::spawn(async move {
                let data = goal.request().data.clone();
                println!(
                    "move_arm goal {} from {}: to {:?}",
                    goal.goal_id(),
                    goal.request().instance_id,
                    data.target_positions
                );
                {
                    let mut j = state.lock().unwrap_or_else(|p| p.into_inner());
                    j.target = data.target_positions;
                    j.max_velocity = data.max_velocity;
                }
                loop {
                    let position = state.lock().unwrap_or_else(|p| p.into_inner()).position;
                    let remaining = position
                        .iter()
                        .zip(data.target_positions)
                        .map(|(p, t)| (t - p).abs())
                        .fold(0.0, f64::max);
                    if goal.is_cancelled() {
                        let _ = goal.complete_cancelled(false, position).await;
                        return;
                    }
                    if remaining < 1e-3 {
                        let _ = goal.complete(true, position).await;
                        return;
                    }
                    let _ = goal.publish_feedback(remaining).await;
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            });
        }
    });

    tokio::spawn(async move {
        let dt = 0.05;
        let mut tick = tokio::time::interval(Duration::from_secs_f64(dt));
        while !runner.cancellation_token().is_cancelled() {
            tick.tick().await;
            let j = {
                let mut j = joints.lock().unwrap_or_else(|p| p.into_inner());
                for i in 0..3 {
                    let step = (j.target[i] - j.position[i])
                        .clamp(-j.max_velocity * dt, j.max_velocity * dt);
                    j.velocity[i] = step / dt;
                    j.position[i] += step;
                }
                *j
            };
            if let Err(e) =
                joint_states::emit(&runner, j.position, j.velocity, SystemTime::now()).await
            {
                eprintln!("emit failed: {e}");
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md).

    use std::time::Duration;

    use super::peppygen::fixtures::exposed_actions::move_arm;
    use super::peppygen::fixtures::harness::Harness;
    use super::peppygen::mock::external::joint_commands;
    use super::peppygen::{QoSProfile, Result};

    const TIMEOUT: Duration = Duration::from_secs(10);

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_command_moves_the_joints_it_reports() -> Result<()> {
        let (mut harness, mocks) = Harness::start(super::setup).await?;
        let first = harness.emitted.joint_states.next_within(TIMEOUT).await?;
        assert_eq!(first.map(|s| s.positions), Some([0.0; 3]));
        mocks
            .external
            .joint_commands
            .publish(&joint_commands::Message {
                target_positions: [0.1, -0.1, 0.05],
                max_velocity: 10.0,
            })
            .await?;
        // At 10 rad/s the joints reach the target within a tick or two.
        loop {
            let state = harness
                .emitted
                .joint_states
                .next_within(TIMEOUT)
                .await?
                .expect("the tap is open");
            if state.positions == [0.1, -0.1, 0.05] {
                break;
            }
        }
        harness.shutdown().await
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn move_arm_refuses_a_goal_without_speed_and_reaches_one_with() -> Result<()> {
        let (harness, _mocks) = Harness::start(super::setup).await?;
        let refused = move_arm::send_goal(
            &harness,
            &move_arm::GoalRequestData {
                target_positions: [1.0; 3],
                max_velocity: 0.0,
            },
            QoSProfile::Standard,
            TIMEOUT,
        )
        .await?;
        assert!(!refused.accepted);
        assert_eq!(
            refused.reason.as_deref(),
            Some("max_velocity must be positive")
        );

        let mut goal = move_arm::send_goal(
            &harness,
            &move_arm::GoalRequestData {
                target_positions: [0.2, 0.0, -0.2],
                max_velocity: 20.0,
            },
            QoSProfile::Standard,
            TIMEOUT,
        )
        .await?;
        assert!(goal.accepted);
        let remaining = goal.on_next_feedback().await?;
        assert!(remaining.remaining <= 0.2 + 1e-9, "{remaining:?}");
        match goal.get_result(TIMEOUT).await?.outcome {
            move_arm::ResultOutcome::Completed(result) => {
                assert!(result.reached);
                assert_eq!(result.final_positions, [0.2, 0.0, -0.2]);
            }
            other => panic!("the goal ended {other:?}"),
        }
        harness.shutdown().await
    }
}
