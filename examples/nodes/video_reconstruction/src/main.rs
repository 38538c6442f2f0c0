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
use peppygen::{NodeBuilder, Parameters, Result};

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
    NodeBuilder::new().run(|_params: Parameters, runner| async move {
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
                let now = match left_cam_video_stream_info::poll(&asker, Duration::from_secs(2))
                    .await
                {
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
    })
}
