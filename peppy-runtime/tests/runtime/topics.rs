//! Topic delivery: nothing lost between calls, external topics, format
//! fingerprints, and a slow reader that holds up nothing else.

use std::time::Duration;

use peppy_runtime::codegen::{
    ConsumedServiceSpec, ConsumedTopicSpec, Decode, DecodeError, Decoder, Encode, FormatSpec,
    OwnerSpec, QosProfile, ServiceSpec, TopicSpec, Writer, call, emit, handle_next, next_message,
    next_payload,
};

use crate::support::{WAIT, hub, namespace, start, start_configured, test_node};
use peppy_runtime::{NodeBuilder, NodeRunner, SharedMemory};

#[derive(Debug, Clone, PartialEq)]
struct Command {
    target: [f64; 3],
    max_velocity: f64,
}

impl Encode for Command {
    fn encode(&self, out: &mut Writer<'_>) {
        self.target.encode(out);
        self.max_velocity.encode(out);
    }
}

impl Decode for Command {
    const MIN_SIZE: usize = 32;
    fn decode(d: &mut Decoder<'_>) -> Result<Self, DecodeError> {
        Ok(Command {
            target: Decode::decode(d)?,
            max_velocity: Decode::decode(d)?,
        })
    }
}

const COMMAND: FormatSpec = FormatSpec {
    fingerprint: 0xc0ffee,
    canonical: "{target_positions:[f64;3],max_velocity:f64}",
};
const OLD_COMMAND: FormatSpec = FormatSpec {
    fingerprint: 0xdead,
    canonical: "{target_positions:[f32;3]}",
};

static COMMANDS_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "joint_commands",
    qos: QosProfile::Reliable,
    format: COMMAND,
};
static OLD_COMMANDS_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "joint_commands",
    qos: QosProfile::Reliable,
    format: OLD_COMMAND,
};
static COMMANDS_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: None,
    owner: OwnerSpec::Any,
    name: "joint_commands",
    qos: QosProfile::Standard,
    format: COMMAND,
};

