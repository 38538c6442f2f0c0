//! `joint_leader`: the leader of a `joint_link` pair. Once paired it
//! streams a sine setpoint to its follower, and only to it; it hears the
//! follower's state, and only its own follower's, and says how far the
//! joint trails. While unpaired its setpoints go nowhere (publishing is a
//! no-op), and a restarted or newly linked follower is picked up as it
//! comes.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::sync::Arc;
use std::time::Duration;

use peppygen::NodeRunner;
use peppygen::paired_topics::follower::{joint_setpoint, joint_state};
pub use peppygen::{NodeBuilder, Parameters, Result};

/// The setpoint at step `n`: a sine of `amplitude`, one period a second.
pub fn setpoint(n: u64, rate_hz: f64, amplitude: f64) -> f64 {
    amplitude * (std::f64::consts::TAU * n as f64 / rate_hz).sin()
}

async fn lead(runner: Arc<NodeRunner>, params: Parameters) -> Result<()> {
    let token = runner.cancellation_token().clone();
    let publisher = joint_setpoint::declare_publisher(&runner).await?;
    let rate = params.rate_hz.clamp(0.1, 10_000.0);
    let mut ticks = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
    let mut sequence = 0u64;
    loop {
        tokio::select! {
            _ = token.cancelled() => return Ok(()),
            _ = ticks.tick() => {}
        }
        // Unpaired, the publish would send nothing: hold the sequence so
        // the next follower starts from the top of the wave.
        if joint_setpoint::paired(&runner)?.is_none() {
            continue;
        }
        let position = setpoint(sequence, rate, params.amplitude);
        publisher
            .publish(joint_setpoint::build_message(position, sequence)?)
            .await?;
        sequence += 1;
    }
}

async fn listen(runner: Arc<NodeRunner>, params: Parameters) -> Result<()> {
    let token = runner.cancellation_token().clone();
    let mut states = joint_state::subscribe(&runner).await?;
    let mut follower = String::new();
    let mut heard = 0u64;
    loop {
        let next = tokio::select! {
            _ = token.cancelled() => return Ok(()),
            next = states.next() => next?,
        };
        let Some((peer, state)) = next else {
            return Ok(());
        };
        let who = format!("{}/{}", peer.producer.instance_id, peer.peer_link_id);
        if who != follower {
            println!("paired with {who}");
            follower = who;
        }
        heard += 1;
        if heard % 125 == 1 {
            let target = setpoint(
                state.setpoint_sequence,
                params.rate_hz.clamp(0.1, 10_000.0),
                params.amplitude,
            );
            println!(
                "follower at {:+.3}, {:.3} behind setpoint {}",
                state.position,
                (target - state.position).abs(),
                state.setpoint_sequence
            );
        }
    }
}

/// The node's entry point, for `NodeBuilder::run` and the test harness.
pub async fn setup(params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    tokio::spawn(lead(runner.clone(), params.clone()));
    tokio::spawn(listen(runner, params));
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The leader on its own: the generated mock plays its follower over
    //! the real wire, paired with it before `setup` runs.

    use std::time::Duration;

    use super::peppygen::fixtures::harness::Harness;

    const TIMEOUT: Duration = Duration::from_secs(10);

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn the_follower_gets_the_sine_from_its_first_step() -> super::Result<()> {
        let (harness, mut mocks) = Harness::start(super::setup).await?;
        let follower = &mut mocks.pairings.follower;
        for expected in 0..5u64 {
            let got = tokio::time::timeout(TIMEOUT, follower.joint_setpoint.next())
                .await
                .expect("no setpoint reached the follower")?
                .expect("the setpoint stream is open");
            assert_eq!(got.sequence, expected);
            let position = super::setpoint(expected, 50.0, 1.0);
            assert!((got.position - position).abs() < 1e-12, "{got:?}");
        }
        harness.shutdown().await
    }
}
