//! Services: pinned calls, discovery for unbound from_any slots, and the
//! three failure kinds.

use std::time::Duration;

use peppy_runtime::Error;
use peppy_runtime::codegen::{
    ConsumedServiceSpec, FormatSpec, OwnerSpec, ServiceSpec, call, handle_next,
};
use peppy_runtime::wire::attachment::{QueryHeader, QueryKind, ReplyStatus, parse_reply};
use peppy_runtime::wire::codec::to_bytes;
use peppy_runtime::wire::keys::{Channel, Owner, entry_selector};
use zenoh::query::{ConsolidationMode, QueryTarget};

use crate::support::{Hub, WAIT, hub, namespace, start, test_node};

const INFO_REQ: FormatSpec = FormatSpec::EMPTY;
const INFO_RESP: FormatSpec = FormatSpec {
    fingerprint: 0x42,
    canonical: "{width:u32,height:u32}",
};
const DEPTH_CAMERA: OwnerSpec = OwnerSpec::Interface {
    name: "depth_camera",
    tag: "v1",
};

static INFO: ServiceSpec = ServiceSpec {
    owner: DEPTH_CAMERA,
    name: "video_stream_info",
    request: INFO_REQ,
    response: INFO_RESP,
};
static SCALE: ServiceSpec = ServiceSpec {
    owner: OwnerSpec::Own,
    name: "scale",
    request: FormatSpec {
        fingerprint: 0x51,
        canonical: "{x:u32}",
    },
    response: FormatSpec {
        fingerprint: 0x52,
        canonical: "{y:u32}",
    },
};

