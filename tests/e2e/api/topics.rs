#![deny(warnings)]

#[peppy::node("tests/e2e/api/topics.json5")]
mod peppygen {}

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppy::runtime::wire::codec::{from_bytes, to_bytes};
use peppy::runtime::wire::keys::{Channel, Owner, entry_key};
use peppygen::consumed_topics::{cam_temperature, joint_commands};
use peppygen::emitted_topics::{frames, tick};
use peppygen::{NodeRunner, Result};

use crate::nodes::realsense_d405;
use crate::support::{WAIT, describe, hear_topics, hub, namespace, start};

/// Reads the camera's temperature and a command from launch `launch-1`,
/// then emits; the producer and reading, and the command's velocity.
async fn use_api(runner: &NodeRunner) -> Result<((String, f32), f64)> {
    let (producer, reading) = cam_temperature::on_next_message_received(runner, None).await?;
    let _: (String, f32) = (producer.clone(), reading.celsius);
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
    tick::emit(runner).await?;
    Ok(((producer, reading.celsius), command.max_velocity))
}

/// A camera fills the node slot; commands come from two launches (sent raw
/// by the hub, as `topic pub` does), and only `launch-1`'s is read; what
/// the node emits is heard on its keys.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_reads_one_launchs_commands_and_emits_on_its_keys() {
    let hub = hub().await;
    let ns = namespace("api-topics");
    let mut heard = hear_topics(&hub, &ns).await;
    let (_, cam) = start::<realsense_d405::Parameters>(&hub, &ns, "cam", &[]).await;
    let (_, node) =
        start::<peppygen::Parameters>(&hub, &ns, "topics", &["--bind", "cam@cam"]).await;
    let info = describe(&hub, &ns, "topics").await;
    let fingerprint = info
        .consumes
        .iter()
        .find(|c| c.name == "joint_commands")
        .unwrap()
        .format
        .fingerprint;
    let commander = Owner::Node {
        name: "commander",
        tag: "v1",
    };
    let mut publishers = Vec::new();
    for (launch, max_velocity) in [("launch-2", 9.0), ("launch-1", 1.5)] {
        let key = entry_key(
            &ns,
            Channel::Topic,
            &commander,
            "joint_commands",
            launch,
            "ctl",
        );
        let payload = to_bytes(&joint_commands::Message {
            target_positions: [0.1, 0.2, 0.3],
            max_velocity,
        });
        publishers.push((hub.session.declare_publisher(key).await.unwrap(), payload));
    }
    let sending = {
        let cam = cam.clone();
        tokio::spawn(async move {
            while !cam.cancellation_token().is_cancelled() {
                let _ = realsense_d405::emitted_topics::temperature::emit(&cam, 36.5).await;
                for (publisher, payload) in &publishers {
                    let attachment = peppy::runtime::wire::attachment::topic(fingerprint);
                    let _ = publisher.put(payload.clone()).attachment(attachment).await;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
    };

    let read = tokio::time::timeout(WAIT, use_api(&node))
        .await
        .expect("a temperature and a command from launch-1")
        .unwrap();
    assert_eq!(read, (("cam".to_string(), 36.5), 1.5));
    let key = |name: &str| {
        info.emits
            .iter()
            .find(|e| e.name == name)
            .unwrap()
            .key
            .clone()
    };
    let sent: frames::Message = from_bytes(&heard.first(&key("frames")).await).unwrap();
    assert_eq!(
        (
            sent.header.frame_id,
            sent.r#type.as_str(),
            sent.data.as_slice()
        ),
        (1, "depth", &[1, 2, 3][..])
    );
    assert_eq!(sent.points, [frames::MessagePointsItem { x: 1.0, y: 2.0 }]);
    assert!(heard.first(&key("tick")).await.is_empty());
    sending.abort();
    node.shutdown().await;
    cam.shutdown().await;
}

/// Generated messages cross the codec intact.
#[test]
fn messages_round_trip() {
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
