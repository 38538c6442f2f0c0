#![deny(warnings)]

#[peppy::node("tests/e2e/api/topics.json5")]
mod peppygen {}

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppy::runtime::wire::codec::{from_bytes, to_bytes};
use peppygen::consumed_topics::{cam_temperature, joint_commands};
use peppygen::emitted_topics::{frames, tick};
use peppygen::{NodeRunner, Result};

async fn use_api(runner: &NodeRunner) -> Result<()> {
    let (producer, reading) = cam_temperature::on_next_message_received(runner, None).await?;
    let _: (String, f32) = (producer, reading.celsius);
    let (_, command) =
        joint_commands::on_next_message_received(runner, Some("launch-1"), None).await?;
    let _: ([f64; 3], f64) = (command.target_positions, command.max_velocity);
    frames::emit(
        runner,
        frames::MessageHeader {
            stamp: SystemTime::now(),
            frame_id: 1,
        },
        [0.0; 7],
        vec![frames::MessagePointsItem { x: 1.0, y: 2.0 }],
        None,
        "depth".to_string(),
        vec![1, 2, 3],
    )
    .await?;
    tick::emit(runner).await
}

#[test]
fn compiles_and_runs() {
    let _ = use_api;
    let message = frames::Message {
        header: frames::MessageHeader {
            stamp: UNIX_EPOCH + Duration::new(5, 6),
            frame_id: 7,
        },
        pose: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
        points: vec![frames::MessagePointsItem { x: 0.5, y: -0.5 }],
        note: Some("calibrated".into()),
        r#type: "rgb".into(),
        data: vec![9; 4],
    };
    let bytes = to_bytes(&message);
    assert_eq!(from_bytes::<frames::Message>(&bytes).unwrap(), message);
    assert!(to_bytes(&tick::Message).is_empty());
}
