//! `NodeBuilder::run` in a real child process: it starts, serves, and stops
//! cleanly on SIGTERM and SIGINT, promptly even when its tasks ignore the
//! stop. The child is this test binary itself, re-run with an environment
//! variable that selects `child_node` or `child_stubborn_node`.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use peppy_runtime::codegen::{
    ActionSpec, ConsumedTopicSpec, FormatSpec, OwnerSpec, QosProfile, ServiceSpec, TopicSpec, emit,
    handle_next, next_goal, next_message,
};
use peppy_runtime::wire::keys::{Space, space_selector};
use peppy_runtime::{Error, NodeBuilder, NodeRunner};

use crate::routing::CAM_VIDEO;
use crate::support::{Frame, TestChild, WAIT, hub, namespace, start};

const CHILD_ENV: &str = "PEPPY_RUNTIME_TEST_CHILD";

crate::support::test_node!(
    ChildCamera,
    r#"{ peppy_schema: "node_v1", manifest: { name: "realsense_d405", tag: "v1" },
         interfaces: { conforms_to: [{ name: "depth_camera", tag: "v1" }] },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [CAM_VIDEO], consumes: [], serves: [], actions: []
);

/// Runs only as the child: a camera node emitting until it is stopped.
#[test]
#[ignore = "a child process of the stop tests, which run it; fails run alone"]
fn child_node() {
    // Not a test of its own: run without its parent, it fails rather
    // than pass having checked nothing.
    let args = std::env::var(CHILD_ENV).unwrap_or_else(|_| {
        panic!("a child process: its parent test runs it with {CHILD_ENV} set")
    });
    let args: Vec<String> = serde_json::from_str(&args).unwrap();
    let result = NodeBuilder::<ChildCamera>::new()
        .with_runtime_config(None)
        .with_args(args)
        .run(|_, runner| async move {
            tokio::spawn(async move {
                let mut seq = 0;
                while !runner.cancellation_token().is_cancelled() {
                    let _ = peppy_runtime::codegen::emit(
                        &runner,
                        &CAM_VIDEO,
                        &Frame { seq, data: vec![] },
                    )
                    .await;
                    seq += 1;
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
            });
            eprintln!("CHILD SETUP DONE");
            Ok(())
        });
    result.expect("the node ran and stopped cleanly");
}

const N: FormatSpec = FormatSpec {
    fingerprint: 0x5701,
    canonical: "{n:u32}",
};
static BEATS: TopicSpec = TopicSpec {
    owner: OwnerSpec::Own,
    name: "beats",
    qos: QosProfile::Standard,
    format: N,
};
static PINGS: ConsumedTopicSpec = ConsumedTopicSpec {
    link_id: None,
    owner: OwnerSpec::Any,
    name: "pings",
    qos: QosProfile::Standard,
    format: N,
};
static STATUS: ServiceSpec = ServiceSpec {
    owner: OwnerSpec::Own,
    name: "status",
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

crate::support::test_node!(
    Stubborn,
    r#"{ peppy_schema: "node_v1", manifest: { name: "stubborn", tag: "v1" },
         interfaces: {
           topics: { emits: [{ name: "beats", message_format: { n: "u32" } }],
                     consumes: [{ name: "pings", message_format: { n: "u32" } }] },
           services: { exposes: [{ name: "status", request_message_format: { n: "u32" }, response_message_format: { n: "u32" } }] },
           actions: { exposes: [{ name: "work",
             goal_service: { request_message_format: { n: "u32" } },
             feedback_topic: { message_format: { n: "u32" } },
             result_service: { response_message_format: { n: "u32" } } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [BEATS], consumes: [PINGS], serves: [STATUS], actions: [WORK]
);

/// Spawns the loops node code is written with, ignoring every error (so
/// `ShuttingDown` too), each counting its calls in `calls`.
fn spawn_ignoring_loops(runner: &Arc<NodeRunner>, calls: &Arc<[AtomicU64; 4]>) {
    let (r, c) = (runner.clone(), calls.clone());
    tokio::spawn(async move {
        loop {
            let _ = handle_next::<u32, u32, _>(&r, &STATUS, |_, n| Ok(n)).await;
            c[0].fetch_add(1, Ordering::Relaxed);
        }
    });
    let (r, c) = (runner.clone(), calls.clone());
    tokio::spawn(async move {
        loop {
            let _ = next_message::<u32>(&r, &PINGS, None).await;
            c[1].fetch_add(1, Ordering::Relaxed);
        }
    });
    let (r, c) = (runner.clone(), calls.clone());
    tokio::spawn(async move {
        loop {
            let _ = next_goal::<u32>(&r, &WORK).await;
            c[2].fetch_add(1, Ordering::Relaxed);
        }
    });
    // Emits without pausing only once refused: a loop that waits
    // between emits stands for it while the node runs.
    let (r, c) = (runner.clone(), calls.clone());
    tokio::spawn(async move {
        loop {
            if emit(&r, &BEATS, &7u32).await.is_ok() {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            c[3].fetch_add(1, Ordering::Relaxed);
        }
    });
}

/// Runs only as the child: a node whose tasks ignore the stop (loops that
/// drop every error, and a blocking task that never ends).
#[test]
#[ignore = "a child process of the stop tests, which run it; fails run alone"]
fn child_stubborn_node() {
    // Not a test of its own: run without its parent, it fails rather
    // than pass having checked nothing.
    let args = std::env::var(CHILD_ENV).unwrap_or_else(|_| {
        panic!("a child process: its parent test runs it with {CHILD_ENV} set")
    });
    let args: Vec<String> = serde_json::from_str(&args).unwrap();
    let result = NodeBuilder::<Stubborn>::new()
        .with_runtime_config(None)
        .with_args(args)
        .run(|_, runner| async move {
            spawn_ignoring_loops(&runner, &Arc::new(Default::default()));
            tokio::task::spawn_blocking(|| {
                loop {
                    std::thread::sleep(Duration::from_millis(50));
                }
            });
            eprintln!("CHILD SETUP DONE");
            Ok(())
        });
    result.expect("the node ran and stopped cleanly");
}

/// Starts `entry` as a child node, stops it with `signal` once it is up,
/// and returns how long it took to exit (0) after the signal.
fn stop_child_with(signal: &str, entry: &str) -> Duration {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let hub = rt.block_on(hub());
    let ns = namespace(&format!("proc-{}", signal.to_lowercase()));
    let args = serde_json::to_string(&[
        "cam",
        "--instance-id",
        "child_cam",
        "--namespace",
        &ns,
        "--connect",
        &hub.endpoint,
    ])
    .unwrap();
    let mut child = TestChild::spawn(&format!("process::{entry}"), &[(CHILD_ENV, &args)], &[]);
    child.until(WAIT, "its setup", |l| l.contains("CHILD SETUP DONE"));
    // The child is visible on the network.
    rt.block_on(hub.sees_a_node(&ns));
    child.signal(signal);
    let signalled = Instant::now();
    let exit = child.exit(Duration::from_secs(10));
    let took = signalled.elapsed();
    assert!(
        exit.success(),
        "the child exits 0 after SIG{signal}: {exit:?}"
    );
    assert!(
        child.seen.iter().any(|l| l.contains("shutting down")),
        "{:?}",
        child.seen
    );
    // Its token is withdrawn.
    let live = space_selector(&ns, Space::Live);
    rt.block_on(async {
        let replies = hub
            .session
            .liveliness()
            .get(&live)
            .timeout(Duration::from_secs(1))
            .await
            .unwrap();
        assert!(
            replies.recv_async().await.is_err(),
            "no liveliness token is left behind"
        );
    });
    took
}

#[test]
fn sigterm_stops_the_node_cleanly() {
    stop_child_with("TERM", "child_node");
}

#[test]
fn sigint_stops_the_node_cleanly() {
    stop_child_with("INT", "child_node");
}

#[test]
fn sigint_stops_a_node_whose_tasks_ignore_the_stop_promptly() {
    let took = stop_child_with("INT", "child_stubborn_node");
    eprintln!("the stubborn node exited {took:?} after SIGINT");
    // A failure bound, not a benchmark: without the bounds the child spins
    // until the 10 s deadline.
    assert!(took < Duration::from_secs(3), "took {took:?}");
}

/// After a stop, loops that ignore `ShuttingDown` park between calls
/// instead of spinning, and a waiting call returns at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calls_on_a_stopped_node_pause_instead_of_spinning() {
    let hub = hub().await;
    let ns = namespace("stopped-calls");
    let (_, runner) = start::<Stubborn>(&hub, &ns, "stubborn", &[]).await;
    let waiting = {
        let r = runner.clone();
        tokio::spawn(async move {
            let e = handle_next::<u32, u32, _>(&r, &STATUS, |_, n| Ok(n)).await;
            (e, Instant::now())
        })
    };
    let calls: Arc<[AtomicU64; 4]> = Arc::new(Default::default());
    spawn_ignoring_loops(&runner, &calls);
    tokio::time::sleep(Duration::from_millis(100)).await;
    let before: Vec<u64> = calls.iter().map(|c| c.load(Ordering::Relaxed)).collect();
    assert_eq!(&before[..3], [0, 0, 0], "nothing to serve or read yet");

    let stopped = Instant::now();
    runner.shutdown().await;
    let (e, woke) = tokio::time::timeout(WAIT, waiting).await.unwrap().unwrap();
    assert!(matches!(e, Err(Error::ShuttingDown)), "{e:?}");
    assert!(woke.duration_since(stopped) < Duration::from_secs(2));
    let window = Duration::from_millis(600);
    let base: Vec<u64> = calls.iter().map(|c| c.load(Ordering::Relaxed)).collect();
    tokio::time::sleep(window).await;
    for (i, (c, s)) in calls.iter().zip(&base).enumerate() {
        let n = c.load(Ordering::Relaxed) - s;
        // One call per 100 ms pause; a spinning loop makes millions.
        assert!(
            (1..=12).contains(&n),
            "loop {i} made {n} calls in {window:?}"
        );
    }
    // Refused calls say why.
    let refused = next_message::<u32>(&runner, &PINGS, None).await;
    assert!(matches!(refused, Err(Error::ShuttingDown)), "{refused:?}");
    let refused = emit(&runner, &BEATS, &1u32).await;
    assert!(matches!(refused, Err(Error::ShuttingDown)), "{refused:?}");
}