test_node!(
    Controller,
    r#"{ peppy_schema: "node_v1", manifest: { name: "arm_controller", tag: "v1" },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [COMMANDS_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    Teleop,
    r#"{ peppy_schema: "node_v1", manifest: { name: "teleop_planner", tag: "v2" },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [COMMANDS_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    OldController,
    r#"{ peppy_schema: "node_v1", manifest: { name: "teleop", tag: "v1" },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [OLD_COMMANDS_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    Arm,
    r#"{ peppy_schema: "node_v1", manifest: { name: "robot_arm", tag: "v1" },
         interfaces: { topics: { consumes: [{ name: "joint_commands", message_format: { target_positions: { $type: "array", $items: "f64", $length: 3 }, max_velocity: "f64" } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [COMMANDS_IN], serves: [], actions: []
);

static RELIABLE_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "ticks",
    qos: QosProfile::Reliable,
    format: FormatSpec {
        fingerprint: 7,
        canonical: "{n:u32}",
    },
};
static RELIABLE_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("src"),
    owner: OwnerSpec::Node {
        name: "ticker",
        tag: "v1",
    },
    name: "ticks",
    qos: QosProfile::Reliable,
    format: FormatSpec {
        fingerprint: 7,
        canonical: "{n:u32}",
    },
};

test_node!(
    Ticker,
    r#"{ peppy_schema: "node_v1", manifest: { name: "ticker", tag: "v1" },
         interfaces: { topics: { emits: [{ name: "ticks", qos_profile: "reliable", message_format: { n: "u32" } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [RELIABLE_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    Counter,
    r#"{ peppy_schema: "node_v1", manifest: { name: "counter", tag: "v1", depends_on: { nodes: [{ name: "ticker", tag: "v1", link_id: "src" }] } },
         interfaces: { topics: { consumes: [{ link_id: "src", name: "ticks" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [RELIABLE_IN], serves: [], actions: []
);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn external_topics_come_from_any_emitter_with_a_matching_format() {
    let hub = hub().await;
    let ns = namespace("external");
    let (_, arm) = start::<Arm>(&hub, &ns, "arm", &[]).await;
    let (_, controller) = start::<Controller>(&hub, &ns, "controller", &[]).await;
    let (_, teleop) = start::<Teleop>(&hub, &ns, "teleop", &[]).await;
    let (_, old) = start::<OldController>(&hub, &ns, "old_teleop", &[]).await;
    let sender = tokio::spawn({
        let (controller, teleop, old) = (controller.clone(), teleop.clone(), old.clone());
        async move {
            for i in 0..500u32 {
                let c = Command {
                    target: [f64::from(i), 0.5, -1.0],
                    max_velocity: 1.0,
                };
                emit(&controller, &COMMANDS_OUT, &c).await.unwrap();
                emit(&teleop, &COMMANDS_OUT, &c).await.unwrap();
                // Same topic name, another format: must never be decoded.
                emit(&old, &OLD_COMMANDS_OUT, &[1.0f32, 2.0, 3.0])
                    .await
                    .unwrap();
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        }
    });
    let mut seen = std::collections::BTreeSet::new();
    tokio::time::timeout(WAIT, async {
        while seen.len() < 2 {
            let (from, c): (String, Command) =
                next_message(&arm, &COMMANDS_IN, None).await.unwrap();
            assert_ne!(
                from, "old_teleop",
                "a sender with another format is never decoded"
            );
            assert_eq!(c.target[1..], [0.5, -1.0]);
            seen.insert(from);
        }
    })
    .await
    .expect("commands from both matching emitters arrive");
    assert_eq!(
        seen.into_iter().collect::<Vec<_>>(),
        ["controller", "teleop"]
    );
    sender.abort();
    for r in [&arm, &controller, &teleop, &old] {
        r.shutdown().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nothing_is_lost_between_calls_on_a_reliable_topic() {
    let hub = hub().await;
    let ns = namespace("lossless");
    let (_, counter) = start::<Counter>(&hub, &ns, "counter", &["--bind", "src@ticker"]).await;
    let (_, ticker) = start::<Ticker>(&hub, &ns, "ticker", &[]).await;
    // Wait until the subscription is matched, then send a burst while the
    // consumer is not reading.
    tokio::time::timeout(WAIT, async {
        loop {
            emit(&ticker, &RELIABLE_OUT, &u32::MAX).await.unwrap();
            if tokio::time::timeout(
                Duration::from_millis(100),
                next_message::<u32>(&counter, &RELIABLE_IN, None),
            )
            .await
            .is_ok()
            {
                break;
            }
        }
    })
    .await
    .expect("subscription matched");
    // A 2 000-message burst; the reader starts late and reads slowly at
    // first, so the queue grows past its nominal depth.
    const BURST: u32 = 2_000;
    let sender = tokio::spawn({
        let ticker = ticker.clone();
        async move {
            for n in 0..BURST {
                emit(&ticker, &RELIABLE_OUT, &n).await.unwrap();
            }
        }
    });
    tokio::time::sleep(Duration::from_millis(300)).await;
    let mut got = Vec::new();
    tokio::time::timeout(WAIT, async {
        while got.len() < BURST as usize {
            let (_, n): (String, u32) = next_message(&counter, &RELIABLE_IN, None).await.unwrap();
            if n != u32::MAX {
                got.push(n);
            }
            if got.len() < 50 {
                tokio::time::sleep(Duration::from_millis(2)).await;
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("only {} of {BURST} arrived", got.len()));
    sender.await.unwrap();
    assert_eq!(got, (0..BURST).collect::<Vec<_>>());
    counter.shutdown().await;
    ticker.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn from_core_node_filters_by_launch() {
    let hub = hub().await;
    let ns = namespace("core");
    let (_, counter) = start::<Counter>(&hub, &ns, "counter", &["--bind", "src@ticker"]).await;
    let (_, ticker) = start::<Ticker>(&hub, &ns, "ticker", &[]).await;
    let sender = tokio::spawn({
        let ticker = ticker.clone();
        async move {
            for n in 0..400u32 {
                let _ = emit(&ticker, &RELIABLE_OUT, &n).await;
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        }
    });
    // Standalone instances belong to the `standalone` core node.
    let (_, n) = tokio::time::timeout(
        WAIT,
        next_message::<u32>(&counter, &RELIABLE_IN, Some("standalone")),
    )
    .await
    .unwrap()
    .unwrap();
    assert!(n < 400);
    let other = tokio::time::timeout(
        Duration::from_millis(500),
        next_message::<u32>(&counter, &RELIABLE_IN, Some("another-launch")),
    )
    .await;
    assert!(other.is_err(), "no message is from another launch");
    sender.abort();
    counter.shutdown().await;
    ticker.shutdown().await;
}

const FLOOD_FRAME: FormatSpec = FormatSpec {
    fingerprint: 0xf1,
    canonical: "{seq:u32,data:[u8]}",
};
const BEAT: FormatSpec = FormatSpec {
    fingerprint: 0xb1,
    canonical: "{n:u32}",
};
const PING_REQ: FormatSpec = FormatSpec {
    fingerprint: 0x91,
    canonical: "{x:u32}",
};
const PING_RESP: FormatSpec = FormatSpec {
    fingerprint: 0x92,
    canonical: "{y:u32}",
};
static FLOOD_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "frames",
    qos: QosProfile::Reliable,
    format: FLOOD_FRAME,
};
static BEAT_OUT: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "beats",
    qos: QosProfile::Reliable,
    format: BEAT,
};
const FLOOD_NODE: OwnerSpec = OwnerSpec::Node {
    name: "flood",
    tag: "v1",
};
static FLOOD_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("src"),
    owner: FLOOD_NODE,
    name: "frames",
    qos: QosProfile::Reliable,
    format: FLOOD_FRAME,
};
static BEAT_IN: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("src"),
    owner: FLOOD_NODE,
    name: "beats",
    qos: QosProfile::Reliable,
    format: BEAT,
};
static PING: ServiceSpec = ServiceSpec {
    owner: OwnerSpec::Own,
    name: "ping",
    request: PING_REQ,
    response: PING_RESP,
};
static PING_STATION: ConsumedServiceSpec = ConsumedServiceSpec {
    link_id: "st",
    owner: OwnerSpec::Node {
        name: "station",
        tag: "v1",
    },
    name: "ping",
    request: PING_REQ,
    response: PING_RESP,
};

test_node!(
    Flood,
    r#"{ peppy_schema: "node_v1", manifest: { name: "flood", tag: "v1", depends_on: { nodes: [{ name: "station", tag: "v1", link_id: "st" }] } },
         interfaces: { topics: { emits: [
             { name: "frames", qos_profile: "reliable", message_format: { seq: "u32", data: "bytes" } },
             { name: "beats", qos_profile: "reliable", message_format: { n: "u32" } } ] },
           services: { consumes: [{ link_id: "st", name: "ping" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [FLOOD_OUT, BEAT_OUT], consumes: [], serves: [], actions: []
);

test_node!(
    Station,
    r#"{ peppy_schema: "node_v1", manifest: { name: "station", tag: "v1", depends_on: { nodes: [{ name: "flood", tag: "v1", link_id: "src" }] } },
         interfaces: { topics: { consumes: [{ link_id: "src", name: "frames" }, { link_id: "src", name: "beats" }] },
           services: { exposes: [{ name: "ping", request_message_format: { x: "u32" }, response_message_format: { y: "u32" } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [FLOOD_IN, BEAT_IN], serves: [PING], actions: []
);

static FLOOD_ALSO: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: Some("also"),
    owner: FLOOD_NODE,
    name: "frames",
    qos: QosProfile::Reliable,
    format: FLOOD_FRAME,
};

test_node!(
    Watch,
    r#"{ peppy_schema: "node_v1", manifest: { name: "watch", tag: "v1", depends_on: { nodes: [
             { name: "flood", tag: "v1", link_id: "src" }, { name: "flood", tag: "v1", link_id: "also" } ] } },
         interfaces: { topics: { consumes: [
             { link_id: "src", name: "frames" }, { link_id: "also", name: "frames" }, { link_id: "src", name: "beats" } ] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [FLOOD_IN, FLOOD_ALSO, BEAT_IN], serves: [], actions: []
);

/// One slow reader of one reliable topic must not hold up the rest of its
/// node: Zenoh delivers every subscription and query of a session on the
/// same threads, so an inbox that blocked there when full would stall the
/// node's other topics and services (and, through TCP, the sender).
///
/// The frames go as bytes: through shared memory, Zenoh 1.10.2 drops a
/// frame now and then on a starved host (docs/FAULTS.md, L2), which the
/// test below reproduces by hand.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reader_that_never_reads_one_topic_stalls_nothing_else() {
    a_reader_that_never_reads(SharedMemory::off(), "slow-reader").await;
}

/// The test above with the producer's frames in shared memory: Zenoh's
/// watchdog, which has no setting, lapses now and then on a starved host
/// and Zenoh drops the frames the reader had not mapped yet
/// (docs/FAULTS.md, L2, with how often). Not in CI, where it failed a run;
/// run by hand, several at once, to see whether a Zenoh upgrade ends it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "FAULTS L2: Zenoh 1.10.2 drops shared-memory frames now and then on a starved host; run by hand"]
async fn a_reader_that_never_reads_loses_no_frame_in_shared_memory() {
    a_reader_that_never_reads(SharedMemory::default(), "slow-reader-shm").await;
}

async fn a_reader_that_never_reads(shm: SharedMemory, ns: &str) {
    let hub = hub().await;
    let ns = namespace(ns);
    let (_, station) = start::<Station>(&hub, &ns, "station", &["--bind", "src@flood"]).await;
    let (_, flood) =
        start_configured::<Flood>(&hub, &ns, "flood", &["--bind", "st@station"], |b| {
            b.shared_memory(shm)
        })
        .await;
    tokio::spawn({
        let station = station.clone();
        async move {
            while handle_next::<u32, u32, _>(&station, &PING, |_, x| Ok(x + 1))
                .await
                .is_ok()
            {}
        }
    });
    beats_pass(&flood, &station).await;
    // 40 MiB on `frames`, which the station does not read: far beyond its
    // inbox's nominal depth (256) and every socket buffer on the way.
    const FRAMES: u32 = 10_000;
    let frame = |seq| crate::support::Frame {
        seq,
        data: vec![(seq % 251) as u8; 4096],
    };
    // The first frame must be queued before the flood can prove anything.
    emit(&flood, &FLOOD_OUT, &frame(0)).await.unwrap();
    tokio::time::timeout(WAIT, async {
        for seq in 1..FRAMES {
            emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
        }
    })
    .await
    .expect("the sender is never held up by a reader that does not read");
    // While all of it sits unread, beats and service calls still pass.
    for n in 0..20u32 {
        emit(&flood, &BEAT_OUT, &n).await.unwrap();
        let (_, beat) = tokio::time::timeout(WAIT, async {
            loop {
                let got = next_message::<u32>(&station, &BEAT_IN, None).await.unwrap();
                if got.1 != u32::MAX {
                    return got;
                }
            }
        })
        .await
        .expect("a beat passes while another topic is unread");
        assert_eq!(beat, n);
        let reply = tokio::time::timeout(WAIT, call::<u32, u32>(&flood, &PING_STATION, WAIT, &n))
            .await
            .expect("a service call is answered while another topic is unread")
            .unwrap();
        assert_eq!((reply.instance_id.as_str(), reply.data), ("station", n + 1));
    }
    // Once the reader reads, every frame is there, in order, intact.
    tokio::time::timeout(WAIT, async {
        for seq in 0..FRAMES {
            let (_, got): (String, crate::support::Frame) =
                next_message(&station, &FLOOD_IN, None).await.unwrap();
            assert_eq!(got, frame(seq), "frame {seq}");
        }
    })
    .await
    .expect("every frame is kept for the reader");
    station.shutdown().await;
    flood.shutdown().await;
}

/// Waits until a beat from `flood` reaches `station`: both subscriptions
/// of the station are matched.
async fn beats_pass(flood: &NodeRunner, station: &NodeRunner) {
    tokio::time::timeout(WAIT, async {
        loop {
            emit(flood, &BEAT_OUT, &u32::MAX).await.unwrap();
            let beat = tokio::time::timeout(
                Duration::from_millis(100),
                next_message::<u32>(station, &BEAT_IN, None),
            );
            if beat.await.is_ok() {
                break;
            }
        }
    })
    .await
    .expect("subscription matched");
}

/// Starts `P` with these shared-memory settings.
pub(crate) async fn start_shm<P: peppy_runtime::codegen::NodeParameters>(
    hub: &crate::support::Hub,
    ns: &str,
    instance: &str,
    bind: &str,
    shm: SharedMemory,
) -> std::sync::Arc<NodeRunner> {
    let configure = |b: NodeBuilder<P>| b.shared_memory(shm);
    start_configured(hub, ns, instance, &["--bind", bind], configure)
        .await
        .1
}

/// A frame whose bytes differ from one frame to the next.
pub(crate) fn patterned(seq: u32, len: usize) -> crate::support::Frame {
    crate::support::Frame {
        seq,
        data: (0..len)
            .map(|i| (i as u32).wrapping_mul(31).wrapping_add(seq) as u8)
            .collect(),
    }
}

/// Large frames are written once into the producer's shared memory and read
/// in place by a reader on this host; small ones, a topic turned off and a
/// reader whose Zenoh has shared memory off (as on another host) get the
/// same bytes the ordinary way.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn large_frames_travel_through_shared_memory_and_everything_else_as_bytes() {
    let hub = hub().await;
    let ns = namespace("shm");
    let on = SharedMemory::default();
    let station = start_shm::<Station>(&hub, &ns, "station", "src@flood", on).await;
    let remote = start_shm::<Station>(&hub, &ns, "remote", "src@flood", SharedMemory::off()).await;
    let flood = start_shm::<Flood>(&hub, &ns, "flood", "st@station", on).await;
    beats_pass(&flood, &station).await;
    beats_pass(&flood, &remote).await;
    let in_shm = |r: &NodeRunner| r.received_in_shared_memory(&FLOOD_IN).unwrap();

    // (frame, this topic's threshold when it is sent, whether it travels in
    // shared memory to the local reader)
    let default = Some(SharedMemory::DEFAULT_THRESHOLD);
    let steps = [
        (patterned(0, 1 << 20), default, true),
        (patterned(1, 100), default, false),
        (patterned(2, 4 << 20), default, true),
        (patterned(3, SharedMemory::DEFAULT_THRESHOLD), default, true),
        // This topic only: off, then from 64 bytes.
        (patterned(4, 1 << 20), None, false),
        (patterned(5, 100), Some(64), true),
    ];
    let mut shared = 0;
    for (frame, threshold, in_place) in &steps {
        flood.set_shm_threshold(&FLOOD_OUT, *threshold);
        emit(&flood, &FLOOD_OUT, frame).await.unwrap();
        tokio::time::timeout(WAIT, async {
            let (from, got): (String, crate::support::Frame) =
                next_message(&station, &FLOOD_IN, None).await.unwrap();
            assert_eq!((from.as_str(), got.seq), ("flood", frame.seq));
            assert!(got == *frame, "frame {} arrives intact", frame.seq);
            let (_, got): (String, crate::support::Frame) =
                next_message(&remote, &FLOOD_IN, None).await.unwrap();
            assert!(
                got == *frame,
                "frame {} reaches the remote reader intact",
                frame.seq
            );
        })
        .await
        .expect("the frame arrives");
        shared += u64::from(*in_place);
        assert_eq!(in_shm(&station), shared, "after frame {}", frame.seq);
    }
    flood.set_shm_threshold(&FLOOD_OUT, default);
    assert_eq!(in_shm(&remote), 0, "shared memory off: nothing mapped");
    assert_eq!(flood.shared_memory(), on);

    // Undecoded, a frame's pixels are a slice of the producer's pages.
    let frame = patterned(6, 1 << 20);
    emit(&flood, &FLOOD_OUT, &frame).await.unwrap();
    let (_, payload) = tokio::time::timeout(WAIT, next_payload(&station, &FLOOD_IN, None))
        .await
        .expect("the frame arrives")
        .unwrap();
    assert!(payload.in_shared_memory());
    let bytes = payload.bytes();
    assert!(matches!(bytes, std::borrow::Cow::Borrowed(_)), "not copied");
    let mut d = Decoder::new(&bytes);
    assert_eq!(u32::decode(&mut d).unwrap(), 6);
    let n = d.count(1).unwrap();
    let pixels = d.take(n).unwrap();
    assert!(pixels == frame.data.as_slice());
    assert!(bytes.as_ptr_range().contains(&pixels.as_ptr()));
    assert!(payload.decode::<crate::support::Frame>().unwrap() == frame);
    for r in [station, remote, flood] {
        r.shutdown().await;
    }
}

/// Starts `P` with a directory for direct links.
async fn start_direct<P: peppy_runtime::codegen::NodeParameters>(
    hub: &crate::support::Hub,
    ns: &str,
    instance: &str,
    bind: &str,
    links: &str,
) -> std::sync::Arc<NodeRunner> {
    let args = ["--bind", bind, "--direct-links", links];
    start_configured::<P>(hub, ns, instance, &args, |b| b)
        .await
        .1
}

/// Reads `n` frames from `reader`, checking they come in order from `first`
/// and intact (`frame(seq)` rebuilds each as sent).
async fn read_in_order(
    reader: &NodeRunner,
    first: u32,
    n: u32,
    frame: impl Fn(u32) -> crate::support::Frame,
) {
    read_entry_in_order(reader, &FLOOD_IN, first, n, frame).await;
}

/// [`read_in_order`] from the consumed entry `entry`.
async fn read_entry_in_order(
    reader: &NodeRunner,
    entry: &'static ConsumedTopicSpec,
    first: u32,
    n: u32,
    frame: impl Fn(u32) -> crate::support::Frame,
) {
    tokio::time::timeout(WAIT, async {
        for seq in first..first + n {
            let (_, got): (String, crate::support::Frame) =
                next_message(reader, entry, None).await.unwrap();
            assert_eq!(
                got.seq,
                seq,
                "{}: frames come once each, in order",
                reader.instance_id()
            );
            assert!(got == frame(seq), "frame {seq} arrives intact");
        }
    })
    .await
    .expect("every frame arrives");
}

/// Two nodes given one directory for direct links (as `up` gives the
/// instances of one launch) hand small messages over it (through the
/// socket, or its shared memory from 16 KiB) and the largest ones (and
/// bursts) through Zenoh, and the reader gets each once, in order,
/// across the switch from Zenoh to the link and back when the producer
/// restarts; a reader without the directory gets the same through Zenoh.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn direct_links_hand_every_message_once_in_order() {
    let hub = hub().await;
    let ns = namespace("direct");
    let dir = tempfile::tempdir().unwrap();
    let links = dir.path().display().to_string();
    let on = SharedMemory::default();
    let station = start_direct::<Station>(&hub, &ns, "station", "src@flood", &links).await;
    let remote = start_shm::<Station>(&hub, &ns, "remote", "src@flood", on).await;
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    beats_pass(&flood, &remote).await;
    // Every seventh frame is larger than a link's shared memory takes: it
    // goes through Zenoh (its shared memory) and takes its place among
    // the others the link carries, one in seven of those through the
    // link's shared memory.
    let frame = |seq: u32| {
        let len = match seq % 7 {
            3 => 1600 << 10,
            5 => 40 << 10,
            _ => 16 + (seq as usize * 37) % 2000,
        };
        patterned(seq, len)
    };
    let direct = |r: &NodeRunner| r.received_over_direct_links(&FLOOD_IN).unwrap();

    // A burst: the first frame links the reader, mid-burst.
    for seq in 0..300 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
    }
    read_in_order(&station, 0, 300, frame).await;
    read_in_order(&remote, 0, 300, frame).await;
    assert_eq!(direct(&remote), 0, "no directory, no direct link");

    // Linked, and a millisecond apart (no burst): every small frame comes
    // over the link, and a 40 KiB one whenever the link's reader has read
    // the frame before it.
    let before = direct(&station);
    for seq in 300..400 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    read_in_order(&station, 300, 100, frame).await;
    read_in_order(&remote, 300, 100, frame).await;
    let small = (300..400).filter(|s| s % 7 != 3 && s % 7 != 5).count() as u64;
    let medium = (300..400).filter(|s| s % 7 == 5).count() as u64;
    let linked = direct(&station) - before;
    assert!(
        (small..=small + medium).contains(&linked),
        "{linked} over the link: every small frame, and none of the largest"
    );
    assert!(
        std::fs::read_dir(dir.path()).unwrap().count() >= 1,
        "the producer's socket is in the directory"
    );

    // The producer restarts: Zenoh until the new one is linked, then the
    // link again.
    flood.shutdown().await;
    drop(flood);
    // Beats left from the first producer would pass for the new one's.
    for reader in [&station, &remote] {
        while tokio::time::timeout(
            Duration::from_millis(200),
            next_message::<u32>(reader, &BEAT_IN, None),
        )
        .await
        .is_ok()
        {}
    }
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    beats_pass(&flood, &remote).await;
    let before = direct(&station);
    for seq in 400..500 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
    }
    read_in_order(&station, 400, 100, frame).await;
    read_in_order(&remote, 400, 100, frame).await;
    tokio::time::timeout(WAIT, async {
        let mut seq = 500;
        while direct(&station) == before {
            emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
            read_in_order(&station, seq, 1, frame).await;
            seq += 1;
        }
    })
    .await
    .expect("the restarted producer is read over a direct link again");
    for r in [station, remote, flood] {
        r.shutdown().await;
    }
}

/// Whether Zenoh knows a subscriber of `flood`'s frames (the hub asks, as
/// a publisher of the same key).
async fn frames_subscribed(hub: &crate::support::Hub, ns: &str) -> bool {
    use peppy_runtime::wire::keys::{Channel, Owner, entry_key};
    let owner = Owner::Node {
        name: "flood",
        tag: "v1",
    };
    let key = entry_key(ns, Channel::Topic, &owner, "frames", "standalone", "flood");
    let probe = hub.session.declare_publisher(key).await.unwrap();
    probe.matching_status().await.unwrap().matching()
}

/// Waits (bounded) until the hub sees `flood`'s frames subscribed or not.
async fn until_frames_subscribed(hub: &crate::support::Hub, ns: &str, yes: bool, what: &str) {
    tokio::time::timeout(WAIT, async {
        while frames_subscribed(hub, ns).await != yes {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .expect(what);
}

/// A consumer pinned to its producer, once linked, reads it through the
/// link and the producer's side key alone: no subscription of the topic's
/// own key is left (Zenoh no longer brings it a copy of what the link
/// carries), and every message still comes once, in order, whether the
/// link carries it (small, or through its shared memory, where the
/// largest are encoded when they come one at a time) or Zenoh does (in a
/// burst, or while the link's memory is full). When the producer stops,
/// the consumer subscribes to the topic's key again, and a restarted
/// producer is read from its first message and linked anew.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pinned_consumer_on_a_link_reads_through_it_and_its_side_key_alone() {
    let hub = hub().await;
    let ns = namespace("direct-sole");
    let dir = tempfile::tempdir().unwrap();
    let links = dir.path().display().to_string();
    let station = start_direct::<Station>(&hub, &ns, "station", "src@flood", &links).await;
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    assert!(
        frames_subscribed(&hub, &ns).await,
        "read through Zenoh first"
    );
    let frame = |seq: u32| {
        let len = match seq % 5 {
            1 => 1600 << 10,
            3 => 40 << 10,
            _ => 16 + (seq as usize * 37) % 2000,
        };
        patterned(seq, len)
    };
    let direct = |r: &NodeRunner| r.received_over_direct_links(&FLOOD_IN).unwrap();

    // Linked: the topic's own key is left once the link's numbers are
    // known.
    let linked = "the consumer reads through the link and side key alone";
    let mut seq = until_sole(&hub, &ns, (&flood, &station), (0, 0), frame, linked).await;

    // Paced, then in a burst: every frame once, in order, the small ones
    // over the link.
    let before = direct(&station);
    for s in seq..seq + 50 {
        emit(&flood, &FLOOD_OUT, &frame(s)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    read_in_order(&station, seq, 50, frame).await;
    let small = (seq..seq + 50).filter(|s| s % 5 != 1 && s % 5 != 3).count() as u64;
    assert!(
        direct(&station) - before >= small,
        "every small frame over the link"
    );
    seq += 50;
    // One at a time, each read before the next (a round trip's pace): the
    // largest frames come over the link too, encoded straight into its
    // shared memory.
    let large = |seq: u32| patterned(seq, 1600 << 10);
    let before = direct(&station);
    for s in seq..seq + 10 {
        emit(&flood, &FLOOD_OUT, &large(s)).await.unwrap();
        read_in_order(&station, s, 1, large).await;
    }
    assert_eq!(
        direct(&station) - before,
        10,
        "every large frame over the link"
    );
    seq += 10;
    for s in seq..seq + 300 {
        emit(&flood, &FLOOD_OUT, &frame(s)).await.unwrap();
    }
    read_in_order(&station, seq, 300, frame).await;
    seq += 300;
    // A flood of small frames, made beforehand so they leave back to
    // back: the link's writer gathers them, and every one comes over it.
    let tiny = |seq: u32| patterned(seq, 8);
    let burst: Vec<_> = (seq..seq + 2000).map(tiny).collect();
    let before = direct(&station);
    for f in &burst {
        emit(&flood, &FLOOD_OUT, f).await.unwrap();
    }
    read_in_order(&station, seq, 2000, tiny).await;
    assert_eq!(direct(&station) - before, 2000, "a flood over the link");
    seq += 2000;
    assert!(!frames_subscribed(&hub, &ns).await, "still on the side key");

    // The producer stops: its last messages come, and the consumer goes
    // back to the topic's key.
    for s in seq..seq + 5 {
        emit(&flood, &FLOOD_OUT, &frame(s)).await.unwrap();
    }
    flood.shutdown().await;
    drop(flood);
    read_in_order(&station, seq, 5, frame).await;
    until_frames_subscribed(&hub, &ns, true, "back on the topic's key").await;
    while tokio::time::timeout(
        Duration::from_millis(200),
        next_message::<u32>(&station, &BEAT_IN, None),
    )
    .await
    .is_ok()
    {}

    // Restarted, it is read from its first message, and linked again.
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    let before = direct(&station);
    for s in 0..20 {
        emit(&flood, &FLOOD_OUT, &frame(s)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    read_in_order(&station, 0, 20, frame).await;
    let relinked = "the restarted producer is read through a link and side key alone";
    until_sole(&hub, &ns, (&flood, &station), (20, before), frame, relinked).await;
    for r in [station, flood] {
        r.shutdown().await;
    }
}

/// Emits `flood`'s frames one at a time from `seq`, `station` reading each
/// in order, until `station` has read more than `before` over direct
/// links and no longer subscribes to the topic's own key: the next
/// frame's number. It fails with `what` after [`WAIT`].
async fn until_sole(
    hub: &crate::support::Hub,
    ns: &str,
    (flood, station): (&NodeRunner, &NodeRunner),
    (mut seq, before): (u32, u64),
    frame: impl Fn(u32) -> crate::support::Frame + Copy,
    what: &str,
) -> u32 {
    let linked = || station.received_over_direct_links(&FLOOD_IN).unwrap() > before;
    tokio::time::timeout(WAIT, async {
        while !linked() || frames_subscribed(hub, ns).await {
            emit(flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
            read_in_order(station, seq, 1, frame).await;
            seq += 1;
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        seq
    })
    .await
    .expect(what)
}

/// Messages from 16 KiB go over a link through its shared memory and are
/// read in place: a reader that keeps them holds the producer's regions,
/// the producer never writes over one held, and once the reader holds too
/// much the rest come through Zenoh; let go, the link carries them again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn messages_a_reader_keeps_from_a_links_shared_memory_stay_intact() {
    let hub = hub().await;
    let ns = namespace("direct-held");
    let dir = tempfile::tempdir().unwrap();
    let links = dir.path().display().to_string();
    let station = start_direct::<Station>(&hub, &ns, "station", "src@flood", &links).await;
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    let direct = |r: &NodeRunner| r.received_over_direct_links(&FLOOD_IN).unwrap();
    let frame = |seq: u32| patterned(seq, 256 << 10);

    // Linked first, with one frame read and dropped.
    tokio::time::timeout(WAIT, async {
        let mut seq = 0;
        while direct(&station) == 0 {
            emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
            read_in_order(&station, seq, 1, frame).await;
            seq += 1;
        }
    })
    .await
    .expect("the reader is linked");

    // 100 frames of 256 KiB kept undecoded: 25 MiB, more than a link
    // holds for its reader, so the later ones come through Zenoh.
    let (first, before) = (1000, direct(&station));
    let mut kept = Vec::new();
    for seq in first..first + 100 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
        let (_, payload) = tokio::time::timeout(WAIT, next_payload(&station, &FLOOD_IN, None))
            .await
            .expect("the frame arrives")
            .unwrap();
        kept.push(payload);
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let over_link = direct(&station) - before;
    assert!(
        (10..100).contains(&over_link),
        "{over_link} of 100 kept frames over the link: some, until it held too much"
    );
    // Read in place, from the link's memory or (once it held too much)
    // Zenoh's.
    assert!(kept.iter().all(|p| p.in_shared_memory()));
    // Every message in between was written by the producer; none of them
    // over a region still held.
    for (seq, payload) in (first..).zip(&kept) {
        let got: crate::support::Frame = payload.decode().unwrap();
        assert!(got == frame(seq), "kept frame {seq} is intact");
    }
    drop(kept);

    // Let go: the link carries them again.
    let before = direct(&station);
    for seq in 2000..2020 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
        read_in_order(&station, seq, 1, frame).await;
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    // A frame goes over the link only if the link's reader has drained
    // the one before (a moment later under load): most, not all.
    let again = direct(&station) - before;
    assert!(again >= 15, "{again} of 20 over the link again");
    for r in [station, flood] {
        r.shutdown().await;
    }
}

/// A consumer whose shared memory is off still reads its producer over a
/// direct link, through the socket: nothing it reads is in shared memory,
/// the link's or Zenoh's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_link_to_a_consumer_with_shared_memory_off_carries_bytes() {
    let hub = hub().await;
    let ns = namespace("direct-noshm");
    let dir = tempfile::tempdir().unwrap();
    let links = dir.path().display().to_string();
    let args = ["--bind", "src@flood", "--direct-links", links.as_str()];
    let off = |b: NodeBuilder<Station>| b.shared_memory(SharedMemory::off());
    let (_, station) = start_configured::<Station>(&hub, &ns, "station", &args, off).await;
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &station).await;
    let direct = |r: &NodeRunner| r.received_over_direct_links(&FLOOD_IN).unwrap();
    let frame = |seq: u32| patterned(seq, 40 << 10);
    tokio::time::timeout(WAIT, async {
        let mut seq = 0;
        while direct(&station) < 20 {
            emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
            let (_, payload) = next_payload(&station, &FLOOD_IN, None).await.unwrap();
            assert!(!payload.in_shared_memory(), "frame {seq} is bytes");
            let got: crate::support::Frame = payload.decode().unwrap();
            assert!(got == frame(seq), "frame {seq} arrives intact");
            seq += 1;
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await
    .expect("the consumer is linked and reads over its link");
    assert_eq!(station.received_in_shared_memory(&FLOOD_IN).unwrap(), 0);
    for r in [station, flood] {
        r.shutdown().await;
    }
}

/// A consumer reading one producer's topic through two entries opens one
/// direct link to it: the producer writes each message once for that
/// consumer, and each entry gets every message once, in order.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_entries_on_one_key_share_one_direct_link() {
    let hub = hub().await;
    let ns = namespace("direct-shared");
    let dir = tempfile::tempdir().unwrap();
    let links = dir.path().display().to_string();
    let args = [
        "--bind",
        "src@flood",
        "--bind",
        "also@flood",
        "--direct-links",
        links.as_str(),
    ];
    let watch = start_configured::<Watch>(&hub, &ns, "watch", &args, |b| b)
        .await
        .1;
    let flood = start_direct::<Flood>(&hub, &ns, "flood", "st@station", &links).await;
    beats_pass(&flood, &watch).await;
    let frame = |seq: u32| patterned(seq, 16 + seq as usize % 300);
    // A millisecond apart (no burst): the first frames link the entries,
    // the rest come over the link too.
    for seq in 0..200 {
        emit(&flood, &FLOOD_OUT, &frame(seq)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    for entry in [&FLOOD_IN, &FLOOD_ALSO] {
        read_entry_in_order(&watch, entry, 0, 200, frame).await;
        let direct = watch.received_over_direct_links(entry).unwrap();
        assert!(
            direct > 100,
            "{}: {direct} of 200 over the link",
            entry.link_id.unwrap()
        );
    }
    assert_eq!(
        flood.direct_links_served(&FLOOD_OUT),
        1,
        "one link to the consumer, for both of its entries"
    );
    for r in [watch, flood] {
        r.shutdown().await;
    }
}
