// Seed 000's consumer code: per-producer state keyed by the instance id
// every consumed message comes with.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/video_reconstruction.json5")]
mod peppygen {}

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use peppygen::consumed_services::left_cam_video_stream_info;
use peppygen::consumed_topics::{
    extras_video_stream, left_cam_video_stream, right_cam_video_stream,
};
use peppygen::{NodeRunner, Result};

use crate::nodes::realsense_d405;
use crate::support::{WAIT, hub, namespace, start, until_up};

type Frame = extras_video_stream::Message;

fn reconstruct(_frames: &HashMap<String, Frame>) {}

/// The seed's loop, until frames from `producers` cameras were seen; the
/// newest frame of each.
async fn run(node_runner: &NodeRunner, producers: usize) -> Result<HashMap<String, Frame>> {
    let info = left_cam_video_stream_info::poll(node_runner, Duration::from_secs(1)).await?;
    println!("left camera is {}x{}", info.data.width, info.data.height);
    let (_, left) = left_cam_video_stream::on_next_message_received(node_runner, None).await?;
    let (_, right) = right_cam_video_stream::on_next_message_received(node_runner, None).await?;
    let _ = (left.header.frame_id, right.frame);
    let mut frames_by_producer: HashMap<String, Frame> = HashMap::new();
    while frames_by_producer.len() < producers {
        let (instance_id, frame) =
            extras_video_stream::on_next_message_received(node_runner, None).await?;
        // Use the returned id as a runtime key; do not compare against a hard-coded name.
        frames_by_producer.insert(instance_id, frame);
        reconstruct(&frames_by_producer);
    }
    Ok(frames_by_producer)
}

/// A camera that answers `video_stream_info` and sends a frame numbered
/// `frame_id` every 20 ms, until it stops.
fn camera(cam: Arc<NodeRunner>, frame_id: u32) {
    use realsense_d405::emitted_topics::video_stream;
    use realsense_d405::exposed_services::video_stream_info;
    let server = cam.clone();
    tokio::spawn(async move {
        while video_stream_info::handle_next_request(&server, |_| {
            Ok(video_stream_info::Response::new(
                640,
                480,
                30,
                "rgb8".into(),
            ))
        })
        .await
        .is_ok()
        {}
    });
    tokio::spawn(async move {
        while !cam.cancellation_token().is_cancelled() {
            let header = video_stream::MessageHeader {
                stamp: SystemTime::now(),
                frame_id,
            };
            let _ = video_stream::emit(&cam, header, "rgb8".into(), 1, 1, vec![0; 3]).await;
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    });
}

/// Cameras fill the two pinned slots, and two more the from_any slot,
/// unbound: it takes every camera no sibling slot claims, and the loop
/// keys their frames by instance id.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn from_any_frames_are_keyed_by_producer_and_pinned_cameras_left_out() {
    let hub = hub().await;
    let ns = namespace("api-recon");
    let (_, recon) = start::<peppygen::Parameters>(
        &hub,
        &ns,
        "recon",
        &["--bind", "left_cam@left", "--bind", "right_cam@right"],
    )
    .await;
    let mut cams = Vec::new();
    for (id, frame_id) in [("left", 1), ("right", 2), ("extra_a", 3), ("extra_b", 4)] {
        let (_, cam) = start::<realsense_d405::Parameters>(&hub, &ns, id, &[]).await;
        camera(cam.clone(), frame_id);
        cams.push(cam);
    }
    // `run` polls once: wait until the left camera's service is reachable.
    until_up(async || left_cam_video_stream_info::poll(&recon, Duration::from_secs(1)).await)
        .await
        .unwrap();

    let frames = tokio::time::timeout(WAIT, run(&recon, 2))
        .await
        .expect("frames from both cameras")
        .unwrap();
    let mut ids: Vec<(&str, u32)> = frames
        .iter()
        .map(|(id, frame)| (id.as_str(), frame.header.frame_id))
        .collect();
    ids.sort();
    assert_eq!(ids, [("extra_a", 3), ("extra_b", 4)]);
    recon.shutdown().await;
    for cam in cams {
        cam.shutdown().await;
    }
}
