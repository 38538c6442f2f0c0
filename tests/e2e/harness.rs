//! The generated test surfaces (`peppygen::mock`, `peppygen::fixtures`) of
//! the fixture nodes, at their edges: many harnesses at once, a lossless
//! topic under load, a message in another format, waits that time out or
//! end with the node's failure, and the test clock.

use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use peppy::{NodeRunner, Result};

use crate::nodes::{shapes, shapes_client, video_reconstruction};
use crate::roundtrip::Samples;

const TIMEOUT: Duration = Duration::from_secs(10);

/// A harness configuration for `shapes`, whose parameters have no defaults.
fn shapes_config() -> shapes::fixtures::harness::Config {
    use peppy::codegen::NodeParameters;
    // The file holds what has no default; the schema fills in the rest.
    let given = serde_json::from_str(include_str!("shapes_params.json")).expect("JSON");
    let model = peppy_schema::NodeModel::from_json(shapes::Parameters::descriptor().model)
        .expect("the compiled model");
    let full = model
        .parameters
        .resolve(&given)
        .expect("shapes_params.json fits");
    let parameters = serde_json::from_value(full).expect("shapes' Parameters");
    shapes::fixtures::harness::Config {
        parameters: Some(parameters),
        ..Default::default()
    }
}

/// The setup of a `shapes` node that answers `echo` with its own instance
/// id and the request's text, and emits its instance id once on
/// `everything`.
async fn answering_shapes(_p: shapes::Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    use shapes::emitted_topics::everything;
    use shapes::exposed_services::echo;
    let me = runner.instance_id().to_string();
    let server = runner.clone();
    tokio::spawn(async move {
        while echo::handle_next_request(&server, |request| {
            let text = format!("{}:{}", server.instance_id(), request.data.text);
            Ok(echo::Response::new(
                text,
                echo::ResponseMeta {
                    id: request.data.meta.id,
                },
            ))
        })
        .await
        .is_ok()
        {}
    });
    let mut first = Samples::new(1).everything();
    first.text = me;
    everything::emit(
        &runner,
        first.flag,
        first.small,
        first.medium,
        first.large,
        first.huge,
        first.tiny,
        first.short,
        first.int,
        first.long,
        first.single,
        first.double,
        first.text,
        first.blob,
        first.when,
    )
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn fifty_harnesses_run_at_once_without_cross_talk() -> Result<()> {
    use shapes::fixtures::exposed_services::echo;
    use shapes::fixtures::harness::Harness;
    let tests = (0..50).map(|i| {
        tokio::spawn(async move {
            let (mut harness, _mocks) =
                Harness::start_with(shapes_config(), answering_shapes).await?;
            let me = harness.instance_id().to_string();
            let first = harness.emitted.everything.next_within(TIMEOUT).await?;
            assert_eq!(first.map(|m| m.text), Some(me.clone()));
            let request = echo::RequestData {
                text: format!("question {i}"),
                meta: echo::EchoMeta { id: i },
            };
            let answer = echo::poll(&harness, &request, TIMEOUT).await?;
            assert_eq!(answer.text, format!("{me}:question {i}"));
            assert_eq!(answer.meta.id, i);
            harness.shutdown().await?;
            Ok::<_, peppy::Error>(me)
        })
    });
    let mut ids = Vec::new();
    for t in tests.collect::<Vec<_>>() {
        ids.push(t.await.expect("the test task did not panic")?);
    }
    ids.sort();
    ids.dedup();
    assert_eq!(ids.len(), 50, "every harness ran its own node");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lossless_topic_delivers_a_thousand_mock_messages_in_order() -> Result<()> {
    use shapes_client::consumed_topics::shapes_everything;
    use shapes_client::fixtures::harness::Harness;
    const COUNT: usize = 1000;
    let seen = Arc::new(Mutex::new(Vec::new()));
    let heard = seen.clone();
    let setup = move |_p: shapes_client::Parameters, runner: Arc<NodeRunner>| async move {
        tokio::spawn(async move {
            while let Ok((_, m)) = shapes_everything::on_next_message_received(&runner, None).await
            {
                heard.lock().unwrap().push(m.large);
            }
        });
        Ok(())
    };
    let (harness, mocks) = Harness::start(setup).await?;
    let topic = &mocks.deps.shapes.everything;
    // The producer's message type, as the consumer's: the same format.
    let sample = Samples::new(2).everything();
    let mut message: shapes_everything::Message =
        peppy::runtime::wire::codec::from_bytes(&peppy::runtime::wire::codec::to_bytes(&sample))
            .expect("one format");
    for n in 0..COUNT {
        message.large = n as u32;
        topic.publish(&message).await?;
    }
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    while seen.lock().unwrap().len() < COUNT && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let seen = seen.lock().unwrap().clone();
    assert_eq!(
        seen,
        (0..COUNT as u32).collect::<Vec<_>>(),
        "every message, in order"
    );
    harness.shutdown().await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_message_in_another_format_is_dropped_not_delivered() -> Result<()> {
    use peppy::runtime::wire::attachment;
    use peppy::runtime::wire::keys::{Channel, Owner, entry_key};
    use shapes_client::consumed_topics::shapes_video_stream;
    use shapes_client::fixtures::harness::Harness;
    let got = Arc::new(Mutex::new(Vec::new()));
    let heard = got.clone();
    let setup = move |_p: shapes_client::Parameters, runner: Arc<NodeRunner>| async move {
        tokio::spawn(async move {
            while let Ok((_, m)) =
                shapes_video_stream::on_next_message_received(&runner, None).await
            {
                heard.lock().unwrap().push(m.frame);
            }
        });
        Ok(())
    };
    let (harness, mocks) = Harness::start(setup).await?;
    let mock = &mocks.deps.shapes;
    assert!(mock.video_stream.wait_for_subscriber(TIMEOUT).await?);
    // The mock's own session sends bytes that decode as a frame, under a
    // fingerprint that is not the topic's: another build of the producer.
    let key = entry_key(
        harness.node_runner().namespace(),
        Channel::Topic,
        &Owner::Node {
            name: "shapes",
            tag: "v1",
        },
        "Video-Stream",
        &mock.producer_ref().core_node,
        mock.instance_id(),
    );
    mock.producer()
        .runner()
        .session()
        .put(key, vec![3, 0, 0, 0, 7, 7, 7])
        .attachment(attachment::topic(0x0bad_f00d))
        .await
        .map_err(|e| peppy::Error::Transport(e.to_string()))?;
    mock.video_stream
        .publish(&shapes_video_stream::Message { frame: vec![1, 2] })
        .await?;
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    while got.lock().unwrap().is_empty() && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Give a wrongly delivered frame the time to show up after the good one.
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(*got.lock().unwrap(), vec![vec![1, 2]]);
    harness.shutdown().await
}

/// A mock's publish returns once the node's code reads the topic, as
/// PeppyOS's harness documents it: a setup that does slow work before it
/// spawns its reader has returned by the time the publish does, though
/// the node's subscription was on the router from its start.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_publish_returns_once_the_nodes_code_reads_the_topic() -> Result<()> {
    use shapes_client::consumed_topics::shapes_video_stream;
    use shapes_client::fixtures::harness::Harness;
    let got = Arc::new(Mutex::new(Vec::new()));
    let heard = got.clone();
    let setup = move |_p: shapes_client::Parameters, runner: Arc<NodeRunner>| async move {
        tokio::time::sleep(Duration::from_millis(300)).await;
        tokio::spawn(async move {
            let Ok(mut frames) = shapes_video_stream::subscribe(&runner).await else {
                return;
            };
            while let Ok(Some((_, m))) = frames.next().await {
                heard.lock().unwrap().push(m.frame);
            }
        });
        Ok(())
    };
    let (harness, mocks) = Harness::start(setup).await?;
    let mock = &mocks.deps.shapes;
    assert!(!harness.setup_finished(), "setup is still at its slow work");
    mock.video_stream
        .publish(&shapes_video_stream::Message { frame: vec![4] })
        .await?;
    assert!(
        harness.setup_finished(),
        "the read topic proves setup returned"
    );
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    while got.lock().unwrap().is_empty() && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(*got.lock().unwrap(), vec![vec![4]]);
    harness.shutdown().await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wait_that_times_out_names_what_it_waited_for() -> Result<()> {
    use shapes_client::fixtures::harness::Harness;
    let idle = |_p: shapes_client::Parameters, _r: Arc<NodeRunner>| async { Ok(()) };
    let (harness, mocks) = Harness::start(idle).await?;
    let e = mocks
        .deps
        .shapes
        .echo
        .next_request(Duration::from_millis(300))
        .await
        .expect_err("the node never calls echo");
    let text = e.to_string();
    assert!(text.contains("timed out after 0.3 s"), "{text}");
    assert!(
        text.contains("a request of service `echo` from the node"),
        "{text}"
    );
    let e = mocks
        .deps
        .shapes
        .move_to
        .next_goal(Duration::from_millis(300))
        .await
        .expect_err("the node never sends a goal");
    assert!(e.to_string().contains("a goal of action `move_to`"), "{e}");
    assert!(harness.setup_finished());
    harness.shutdown().await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_setup_that_panics_ends_the_waits_and_fails_the_shutdown() -> Result<()> {
    use shapes::fixtures::harness::Harness;
    let broken = |_p: shapes::Parameters, _r: Arc<NodeRunner>| async move {
        if SystemTime::now() > SystemTime::UNIX_EPOCH {
            panic!("camera unplugged");
        }
        Ok(())
    };
    let (mut harness, _mocks) = Harness::start_with(shapes_config(), broken).await?;
    // Unbounded: without the node's failure this would wait forever.
    let e = harness
        .emitted
        .everything
        .next()
        .await
        .expect_err("the node failed");
    assert!(
        e.to_string().contains("setup panicked: camera unplugged"),
        "{e}"
    );
    assert!(!harness.setup_finished());
    let e = harness.shutdown().await.expect_err("the panic surfaces");
    assert!(e.to_string().contains("camera unplugged"), "{e}");

    let failing = |_p: shapes::Parameters, _r: Arc<NodeRunner>| async move {
        Err(peppy::Error::User("hardware missing".into()))
    };
    let (harness, _mocks) = Harness::start_with(shapes_config(), failing).await?;
    let e = harness
        .shutdown()
        .await
        .expect_err("setup's error surfaces");
    assert_eq!(e.to_string(), "hardware missing");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_test_clock_skews_wall_time_and_drives_sim_time() -> Result<()> {
    use shapes::fixtures::harness::{Config, Harness};
    let clocked =
        |_p: shapes::Parameters, r: Arc<NodeRunner>| async move { peppy::clock::init(&r).await };
    let (harness, _mocks) = Harness::start_with(shapes_config(), clocked).await?;
    let hour: i64 = 3_600_000_000_000;
    harness.clock.set_offset_ns(hour)?;
    let sync = peppy::clock::synchronize(harness.node_runner(), Some(TIMEOUT)).await?;
    assert!(sync.offset_ns > hour / 2, "{sync:?}");
    assert!(
        harness.clock.tick(1).await.is_err(),
        "a wall clock has no ticks"
    );
    harness.shutdown().await?;

    let config = Config {
        use_sim_time: true,
        ..shapes_config()
    };
    let (harness, _mocks) = Harness::start_with(config, clocked).await?;
    assert!(
        harness.clock.set_offset_ns(1).is_err(),
        "sim time has no wall offset"
    );
    // Setup binds the clock; until the first tick there is no time.
    tokio::time::timeout(TIMEOUT, async {
        while !harness.setup_finished() {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("setup returns");
    assert!(peppy::clock::now_ns().is_err());
    harness.clock.tick(1_000_000_000).await?;
    assert_eq!(peppy::clock::now_ns()?, 1_000_000_000);
    harness.clock.tick(2_500_000_000).await?;
    assert_eq!(peppy::clock::now_ns()?, 2_500_000_000);
    harness.clock.advance(500_000_000).await?;
    assert_eq!(peppy::clock::now_ns()?, 3_000_000_000);
    assert_eq!(harness.clock.sim_now_ns(), 3_000_000_000);
    harness.shutdown().await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_slot_gets_the_mocks_its_cardinality_and_config_ask_for() -> Result<()> {
    use video_reconstruction::consumed_topics::backup_cams_video_stream;
    use video_reconstruction::fixtures::harness::{Config, Harness};
    let frames = Arc::new(Mutex::new(Vec::new()));
    let heard = frames.clone();
    let setup = move |_p: video_reconstruction::Parameters, runner: Arc<NodeRunner>| async move {
        tokio::spawn(async move {
            while let Ok((from, m)) =
                backup_cams_video_stream::on_next_message_received(&runner, None).await
            {
                heard.lock().unwrap().push((from, m.frame));
            }
        });
        Ok(())
    };
    let config = Config {
        backup_cams_instances: 3,
        ..Config::default()
    };
    let (harness, mocks) = Harness::start_with(config, setup).await?;
    // One mock for each single slot, three for the list slot, named in order.
    assert_eq!(mocks.deps.left_cam.instance_id(), "mock-left_cam");
    assert_eq!(mocks.deps.front.instance_id(), "mock-front");
    let ids: Vec<&str> = mocks
        .deps
        .backup_cams
        .iter()
        .map(|m| m.instance_id())
        .collect();
    assert_eq!(
        ids,
        [
            "mock-backup_cams-0",
            "mock-backup_cams-1",
            "mock-backup_cams-2"
        ]
    );
    assert_eq!(harness.node_runner().bound_producers("backup_cams"), ids);
    assert_eq!(
        harness.node_runner().bound_producer_refs("left_cam"),
        [mocks.deps.left_cam.producer_ref()]
    );
    for (n, mock) in mocks.deps.backup_cams.iter().enumerate() {
        let message = backup_cams_video_stream::Message {
            header: backup_cams_video_stream::MessageHeader {
                stamp: SystemTime::UNIX_EPOCH,
                frame_id: n as u32,
            },
            encoding: "mono8".into(),
            width: 1,
            height: 1,
            frame: vec![n as u8],
        };
        mock.video_stream.publish(&message).await?;
    }
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    while frames.lock().unwrap().len() < 3 && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let mut got = frames.lock().unwrap().clone();
    got.sort();
    let want: Vec<(String, Vec<u8>)> = (0..3u8)
        .map(|n| (format!("mock-backup_cams-{n}"), vec![n]))
        .collect();
    assert_eq!(got, want, "each mock's frame, from that mock");
    harness.shutdown().await?;

    let wrong = Config {
        backup_cams_instance_ids: vec!["cam_a".into()],
        ..Config::default()
    };
    let (harness, mocks) = Harness::start_with(wrong, |_p, _r| async { Ok(()) }).await?;
    assert_eq!(mocks.deps.backup_cams[0].instance_id(), "cam_a");
    harness.shutdown().await
}