test_node!(
    Camera,
    r#"{ peppy_schema: "node_v1", manifest: { name: "realsense_d405", tag: "v1" },
         interfaces: { conforms_to: [{ name: "depth_camera", tag: "v1" }],
                       services: { exposes: [{ name: "scale", request_message_format: { x: "u32" }, response_message_format: { y: "u32" } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [INFO, SCALE], actions: []
);

static LEFT_INFO: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "left_cam",
    owner: DEPTH_CAMERA,
    name: "video_stream_info",
    request: INFO_REQ,
    response: INFO_RESP,
};
static ANY_INFO: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "backup_cams",
    owner: DEPTH_CAMERA,
    name: "video_stream_info",
    request: INFO_REQ,
    response: INFO_RESP,
};
static LEFT_SCALE: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "left_node",
    owner: OwnerSpec::Node {
        name: "realsense_d405",
        tag: "v1",
    },
    name: "scale",
    request: FormatSpec {
        fingerprint: 0x51,
        canonical: "{x:u32}",
    },
    response: FormatSpec {
        fingerprint: 0x52,
        canonical: "{y:u32}",
    },
};

test_node!(
    Recon,
    r#"{ peppy_schema: "node_v1", manifest: { name: "video_reconstruction", tag: "v1", depends_on: {
           interfaces: [
             { name: "depth_camera", tag: "v1", link_id: "left_cam" },
             { name: "depth_camera", tag: "v1", link_id: "backup_cams", from_any: true } ],
           nodes: [ { name: "realsense_d405", tag: "v1", link_id: "left_node" } ] } },
         interfaces: { services: { consumes: [
           { link_id: "left_cam", name: "video_stream_info" },
           { link_id: "backup_cams", name: "video_stream_info" },
           { link_id: "left_node", name: "scale" } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [], actions: []
);

/// Serves `video_stream_info` forever, answering with `width`.
fn serve_info(runner: std::sync::Arc<peppy_runtime::NodeRunner>, width: u32) {
    tokio::spawn(async move {
        while handle_next::<(), [u32; 2], _>(&runner, &INFO, |_, ()| Ok([width, 480]))
            .await
            .is_ok()
        {}
    });
}

/// A reconstruction node as `instance`, both its pinned slots on
/// `rs_left`.
async fn start_recon(
    hub: &Hub,
    ns: &str,
    instance: &str,
) -> (Recon, std::sync::Arc<peppy_runtime::NodeRunner>) {
    start::<Recon>(
        hub,
        ns,
        instance,
        &["--bind", "left_cam@rs_left", "--bind", "left_node@rs_left"],
    )
    .await
}

async fn call_until_up<T>(f: impl AsyncFn() -> peppy_runtime::Result<T>) -> T {
    tokio::time::timeout(WAIT, async {
        loop {
            match f().await {
                Ok(v) => return v,
                Err(Error::ServiceUnreachable { .. }) => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                Err(e) => panic!("{e}"),
            }
        }
    })
    .await
    .expect("the server became reachable")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pinned_and_discovered_calls_reach_the_right_server() {
    let hub = hub().await;
    let ns = namespace("svc");
    let (_, recon) = start_recon(&hub, &ns, "recon").await;
    let (_, left) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    let (_, other) = start::<Camera>(&hub, &ns, "rs_other", &[]).await;
    serve_info(left.clone(), 640);
    serve_info(other.clone(), 1280);

    let r = call_until_up(async || {
        call::<(), [u32; 2]>(&recon, &LEFT_INFO, Duration::from_secs(2), &()).await
    })
    .await;
    assert_eq!((r.instance_id.as_str(), r.data), ("rs_left", [640, 480]));
    assert_eq!(r.core_node, "standalone");
    // Unbound from_any: any camera except the one a sibling pins.
    let r = call_until_up(async || {
        call::<(), [u32; 2]>(&recon, &ANY_INFO, Duration::from_secs(2), &()).await
    })
    .await;
    assert_eq!((r.instance_id.as_str(), r.data), ("rs_other", [1280, 480]));
    for r in [&recon, &left, &other] {
        r.shutdown().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pinned_call_follows_its_server_into_another_launch() {
    let hub = hub().await;
    let ns = namespace("relaunch");
    let (_, recon) = start_recon(&hub, &ns, "recon").await;
    let (_, first) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    serve_info(first.clone(), 640);
    let ask_left =
        async || call::<(), [u32; 2]>(&recon, &LEFT_INFO, Duration::from_secs(2), &()).await;
    // The first answer teaches the caller the server's own key (its core
    // node); the next calls go there.
    for _ in 0..3 {
        let r = call_until_up(ask_left).await;
        assert_eq!((r.core_node.as_str(), r.data), ("standalone", [640, 480]));
    }
    first.shutdown().await;
    // The same instance id, started by a launch: another core node, so
    // another key.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let config = dir.path().join("rs_left.json");
    let startup = peppy_runtime::StartupConfig {
        instance_id: "rs_left".into(),
        core_node: "lab-2".into(),
        namespace: ns.clone(),
        slots: Vec::new(),
        pairs: Vec::new(),
        parameters: serde_json::json!({}),
        zenoh: peppy_runtime::Endpoints {
            connect: vec![hub.endpoint.clone()],
            ..Default::default()
        },
        use_sim_time: false,
        shutdown_grace_secs: None,
        direct_links: None,
        producer_cores: Default::default(),
    };
    std::fs::write(&config, serde_json::to_string(&startup).expect("json")).expect("written");
    let (_, second) = tokio::time::timeout(
        WAIT,
        peppy_runtime::NodeBuilder::<Camera>::new()
            .with_runtime_config(Some(config))
            .with_args(vec!["node".to_string()])
            .start(),
    )
    .await
    .expect("node start timed out")
    .expect("node starts");
    serve_info(second.clone(), 1280);
    // Once a caller that never knew the old key reaches the new server,
    // the old caller does at its first call: it finds nobody at the key it
    // knew and asks again with the wildcard within the same call.
    let (_, fresh) = start_recon(&hub, &ns, "recon_2").await;
    let r = call_until_up(async || {
        call::<(), [u32; 2]>(&fresh, &LEFT_INFO, Duration::from_secs(2), &()).await
    })
    .await;
    assert_eq!((r.core_node.as_str(), r.data), ("lab-2", [1280, 480]));
    tokio::time::sleep(Duration::from_millis(200)).await;
    let r = ask_left()
        .await
        .expect("the old caller finds the relaunched server");
    assert_eq!((r.core_node.as_str(), r.data), ("lab-2", [1280, 480]));
    for r in [&recon, &fresh, &second] {
        r.shutdown().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unreachable_timeout_and_handler_errors_are_distinct() {
    let hub = hub().await;
    let ns = namespace("svc-errors");
    let (_, recon) = start_recon(&hub, &ns, "recon").await;
    // Nobody serves yet.
    let err = call::<u32, u32>(&recon, &LEFT_SCALE, Duration::from_millis(500), &1)
        .await
        .unwrap_err();
    assert!(matches!(err, Error::ServiceUnreachable { .. }), "{err}");

    let (_, cam) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    // The server is up (its queryable acks) but nobody handles the request.
    let err = tokio::time::timeout(WAIT, async {
        loop {
            match call::<u32, u32>(&recon, &LEFT_SCALE, Duration::from_millis(500), &1).await {
                Err(Error::ServiceUnreachable { .. }) => continue,
                other => return other,
            }
        }
    })
    .await
    .unwrap()
    .unwrap_err();
    assert!(matches!(err, Error::ServiceTimeout { .. }), "{err}");

    // A handler error comes back with its text.
    let server = cam.clone();
    tokio::spawn(async move {
        while handle_next::<u32, u32, _>(&server, &SCALE, |caller, x| {
            if x == 0 {
                Err(format!("cannot scale zero for {}", caller.instance_id).into())
            } else {
                Ok(x * 2)
            }
        })
        .await
        .is_ok()
        {}
    });
    let err = call::<u32, u32>(&recon, &LEFT_SCALE, Duration::from_secs(5), &0)
        .await
        .unwrap_err();
    match err {
        Error::ServiceError {
            reason,
            instance_id,
            ..
        } => {
            assert_eq!(reason, "cannot scale zero for recon");
            assert_eq!(instance_id.as_deref(), Some("rs_left"));
        }
        other => panic!("{other}"),
    }
    // Ten concurrent callers are all served by one queryable.
    let calls = (1..=10u32).map(|x| {
        let recon = recon.clone();
        tokio::spawn(async move {
            call::<u32, u32>(&recon, &LEFT_SCALE, Duration::from_secs(5), &x)
                .await
                .map(|r| r.data)
        })
    });
    let mut results = Vec::new();
    for c in calls {
        results.push(c.await.unwrap().unwrap());
    }
    assert_eq!(results, (1..=10).map(|x| x * 2).collect::<Vec<_>>());
    recon.shutdown().await;
    cam.shutdown().await;
}

/// The statuses, in order, of the replies to one raw request for `scale`
/// of `rs_left` in `ns`, sent from the hub's session.
async fn raw_statuses(hub: &Hub, ns: &str, x: u32, budget: Duration) -> Vec<ReplyStatus> {
    let header = QueryHeader {
        kind: QueryKind::Request,
        fingerprint: 0x51,
        core: "standalone".into(),
        instance: "raw_caller".into(),
    };
    let replies = hub
        .session
        .get(entry_selector(
            ns,
            Channel::Service,
            Some(&Owner::Node {
                name: "realsense_d405",
                tag: "v1",
            }),
            "scale",
            None,
            Some("rs_left"),
        ))
        .payload(to_bytes(&x))
        .attachment(header.encode())
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(budget)
        .await
        .unwrap();
    let mut statuses = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        // Zenoh's own `Timeout` error ends a request still held.
        let Ok(sample) = reply.into_result() else {
            continue;
        };
        let attachment = sample.attachment().expect("a status").to_bytes();
        statuses.push(parse_reply(&attachment).expect("a valid status").0);
    }
    statuses
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_prompt_answer_comes_alone_and_a_held_request_is_acked() {
    let hub = hub().await;
    let ns = namespace("svc-acks");
    let (_, cam) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    // Nobody handles: the server holds the request and acks it, once.
    let held = tokio::time::timeout(WAIT, async {
        loop {
            let statuses = raw_statuses(&hub, &ns, 1, Duration::from_millis(300)).await;
            if !statuses.is_empty() {
                return statuses;
            }
        }
    })
    .await
    .unwrap();
    assert_eq!(held, [ReplyStatus::Ack]);

    let server = cam.clone();
    tokio::spawn(async move {
        while handle_next::<u32, u32, _>(&server, &SCALE, |_, x| Ok(x * 2))
            .await
            .is_ok()
        {}
    });
    // An answer within the grace needs no ack; a late one (a busy machine)
    // is acked first. Either way exactly one answer ends the request.
    let mut alone = 0;
    for x in 0..10 {
        let statuses = raw_statuses(&hub, &ns, x, Duration::from_secs(5)).await;
        match statuses.as_slice() {
            [ReplyStatus::Ok] => alone += 1,
            [ReplyStatus::Ack, ReplyStatus::Ok] => {}
            other => panic!("request {x}: replies {other:?}"),
        }
    }
    assert!(alone > 0, "every prompt answer was acked first");
    cam.shutdown().await;
}

test_node!(
    Zed,
    r#"{ peppy_schema: "node_v1", manifest: { name: "zed_2i", tag: "v1" },
         interfaces: { conforms_to: [{ name: "depth_camera", tag: "v1" }] },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [INFO], actions: []
);

static RS_INFO: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "realsenses",
    owner: DEPTH_CAMERA,
    name: "video_stream_info",
    request: INFO_REQ,
    response: INFO_RESP,
};

// A node slot on realsense_d405:v1 calling the service realsense inherits
// from depth_camera:v1, on the interface's key the ZED shares.
test_node!(
    RealsenseCaller,
    r#"{ peppy_schema: "node_v1", manifest: { name: "caller", tag: "v1", depends_on: { nodes: [
           { name: "realsense_d405", tag: "v1", link_id: "realsenses", from_any: true } ] } },
         interfaces: { services: { consumes: [ { link_id: "realsenses", name: "video_stream_info" } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [], actions: []
);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_slot_on_an_inherited_service_calls_only_its_node() {
    let hub = hub().await;
    let ns = namespace("svc-node-slot");
    let (_, caller) = start::<RealsenseCaller>(&hub, &ns, "caller", &[]).await;
    let (_, zed) = start::<Zed>(&hub, &ns, "zed_overhead", &[]).await;
    serve_info(zed.clone(), 2208);
    // Only the ZED serves: the slot has nobody to call.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let err = call::<(), [u32; 2]>(&caller, &RS_INFO, Duration::from_secs(1), &())
        .await
        .unwrap_err();
    assert!(matches!(err, Error::ServiceUnreachable { .. }), "{err}");
    let (_, rs) = start::<Camera>(&hub, &ns, "rs_a", &[]).await;
    serve_info(rs.clone(), 640);
    for _ in 0..5 {
        let r = call_until_up(async || {
            call::<(), [u32; 2]>(&caller, &RS_INFO, Duration::from_secs(2), &()).await
        })
        .await;
        assert_eq!((r.instance_id.as_str(), r.data), ("rs_a", [640, 480]));
    }
    for r in [&caller, &zed, &rs] {
        r.shutdown().await;
    }
}

/// A shutdown hook still calls services: the token has fired, messaging
/// has not closed. Once it has, a call is refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_shutdown_hook_can_still_call_a_service() {
    let hub = hub().await;
    let ns = namespace("svc-hook");
    let (_, recon) = start_recon(&hub, &ns, "recon").await;
    let (_, left) = start::<Camera>(&hub, &ns, "rs_left", &[]).await;
    serve_info(left.clone(), 640);
    // Reachable before the stop.
    call_until_up(async || {
        call::<(), [u32; 2]>(&recon, &LEFT_INFO, Duration::from_secs(2), &()).await
    })
    .await;
    let (tx, rx) = tokio::sync::oneshot::channel();
    let r = recon.clone();
    recon.on_shutdown(async move {
        let stopping = r.cancellation_token().is_cancelled();
        let answer = call::<(), [u32; 2]>(&r, &LEFT_INFO, WAIT, &()).await;
        let _ = tx.send((stopping, answer.map(|a| a.data)));
    });
    tokio::time::timeout(WAIT, recon.shutdown()).await.unwrap();
    let (stopping, answer) = rx.await.unwrap();
    assert!(stopping);
    assert_eq!(answer.unwrap(), [640, 480]);
    let refused = call::<(), [u32; 2]>(&recon, &LEFT_INFO, WAIT, &()).await;
    assert!(matches!(refused, Err(Error::ShuttingDown)), "{refused:?}");
    left.shutdown().await;
}
