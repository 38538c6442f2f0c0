//! The stack clock of a launch: `up` publishes wall ticks and answers sync
//! for its namespace, follows sim ticks, and tells each instance whether
//! it follows sim time (`framework.use_sim_time`). Two instances of one
//! node, one on sim time: nodes started in this process from the very
//! runtime configs the launch wrote read their clocks.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use peppy_runtime::clock::{self, ClockSource, ClockTick};
use peppy_runtime::codegen::{NodeDescriptor, NodeParameters};
use peppy_runtime::wire::keys::{clock_sync_key, clock_tick_key};
use peppy_runtime::{Error, NodeBuilder, StartupConfig};

const WAIT: Duration = Duration::from_secs(30);

const NODE: &str = r#"{ "peppy_schema": "node_v1", "manifest": { "name": "clocked", "tag": "v1" },
    "execution": { "language": "shell", "run_cmd": ["sh", "-c", "exec sleep 1000"] } }"#;

/// The `clocked` node, run in this process.
#[derive(Debug, serde::Deserialize)]
struct Clocked {}

impl NodeParameters for Clocked {
    fn descriptor() -> &'static NodeDescriptor {
        static D: std::sync::LazyLock<NodeDescriptor> = std::sync::LazyLock::new(|| {
            let (doc, _) = peppy_schema::NodeDoc::parse("peppy.json5", NODE).expect("valid node");
            NodeDescriptor {
                model: Box::leak(peppy_schema::NodeModel::of(&doc).to_json().into_boxed_str()),
                document_path: "clocked/peppy.json5",
                emitted_topics: &[],
                consumed_topics: &[],
                exposed_services: &[],
                exposed_actions: &[],
            }
        });
        &D
    }
}

fn free_endpoint() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("tcp/127.0.0.1:{port}")
}

/// The runtime config the launch wrote for `instance`, once written.
fn runtime_config(dir: &Path, instance: &str) -> PathBuf {
    let deadline = Instant::now() + WAIT;
    loop {
        let found = std::fs::read_dir(dir.join(".peppy/runs"))
            .into_iter()
            .flatten()
            .flatten()
            .map(|run| run.path().join(format!("{instance}.json")))
            .find(|p| p.exists());
        if let Some(path) = found {
            return path;
        }
        assert!(
            Instant::now() < deadline,
            "no runtime config for {instance}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn os_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}

fn close(a: u64, b: u64) -> bool {
    a.abs_diff(b) < 1_000_000_000
}

fn stop(mut child: Child) -> (i32, String) {
    assert!(
        Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + WAIT;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("peppy-launch did not stop");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (status.code().unwrap_or(-1), reader.join().unwrap())
}

#[test]
fn a_launch_serves_wall_and_sim_time_and_each_instance_follows_its_own() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("clocked")).unwrap();
    std::fs::write(dir.path().join("clocked/peppy.json5"), NODE).unwrap();
    let launcher = r#"{ peppy_schema: "launcher/v1", deployments: [
        { source: { local: "clocked" }, instances: [
            { instance_id: "on_sim", framework: { use_sim_time: true } },
            { instance_id: "on_wall" } ] } ] }"#;
    std::fs::write(dir.path().join("stack.json5"), launcher).unwrap();
    let endpoint = free_endpoint();
    let ns = format!("clock-{}", std::process::id());
    let up = Command::new(env!("CARGO_BIN_EXE_peppy-launch"))
        .args([
            "up",
            "stack.json5",
            "--listen",
            &endpoint,
            "--namespace",
            &ns,
        ])
        .current_dir(dir.path())
        .env("NO_COLOR", "1")
        .env_remove("PEPPY_REPOSITORIES")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let sim_config = runtime_config(dir.path(), "on_sim");
    let wall_config = runtime_config(dir.path(), "on_wall");
    let read = |p: &Path| -> StartupConfig {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    assert!(read(&sim_config).use_sim_time);
    assert!(!read(&wall_config).use_sim_time);
    // Only what differs from a node's defaults is written.
    let raw: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&wall_config).unwrap()).unwrap();
    assert!(raw.get("use_sim_time").is_none(), "{raw}");

    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        tokio::time::timeout(WAIT, async {
            let start = |path: PathBuf| {
                NodeBuilder::<Clocked>::new()
                    .with_args(["clocked"])
                    .with_runtime_config(Some(path))
                    .start()
            };
            let (_, wall) = start(wall_config).await.unwrap();
            let (_, sim) = start(sim_config).await.unwrap();
            assert!(sim.use_sim_time() && !wall.use_sim_time());

            // Wall time: this host's clock, the launch's on the same host.
            clock::init(&wall).await.unwrap();
            assert!(close(clock::now_ns().unwrap(), os_now()));
            let sync = clock::synchronize(&wall, None).await.unwrap();
            assert!(sync.offset_ns.unsigned_abs() < 1_000_000_000, "{sync:?}");
            assert!(sync.round_trip_delay_ns > 0, "{sync:?}");
            let ticks = clock::subscribe(&wall).await.unwrap();
            let first = ticks.on_next_tick().await.unwrap().unwrap();
            let second = ticks.on_next_tick().await.unwrap().unwrap();
            assert!(close(first.time, os_now()) && second.time > first.time);

            // Sim time: nothing before the simulator's first tick, on
            // either side; then its time.
            clock::init(&sim).await.unwrap();
            assert!(matches!(clock::now_ns(), Err(Error::ClockNotReady)));
            let e = clock::synchronize(&sim, None).await.unwrap_err();
            assert!(matches!(e, Error::ClockNotReady), "{e:?}");
            let sim_ticks = clock::subscribe(&sim).await.unwrap();
            let mut config = zenoh::Config::default();
            config.insert_json5("mode", "\"client\"").unwrap();
            config
                .insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
                .unwrap();
            config
                .insert_json5("scouting/multicast/enabled", "false")
                .unwrap();
            let simulator = zenoh::open(config).await.unwrap();
            let sim_key = clock_tick_key(&ns, ClockSource::Sim);
            let t = 7_000_000_000u64;
            let tick = loop {
                simulator
                    .put(&sim_key, t.to_le_bytes().to_vec())
                    .await
                    .unwrap();
                if let Ok(tick) =
                    tokio::time::timeout(Duration::from_millis(100), sim_ticks.on_next_tick()).await
                {
                    break tick.unwrap();
                }
            };
            assert_eq!(tick, Some(ClockTick { time: t }));
            while clock::now_ns().ok() != Some(t) {
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
            let sync = loop {
                match clock::synchronize(&sim, None).await {
                    Ok(s) => break s,
                    Err(Error::ClockNotReady) => {
                        tokio::time::sleep(Duration::from_millis(20)).await
                    }
                    Err(e) => panic!("{e}"),
                }
            };
            assert_eq!(
                (sync.raw.server_recv_time, sync.raw.server_send_time),
                (t, t)
            );
            assert_eq!(sync.offset_ns, 0);
            // The wall instance's clock is still the wall.
            let tick = ticks.on_next_tick().await.unwrap().unwrap();
            assert!(close(tick.time, os_now()), "{tick:?}");
            // A malformed query is refused, not answered.
            let replies = simulator
                .get(clock_sync_key(&ns))
                .payload(vec![0u8; 3])
                .await
                .unwrap();
            let reply = replies.recv_async().await.unwrap();
            assert!(reply.result().is_err());
            simulator.close().await.unwrap();
            sim.shutdown().await;
            wall.shutdown().await;
        })
        .await
        .expect("the clock checks end in time");
    });
    let (code, stderr) = stop(up);
    assert_eq!(code, 0, "{stderr}");
}
