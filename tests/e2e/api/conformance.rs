#![deny(warnings)]

#[peppy::node("tests/e2e/api/conformance.json5")]
mod peppygen {}

use std::time::SystemTime;

use peppygen::emitted_topics::{self, depth_camera, uvc_camera};
use peppygen::{NodeRunner, Result};
use peppygen::{exposed_actions, exposed_services};

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

#[test]
fn compiles_and_runs() {
    let _ = produce;
}
