//! Topics through generated `emit` and `on_next_message_received`.

use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppy::NodeRunner;

use crate::nodes::{
    arm_controller, realsense_d405, robot_arm, shapes, shapes_client, video_reconstruction,
};
use crate::support::{WAIT, eventually, hub, namespace, start};

/// Runs `$send` (a block using `$s: &NodeRunner`) every 20 ms until the
/// returned task is aborted.
macro_rules! keep_sending {
    ($runner:expr, |$s:ident| $send:block) => {{
        let runner: Arc<NodeRunner> = $runner;
        tokio::spawn(async move {
            let $s: &NodeRunner = &runner;
            while !$s.cancellation_token().is_cancelled() {
                $send
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
    }};
}

/// Seed 002's loop: the controller's commands reach the arm through its
/// external consumed topic, the arm's states reach the controller through
/// its linked one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn robot_arm_and_controller_close_the_loop() {
    let hub = hub().await;
    let ns = namespace("arm-loop");
    let (_, arm) = start::<robot_arm::Parameters>(&hub, &ns, "arm", &[]).await;
    let (params, controller) =
        start::<arm_controller::Parameters>(&hub, &ns, "controller", &["--bind", "robot_arm@arm"])
            .await;
    let _ = params;

    let echo: tokio::task::JoinHandle<peppy::Result<()>> = tokio::spawn({
        let arm = arm.clone();
        async move {
            use robot_arm::consumed_topics::joint_commands;
            use robot_arm::emitted_topics::joint_states;
            loop {
                let (from, command) =
                    joint_commands::on_next_message_received(&arm, Some("standalone"), None)
                        .await?;
                assert_eq!(from, "controller");
                joint_states::emit(
                    &arm,
                    command.target_positions,
                    [command.max_velocity; 3],
                    UNIX_EPOCH + Duration::new(7, 9),
                )
                .await?;
            }
        }
    });

    use arm_controller::consumed_topics::robot_arm_joint_states;
    use arm_controller::emitted_topics::joint_commands;
    let (from, state) = eventually("a joint state in reply to a command", async || {
        joint_commands::emit(&controller, [0.1, 0.2, 0.3], 1.5)
            .await
            .unwrap();
        tokio::time::timeout(
            Duration::from_millis(200),
            robot_arm_joint_states::on_next_message_received(&controller, None, None),
        )
        .await
        .ok()
        .map(|r| r.unwrap())
    })
    .await;
    assert_eq!(from, "arm");
    assert_eq!(state.positions, [0.1, 0.2, 0.3]);
    assert_eq!(state.velocities, [1.5; 3]);
    assert_eq!(state.timestamp, UNIX_EPOCH + Duration::new(7, 9));
    echo.abort();
    arm.shutdown().await;
    controller.shutdown().await;
}

/// An external topic's third argument (the original's `from_instance_id`)
/// keeps one producer's messages when several emit the topic; without it
/// every producer's arrive.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_external_topic_reads_one_producer_when_asked() {
    let hub = hub().await;
    let ns = namespace("arm-two-controllers");
    let (_, arm) = start::<robot_arm::Parameters>(&hub, &ns, "arm", &[]).await;
    let mut senders = Vec::new();
    for (id, max_velocity) in [("ctl_a", 1.0), ("ctl_b", 2.0)] {
        let (_, controller) =
            start::<arm_controller::Parameters>(&hub, &ns, id, &["--bind", "robot_arm@arm"]).await;
        senders.push(keep_sending!(controller, |s| {
            let _ = arm_controller::emitted_topics::joint_commands::emit(s, [0.0; 3], max_velocity)
                .await;
        }));
    }

    use robot_arm::consumed_topics::joint_commands;
    for _ in 0..20 {
        let (from, command) = tokio::time::timeout(
            WAIT,
            joint_commands::on_next_message_received(&arm, None, Some("ctl_b")),
        )
        .await
        .expect("a command from ctl_b")
        .unwrap();
        assert_eq!((from.as_str(), command.max_velocity), ("ctl_b", 2.0));
    }
    let mut seen = std::collections::BTreeSet::new();
    while seen.len() < 2 {
        let (from, _) = tokio::time::timeout(
            WAIT,
            joint_commands::on_next_message_received(&arm, None, None),
        )
        .await
        .expect("commands from both controllers")
        .unwrap();
        seen.insert(from);
    }
    for sender in senders {
        sender.abort();
    }
    arm.shutdown().await;
}

/// A conforming producer's inherited topic reaches interface slots and
/// node slots alike; its own topic reaches the node slot.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn conformed_and_native_topics_reach_their_slots() {
    let hub = hub().await;
    let ns = namespace("conformance");
    let (_, recon) = start::<video_reconstruction::Parameters>(
        &hub,
        &ns,
        "recon",
        &[
            "--bind",
            "left_cam@cam",
            "--bind",
            "right_cam@cam",
            "--bind",
            "front@cam",
        ],
    )
    .await;
    let (_, cam) = start::<realsense_d405::Parameters>(&hub, &ns, "cam", &[]).await;
    let sender = keep_sending!(cam.clone(), |cam| {
        use realsense_d405::emitted_topics::{temperature, video_stream};
        let header = video_stream::MessageHeader {
            stamp: SystemTime::now(),
            frame_id: 42,
        };
        video_stream::emit(cam, header, "rgb8".into(), 2, 1, vec![1, 2, 3, 4, 5, 6])
            .await
            .unwrap();
        temperature::emit(cam, 36.5).await.unwrap();
    });

    use video_reconstruction::consumed_topics as c;
    let (from, frame) = tokio::time::timeout(
        WAIT,
        c::left_cam_video_stream::on_next_message_received(&recon, None),
    )
    .await
    .unwrap()
    .unwrap();
    assert_eq!(
        (from.as_str(), frame.header.frame_id, frame.frame.len()),
        ("cam", 42, 6)
    );
    let (_, frame) = tokio::time::timeout(
        WAIT,
        c::front_video_stream::on_next_message_received(&recon, None),
    )
    .await
    .unwrap()
    .unwrap();
    assert_eq!(frame.encoding, "rgb8");
    let (_, t) = tokio::time::timeout(
        WAIT,
        c::front_temperature::on_next_message_received(&recon, None),
    )
    .await
    .unwrap()
    .unwrap();
    assert_eq!(t.celsius, 36.5);
    sender.abort();
    recon.shutdown().await;
    cam.shutdown().await;
}

/// Every message shape crosses the wire intact: producer-side types out,
/// consumer-side types in.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_message_shape_crosses_the_wire() {
    let hub = hub().await;
    let ns = namespace("shapes");
    let (_, client) =
        start::<shapes_client::Parameters>(&hub, &ns, "client", &["--bind", "shapes@shapes"]).await;
    let (_, server) =
        start::<shapes::Parameters>(&hub, &ns, "shapes", &crate::params::SHAPES_ARGS).await;
    let sample = crate::roundtrip::Samples::new(1);
    let sender = keep_sending!(server.clone(), |s| {
        sample.emit_all(s).await.unwrap();
    });
    sample.expect_all(&client, "shapes").await;
    sender.abort();
    client.shutdown().await;
    server.shutdown().await;
}
