//! The stack clock against a launch's clock server (`clock::serve`, what
//! `peppy-launch up` runs) on the hub: wall time, sim time, sync, ticks.
//! One test, since `clock::now_ns` answers for one node of the process.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use peppy_runtime::Error;
use peppy_runtime::clock::{self, ClockSource, ClockTick};
use peppy_runtime::wire::keys::clock_tick_key;

use crate::shutdown::Hooked;
use crate::support::{WAIT, hub, namespace, start};

fn os_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}

/// `a` and `b` within a second of each other.
fn close(a: u64, b: u64) -> bool {
    a.abs_diff(b) < Duration::from_secs(1).as_nanos() as u64
}

async fn next_tick(sub: &clock::ClockSubscription) -> Option<ClockTick> {
    tokio::time::timeout(WAIT, sub.on_next_tick())
        .await
        .expect("a tick arrives")
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wall_and_sim_time_synchronize_with_the_launch() {
    let hub = hub().await;
    let ns = namespace("clock");
    assert!(matches!(clock::now_ns(), Err(Error::ClockNotReady)));
    let (_, wall) = start::<Hooked>(&hub, &ns, "wall_node", &[]).await;
    assert!(!wall.use_sim_time());
    // Nobody serves the clock yet: no answer.
    let e = clock::synchronize(&wall, Some(Duration::from_millis(300)))
        .await
        .unwrap_err();
    assert!(matches!(e, Error::ServiceUnreachable { .. }), "{e:?}");
    let _server = clock::serve(&hub.session, &ns).await.unwrap();

    // Wall: the OS clock, an offset of about 0 on one host.
    clock::init(&wall).await.unwrap();
    clock::init(&wall).await.unwrap();
    assert!(close(clock::now_ns().unwrap(), os_now()));
    let sync = clock::synchronize(&wall, Some(WAIT)).await.unwrap();
    assert!(sync.offset_ns.unsigned_abs() < 1_000_000_000, "{sync:?}");
    assert!(sync.round_trip_delay_ns > 0, "{sync:?}");
    assert!(sync.raw.server_recv_time <= sync.raw.server_send_time);
    let ticks = clock::subscribe(&wall).await.unwrap();
    let tick = next_tick(&ticks).await.unwrap();
    assert!(close(tick.time, os_now()), "{tick:?}");

    // Sim: nothing until the first tick, then the simulator's time.
    let (_, sim) = start::<Hooked>(&hub, &ns, "sim_node", &["--use-sim-time"]).await;
    assert!(sim.use_sim_time());
    clock::init(&sim).await.unwrap();
    assert!(matches!(clock::now_ns(), Err(Error::ClockNotReady)));
    let e = clock::synchronize(&sim, Some(WAIT)).await.unwrap_err();
    assert!(matches!(e, Error::ClockNotReady), "{e:?}");
    let sim_ticks = clock::subscribe(&sim).await.unwrap();
    // A malformed tick is dropped, the next read.
    let sim_key = clock_tick_key(&ns, ClockSource::Sim);
    let (_, simulator) = start::<Hooked>(&hub, &ns, "simulator", &[]).await;
    tokio::time::timeout(WAIT, async {
        // Until the subscription is known to the publisher's session.
        loop {
            hub.session.put(&sim_key, vec![1u8, 2, 3]).await.unwrap();
            clock::publish_sim_time(&simulator, 42_000).await.unwrap();
            match tokio::time::timeout(Duration::from_millis(100), sim_ticks.on_next_tick()).await {
                Ok(t) => break assert_eq!(t.unwrap(), Some(ClockTick { time: 42_000 })),
                Err(_) => continue,
            }
        }
    })
    .await
    .expect("the sim tick arrives");
    tokio::time::timeout(WAIT, async {
        while clock::now_ns().ok() != Some(42_000) {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("now_ns gives the sim time");
    // The launch has seen it too: its answer is the sim time.
    let sync = tokio::time::timeout(WAIT, async {
        loop {
            match clock::synchronize(&sim, Some(WAIT)).await {
                Ok(s) => break s,
                Err(Error::ClockNotReady) => tokio::time::sleep(Duration::from_millis(20)).await,
                Err(e) => panic!("{e}"),
            }
        }
    })
    .await
    .unwrap();
    assert_eq!(sync.raw.server_recv_time, 42_000);
    assert_eq!((sync.offset_ns, sync.round_trip_delay_ns), (0, 0));
    // The wall node's ticks are still the launch's OS clock.
    let tick = next_tick(&ticks).await.unwrap();
    assert!(close(tick.time, os_now()), "{tick:?}");

    // Once the node stops, no more ticks.
    sim.shutdown().await;
    assert_eq!(next_tick(&sim_ticks).await, None);
    simulator.shutdown().await;
    wall.shutdown().await;
}
