//! Faults (docs/FAULTS.md): what a node does when what reaches it is
//! wrong (garbage on every entry kind), too much (a flood on a dropping
//! topic, one 64 MiB message) or a clock that misbehaves (sim time that
//! stops or goes back, a launch's wall clock that jumps).

use std::hash::Hasher;
use std::sync::Arc;
use std::time::{Duration, Instant};

use peppy_runtime::clock::{self, ClockTick};
use peppy_runtime::codegen::{
    ActionSpec, ConsumedActionSpec, ConsumedServiceSpec, ConsumedTopicSpec, Decode, Decoder,
    FormatSpec, OutgoingMessage, OwnerSpec, QosProfile, ServiceSpec, TopicSpec, call,
    declare_paired_publisher, emit, handle_next, next_goal, next_message, next_payload, send_goal,
    subscribe_paired,
};
use peppy_runtime::testing::{Harness, HarnessConfig};
use peppy_runtime::wire::attachment::{self, QueryHeader, QueryKind, ReplyStatus, parse_reply};
use peppy_runtime::wire::codec::to_bytes;
use peppy_runtime::wire::keys::{
    ActionPart, Channel, Owner, action_part_key, entry_key, pairing_topic_key,
};
use peppy_runtime::{NodeRunner, Outcome, STANDALONE_CORE, SharedMemory};
use zenoh::query::{ConsolidationMode, QueryTarget};

use crate::pairings::{SETPOINT_IN, SETPOINT_OUT, VALUE, arm, commander, paired_with};
use crate::shutdown::Hooked;
use crate::support::{
    Frame, Hub, TestChild, WAIT, hub, namespace, start, start_configured, test_node,
};
use crate::topics::{patterned, start_shm};

const N: FormatSpec = FormatSpec {
    fingerprint: 0xfa_0001,
    canonical: "{n:u32}",
};
const SINK: OwnerSpec = OwnerSpec::Node {
    name: "sink",
    tag: "v1",
};
const SINK_KEY: Owner<'static> = Owner::Node {
    name: "sink",
    tag: "v1",
};

static CMDS_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "cmds",
    qos: QosProfile::Reliable,
    format: N,
};
static CMDS_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: None,
    owner: OwnerSpec::Any,
    name: "cmds",
    qos: QosProfile::Reliable,
    format: N,
};
static DOUBLE: ServiceSpec = ServiceSpec {
    owner: OwnerSpec::Own,
    name: "double",
    request: N,
    response: N,
};
static DOUBLE_CALL: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "sink",
    owner: SINK,
    name: "double",
    request: N,
    response: N,
};
static WORK: ActionSpec = ActionSpec {
    owner: OwnerSpec::Own,
    name: "work",
    goal: N,
    feedback: N,
    result: N,
};
static WORK_CALL: ConsumedActionSpec = ConsumedActionSpec {
    link_id: "sink",
    owner: SINK,
    name: "work",
    goal: N,
    feedback: N,
    result: N,
};

