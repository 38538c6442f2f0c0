//! `arm_controller`: plans the next joint target from the arm's state and
//! commands it. `joint_states` comes through the linked `robot_arm` slot
//! (module `robot_arm_joint_states`); `joint_commands` goes out to whoever
//! listens: the arm hears it as an external topic.

#[peppy::node("peppy.json5")]
mod peppygen {}

use peppygen::consumed_topics::robot_arm_joint_states;
use peppygen::emitted_topics::joint_commands;
use peppygen::{NodeBuilder, Parameters, Result};

fn next_target(current: &[f64; 3], step: f64) -> [f64; 3] {
    // Sweep the first joint back and forth between -1 and 1 rad.
    let mut t = *current;
    t[0] = if current[0] > 1.0 {
        -1.0
    } else {
        current[0] + step
    };
    t
}

fn main() -> Result<()> {
    NodeBuilder::new().run(|params: Parameters, runner| async move {
        tokio::spawn(async move {
            let mut cycle = 0u64;
            while let Ok((arm, state)) =
                robot_arm_joint_states::on_next_message_received(&runner, None).await
            {
                cycle += 1;
                let target = next_target(&state.positions, params.step);
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
    })
}
