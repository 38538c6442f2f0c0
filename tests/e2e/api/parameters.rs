#![deny(warnings)]

#[peppy::node("tests/e2e/api/parameters.json5")]
mod peppygen {}

use std::time::{Duration, UNIX_EPOCH};

use peppygen::parameters::{CamerasItem, Video, VideoEncoder};
use peppygen::{NodeBuilder, Parameters, StandaloneConfig};

/// Parameters read from JSON, written back, refused at a wrong array
/// length, and handed to a node as its standalone fallback, which starts
/// with them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameters_round_trip_and_start_a_node() {
    let json = format!(
        r#"{{ "rate_hz": 10.0, "name": "cam", "start": 1.5, "type": "x",
             "video": {{ "fps": 30, "encoder": {{ "codec": "h264", "bitrate": 9 }} }},
             "gains": [1.0, 2.0, 3.0], "weights": {:?},
             "cameras": [{{ "serial": "SN1", "port": 80 }}] }}"#,
        vec![7u8; 64]
    );
    let params: Parameters = serde_json::from_str(&json).unwrap();
    let expected = Parameters {
        rate_hz: 10.0,
        name: "cam".into(),
        start: UNIX_EPOCH + Duration::from_millis(1500),
        video: Video {
            fps: 30,
            encoder: VideoEncoder {
                codec: "h264".into(),
                bitrate: 9,
            },
        },
        gains: [1.0, 2.0, 3.0],
        weights: [7; 64],
        cameras: vec![CamerasItem {
            serial: "SN1".into(),
            port: 80,
        }],
        r#type: "x".into(),
    };
    assert_eq!(params, expected);
    let back: Parameters = serde_json::from_value(serde_json::to_value(&params).unwrap()).unwrap();
    assert_eq!(back, params);
    let wrong_length = json.replace(&format!("{:?}", vec![7u8; 64]), "[1, 2]");
    assert!(serde_json::from_str::<Parameters>(&wrong_length).is_err());
    let (given, runner) = tokio::time::timeout(
        crate::support::WAIT,
        NodeBuilder::<Parameters>::new()
            .with_args(["node", "--listen", "tcp/127.0.0.1:0"])
            .with_runtime_config(None)
            .standalone(StandaloneConfig::new().with_parameters(&params))
            .start(),
    )
    .await
    .expect("node start timed out")
    .unwrap();
    assert_eq!(given, expected);
    runner.shutdown().await;
}
