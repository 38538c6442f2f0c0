//! Generated pairing code end to end: the `arm_commander` fixture's setup
//! under its generated harness, answering its mock peer's states with
//! setpoints, and observing a mock source.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use peppy::{NodeRunner, Result};

use crate::nodes::arm_commander;

const TIMEOUT: Duration = Duration::from_secs(10);

/// Answers each state of its arm with a setpoint one further, and counts
/// what it observes.
async fn commander(_p: arm_commander::Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    use arm_commander::paired_topics::{arm, arms};
    let peer = arm::wait_paired(&runner).await?;
    assert_eq!(arm::setpoint::paired(&runner)?, Some(peer));
    let publisher = arm::setpoint::declare_publisher(&runner).await?;
    let mut states = arm::state::subscribe(&runner).await?;
    let mut observed = arms::state::subscribe(&runner).await?;
    assert_eq!(arms::sources(&runner)?.len(), 1);
    tokio::spawn(async move {
        while let Ok(Some((_, state))) = states.next().await {
            let m = arm::setpoint::build_message(state.position + 1.0, 0.5).unwrap();
            let _ = publisher.publish(m).await;
        }
    });
    let answer = runner.clone();
    tokio::spawn(async move {
        while let Ok(Some((source, state))) = observed.next().await {
            // What it observed goes back to its peer, tagged.
            let p = arm::setpoint::build_message(state.position, -1.0).unwrap();
            let publisher = arm::setpoint::declare_publisher(&answer).await.unwrap();
            assert_eq!(source.source_link_id, "mock_source");
            let _ = publisher.publish(p).await;
        }
    });
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_generated_commander_pairs_with_its_mock_peer_and_observes_its_mock_source() -> Result<()>
{
    use arm_commander::mock::observed::arms::state as observed;
    use arm_commander::mock::pairings::arm::state;
    let (harness, mut mocks) = arm_commander::fixtures::harness::Harness::start(commander).await?;
    assert_eq!(mocks.pairings.arm.peer_info().peer_link_id, "mock_peer");
    assert_eq!(mocks.observed.arms.len(), 1);
    let msg = state::Message {
        header: state::MessageHeader {
            stamp: SystemTime::now(),
            frame_id: 1,
        },
        position: 2.0,
    };
    mocks.pairings.arm.state.publish(&msg).await?;
    let setpoint = tokio::time::timeout(TIMEOUT, mocks.pairings.arm.setpoint.next())
        .await
        .expect("a setpoint arrives")?
        .expect("the mock is up");
    assert_eq!((setpoint.position, setpoint.velocity), (3.0, 0.5));
    let seen = observed::Message {
        header: observed::MessageHeader {
            stamp: SystemTime::now(),
            frame_id: 2,
        },
        position: 7.0,
    };
    mocks.observed.arms[0].state.publish(&seen).await?;
    let echoed = tokio::time::timeout(TIMEOUT, mocks.pairings.arm.setpoint.next())
        .await
        .expect("the observed state comes back")?
        .expect("the mock is up");
    assert_eq!((echoed.position, echoed.velocity), (7.0, -1.0));
    harness.shutdown().await
}
