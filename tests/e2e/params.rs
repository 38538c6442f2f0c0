//! Generated `Parameters`: filled from defaults and command-line values by
//! the runtime, deserialized into typed fields (times, fixed arrays of any
//! length, groups, arrays of objects).

use std::time::{Duration, UNIX_EPOCH};

use crate::nodes::shapes;
use crate::support::{hub, namespace, start};

/// The required parameters of the `shapes` fixture, as command-line values.
pub(crate) const SHAPES_ARGS: [&str; 2] = [
    "--params",
    concat!(env!("CARGO_MANIFEST_DIR"), "/tests/e2e/shapes_params.json"),
];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameters_are_typed_and_defaults_filled() {
    let hub = hub().await;
    let ns = namespace("params");
    let (p, runner) = start::<shapes::Parameters>(
        &hub,
        &ns,
        "shapes",
        &[SHAPES_ARGS[0], SHAPES_ARGS[1], "video.fps=60", "retries=5"],
    )
    .await;
    assert_eq!(p.rate_hz, 10.0);
    assert_eq!(p.retries, 5);
    assert_eq!(p.name, "cam");
    assert_eq!(
        p.start,
        UNIX_EPOCH + Duration::from_millis(1_700_000_000_500)
    );
    assert_eq!(p.video.fps, 60);
    assert_eq!(p.video.encoder.codec, "h264");
    assert_eq!(p.video.encoder.bitrate, 4_000_000);
    assert_eq!(p.gains, [1.0, 2.0, 3.0]);
    assert_eq!(p.weights[39], 0.5);
    assert_eq!(p.tags, ["a", "b"]);
    assert_eq!(p.deadlines, [UNIX_EPOCH + Duration::from_secs(10)]);
    assert_eq!(p.cameras[0].serial, "SN1");
    assert_eq!(p.cameras[0].port, 8080);
    assert_eq!(p.r#type, "default");
    // Parameters serialize back to what the runtime accepts (standalone fallbacks).
    let json = serde_json::to_string(&p).unwrap();
    assert!(json.contains("\"start\":1700000000.5"), "{json}");
    assert!(json.contains("\"type\":\"default\""), "{json}");
    let _ = peppy::StandaloneConfig::new().with_parameters(&p);
    runner.shutdown().await;
}
