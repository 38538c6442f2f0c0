//! `peppylib_camera` in-process against its generated harness
//! (`peppygen::fixtures`, from the `testing` feature): what it streams,
//! what it answers, and the clock it stamps frames with.

use std::time::{Duration, UNIX_EPOCH};

use peppygen::fixtures::exposed_services::camera::video_stream_info;
use peppygen::fixtures::harness::{Config, Harness};
use peppygen::{Parameters, Result};

const TIMEOUT: Duration = Duration::from_secs(10);

/// A small, fast camera: a few frames take well under a second.
fn small_camera(use_sim_time: bool) -> Config {
    Config {
        parameters: Some(Parameters {
            width: 5,
            height: 3,
            frames_per_second: 50,
        }),
        use_sim_time,
        ..Config::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_are_numbered_and_their_bytes_move_with_the_number() -> Result<()> {
    let (mut harness, _mocks) =
        Harness::start_with(small_camera(false), peppylib_camera::setup).await?;
    let mut last = None;
    for _ in 0..3 {
        let frame = harness
            .emitted
            .camera_video_stream
            .next_within(TIMEOUT)
            .await?
            .expect("the tap is open");
        assert_eq!((frame.width, frame.height), (5, 3));
        assert_eq!(frame.encoding, "mono8");
        // Byte i of frame n is i + n.
        let n = frame.header.frame_id;
        let expected: Vec<u8> = (0..15u32).map(|i| (i + n) as u8).collect();
        assert_eq!(frame.frame, expected);
        if let Some(previous) = last {
            assert!(n > previous, "frame {n} after {previous}");
        }
        last = Some(n);
    }
    harness.shutdown().await
}

/// The harness names the node and its document as PeppyOS's does.
#[test]
fn the_harness_names_the_node_and_finds_its_document() {
    use peppygen::fixtures::harness::{NODE_NAME, NODE_TAG, PEPPY_CONFIG_PATH};
    assert_eq!((NODE_NAME, NODE_TAG), ("peppylib_camera", "v1"));
    let document = std::fs::read_to_string(PEPPY_CONFIG_PATH).expect("the node's peppy.json5");
    assert!(document.contains("name: \"peppylib_camera\""), "{document}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stream_info_tells_the_configured_stream() -> Result<()> {
    let (harness, _mocks) =
        Harness::start_with(small_camera(false), peppylib_camera::setup).await?;
    let info = video_stream_info::poll(&harness, TIMEOUT).await?;
    assert_eq!(
        (info.width, info.height, info.frames_per_second),
        (5, 3, 50)
    );
    assert_eq!(info.encoding, "mono8");
    harness.shutdown().await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_sim_time_frames_carry_the_stack_clock() -> Result<()> {
    let (mut harness, _mocks) =
        Harness::start_with(small_camera(true), peppylib_camera::setup).await?;
    let sim = UNIX_EPOCH + Duration::from_secs(42);
    harness.clock.tick(42_000_000_000).await?;
    // Frames sent before the tick carry the OS clock; from the tick on,
    // the simulated time (which stands still until the next tick).
    let mut seen = 0;
    loop {
        let frame = harness
            .emitted
            .camera_video_stream
            .next_within(TIMEOUT)
            .await?
            .expect("the tap is open");
        if frame.header.stamp == sim {
            break;
        }
        seen += 1;
        assert!(seen < 20, "no frame stamped with the sim time: {frame:?}");
    }
    harness.shutdown().await
}

/// The harness is the node's core node, datastore included: the camera's
/// first start is counted there, written by the camera itself.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_camera_counts_its_start_in_the_datastore() -> Result<()> {
    use peppylib::datastore;

    let (harness, _mocks) =
        Harness::start_with(small_camera(false), peppylib_camera::setup).await?;
    let runner = harness.node_runner().clone();
    let key = format!("peppylib_camera/{}/starts", harness.instance_id());
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    let stored = loop {
        if let Some(v) = datastore::get(&runner, key.as_str(), TIMEOUT).await? {
            break v;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "the camera never counted its start"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert_eq!(stored.value, b"1");
    assert_eq!(stored.encoding, datastore::Encoding::TEXT_PLAIN);
    assert_eq!(stored.last_modified_by, harness.instance_id());
    let keys = datastore::list(&runner, TIMEOUT).await?;
    assert_eq!(keys.len(), 1);
    assert_eq!(keys[0].key, key);
    assert!(datastore::remove(&runner, key.as_str(), TIMEOUT).await?);
    assert!(!datastore::remove(&runner, key.as_str(), TIMEOUT).await?);
    assert_eq!(datastore::get(&runner, key.as_str(), None).await?, None);
    harness.shutdown().await
}
