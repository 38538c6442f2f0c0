//! `camera_viewer`: a node in the `node/v1` spelling and PeppyOS's `peppylib`
//! node API. Its module paths nest consumed entries under their slot
//! (`consumed_topics::cameras::video_stream`), each slot says what the
//! launcher linked to it, and frames arrive through held subscriptions.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use peppygen::consumed_topics::{cameras, overhead};
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(_params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    let linked: Vec<String> = cameras::bound_producers(&runner)
        .iter()
        .map(ToString::to_string)
        .collect();
    println!("cameras: linked to {}", linked.join(", "));
    match overhead::bound_producer(&runner) {
        Some(camera) => println!("overhead: linked to {camera}"),
        None => println!("overhead: vacant"),
    }
    // Subscribed before setup returns: nothing sent from now on is missed.
    let mut frames_in = cameras::video_stream::subscribe(&runner).await?;
    let mut overhead_in = overhead::video_stream::subscribe(&runner).await?;
    tokio::spawn(async move {
        let mut frames: BTreeMap<String, u64> = BTreeMap::new();
        let mut last = Instant::now();
        while let Ok(Some((camera, frame))) = frames_in.next().await {
            let count = frames.entry(camera.to_string()).or_insert(0);
            if *count == 0 {
                println!(
                    "cameras: first frame from {camera} ({}x{})",
                    frame.width, frame.height
                );
            }
            *count += 1;
            if last.elapsed() > Duration::from_secs(5) {
                last = Instant::now();
                let row: Vec<String> = frames.iter().map(|(c, n)| format!("{c}:{n}")).collect();
                println!("viewing {}", row.join(" "));
            }
        }
    });
    tokio::spawn(async move {
        while let Ok(Some((camera, frame))) = overhead_in.next().await {
            println!("overhead: frame {} from {camera}", frame.header.frame_id);
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md):
    //! mocks play the cameras linked to `cameras` and `overhead`.

    use std::time::{Duration, SystemTime};

    use super::peppygen::Result;
    use super::peppygen::fixtures::harness::{Config, Harness};
    use super::peppygen::mock::deps::cameras::video_stream;
    use super::peppygen::mock::deps::overhead::video_stream as overhead_stream;

    const TIMEOUT: Duration = Duration::from_secs(10);

    fn frame(frame_id: u32) -> video_stream::Message {
        video_stream::Message {
            header: video_stream::MessageHeader {
                stamp: SystemTime::now(),
                frame_id,
            },
            encoding: "mono8".into(),
            width: 3,
            height: 2,
            frame: vec![7; 6],
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn it_views_every_linked_camera_with_the_overhead_slot_vacant() -> Result<()> {
        let config = Config {
            cameras_instances: 2,
            overhead_vacant: true,
            ..Config::default()
        };
        let (harness, mocks) = Harness::start_with(config, super::setup).await?;
        assert!(mocks.deps.overhead.is_none());
        assert_eq!(mocks.deps.cameras.len(), 2);
        // The node subscribes before setup returns: each camera's publish
        // finds its subscription.
        for (n, camera) in mocks.deps.cameras.iter().enumerate() {
            assert!(camera.video_stream.wait_for_subscriber(TIMEOUT).await?);
            camera.video_stream.publish(&frame(n as u32)).await?;
        }
        // Setup (which reads what each slot is linked to) returned Ok.
        harness.shutdown().await
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_linked_overhead_camera_is_watched_too() -> Result<()> {
        let (harness, mocks) = Harness::start(super::setup).await?;
        let overhead = mocks.deps.overhead.expect("the slot is linked by default");
        assert!(overhead.video_stream.wait_for_subscriber(TIMEOUT).await?);
        overhead
            .video_stream
            .publish(&overhead_stream::Message {
                header: overhead_stream::MessageHeader {
                    stamp: SystemTime::now(),
                    frame_id: 9,
                },
                encoding: "mono8".into(),
                width: 1,
                height: 1,
                frame: vec![0],
            })
            .await?;
        harness.shutdown().await
    }
}
