//! `robot_arm`: drives three joints (simulated) toward the latest command
//! and reports their state at 20 Hz. It hears `joint_commands` from any
//! controller as an external consumed topic: it does not depend on the
//! controller, which is what lets the controller depend on it.

peppy::include_generated!();

use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use peppygen::consumed_topics::joint_commands;
use peppygen::emitted_topics::joint_states;
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
                joint_commands::on_next_message_received(&listener, None).await
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
