#![deny(warnings)]

#[peppy::node("tests/e2e/api/conformance.json5")]
mod peppygen {}

use std::time::{Duration, SystemTime};

use peppy::runtime::Outcome;
use peppy::runtime::wire::codec::{from_bytes, to_bytes};
use peppygen::emitted_topics::{self, depth_camera, uvc_camera};
use peppygen::{NodeRunner, Result};
use peppygen::{exposed_actions, exposed_services};

use crate::support::{WAIT, describe, hear_topics, hub, namespace, start, tool, until_up};

async fn produce(runner: &NodeRunner) -> Result<()> {
    // Defined by three interfaces: only the nested paths exist.
    depth_camera::v1::video_stream::emit(
        runner,
        depth_camera::v1::video_stream::MessageHeader {
            stamp: SystemTime::now(),
            frame_id: 1,
        },
        "rgb8".into(),
        640,
        480,
        vec![0; 4],
    )
    .await?;
    depth_camera::v2::video_stream::emit(runner, SystemTime::now(), vec![1, 2]).await?;
    uvc_camera::v1_beta::video_stream::emit(runner, vec![0xff, 0xd8]).await?;
    // Unambiguous conformed entries also have their flat names.
    emitted_topics::calibrated::emit(runner).await?;
    depth_camera::v2::calibrated::emit(runner).await?;
    emitted_topics::status::emit(runner, true).await?;
    exposed_services::video_stream_info::handle_next_request(runner, |_| {
        Ok(exposed_services::video_stream_info::Response::new(
            640,
            480,
            30,
            "rgb8".into(),
        ))
    })
    .await?;
    exposed_services::uvc_camera::v1_beta::set_exposure::handle_next_request(runner, |request| {
        let _: u32 = request.data.micros;
        Ok(())
    })
    .await?;
    exposed_services::set_exposure::handle_next_request(runner, |_| Ok(())).await?;
    // An inherited action, nested and flat.
    let mut nested =
        exposed_actions::depth_camera::v2::calibrate::ActionHandle::expose(runner).await?;
    let mut flat = exposed_actions::calibrate::ActionHandle::expose(runner).await?;
    if let Some(ctx) = flat
        .handle_goal_next_request(|goal| {
            let _: (u8, u8) = (goal.data.board.rows, goal.data.board.cols);
            Ok(exposed_actions::calibrate::GoalResponse::accept())
        })
        .await?
    {
        ctx.publish_feedback(12).await?;
        ctx.complete(0.25).await?;
    }
    let _ = nested
        .handle_goal_next_request(|_| Ok(exposed_actions::calibrate::GoalResponse::reject("busy")))
        .await?;
    Ok(())
}

/// `produce` runs against a tool playing the consumers: every emit is
/// heard on its own key, each service answers, the flat action accepts the
/// first goal and the nested one rejects the second.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_conforming_node_serves_every_entry_of_its_interfaces() {
    let hub = hub().await;
    let ns = namespace("api-conformance");
    let mut heard = hear_topics(&hub, &ns).await;
    let (_, zed) = start::<peppygen::Parameters>(&hub, &ns, "zed", &[]).await;
    let producing = tokio::spawn({
        let zed = zed.clone();
        async move { produce(&zed).await }
    });
    let info = describe(&hub, &ns, "zed").await;
    let tool = tool(&hub);
    let t = Duration::from_secs(2);

    let service = |name: &str| info.services.iter().find(|s| s.name == name).unwrap();
    let body = until_up(async || {
        tool.call(service("video_stream_info"), "zed", Vec::new(), t)
            .await
    })
    .await
    .unwrap();
    let stream: exposed_services::video_stream_info::Response = from_bytes(&body).unwrap();
    assert_eq!(
        (stream.width, stream.height, stream.frames_per_second),
        (640, 480, 30)
    );
    assert_eq!(stream.encoding, "rgb8");
    // The nested and the flat `set_exposure` are one service: two requests.
    for micros in [100, 200] {
        let request = exposed_services::set_exposure::RequestData { micros };
        let body = tool
            .call(service("set_exposure"), "zed", to_bytes(&request), t)
            .await
            .unwrap();
        assert!(body.is_empty());
    }

    let calibrate = info.actions.iter().find(|a| a.name == "calibrate").unwrap();
    let goal = to_bytes(&exposed_actions::calibrate::GoalRequestData {
        board: exposed_actions::calibrate::GoalBoard { rows: 6, cols: 9 },
    });
    let mut first = tool
        .send_goal(calibrate, "zed", goal.clone(), t)
        .await
        .unwrap();
    assert!(first.accepted, "{:?}", first.error_message);
    let feedback: exposed_actions::calibrate::CalibrateFeedback =
        first.next_feedback().await.unwrap();
    assert_eq!(feedback.views, 12);
    let result = first.result(t).await.unwrap();
    assert_eq!(
        result,
        Outcome::Completed(exposed_actions::calibrate::CalibrateResult { rms_error: 0.25 })
    );
    let second = tool.send_goal(calibrate, "zed", goal, t).await.unwrap();
    assert!(!second.accepted);
    assert_eq!(second.error_message.as_deref(), Some("busy"));

    let key = |owner: &str, tag: &str, name: &str| {
        let e = info
            .emits
            .iter()
            .find(|e| {
                (e.owner.name.as_str(), e.owner.tag.as_str(), e.name.as_str()) == (owner, tag, name)
            })
            .unwrap_or_else(|| panic!("{owner}:{tag} {name} is not described"));
        e.key.clone()
    };
    let v1: depth_camera::v1::video_stream::Message = from_bytes(
        &heard
            .first(&key("depth_camera", "v1", "video_stream"))
            .await,
    )
    .unwrap();
    assert_eq!(
        (
            v1.header.frame_id,
            v1.encoding.as_str(),
            v1.width,
            v1.height
        ),
        (1, "rgb8", 640, 480)
    );
    let v2: depth_camera::v2::video_stream::Message = from_bytes(
        &heard
            .first(&key("depth_camera", "v2", "video_stream"))
            .await,
    )
    .unwrap();
    assert_eq!(v2.depth, [1, 2]);
    let uvc: uvc_camera::v1_beta::video_stream::Message = from_bytes(
        &heard
            .first(&key("uvc_camera", "v1-beta", "video_stream"))
            .await,
    )
    .unwrap();
    assert_eq!(uvc.jpeg, [0xff, 0xd8]);
    assert!(
        heard
            .first(&key("depth_camera", "v2", "calibrated"))
            .await
            .is_empty()
    );
    let status: emitted_topics::status::Message =
        from_bytes(&heard.first(&key("zed_2i", "v1", "status")).await).unwrap();
    assert!(status.ok);

    // The nested handle waits for a goal it would accept until the node stops.
    zed.shutdown().await;
    tokio::time::timeout(WAIT, producing)
        .await
        .expect("produce returns once the node stops")
        .unwrap()
        .unwrap();
}
