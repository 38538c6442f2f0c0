//! SPEC 5 slot routing with real producers: pinned slots, from_any bound and
//! unbound, explicit conformance only, late joiners and restarts.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::time::Duration;

use peppy_runtime::NodeRunner;
use peppy_runtime::codegen::{
    ConsumedTopicSpec, FormatSpec, OwnerSpec, QosProfile, TopicSpec, next_message,
};
use peppy_runtime::wire::keys::{Space, liveliness_key, space_selector};

use crate::support::{Frame, WAIT, hub, keep_emitting, namespace, start, test_node};

const FRAME: FormatSpec = FormatSpec {
    fingerprint: 0x1111,
    canonical: "{seq:u32,data:[u8]}",
};
const DEPTH_CAMERA: OwnerSpec = OwnerSpec::Interface {
    name: "depth_camera",
    tag: "v1",
};

pub(crate) static CAM_VIDEO: TopicSpec = TopicSpec {
    owner: DEPTH_CAMERA,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};
static IMPOSTOR_VIDEO: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};

test_node!(
    Camera,
    r#"{ peppy_schema: "node_v1", manifest: { name: "realsense_d405", tag: "v1" },
         interfaces: { conforms_to: [{ name: "depth_camera", tag: "v1" }] },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [CAM_VIDEO], consumes: [], serves: [], actions: []
);

test_node!(
    Zed,
    r#"{ peppy_schema: "node_v1", manifest: { name: "zed_2i", tag: "v1" },
         interfaces: { conforms_to: [{ name: "depth_camera", tag: "v1" }] },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [CAM_VIDEO], consumes: [], serves: [], actions: []
);