test_node!(
    Sink,
    r#"{ peppy_schema: "node_v1", manifest: { name: "sink", tag: "v1" },
         interfaces: {
           topics: { consumes: [{ name: "cmds", message_format: { n: "u32" } }] },
           services: { exposes: [{ name: "double", request_message_format: { n: "u32" }, response_message_format: { n: "u32" } }] },
           actions: { exposes: [{ name: "work",
             goal_service: { request_message_format: { n: "u32" } },
             feedback_topic: { message_format: { n: "u32" } },
             result_service: { response_message_format: { n: "u32" } } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [CMDS_IN], serves: [DOUBLE], actions: [WORK]
);

test_node!(
    Client,
    r#"{ peppy_schema: "node_v1", manifest: { name: "client", tag: "v1", depends_on: { nodes: [{ name: "sink", tag: "v1", link_id: "sink" }] } },
         interfaces: {
           topics: { emits: [{ name: "cmds", qos_profile: "reliable", message_format: { n: "u32" } }] },
           services: { consumes: [{ link_id: "sink", name: "double" }] },
           actions: { consumes: [{ link_id: "sink", name: "work" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [CMDS_OUT], consumes: [], serves: [], actions: []
);

/// Serves `double` and `work` until the node stops.
fn serve_sink(sink: &Arc<NodeRunner>) {
    let runner = sink.clone();
    tokio::spawn(async move {
        while handle_next::<u32, u32, _>(&runner, &DOUBLE, |_, n| Ok(n.wrapping_mul(2)))
            .await
            .is_ok()
        {}
    });
    let runner = sink.clone();
    tokio::spawn(async move {
        while let Ok(goal) = next_goal::<u32>(&runner, &WORK).await {
            let n = goal.data;
            if let Ok(ctx) = goal.accept() {
                let _ = ctx.complete(&n.wrapping_mul(10));
            }
        }
    });
}

/// The replies (status, payload) `hub` gets to one raw query: what a peer
/// that is not peppy, or a broken one, would send.
async fn raw_query(
    hub: &Hub,
    key: &str,
    header: Option<Vec<u8>>,
    payload: Vec<u8>,
) -> Vec<(ReplyStatus, Vec<u8>)> {
    let replies = hub
        .session
        .get(key)
        .payload(payload)
        .attachment(header)
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(Duration::from_secs(10))
        .await
        .unwrap();
    let mut got = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        // Zenoh's own `Timeout` error is no answer of the node's.
        let Ok(sample) = reply.into_result() else {
            continue;
        };
        let status = sample
            .attachment()
            .and_then(|a| parse_reply(&a.to_bytes()))
            .expect("every reply of a node carries a status")
            .0;
        got.push((status, sample.payload().to_bytes().into_owned()));
    }
    got
}

/// A request header of `mallory` in a format of `fingerprint`.
fn header(fingerprint: u64) -> Option<Vec<u8>> {
    Some(QueryHeader::encode_parts(
        QueryKind::Request,
        fingerprint,
        "elsewhere",
        "mallory",
    ))
}

/// The one answer among `replies` apart from acks (a busy machine may ack
/// a request before its handler answers).
fn answer(replies: Vec<(ReplyStatus, Vec<u8>)>) -> (ReplyStatus, Vec<u8>) {
    let mut answers: Vec<_> = replies
        .into_iter()
        .filter(|(s, _)| *s != ReplyStatus::Ack)
        .collect();
    assert_eq!(answers.len(), 1, "one answer: {answers:?}");
    answers.remove(0)
}

/// The answer's status and text (an error's reason, a server's format).
fn text(answer: (ReplyStatus, Vec<u8>)) -> (ReplyStatus, String) {
    (answer.0, String::from_utf8_lossy(&answer.1).into_owned())
}

/// Bytes that are no goal envelope (a goal id, then the goal).
const NOT_AN_ENVELOPE: [u8; 3] = [0xff, 0xff, 0xff];

/// A node meets garbage on every entry it has: on a topic it consumes
/// (a payload that does not decode behind a valid attachment, a payload
/// without an attachment, or with a broken or foreign one), on its
/// service and its action goal (a query without a header, in another
/// format, with a payload that does not decode), on its action's cancel
/// and result, and on a pairing topic from its peer's own key. peppy
/// promises that none of it reaches the node's code as a message or
/// stops the node: a topic drops it (a raw read still sees undecodable
/// bytes behind a valid attachment: decoding is the reader's), a query
/// without a valid header is dropped unanswered, a foreign format is
/// answered `FormatMismatch` with the server's format, and an undecodable
/// request is answered with an error; the valid traffic after it is
/// served as before.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn garbage_on_every_entry_kind_is_dropped_and_the_node_keeps_serving() {
    let hub = hub().await;
    let ns = namespace("fault-garbage");
    let (_, sink) = start::<Sink>(&hub, &ns, "sink", &[]).await;
    let (_, client) = start::<Client>(&hub, &ns, "client", &["--bind", "sink@sink"]).await;
    serve_sink(&sink);

    // Topic: a forged producer's messages come in order, so the valid one
    // after the garbage is the first the reader gets.
    let forged = Owner::Node {
        name: "mallory",
        tag: "v1",
    };
    let key = entry_key(&ns, Channel::Topic, &forged, "cmds", "elsewhere", "mallory");
    let mallory = hub.session.declare_publisher(key).await.unwrap();
    let valid = Some(attachment::topic(N.fingerprint));
    tokio::time::timeout(WAIT, async {
        loop {
            mallory
                .put(u32::MAX.to_le_bytes().to_vec())
                .attachment(valid.clone())
                .await
                .unwrap();
            let heard = tokio::time::timeout(
                Duration::from_millis(100),
                next_message::<u32>(&sink, &CMDS_IN, None),
            );
            if heard.await.is_ok() {
                break;
            }
        }
    })
    .await
    .expect("the sink hears the forged producer");
    let mut broken_version = attachment::topic(N.fingerprint);
    broken_version[0] = 0x7f;
    let garbage: [(Vec<u8>, Option<Vec<u8>>); 5] = [
        (vec![1, 2, 3], valid.clone()),
        (vec![1, 2, 3, 4, 5], valid.clone()),
        // Each decodes as a u32: only the attachment refuses it.
        (7u32.to_le_bytes().to_vec(), None),
        (7u32.to_le_bytes().to_vec(), Some(broken_version)),
        (
            7u32.to_le_bytes().to_vec(),
            Some(attachment::topic(N.fingerprint ^ 1)),
        ),
    ];
    for (payload, attached) in garbage {
        mallory.put(payload).attachment(attached).await.unwrap();
    }
    mallory
        .put(42u32.to_le_bytes().to_vec())
        .attachment(valid.clone())
        .await
        .unwrap();
    let got = tokio::time::timeout(WAIT, async {
        loop {
            let (from, n) = next_message::<u32>(&sink, &CMDS_IN, None).await.unwrap();
            // Sentinels still in flight from the loop above.
            if n != u32::MAX {
                return (from, n);
            }
        }
    })
    .await
    .expect("the valid message after the garbage arrives");
    assert_eq!(got, ("mallory".to_string(), 42), "the garbage was dropped");
    // Read raw, an undecodable payload behind a valid attachment is there.
    mallory
        .put(vec![9, 9, 9])
        .attachment(valid.clone())
        .await
        .unwrap();
    let (_, raw) = tokio::time::timeout(WAIT, next_payload(&sink, &CMDS_IN, None))
        .await
        .expect("the raw payload arrives")
        .unwrap();
    assert_eq!(&*raw.bytes(), [9, 9, 9]);
    // The real producer is still heard.
    tokio::time::timeout(WAIT, async {
        loop {
            emit(&client, &CMDS_OUT, &7u32).await.unwrap();
            let heard = tokio::time::timeout(
                Duration::from_millis(200),
                next_message::<u32>(&sink, &CMDS_IN, None),
            );
            if let Ok(got) = heard.await {
                assert_eq!(got.unwrap(), ("client".to_string(), 7));
                break;
            }
        }
    })
    .await
    .expect("the client's message arrives after the garbage");

    // Service: reachable first, so an unanswered query means dropped.
    let double = async || call::<u32, u32>(&client, &DOUBLE_CALL, WAIT, &21).await;
    let reply = until_reachable(double).await;
    assert_eq!(reply.data, 42);
    let key = entry_key(
        &ns,
        Channel::Service,
        &SINK_KEY,
        "double",
        STANDALONE_CORE,
        "sink",
    );
    let four = 4u32.to_le_bytes().to_vec();
    assert!(
        raw_query(&hub, &key, None, four.clone()).await.is_empty(),
        "a query without a header is dropped"
    );
    assert!(
        raw_query(&hub, &key, Some(vec![1, 0, 1]), four.clone())
            .await
            .is_empty(),
        "a query with a broken header is dropped"
    );
    let (status, body) = text(answer(
        raw_query(&hub, &key, header(N.fingerprint ^ 1), four).await,
    ));
    assert_eq!(
        (status, body.as_str()),
        (ReplyStatus::FormatMismatch, N.canonical)
    );
    let (status, body) = text(answer(
        raw_query(&hub, &key, header(N.fingerprint), vec![1, 2, 3]).await,
    ));
    assert_eq!(status, ReplyStatus::HandlerError);
    assert!(body.starts_with("request does not decode"), "{body}");
    let reply = tokio::time::timeout(WAIT, double())
        .await
        .expect("a valid call after the garbage is answered")
        .unwrap();
    assert_eq!((reply.instance_id.as_str(), reply.data), ("sink", 42));

    // Action: the goal, then cancel and result.
    let goal = async || send_goal(&client, &WORK_CALL, WAIT, &5u32).await;
    let first = until_reachable(goal).await;
    assert!(first.accepted);
    let base = entry_key(
        &ns,
        Channel::Action,
        &SINK_KEY,
        "work",
        STANDALONE_CORE,
        "sink",
    );
    let goal_key = action_part_key(&base, ActionPart::Goal);
    let mut envelope = to_bytes("fault-goal-1");
    envelope.extend_from_slice(&[1, 2, 3]);
    assert!(
        raw_query(&hub, &goal_key, None, envelope.clone())
            .await
            .is_empty(),
        "a goal without a header is dropped"
    );
    let (status, body) = text(answer(
        raw_query(&hub, &goal_key, header(N.fingerprint ^ 1), envelope.clone()).await,
    ));
    assert_eq!(
        (status, body.as_str()),
        (ReplyStatus::FormatMismatch, N.canonical)
    );
    let (status, body) = text(answer(
        raw_query(
            &hub,
            &goal_key,
            header(N.fingerprint),
            NOT_AN_ENVELOPE.to_vec(),
        )
        .await,
    ));
    assert_eq!(
        (status, body.as_str()),
        (ReplyStatus::HandlerError, "malformed goal envelope")
    );
    // A well-formed envelope around a goal that does not decode: the
    // server's loop rejects it and goes on.
    let (status, body) = answer(raw_query(&hub, &goal_key, header(N.fingerprint), envelope).await);
    assert_eq!(status, ReplyStatus::Ok);
    let mut d = Decoder::new(&body);
    assert!(!bool::decode(&mut d).unwrap(), "the goal is rejected");
    let reason = Option::<String>::decode(&mut d).unwrap().unwrap();
    assert!(reason.starts_with("goal does not decode"), "{reason}");
    for part in [ActionPart::Cancel, ActionPart::Result] {
        let key = action_part_key(&base, part);
        assert!(
            raw_query(&hub, &key, None, NOT_AN_ENVELOPE.to_vec())
                .await
                .is_empty(),
            "a {} query naming no goal is dropped",
            part.as_str()
        );
    }
    let g = tokio::time::timeout(WAIT, goal())
        .await
        .expect("a valid goal after the garbage is answered")
        .unwrap();
    assert!(g.accepted);
    assert_eq!(g.result::<u32>(WAIT).await.unwrap(), Outcome::Completed(50));
    assert_eq!(
        first.result::<u32>(WAIT).await.unwrap(),
        Outcome::Completed(50)
    );

    // Pairing: garbage under the peer's own key (anyone on the network can
    // publish there) reaches the pair's inbox and is dropped.
    let arm_1 = arm(&hub, &ns, "arm_1", &[]).await;
    let c1 = commander(&hub, &ns, "c1", &["--link", "arm@arm_1/commander"]).await;
    paired_with(&arm_1, "commander").await;
    paired_with(&c1, "arm").await;
    let mut hears = subscribe_paired::<u64>(&arm_1, &SETPOINT_IN).await.unwrap();
    let key = pairing_topic_key(
        &ns,
        "arm_link",
        "v1",
        "setpoint",
        STANDALONE_CORE,
        "c1",
        "arm",
    );
    let as_c1 = hub.session.declare_publisher(key).await.unwrap();
    let valid = Some(attachment::topic(VALUE.fingerprint));
    tokio::time::timeout(WAIT, async {
        loop {
            as_c1
                .put(u64::MAX.to_le_bytes().to_vec())
                .attachment(valid.clone())
                .await
                .unwrap();
            if tokio::time::timeout(Duration::from_millis(100), hears.next())
                .await
                .is_ok()
            {
                break;
            }
        }
    })
    .await
    .expect("the arm hears its peer's key");
    as_c1
        .put(vec![1, 2, 3])
        .attachment(valid.clone())
        .await
        .unwrap();
    as_c1
        .put(5u64.to_le_bytes().to_vec())
        .attachment(None::<Vec<u8>>)
        .await
        .unwrap();
    as_c1
        .put(6u64.to_le_bytes().to_vec())
        .attachment(Some(attachment::topic(VALUE.fingerprint ^ 1)))
        .await
        .unwrap();
    as_c1
        .put(42u64.to_le_bytes().to_vec())
        .attachment(valid)
        .await
        .unwrap();
    let n = tokio::time::timeout(WAIT, async {
        loop {
            let (peer, n) = hears.next().await.unwrap().expect("the node is up");
            assert_eq!(peer.producer.instance_id, "c1");
            if n != u64::MAX {
                return n;
            }
        }
    })
    .await
    .expect("the valid message after the garbage arrives");
    assert_eq!(n, 42, "the garbage was dropped");
    let publisher = declare_paired_publisher(&c1, &SETPOINT_OUT).await.unwrap();
    publisher
        .publish(OutgoingMessage::new(&SETPOINT_OUT.topic, 43u64))
        .await
        .unwrap();
    let (_, n) = tokio::time::timeout(WAIT, hears.next())
        .await
        .expect("the real peer is still heard")
        .unwrap()
        .unwrap();
    assert_eq!(n, 43);

    assert!(!sink.cancellation_token().is_cancelled());
    assert!(!arm_1.cancellation_token().is_cancelled());
    for r in [sink, client, arm_1, c1] {
        r.shutdown().await;
    }
}

/// Retries `f` (bounded) while its server is not reachable yet.
async fn until_reachable<T>(f: impl AsyncFn() -> peppy_runtime::Result<T>) -> T {
    tokio::time::timeout(WAIT, async {
        loop {
            match f().await {
                Err(peppy_runtime::Error::ServiceUnreachable { .. }) => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                other => return other.unwrap(),
            }
        }
    })
    .await
    .expect("the server became reachable")
}

const SNAP: FormatSpec = FormatSpec {
    fingerprint: 0xfa_0002,
    canonical: "{seq:u32,data:bytes}",
};
const SNAP_CAM: OwnerSpec = OwnerSpec::Node {
    name: "snap_cam",
    tag: "v1",
};
static SENSOR_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "frames",
    qos: QosProfile::SensorData,
    format: SNAP,
};
static STATUS_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "status",
    qos: QosProfile::Standard,
    format: SNAP,
};
static SENSOR_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("cam"),
    owner: SNAP_CAM,
    name: "frames",
    qos: QosProfile::SensorData,
    format: SNAP,
};
static STATUS_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("cam"),
    owner: SNAP_CAM,
    name: "status",
    qos: QosProfile::Standard,
    format: SNAP,
};

test_node!(
    SnapCam,
    r#"{ peppy_schema: "node_v1", manifest: { name: "snap_cam", tag: "v1" },
         interfaces: { topics: { emits: [
             { name: "frames", qos_profile: "sensor_data", message_format: { seq: "u32", data: "bytes" } },
             { name: "status", qos_profile: "standard", message_format: { seq: "u32", data: "bytes" } } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [SENSOR_OUT, STATUS_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    Viewer,
    r#"{ peppy_schema: "node_v1", manifest: { name: "viewer", tag: "v1", depends_on: { nodes: [{ name: "snap_cam", tag: "v1", link_id: "cam" }] } },
         interfaces: { topics: { consumes: [{ link_id: "cam", name: "frames" }, { link_id: "cam", name: "status" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [SENSOR_IN, STATUS_IN], serves: [], actions: []
);

/// Emits a marker on `out` until `viewer` reads one on `inbound`.
async fn until_heard(
    cam: &NodeRunner,
    viewer: &NodeRunner,
    out: &'static TopicSpec,
    inbound: &'static ConsumedTopicSpec,
) {
    let marker = Frame {
        seq: u32::MAX,
        data: Vec::new(),
    };
    tokio::time::timeout(WAIT, async {
        loop {
            emit(cam, out, &marker).await.unwrap();
            let heard = tokio::time::timeout(
                Duration::from_millis(100),
                next_message::<Frame>(viewer, inbound, None),
            );
            if heard.await.is_ok() {
                break;
            }
        }
    })
    .await
    .expect("subscription matched");
}

/// A slow consumer of a dropping topic (`sensor_data`: the newest 5,
/// `standard`: the newest 10) while its producer floods it: the producer
/// never waits, and the consumer, reading at last, gets the newest
/// messages only, as many as its queue holds, in order, none twice. The
/// reliable counterpart is `topics::a_reader_that_never_reads_one_topic_stalls_nothing_else`,
/// where the same flood is kept whole: reliable keeps everything,
/// dropping keeps the newest.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_consumer_on_a_dropping_profile_keeps_the_newest_in_order() {
    let hub = hub().await;
    let ns = namespace("fault-newest");
    let (_, viewer) = start::<Viewer>(&hub, &ns, "viewer", &["--bind", "cam@cam"]).await;
    let (_, cam) = start::<SnapCam>(&hub, &ns, "cam", &[]).await;
    let topics = [
        (&SENSOR_OUT, &SENSOR_IN, 5u32),
        (&STATUS_OUT, &STATUS_IN, 10),
    ];
    for (out, inbound, _) in topics {
        until_heard(&cam, &viewer, out, inbound).await;
    }
    // 40 MiB a topic, unread.
    const FLOOD: u32 = 10_000;
    let frame = |seq| patterned(seq, 4096);
    tokio::time::timeout(WAIT, async {
        for seq in 0..FLOOD {
            for (out, _, _) in topics {
                emit(&cam, out, &frame(seq)).await.unwrap();
            }
        }
    })
    .await
    .expect("the producer is never held up by a consumer that does not read");
    // Then, the flood long delivered, one message fewer than the queue
    // holds, spaced out so that none is lost on the way: the queue then
    // holds the newest frame of the flood that reached it, and these.
    tokio::time::sleep(Duration::from_secs(1)).await;
    for (out, _, depth) in topics {
        for seq in FLOOD..FLOOD + depth - 1 {
            emit(&cam, out, &frame(seq)).await.unwrap();
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    for (_, inbound, depth) in topics {
        let mut got = Vec::new();
        for _ in 0..depth {
            let (_, f) = tokio::time::timeout(WAIT, next_message::<Frame>(&viewer, inbound, None))
                .await
                .unwrap_or_else(|_| panic!("{}: {} of {depth} kept", inbound.name, got.len()))
                .unwrap();
            assert!(
                f == frame(f.seq),
                "{}: frame {} intact",
                inbound.name,
                f.seq
            );
            got.push(f.seq);
        }
        let more = tokio::time::timeout(
            Duration::from_millis(300),
            next_message::<Frame>(&viewer, inbound, None),
        )
        .await;
        assert!(
            more.is_err(),
            "{}: at most {depth} kept, then {:?}",
            inbound.name,
            more.map(|m| m.unwrap().1.seq)
        );
        let newest_of_flood = got[0];
        assert!(
            (depth..FLOOD).contains(&newest_of_flood),
            "{}: the oldest were dropped, not the newest: {got:?}",
            inbound.name
        );
        assert_eq!(
            got[1..],
            (FLOOD..FLOOD + depth - 1).collect::<Vec<_>>(),
            "{}: the newest, in order, none twice",
            inbound.name
        );
    }
    viewer.shutdown().await;
    cam.shutdown().await;
}

const BLOB: FormatSpec = FormatSpec {
    fingerprint: 0xfa_0003,
    canonical: "{seq:u32,data:bytes}",
};
static BLOB_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "blobs",
    qos: QosProfile::Reliable,
    format: BLOB,
};
static BLOB_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("src"),
    owner: OwnerSpec::Node {
        name: "blob_source",
        tag: "v1",
    },
    name: "blobs",
    qos: QosProfile::Reliable,
    format: BLOB,
};

test_node!(
    BlobSource,
    r#"{ peppy_schema: "node_v1", manifest: { name: "blob_source", tag: "v1" },
         interfaces: { topics: { emits: [{ name: "blobs", qos_profile: "reliable", message_format: { seq: "u32", data: "bytes" } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [BLOB_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    BlobSink,
    r#"{ peppy_schema: "node_v1", manifest: { name: "blob_sink", tag: "v1", depends_on: { nodes: [{ name: "blob_source", tag: "v1", link_id: "src" }] } },
         interfaces: { topics: { consumes: [{ link_id: "src", name: "blobs" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [BLOB_IN], serves: [], actions: []
);

fn digest(bytes: &[u8]) -> u64 {
    let mut h = std::hash::DefaultHasher::new();
    h.write(bytes);
    h.finish()
}

/// The next blob of `sink` that is not a marker: its seq, its data's
/// length and digest, and whether it came in shared memory. Read in place,
/// not decoded into a copy.
async fn next_blob(sink: &NodeRunner) -> (u32, usize, u64, bool) {
    tokio::time::timeout(WAIT, async {
        loop {
            let (_, payload) = next_payload(sink, &BLOB_IN, None).await.unwrap();
            let bytes = payload.bytes();
            let mut d = Decoder::new(&bytes);
            let seq = u32::decode(&mut d).unwrap();
            if seq == u32::MAX {
                continue;
            }
            let n = d.count(1).unwrap();
            let data = d.take(n).unwrap();
            assert_eq!(d.remaining(), 0);
            return (seq, n, digest(data), payload.in_shared_memory());
        }
    })
    .await
    .expect("the blob arrives")
}

/// One 64 MiB message on a reliable topic, far past Zenoh's batch (64 KiB)
/// and the node's default shared-memory pool (32 MiB): it arrives whole
/// (same length and digest) to a reader on this host and to one with
/// shared memory off (as on another host) whether its producer has shared
/// memory off, on with a pool too small for it (it then goes as bytes,
/// logged once), or on with room for it (then in place to the local
/// reader); and a small message after it follows it in order. The limit
/// is Zenoh's receive limit (1 GiB a message, its default
/// `transport/link/rx/max_message_size`), far above this one; past it
/// `emit` refuses the message (`Error::MessageTooLarge`, the unit test
/// `topics::tests::a_message_no_node_would_receive_is_refused_with_figures`)
/// where every reader would drop it unseen.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversize_message_arrives_whole_or_fails_loudly() {
    const SIZE: usize = 64 << 20;
    let hub = hub().await;
    let big = patterned(1, SIZE);
    let want = digest(&big.data);
    let on = SharedMemory::default();
    // (producer's setting, whether the local reader maps the blob)
    let cases = [
        (SharedMemory::off(), false),
        (on, false),
        (on.pool(256 << 20), true),
    ];
    for (i, (shm, in_place)) in cases.into_iter().enumerate() {
        let ns = namespace(&format!("fault-oversize-{i}"));
        let local = start_shm::<BlobSink>(&hub, &ns, "local", "src@blob_source", on).await;
        let remote =
            start_shm::<BlobSink>(&hub, &ns, "remote", "src@blob_source", SharedMemory::off())
                .await;
        let configure = |b: peppy_runtime::NodeBuilder<BlobSource>| b.shared_memory(shm);
        let (_, source) = start_configured(&hub, &ns, "blob_source", &[], configure).await;
        let marker = Frame {
            seq: u32::MAX,
            data: Vec::new(),
        };
        for sink in [&local, &remote] {
            tokio::time::timeout(WAIT, async {
                loop {
                    emit(&source, &BLOB_OUT, &marker).await.unwrap();
                    let heard = tokio::time::timeout(
                        Duration::from_millis(100),
                        next_payload(sink, &BLOB_IN, None),
                    );
                    if heard.await.is_ok() {
                        break;
                    }
                }
            })
            .await
            .expect("subscription matched");
        }
        tokio::time::timeout(WAIT, emit(&source, &BLOB_OUT, &big))
            .await
            .expect("the emit returns")
            .expect("the emit succeeds");
        emit(&source, &BLOB_OUT, &patterned(2, 16)).await.unwrap();
        // A host that lets a process lock too little memory has shared
        // memory turned off at start.
        let maps = in_place && local.shared_memory().enabled() && source.shared_memory().enabled();
        for (sink, mapped) in [(&local, maps), (&remote, false)] {
            let got = next_blob(sink).await;
            assert_eq!(
                got,
                (1, SIZE, want, mapped),
                "case {i}: {} gets the blob whole",
                sink.instance_id()
            );
            let after = next_blob(sink).await;
            assert_eq!(after.0, 2, "case {i}: the next message follows it");
        }
        for r in [local, remote, source] {
            r.shutdown().await;
        }
    }
}

/// The child process's environment variable: the scenario to run.
const CHILD_ENV: &str = "PEPPY_RUNTIME_TEST_FAULTS_CHILD";

/// Runs `entry` of this module as a child process (this test binary
/// again: the stack clock is one per process, and the clock tests of
/// `clock` bind it in this one), and fails unless it passes and says
/// `done`.
fn run_child(entry: &str, done: &str) {
    let mut child = TestChild::spawn(&format!("faults::{entry}"), &[(CHILD_ENV, entry)], &[]);
    let status = child.exit(Duration::from_secs(120));
    let text = child.seen.join("\n");
    assert!(status.success(), "the child `{entry}` failed:\n{text}");
    assert!(
        text.contains(done),
        "the child `{entry}` ran nothing:\n{text}"
    );
}

/// Fails unless run by its parent test.
fn as_child(entry: &str) {
    let env = std::env::var(CHILD_ENV).unwrap_or_default();
    assert_eq!(
        env, entry,
        "a child process: its parent test runs it with {CHILD_ENV}={entry}"
    );
}

/// Publishes `t` from `simulator` until the clock reads it.
async fn tick_until_read(simulator: &NodeRunner, t: u64) {
    tokio::time::timeout(WAIT, async {
        while clock::now_ns().ok() != Some(t) {
            clock::publish_sim_time(simulator, t).await.unwrap();
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .unwrap_or_else(|_| panic!("the sim tick {t} is read: {:?}", clock::now_ns()));
}

/// What the launch's clock answers a sim-time node, once it answers `t`.
async fn launch_answers(node: &NodeRunner, t: u64) {
    tokio::time::timeout(WAIT, async {
        loop {
            match clock::synchronize(node, Some(WAIT)).await {
                Ok(s) if s.raw.server_recv_time == t => break,
                Ok(_) | Err(peppy_runtime::Error::ClockNotReady) => {
                    tokio::time::sleep(Duration::from_millis(20)).await
                }
                Err(e) => panic!("{e}"),
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("the launch answers the sim time {t}"));
}

const SECOND: u64 = 1_000_000_000;

/// Runs only as the child of `sim_time_that_stops_holds_at_its_last_tick`.
#[test]
#[ignore = "a child process of sim_time_that_stops_holds_at_its_last_tick, which runs it; fails run alone"]
fn child_sim_time_stops() {
    as_child("child_sim_time_stops");
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let hub = hub().await;
        let ns = namespace("fault-sim-stops");
        let _launch = clock::serve(&hub.session, &ns).await.unwrap();
        let (_, node) = start::<Hooked>(&hub, &ns, "sim_node", &["--use-sim-time"]).await;
        clock::init(&node).await.unwrap();
        let ticks = clock::subscribe(&node).await.unwrap();
        let (_, simulator) = start::<Hooked>(&hub, &ns, "simulator", &[]).await;
        for t in 1..=3 {
            tick_until_read(&simulator, t * SECOND).await;
        }
        launch_answers(&node, 3 * SECOND).await;
        // The simulator stops (or hangs).
        simulator.shutdown().await;
        let stopped = Instant::now();
        while stopped.elapsed() < Duration::from_secs(1) {
            assert_eq!(
                clock::now_ns().unwrap(),
                3 * SECOND,
                "held, not extrapolated"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let sync = clock::synchronize(&node, Some(WAIT)).await.unwrap();
        assert_eq!(
            sync.raw.server_recv_time,
            3 * SECOND,
            "the launch holds too"
        );
        // The ticks queued (the last one maybe more than once, as it was
        // sent until read), then nothing: a wait for the next tick ends at
        // the caller's bound.
        let mut queued = Vec::new();
        while let Ok(tick) =
            tokio::time::timeout(Duration::from_millis(500), ticks.on_next_tick()).await
        {
            queued.push(tick.unwrap().expect("the node is up").time);
            assert!(
                queued.len() < 1000,
                "ticks keep coming: {:?}",
                &queued[..20]
            );
        }
        assert_eq!(queued.last(), Some(&(3 * SECOND)), "{queued:?}");
        assert!(queued.is_sorted(), "{queued:?}");

        // A simulator that restarts (or resets its world) goes back: the
        // earlier time is taken as the time, by the node, its
        // subscription and the launch alike.
        let (_, simulator) = start::<Hooked>(&hub, &ns, "simulator_2", &[]).await;
        tick_until_read(&simulator, SECOND / 2).await;
        let tick = tokio::time::timeout(WAIT, ticks.on_next_tick())
            .await
            .expect("the earlier tick is delivered")
            .unwrap();
        assert_eq!(tick, Some(ClockTick { time: SECOND / 2 }));
        launch_answers(&node, SECOND / 2).await;
        tick_until_read(&simulator, SECOND).await;
        simulator.shutdown().await;
        node.shutdown().await;
    });
    eprintln!("CHILD SIM CLOCK CHECKED");
}

/// Sim time whose simulator stops: the node's clock holds at the last
/// tick (it never extrapolates from the wall clock), the launch's sync
/// answers hold there too, and a wait for the next tick ends only at the
/// caller's bound. A tick earlier than the last (a simulator restarted or
/// reset) is taken as the new time, without complaint, everywhere. Run in
/// a child process: the stack clock is one per process.
#[test]
fn sim_time_that_stops_holds_at_its_last_tick() {
    run_child("child_sim_time_stops", "CHILD SIM CLOCK CHECKED");
}

/// How far apart two readings of clocks on this host may be: generous
/// for a loaded machine, far below the jumps the test makes.
const SLACK: u64 = 10 * SECOND;
const HOUR: i64 = 3_600_000_000_000;

/// The next tick of `ticks` whose time is `offset` from this host's clock.
async fn tick_at(ticks: &clock::ClockSubscription, offset: i64) -> (u64, Instant) {
    tokio::time::timeout(WAIT, async {
        loop {
            let tick = ticks.on_next_tick().await.unwrap().expect("the node is up");
            let want = clock::os_now_ns().saturating_add_signed(offset);
            if tick.time.abs_diff(want) < SLACK {
                return (tick.time, Instant::now());
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("a tick {offset} ns from this host's clock"))
}

/// A launch's wall clock that jumps an hour forward, then two back: the
/// times it hands out (its ticks, and the offset `synchronize` measures)
/// follow each jump, while what is measured on a steady clock does not:
/// the ticks keep coming at their period (a timer set by wall time would
/// stop for the two hours after the jump back), and the round trip
/// `synchronize` measures stays short. The node's own `now_ns` is its
/// host's clock, which this test does not move (it would take moving the
/// host's clock): the jump is the launch's, served by the test harness's
/// clock (`TestClock::set_offset_ns`).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wall_clock_jump_moves_stamps_not_timers() {
    let (harness, _) =
        Harness::start::<Hooked, _, _>(&[], HarnessConfig::default(), |_, _| async { Ok(()) })
            .await
            .unwrap();
    let node = harness.node_runner().clone();
    let ticks = clock::subscribe(&node).await.unwrap();
    for offset in [0, HOUR, -HOUR, 0] {
        harness.clock().set_offset_ns(offset).unwrap();
        let (mut last, mut at) = tick_at(&ticks, offset).await;
        for _ in 0..10 {
            let (time, now) = tick_at(&ticks, offset).await;
            assert!(
                time > last,
                "offset {offset}: ticks move forward between jumps"
            );
            // The period is 100 ms; a timer set by wall time would wait
            // out the jump (two hours, going back).
            let gap = now - at;
            assert!(
                gap < Duration::from_secs(5),
                "offset {offset}: a tick {gap:?} after the last"
            );
            (last, at) = (time, now);
        }
        let sync = clock::synchronize(&node, Some(WAIT)).await.unwrap();
        assert!(
            sync.offset_ns.abs_diff(offset) < SLACK,
            "offset {offset}: {sync:?}"
        );
        assert!(sync.round_trip_delay_ns < SLACK, "{sync:?}");
    }
    harness.shutdown().await.unwrap();
}
