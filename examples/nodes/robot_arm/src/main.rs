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
use peppygen::{NodeBuilder, Parameters, Result};

#[derive(Clone, Copy, Default)]
struct Joints {
    position: [f64; 3],
    velocity: [f64; 3],
    target: [f64; 3],
    max_velocity: f64,
}

fn main() -> Result<()> {
    NodeBuilder::new().run(|_params: Parameters, runner| async move {
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
    })
}
