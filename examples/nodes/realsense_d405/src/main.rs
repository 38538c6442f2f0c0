//! `realsense_d405`: Intel RealSense D405 driver (synthetic frames: no hardware needed).
//!
//! Conforms to `depth_camera:v1`, so it inherits `video_stream` and
//! `video_stream_info` from the interface without restating them. Frames are
//! synthesised (a diagonal gradient moving right) at the `width`, `height` and `frames_per_second`
//! parameters.

peppy::include_generated!();

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use peppygen::emitted_topics::video_stream;
use peppygen::exposed_services::video_stream_info;
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

fn frame(w: u32, h: u32, t: u32) -> Vec<u8> {
    let (w, h) = (w as usize, h as usize);
    let t = t as usize;
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            out.push((x + y + t) as u8);
        }
    }
    out
}

fn main() -> Result<()> {
    NodeBuilder::new().run(setup)
}

/// Starts the node's tasks: what `main` runs, and what its tests run
/// in-process against mocks (see the tests below).
async fn setup(params: Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    let (width, height, fps) = (params.width, params.height, params.frames_per_second.max(1));
    eprintln!(
        "realsense_d405 `{}`: {width}x{height} @ {fps} fps",
        runner.instance_id()
    );

    let server = runner.clone();
    tokio::spawn(async move {
        while video_stream_info::handle_next_request(&server, |request| {
            eprintln!("stream info asked by `{}`", request.instance_id);
            Ok(video_stream_info::Response::new(
                width,
                height,
                fps,
                "mono8".to_string(),
            ))
        })
        .await
        .is_ok()
        {}
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
}

#[cfg(test)]
mod tests {
    //! The node in-process against its test surfaces (docs/TESTING.md).

    use std::time::Duration;

    use super::peppygen::fixtures::exposed_services::video_stream_info;
    use super::peppygen::fixtures::harness::{Config, Harness};
    use super::peppygen::{Parameters, Result};

    const TIMEOUT: Duration = Duration::from_secs(10);

    /// A small, fast camera: a few frames take well under a second.
    fn small_camera() -> Config {
        Config {
            parameters: Some(Parameters {
                width: 8,
                height: 6,
                frames_per_second: 50,
            }),
            ..Config::default()
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn frames_are_a_diagonal_gradient_moving_right() -> Result<()> {
        let (mut harness, _mocks) = Harness::start_with(small_camera(), super::setup).await?;
        let first = harness
            .emitted
            .video_stream
            .next_within(TIMEOUT)
            .await?
            .expect("the tap is open");
        let second = harness
            .emitted
            .video_stream
            .next_within(TIMEOUT)
            .await?
            .expect("the tap is open");
        for frame in [&first, &second] {
            assert_eq!((frame.width, frame.height), (8, 6));
            assert_eq!(frame.encoding, "mono8");
            assert_eq!(frame.frame.len(), 8 * 6);
        }
        // Frames are numbered in order (sensor data may drop one, never
        // reorder them).
        assert!(second.header.frame_id > first.header.frame_id);
        // Pixel (x, y) of frame t is x + y + t: one step right per frame.
        for frame in [&first, &second] {
            let t = frame.header.frame_id as usize;
            assert_eq!(frame.frame[0], t as u8);
            assert_eq!(frame.frame[3], (3 + t) as u8, "(3, 0)");
            assert_eq!(frame.frame[2 * 8 + 5], (2 + 5 + t) as u8, "(5, 2)");
        }
        harness.shutdown().await
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn stream_info_tells_the_configured_stream() -> Result<()> {
        let (harness, _mocks) = Harness::start_with(small_camera(), super::setup).await?;
        let info = video_stream_info::poll(&harness, TIMEOUT).await?;
        assert_eq!(
            (info.width, info.height, info.frames_per_second),
            (8, 6, 50)
        );
        assert_eq!(info.encoding, "mono8");
        harness.shutdown().await
    }
}
