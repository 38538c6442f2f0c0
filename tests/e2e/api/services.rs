#![deny(warnings)]

#[peppy::node("tests/e2e/api/services.json5")]
mod peppygen {}

use std::time::Duration;

use peppy::runtime::wire::codec::{from_bytes, to_bytes};
use peppygen::consumed_services::{cam_video_stream_info, front_reset};
use peppygen::exposed_services::{command, echo, status, trigger};
use peppygen::{NodeRunner, Result};

use crate::nodes::realsense_d405;
use crate::support::{WAIT, describe, hub, namespace, start, tool, until_up};

async fn serve(runner: &NodeRunner) -> Result<()> {
    echo::handle_next_request(runner, |request: echo::Request| {
        let _: (&str, &str) = (&request.instance_id, &request.core_node);
        Ok(echo::Response::new(
            request.data.text,
            echo::ResponseMeta {
                id: request.data.meta.id,
            },
        ))
    })
    .await?;
    trigger::handle_next_request(runner, |request| {
        let _ = request.instance_id;
        Ok(())
    })
    .await?;
    status::handle_next_request(runner, |_| Ok(status::Response::new(true))).await?;
    command::handle_next_request(runner, |request| {
        if request.data.code == 0 {
            return Err("code 0 is reserved".into());
        }
        Ok(())
    })
    .await
}

/// Calls both consumed services; the camera's frame size and whether both
/// resets went through.
async fn call(runner: &NodeRunner) -> Result<((u32, u32), bool)> {
    let info = cam_video_stream_info::poll(runner, Duration::from_secs(1)).await?;
    let (width, height) = (info.data.width, info.data.height);
    let _: (String, String, u32, u32, u8, String) = (
        info.instance_id,
        info.core_node,
        width,
        height,
        info.data.frames_per_second,
        info.data.encoding,
    );
    let reset = front_reset::poll(
        runner,
        Duration::from_secs(1),
        front_reset::Request::new(true),
    )
    .await?;
    let _: (bool, Option<String>) = (reset.data.ok, reset.data.note);
    let literal = front_reset::Request { hard: false };
    let again = front_reset::poll(runner, Duration::from_secs(1), literal).await?;
    Ok(((width, height), reset.data.ok && again.data.ok))
}

/// One node both serves (a tool calls each of its services in turn) and
/// calls (a camera answers through the interface slot and the node slot).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_serves_and_calls_services_through_its_slots() {
    let hub = hub().await;
    let ns = namespace("api-services");
    let (_, cam) = start::<realsense_d405::Parameters>(&hub, &ns, "cam", &[]).await;
    {
        use realsense_d405::exposed_services::{reset, video_stream_info};
        let server = cam.clone();
        tokio::spawn(async move {
            while reset::handle_next_request(&server, |_| Ok(reset::Response::new(true, None)))
                .await
                .is_ok()
            {}
        });
        let server = cam.clone();
        tokio::spawn(async move {
            while video_stream_info::handle_next_request(&server, |_| {
                Ok(video_stream_info::Response::new(
                    320,
                    240,
                    15,
                    "mono8".into(),
                ))
            })
            .await
            .is_ok()
            {}
        });
    }
    let (_, node) = start::<peppygen::Parameters>(
        &hub,
        &ns,
        "svc",
        &["--bind", "cam@cam", "--bind", "front@cam"],
    )
    .await;
    let serving = tokio::spawn({
        let node = node.clone();
        async move { serve(&node).await }
    });

    let info = describe(&hub, &ns, "svc").await;
    let tool = tool(&hub);
    let t = Duration::from_secs(2);
    let service = |name: &str| info.services.iter().find(|s| s.name == name).unwrap();
    let request = echo::RequestData {
        text: "hi".into(),
        meta: echo::EchoMeta { id: 7 },
    };
    let body = until_up(async || {
        tool.call(service("echo"), "svc", to_bytes(&request), t)
            .await
    })
    .await
    .unwrap();
    let echoed: echo::Response = from_bytes(&body).unwrap();
    assert_eq!((echoed.text.as_str(), echoed.meta.id), ("hi", 7));
    let body = tool
        .call(service("trigger"), "svc", Vec::new(), t)
        .await
        .unwrap();
    assert!(body.is_empty());
    let body = tool
        .call(service("status"), "svc", Vec::new(), t)
        .await
        .unwrap();
    assert!(from_bytes::<status::Response>(&body).unwrap().up);
    let refused = tool
        .call(
            service("command"),
            "svc",
            to_bytes(&command::RequestData { code: 0 }),
            t,
        )
        .await
        .unwrap_err();
    match refused {
        peppy::Error::ServiceError { reason, .. } => assert_eq!(reason, "code 0 is reserved"),
        other => panic!("{other}"),
    }
    tokio::time::timeout(WAIT, serving)
        .await
        .expect("serve returns after its four requests")
        .unwrap()
        .unwrap();

    until_up(async || cam_video_stream_info::poll(&node, t).await)
        .await
        .unwrap();
    until_up(async || front_reset::poll(&node, t, front_reset::Request::new(false)).await)
        .await
        .unwrap();
    assert_eq!(call(&node).await.unwrap(), ((320, 240), true));
    node.shutdown().await;
    cam.shutdown().await;
}
