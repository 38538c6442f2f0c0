// Seed 000's consumer code: per-producer state keyed by the instance id
// every consumed message comes with.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/video_reconstruction.json5")]
mod peppygen {}

use std::collections::HashMap;
use std::time::Duration;

use peppygen::consumed_services::left_cam_video_stream_info;
use peppygen::consumed_topics::{
    extras_video_stream, left_cam_video_stream, right_cam_video_stream,
};
use peppygen::{NodeRunner, Result};

type Frame = extras_video_stream::Message;

fn reconstruct(_frames: &HashMap<String, Frame>) {}

async fn run(node_runner: &NodeRunner) -> Result<()> {
    let info = left_cam_video_stream_info::poll(node_runner, Duration::from_secs(1)).await?;
    println!("left camera is {}x{}", info.data.width, info.data.height);
    let (_, left) = left_cam_video_stream::on_next_message_received(node_runner, None).await?;
    let (_, right) = right_cam_video_stream::on_next_message_received(node_runner, None).await?;
    let _ = (left.header.frame_id, right.frame);
    let mut frames_by_producer: HashMap<String, Frame> = HashMap::new();
    loop {
        let (instance_id, frame) =
            extras_video_stream::on_next_message_received(node_runner, None).await?;
        // Use the returned id as a runtime key; do not compare against a hard-coded name.
        frames_by_producer.insert(instance_id, frame);
        reconstruct(&frames_by_producer);
    }
}

#[test]
fn compiles_and_runs() {
    let _ = run;
}