// Named like the interface, same topic and format, but no conforms_to.
test_node!(
    Impostor,
    r#"{ peppy_schema: "node_v1", manifest: { name: "depth_camera", tag: "v1" },
         interfaces: { topics: { emits: [{ name: "video_stream", message_format: { seq: "u32", data: { $type: "array", $items: "u8" } } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [IMPOSTOR_VIDEO], consumes: [], serves: [], actions: []
);

static LEFT: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("left_cam"),
    owner: DEPTH_CAMERA,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};
static RIGHT: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("right_cam"),
    owner: DEPTH_CAMERA,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};
static BACKUP: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("backup_cams"),
    owner: DEPTH_CAMERA,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};

test_node!(
    Recon,
    r#"{ peppy_schema: "node_v1", manifest: { name: "video_reconstruction", tag: "v1", depends_on: { interfaces: [
           { name: "depth_camera", tag: "v1", link_id: "left_cam" },
           { name: "depth_camera", tag: "v1", link_id: "right_cam" },
           { name: "depth_camera", tag: "v1", link_id: "backup_cams", from_any: true } ] } },
         interfaces: { topics: { consumes: [
           { link_id: "left_cam", name: "video_stream" },
           { link_id: "right_cam", name: "video_stream" },
           { link_id: "backup_cams", name: "video_stream" } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [LEFT, RIGHT, BACKUP], serves: [], actions: []
);

fn frame(seq: u32) -> Frame {
    Frame {
        seq,
        data: vec![seq as u8; 16],
    }
}

/// Reads `spec` until every producer in `expect` was seen `n` times; fails
/// on any producer outside `expect`. Returns the counts.
async fn read_until(
    runner: &NodeRunner,
    spec: &'static ConsumedTopicSpec,
    expect: &[&str],
    n: usize,
) -> BTreeMap<String, usize> {
    let expected: BTreeSet<&str> = expect.iter().copied().collect();
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let done = |c: &BTreeMap<String, usize>| {
        expected
            .iter()
            .all(|e| c.get(*e).copied().unwrap_or(0) >= n)
    };
    tokio::time::timeout(WAIT, async {
        while !done(&counts) {
            let (producer, msg): (String, Frame) = next_message(runner, spec, None).await.unwrap();
            assert!(
                expected.contains(producer.as_str()),
                "slot `{}` received from `{producer}`, expected only {expected:?}",
                spec.link_id.unwrap()
            );
            assert_eq!(msg.data.len(), 16);
            *counts.entry(producer).or_default() += 1;
        }
    })
    .await
    .unwrap_or_else(|_| {
        panic!(
            "slot `{}` got {counts:?}, expected {n} from each of {expected:?}",
            spec.link_id.unwrap()
        )
    });
    counts
}

async fn stop(runners: &[&Arc<NodeRunner>]) {
    for r in runners {
        r.shutdown().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pinned_slots_get_their_producer_and_from_any_takes_the_unclaimed() {
    let hub = hub().await;
    let ns = namespace("pinned");
    let (_, recon) = start::<Recon>(
        &hub,
        &ns,
        "recon_1",
        &["--bind", "left_cam@rs_left", "--bind", "right_cam@rs_right"],
    )
    .await;
    let (_, left) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    let (_, right) = start::<Camera>(&hub, &ns, "rs_right", &[]).await;
    let (_, zed) = start::<Zed>(&hub, &ns, "zed_overhead", &[]).await;
    let (_, impostor) = start::<Impostor>(&hub, &ns, "impostor", &[]).await;
    for cam in [&left, &right, &zed] {
        keep_emitting(cam.clone(), &CAM_VIDEO, Duration::from_millis(20), frame);
    }
    keep_emitting(
        impostor.clone(),
        &IMPOSTOR_VIDEO,
        Duration::from_millis(20),
        frame,
    );

    read_until(&recon, &LEFT, &["rs_left"], 10).await;
    read_until(&recon, &RIGHT, &["rs_right"], 10).await;
    // Unbound from_any: any depth camera except those pinned by siblings;
    // the impostor does not conform and never arrives.
    read_until(&recon, &BACKUP, &["zed_overhead"], 10).await;
    stop(&[&recon, &left, &right, &zed, &impostor]).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bound_from_any_list_replaces_the_wildcard() {
    let hub = hub().await;
    let ns = namespace("bound");
    let (_, recon) = start::<Recon>(
        &hub,
        &ns,
        "recon_1",
        &[
            "--bind",
            "left_cam@rs_left",
            "--bind",
            "right_cam@rs_left",
            "--bind",
            "extra@zed_a",
            "--bind",
            "more@rs_left",
        ],
    )
    .await;
    let (_, rs) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    let (_, zed_a) = start::<Zed>(&hub, &ns, "zed_a", &[]).await;
    let (_, zed_b) = start::<Zed>(&hub, &ns, "zed_b", &[]).await;
    for cam in [&rs, &zed_a, &zed_b] {
        keep_emitting(cam.clone(), &CAM_VIDEO, Duration::from_millis(20), frame);
    }
    // One producer bound to two pinned slots reaches both.
    read_until(&recon, &LEFT, &["rs_left"], 5).await;
    read_until(&recon, &RIGHT, &["rs_left"], 5).await;
    // Listed: zed_a and rs_left, minus rs_left (pinned by a sibling). zed_b is unlisted.
    read_until(&recon, &BACKUP, &["zed_a"], 20).await;
    stop(&[&recon, &rs, &zed_a, &zed_b]).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn late_and_restarted_producers_are_picked_up() {
    let hub = hub().await;
    let ns = namespace("late");
    let (_, recon) = start::<Recon>(
        &hub,
        &ns,
        "recon_1",
        &["--bind", "left_cam@rs_left", "--bind", "right_cam@rs_right"],
    )
    .await;
    // The producer starts after its consumer.
    let (_, left) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    keep_emitting(left.clone(), &CAM_VIDEO, Duration::from_millis(20), frame);
    read_until(&recon, &LEFT, &["rs_left"], 5).await;
    // It goes away and comes back with the same instance id.
    left.shutdown().await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    while tokio::time::timeout(
        Duration::from_millis(100),
        next_message::<Frame>(&recon, &LEFT, None),
    )
    .await
    .is_ok()
    {}
    let (_, again) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    keep_emitting(again.clone(), &CAM_VIDEO, Duration::from_millis(20), |s| {
        frame(s + 1000)
    });
    let fresh = tokio::time::timeout(WAIT, async {
        loop {
            let (p, f): (String, Frame) = next_message(&recon, &LEFT, None).await.unwrap();
            if f.seq >= 1000 {
                return p;
            }
        }
    })
    .await
    .expect("the restarted producer's frames arrive");
    assert_eq!(fresh, "rs_left");
    stop(&[&recon, &again]).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn namespaces_never_cross_talk() {
    let hub = hub().await;
    let (ns_a, ns_b) = (namespace("ns-a"), namespace("ns-b"));
    let (_, recon_a) = start::<Recon>(
        &hub,
        &ns_a,
        "recon_1",
        &["--bind", "left_cam@rs_left", "--bind", "right_cam@rs_right"],
    )
    .await;
    let (_, cam_a) = start::<Camera>(&hub, &ns_a, "rs_left", &[]).await;
    let (_, cam_b) = start::<Camera>(&hub, &ns_b, "rs_left", &[]).await;
    keep_emitting(cam_a.clone(), &CAM_VIDEO, Duration::from_millis(20), frame);
    keep_emitting(cam_b.clone(), &CAM_VIDEO, Duration::from_millis(20), |s| {
        frame(s + 1_000_000)
    });
    tokio::time::timeout(WAIT, async {
        for _ in 0..30 {
            let (_, f): (String, Frame) = next_message(&recon_a, &LEFT, None).await.unwrap();
            assert!(
                f.seq < 1_000_000,
                "a frame from the other namespace arrived"
            );
        }
    })
    .await
    .expect("frames from the own namespace arrive");
    stop(&[&recon_a, &cam_a, &cam_b]).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pinned_slot_without_binding_fails_at_start_up() {
    let hub = hub().await;
    let ns = namespace("unbound");
    let err =
        crate::support::try_start::<Recon>(&hub, &ns, "recon_1", &["--bind", "left_cam@rs_left"])
            .await
            .unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("slot `right_cam`") && text.contains("--bind right_cam@"),
        "{text}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_is_visible_while_up_and_gone_after_shutdown() {
    let hub = hub().await;
    let ns = namespace("live");
    let (_, cam) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    let present = |hub: &crate::support::Hub| {
        let (session, ns) = (hub.session.clone(), ns.clone());
        async move {
            let replies = session
                .liveliness()
                .get(space_selector(&ns, Space::Live))
                .timeout(Duration::from_secs(2))
                .await
                .unwrap();
            let mut keys = Vec::new();
            while let Ok(r) = replies.recv_async().await {
                if let Ok(s) = r.result() {
                    keys.push(s.key_expr().to_string());
                }
            }
            keys
        }
    };
    let keys = tokio::time::timeout(WAIT, async {
        loop {
            let keys = present(&hub).await;
            if !keys.is_empty() {
                return keys;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    })
    .await
    .expect("the node's liveliness token appears");
    assert_eq!(
        keys,
        [liveliness_key(
            &ns,
            "standalone",
            "rs_left",
            "realsense_d405",
            "v1"
        )]
    );
    cam.shutdown().await;
    tokio::time::timeout(WAIT, async {
        while !present(&hub).await.is_empty() {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    })
    .await
    .expect("the liveliness token is withdrawn at shutdown");
}

static RS_ONLY: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("realsenses"),
    owner: DEPTH_CAMERA,
    name: "video_stream",
    qos: QosProfile::SensorData,
    format: FRAME,
};

// A node slot on realsense_d405:v1 consuming the topic realsense inherits
// from depth_camera:v1: it travels on the interface's key, which the ZED
// shares.
test_node!(
    RealsenseWatcher,
    r#"{ peppy_schema: "node_v1", manifest: { name: "watcher", tag: "v1", depends_on: { nodes: [
           { name: "realsense_d405", tag: "v1", link_id: "realsenses", from_any: true } ] } },
         interfaces: { topics: { consumes: [ { link_id: "realsenses", name: "video_stream" } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [RS_ONLY], serves: [], actions: []
);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_slot_on_an_inherited_topic_takes_only_its_node() {
    let hub = hub().await;
    let ns = namespace("node-slot");
    // The ZED is up first, so a consumer that only looked at keys would
    // see its frames before any realsense frame.
    let (_, zed) = start::<Zed>(&hub, &ns, "zed_overhead", &[]).await;
    keep_emitting(zed.clone(), &CAM_VIDEO, Duration::from_millis(10), frame);
    let (_, watcher) = start::<RealsenseWatcher>(&hub, &ns, "watcher", &[]).await;
    let (_, rs) = start::<Camera>(&hub, &ns, "rs_a", &[]).await;
    keep_emitting(rs.clone(), &CAM_VIDEO, Duration::from_millis(20), frame);
    read_until(&watcher, &RS_ONLY, &["rs_a"], 20).await;

    // Bound to several producers (one of them a ZED by mistake, as a
    // command line can say): still only realsense frames.
    let (_, bound) = start::<RealsenseWatcher>(
        &hub,
        &ns,
        "bound",
        &[
            "--bind",
            "realsenses@rs_a",
            "--bind",
            "realsenses@zed_overhead",
        ],
    )
    .await;
    read_until(&bound, &RS_ONLY, &["rs_a"], 20).await;
    stop(&[&watcher, &bound, &rs, &zed]).await;
}
