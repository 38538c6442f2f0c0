//! `video_reconstruction`: depends on the `depth_camera:v1` interface three
//! times: pinned `left_cam` and `right_cam`, and a `from_any` `backup_cams`
//! slot. It never names a producer node; the launcher decides which cameras
//! fill the slots. State is kept per producer, keyed by the instance id
//! each message arrives with.

peppy::include_generated!();

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use peppygen::consumed_services::left_cam_video_stream_info;
use peppygen::consumed_topics::{
    backup_cams_video_stream, left_cam_video_stream, right_cam_video_stream,
};
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

/// Frames seen per slot and producer.
type Seen = Arc<Mutex<BTreeMap<(&'static str, String), u64>>>;

fn record(seen: &Seen, slot: &'static str, producer: &str, width: u32, height: u32) {
    let mut seen = seen.lock().unwrap_or_else(|p| p.into_inner());
    let count = seen.entry((slot, producer.to_string())).or_insert(0);
    if *count == 0 {
        println!("{slot}: first frame from {producer} ({width}x{height})");
    }
    *count += 1;
}

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(_params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    let seen: Seen = Arc::default();

    macro_rules! read_slot {
        ($module:ident, $slot:literal) => {{
            let (runner, seen) = (runner.clone(), seen.clone());
            tokio::spawn(async move {
                while let Ok((producer, frame)) =
                    $module::on_next_message_received(&runner, None).await
                {
                    record(&seen, $slot, &producer, frame.width, frame.height);
                }
            });
        }};
    }
    read_slot!(left_cam_video_stream, "left_cam");
    read_slot!(right_cam_video_stream, "right_cam");
    read_slot!(backup_cams_video_stream, "backup_cams");

    // Ask the left camera what it streams (it may start after us), then
    // keep checking every 2 s, saying when the answer changes: a camera
    // out of reach (a machine or a link lost) shows here.
    let asker = runner.clone();
    tokio::spawn(async move {
        let mut last: Option<String> = None;
        while !asker.cancellation_token().is_cancelled() {
            let now = match left_cam_video_stream_info::poll(&asker, Duration::from_secs(2)).await {
                Ok(info) => {
                    let d = info.data;
                    format!(
                        "left_cam is {}: {}x{} @ {} fps, {}",
                        info.instance_id, d.width, d.height, d.frames_per_second, d.encoding
                    )
                }
                Err(e) => format!("left_cam stream info: {e}"),
            };
            // Before the first answer, a camera that is not up yet is
            // not news.
            let news = last.as_deref() != Some(now.as_str())
                && (last.is_some() || now.starts_with("left_cam is"));
            if news {
                println!("{now}");
            }
            if news || last.is_some() {
                last = Some(now);
            }
            tokio::time::sleep(Duration::from_secs(2)).await;
        }
    });

    // Once a second: what the reconstruction is built from.
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.tick().await;
        while !runner.cancellation_token().is_cancelled() {
            tick.tick().await;
            let seen = seen.lock().unwrap_or_else(|p| p.into_inner()).clone();
            let summary: Vec<String> = seen
                .iter()
                .map(|((slot, p), n)| format!("{slot}<-{p}:{n}"))
                .collect();
            println!("reconstructing from {}", summary.join(" "));
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md):
    //! mocks play the left, right and backup cameras.

    use std::time::{Duration, SystemTime};

    use super::peppygen::Result;
    use super::peppygen::fixtures::harness::{Config, Harness};
    use super::peppygen::mock::deps::left_cam::video_stream_info;

    const TIMEOUT: Duration = Duration::from_secs(10);

    /// A small frame of slot module `$slot` (each slot has its own types).
    macro_rules! frame {
        ($slot:ident, $frame_id:expr) => {{
            use super::peppygen::mock::deps::$slot::video_stream::{Message, MessageHeader};
            Message {
                header: MessageHeader {
                    stamp: SystemTime::now(),
                    frame_id: $frame_id,
                },
                encoding: "mono8".into(),
                width: 2,
                height: 1,
                frame: vec![0; 2],
            }
        }};
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn it_listens_to_every_camera_and_keeps_asking_the_left_one() -> Result<()> {
        let config = Config {
            backup_cams_instances: 2,
            ..Config::default()
        };
        let (harness, mocks) = Harness::start_with(config, super::setup).await?;
        let cams = mocks.deps;
        assert_eq!(cams.backup_cams.len(), 2);

        // The service takes no request data: a request is only a call.
        let answer = cams
            .left_cam
            .video_stream_info
            .next_request(TIMEOUT)
            .await?;
        answer
            .respond(video_stream_info::ResponseData {
                width: 2,
                height: 1,
                frames_per_second: 30,
                encoding: "mono8".into(),
            })
            .await?;

        // A mock's publish fails unless the node subscribed through its
        // slot: every camera, each backup one included, is read.
        cams.left_cam
            .video_stream
            .publish(&frame!(left_cam, 1))
            .await?;
        cams.right_cam
            .video_stream
            .publish(&frame!(right_cam, 2))
            .await?;
        for (n, backup) in cams.backup_cams.iter().enumerate() {
            backup
                .video_stream
                .publish(&frame!(backup_cams, 3 + n as u32))
                .await?;
        }

        // It checks the left camera again (every 2 s), an answer or not:
        // a failed call is reported, not fatal.
        let answer = cams
            .left_cam
            .video_stream_info
            .next_request(TIMEOUT)
            .await?;
        answer.respond_error("the camera is rebooting").await?;
        let _again = cams
            .left_cam
            .video_stream_info
            .next_request(TIMEOUT)
            .await?;
        assert_eq!(cams.left_cam.video_stream_info.captured_count(), 3);
        harness.shutdown().await
    }
}
