//! `zed_2i`: Stereolabs ZED 2i driver (synthetic frames: no hardware needed).
//!
//! Conforms to `depth_camera:v1`, so it inherits `video_stream` and
//! `video_stream_info` from the interface without restating them. Frames are
//! synthesised (horizontal bands moving down) at the `width`, `height` and `frames_per_second`
//! parameters.

#[peppy::node("peppy.json5")]
mod peppygen {}

use std::time::{Duration, SystemTime};

use peppygen::emitted_topics::video_stream;
use peppygen::exposed_services::video_stream_info;
use peppygen::{NodeBuilder, Parameters, Result};

fn frame(w: u32, h: u32, t: u32) -> Vec<u8> {
    let (w, h) = (w as usize, h as usize);
    let t = t as usize;
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        out.extend(std::iter::repeat_n(((y + t) / 4 * 16) as u8, w));
    }
    out
}

fn main() -> Result<()> {
    NodeBuilder::new().run(|params: Parameters, runner| async move {
        let (width, height, fps) = (params.width, params.height, params.frames_per_second.max(1));
        eprintln!(
            "zed_2i `{}`: {width}x{height} @ {fps} fps",
            runner.instance_id()
        );

        let server = runner.clone();
        // Written the way many nodes are: the error ignored, no way out of
        // the loop. The node still stops promptly on Ctrl-C: a call on a
        // stopped node pauses before it returns, and the runtime drops its
        // tasks at shutdown.
        tokio::spawn(async move {
            loop {
                let _ = video_stream_info::handle_next_request(&server, |request| {
                    eprintln!("stream info asked by `{}`", request.instance_id);
                    Ok(video_stream_info::Response::new(
                        width,
                        height,
                        fps,
                        "mono8".to_string(),
                    ))
                })
                .await;
            }
        });

        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / f64::from(fps)));
            let mut frame_id = 0u32;
            while !runner.cancellation_token().is_cancelled() {
                tick.tick().await;
                let header = video_stream::MessageHeader {
                    stamp: SystemTime::now(),
                    frame_id,
                };
                let pixels = frame(width, height, frame_id);
                if let Err(e) =
                    video_stream::emit(&runner, header, "mono8".to_string(), width, height, pixels)
                        .await
                {
                    eprintln!("emit failed: {e}");
                }
                frame_id = frame_id.wrapping_add(1);
            }
        });
        Ok(())
    })
}
