//! `camera_mosaic`: one `from_any` slot (`extras`) taking every depth camera
//! the launcher binds to it. The free-form binding keys never reach the
//! code: producers are told apart by the instance id each frame carries.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use peppygen::consumed_topics::extras_video_stream;
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    tokio::spawn(async move {
        // `from_core_node` filters by the machine a camera runs on.
        let only = Some(params.only_core_node).filter(|c| !c.is_empty());
        let mut tiles: BTreeMap<String, u64> = BTreeMap::new();
        let mut last = Instant::now();
        while let Ok((producer, frame)) =
            extras_video_stream::on_next_message_received(&runner, only.as_deref()).await
        {
            let count = tiles.entry(producer.clone()).or_insert(0);
            if *count == 0 {
                println!(
                    "extras: first frame from {producer} ({}x{})",
                    frame.width, frame.height
                );
            }
            *count += 1;
            if last.elapsed() > Duration::from_secs(1) {
                last = Instant::now();
                let row: Vec<String> = tiles.iter().map(|(p, n)| format!("{p}:{n}")).collect();
                println!("mosaic of {} tiles: {}", tiles.len(), row.join(" "));
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md):
    //! mocks play the cameras bound to `extras`.

    use std::time::{Duration, SystemTime};

    use super::peppygen::fixtures::harness::{Config, Harness};
    use super::peppygen::mock::deps::extras::video_stream;
    use super::peppygen::{Parameters, Result};

    fn frame(frame_id: u32) -> video_stream::Message {
        video_stream::Message {
            header: video_stream::MessageHeader {
                stamp: SystemTime::now(),
                frame_id,
            },
            encoding: "mono8".into(),
            width: 4,
            height: 2,
            frame: vec![0; 8],
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn it_takes_frames_from_every_camera_bound_to_extras() -> Result<()> {
        let config = Config {
            extras_instance_ids: vec!["cam_a".into(), "cam_b".into(), "cam_c".into()],
            parameters: Some(Parameters {
                only_core_node: String::new(),
            }),
            ..Config::default()
        };
        let (harness, mocks) = Harness::start_with(config, super::setup).await?;
        let ids: Vec<&str> = mocks.deps.extras.iter().map(|m| m.instance_id()).collect();
        assert_eq!(ids, ["cam_a", "cam_b", "cam_c"]);
        // A mock's publish fails unless the node's subscription covers it.
        for round in 0..3 {
            for camera in &mocks.deps.extras {
                camera.video_stream.publish(&frame(round)).await?;
            }
        }
        let wait = tokio::time::timeout(Duration::from_secs(10), harness.shutdown());
        wait.await.expect("the node stops")
    }
}
