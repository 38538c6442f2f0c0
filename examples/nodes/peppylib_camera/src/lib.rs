//! `peppylib_camera`: a `depth_camera:v1` written in PeppyOS's `peppylib`
//! node API. It declares its publisher once and publishes built messages,
//! answers `video_stream_info`, stamps frames with the stack's clock (sim
//! time when the launcher says `framework.use_sim_time`), counts its starts
//! in its core node's datastore (so a restarted camera knows it
//! restarted), and says goodbye from a shutdown hook.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppygen::emitted_topics::camera::video_stream;
use peppygen::exposed_services::camera::video_stream_info;
use peppygen::{NodeRunner, Parameters, Result};
use peppylib::datastore::{self, Encoding};
use peppylib::runtime::CancellationToken;

/// The clock's time as a `time` field; the OS clock until the clock has a
/// reading (a sim clock before its first tick).
fn stamp() -> SystemTime {
    match peppygen::clock::now_ns() {
        Ok(ns) => UNIX_EPOCH + Duration::from_nanos(ns),
        Err(_) => SystemTime::now(),
    }
}

/// A frame whose bytes move with the frame number, so a viewer sees
/// frames change.
fn frame(width: u32, height: u32, n: u64) -> Vec<u8> {
    (0..width * height)
        .map(|i| (u64::from(i) + n) as u8)
        .collect()
}

async fn stream(
    runner: Arc<NodeRunner>,
    params: Parameters,
    sent: Arc<AtomicU64>,
    token: CancellationToken,
) -> Result<()> {
    let publisher = video_stream::declare_publisher(&runner).await?;
    let period = Duration::from_secs(1) / u32::from(params.frames_per_second.max(1));
    let mut ticks = tokio::time::interval(period);
    loop {
        tokio::select! {
            _ = token.cancelled() => return Ok(()),
            _ = ticks.tick() => {}
        }
        let n = sent.load(Ordering::Relaxed);
        let header = video_stream::MessageHeader {
            stamp: stamp(),
            frame_id: n as u32,
        };
        let message = video_stream::build_message(
            header,
            "mono8".to_string(),
            params.width,
            params.height,
            frame(params.width, params.height, n),
        )?;
        publisher.publish(message).await?;
        if n == 0 {
            println!(
                "peppylib_camera: first frame ({}x{})",
                params.width, params.height
            );
        }
        sent.fetch_add(1, Ordering::Relaxed);
    }
}

async fn serve_info(runner: Arc<NodeRunner>, params: Parameters, token: CancellationToken) {
    loop {
        let fps = params.frames_per_second;
        let (width, height) = (params.width, params.height);
        tokio::select! {
            _ = token.cancelled() => return,
            served = video_stream_info::handle_next_request(&runner, move |_request| {
                Ok(video_stream_info::Response::new(width, height, fps, "mono8".to_string()))
            }) => {
                if served.is_err() {
                    return;
                }
            }
        }
    }
}

/// How long the camera waits for its core node's datastore: a camera
/// started without one (a bare `cargo run`) streams all the same.
const DATASTORE_TIMEOUT: Duration = Duration::from_secs(2);

/// Counts this start in the core node's datastore, under a key of this
/// instance: the count survives the camera's restarts, not the stack's.
async fn count_start(runner: &NodeRunner) -> Result<u64> {
    let key = format!("peppylib_camera/{}/starts", runner.instance_id());
    let before = datastore::get(runner, key.as_str(), DATASTORE_TIMEOUT).await?;
    let starts = before
        .as_ref()
        .and_then(|v| std::str::from_utf8(&v.value).ok()?.parse::<u64>().ok())
        .unwrap_or(0)
        + 1;
    datastore::store(
        runner,
        key.as_str(),
        starts.to_string().into_bytes(),
        Encoding::TEXT_PLAIN,
        DATASTORE_TIMEOUT,
    )
    .await?;
    match before {
        Some(v) => println!(
            "peppylib_camera: start {starts} (the count was last written by {})",
            v.last_modified_by
        ),
        None => println!("peppylib_camera: start {starts}"),
    }
    Ok(starts)
}

/// Starts the camera's tasks: what `main` runs, and what its tests
/// (`tests/harness.rs`) run in-process against the generated harness.
pub async fn setup(params: Parameters, node_runner: Arc<NodeRunner>) -> Result<()> {
    peppygen::clock::init(&node_runner).await?;
    if let Err(e) = count_start(&node_runner).await {
        eprintln!("peppylib_camera: starts not counted: {e}");
    }
    let token = node_runner.cancellation_token().clone();
    let sent = Arc::new(AtomicU64::new(0));

    let counted = sent.clone();
    node_runner.on_shutdown(async move {
        println!(
            "peppylib_camera: stopping after {} frames",
            counted.load(Ordering::Relaxed)
        );
    });

    let streaming = (node_runner.clone(), params.clone(), token.clone());
    tokio::spawn(async move {
        let (runner, params, token) = streaming;
        if let Err(e) = stream(runner, params, sent, token).await {
            eprintln!("peppylib_camera: streaming stopped: {e}");
        }
    });
    tokio::spawn(serve_info(node_runner.clone(), params, token));
    Ok(())
}
