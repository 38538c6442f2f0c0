//! Services through generated `handle_next_request` and `poll`, with and
//! without request and response data, pinned through node and interface
//! slots; handler errors come back with their text.

use std::sync::Arc;
use std::time::Duration;

use peppy::{Error, NodeRunner};

use crate::nodes::{realsense_d405, shapes, shapes_client, video_reconstruction};
use crate::support::{hub, namespace, start, until_up};

/// Serves with `$serve` (an expression of `$s: &NodeRunner`) until the node stops.
macro_rules! serving {
    ($runner:expr, |$s:ident| $serve:expr) => {{
        let runner: Arc<NodeRunner> = $runner;
        tokio::spawn(async move {
            let $s: &NodeRunner = &runner;
            while $serve.await.is_ok() {}
        });
    }};
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn node_and_interface_slot_services() {
    let hub = hub().await;
    let ns = namespace("svc");
    let (_, recon) = start::<video_reconstruction::Parameters>(
        &hub,
        &ns,
        "recon",
        &[
            "--bind",
            "left_cam@cam",
            "--bind",
            "right_cam@cam",
            "--bind",
            "front@cam",
        ],
    )
    .await;
    let (_, cam) = start::<realsense_d405::Parameters>(&hub, &ns, "cam", &[]).await;
    {
        use realsense_d405::exposed_services::{reset, video_stream_info};
        serving!(cam.clone(), |cam| {
            reset::handle_next_request(cam, |request| {
                if request.data.hard {
                    return Err(format!("{} may not hard-reset", request.instance_id).into());
                }
                Ok(reset::Response::new(true, Some(request.core_node)))
            })
        });
        serving!(cam.clone(), |cam| {
            video_stream_info::handle_next_request(cam, |request| {
                assert_eq!(request.instance_id, "recon");
                Ok(video_stream_info::Response::new(
                    640,
                    480,
                    30,
                    "rgb8".into(),
                ))
            })
        });
    }

    use video_reconstruction::consumed_services::{front_reset, left_cam_video_stream_info};
    let timeout = Duration::from_secs(2);
    let info = until_up(async || left_cam_video_stream_info::poll(&recon, timeout).await)
        .await
        .unwrap();
    assert_eq!(info.instance_id, "cam");
    assert_eq!((info.data.width, info.data.frames_per_second), (640, 30));

    let ok = until_up(async || {
        front_reset::poll(&recon, timeout, front_reset::Request::new(false)).await
    })
    .await
    .unwrap();
    assert!(ok.data.ok);
    assert_eq!(ok.data.note.as_deref(), Some("standalone"));
    let err = front_reset::poll(&recon, timeout, front_reset::Request { hard: true })
        .await
        .unwrap_err();
    match err {
        Error::ServiceError {
            reason,
            instance_id,
            ..
        } => {
            assert_eq!(instance_id.as_deref(), Some("cam"));
            assert_eq!(reason, "recon may not hard-reset");
        }
        other => panic!("{other}"),
    }
    recon.shutdown().await;
    cam.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn services_with_and_without_request_and_response() {
    let hub = hub().await;
    let ns = namespace("svc-shapes");
    let (_, client) =
        start::<shapes_client::Parameters>(&hub, &ns, "client", &["--bind", "shapes@shapes"]).await;
    let (_, server) =
        start::<shapes::Parameters>(&hub, &ns, "shapes", &crate::params::SHAPES_ARGS).await;
    let commands = Arc::new(std::sync::Mutex::new(Vec::new()));
    {
        use shapes::exposed_services::{command, echo, status, trigger};
        serving!(server.clone(), |s| {
            echo::handle_next_request(s, |r| {
                Ok(echo::Response::new(
                    r.data.text.to_uppercase(),
                    echo::ResponseMeta {
                        id: r.data.meta.id + 1,
                    },
                ))
            })
        });
        serving!(server.clone(), |s| {
            trigger::handle_next_request(s, |_request: trigger::Request| Ok(()))
        });
        serving!(server.clone(), |s| {
            status::handle_next_request(s, |_| Ok(status::Response::new(true)))
        });
        let commands = commands.clone();
        serving!(server.clone(), |s| {
            command::handle_next_request(s, |r| {
                commands.lock().unwrap().push(r.data.code);
                Ok(())
            })
        });
    }

    use shapes_client::consumed_services::{
        shapes_command, shapes_echo, shapes_status, shapes_trigger,
    };
    let t = Duration::from_secs(2);
    let echoed = until_up(async || {
        shapes_echo::poll(
            &client,
            t,
            shapes_echo::Request::new("hi".into(), shapes_echo::EchoMeta { id: 1 }),
        )
        .await
    })
    .await
    .unwrap();
    assert_eq!((echoed.data.text.as_str(), echoed.data.meta.id), ("HI", 2));
    let triggered = until_up(async || shapes_trigger::poll(&client, t).await)
        .await
        .unwrap();
    assert_eq!(triggered.instance_id, "shapes");
    let up = until_up(async || shapes_status::poll(&client, t).await)
        .await
        .unwrap();
    assert!(up.data.up);
    let done =
        until_up(async || shapes_command::poll(&client, t, shapes_command::Request::new(9)).await)
            .await
            .unwrap();
    assert_eq!(done.core_node, "standalone");
    assert_eq!(*commands.lock().unwrap(), [9]);
    client.shutdown().await;
    server.shutdown().await;
}
