// The action API of SPEC 4, written the way the original's node code was.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/actions.json5")]
mod peppygen {}

use std::time::Duration;

use peppy::runtime::Outcome;
use peppy::runtime::wire::codec::to_bytes;
use peppygen::consumed_actions::cam_calibrate;
use peppygen::exposed_actions::{home, move_to};
use peppygen::{NodeRunner, QoSProfile, Result};

use crate::nodes::zed_2i;
use crate::support::{WAIT, describe, hub, namespace, start, tool, until_up};

/// Serves `move_to` until the node stops.
async fn serve_move_to(node_runner: &NodeRunner) -> Result<()> {
    let mut handle = move_to::ActionHandle::expose(node_runner).await?;
    while let Some(ctx) = handle
        .handle_goal_next_request(|request: &move_to::GoalRequest| {
            let _: (&str, &str) = (&request.instance_id, &request.core_node);
            if request.data.speed > 2.0 {
                return Ok(move_to::GoalResponse::reject("too fast"));
            }
            Ok(move_to::GoalResponse::accept())
        })
        .await?
    {
        let _: &str = ctx.goal_id();
        let target: &move_to::GoalTarget = &ctx.request().data.target;
        let _ = (target.x, target.y);
        ctx.publish_feedback(0.5).await?;
        if ctx.is_cancelled() {
            ctx.complete_cancelled(false).await?;
            continue;
        }
        tokio::select! {
            () = ctx.cancel_signal() => ctx.complete_cancelled(false).await?,
            () = std::future::ready(()) => ctx.complete(true).await?,
        }
    }
    Ok(())
}

/// Serves `home` until the node stops.
async fn serve_home(node_runner: &NodeRunner) -> Result<()> {
    let mut homing = home::ActionHandle::expose(node_runner).await?;
    while let Some(ctx) = homing
        .handle_goal_next_request(|_| Ok(home::GoalResponse::new(true, None)))
        .await?
    {
        ctx.complete().await?;
    }
    Ok(())
}

/// Sends one calibration goal: the first feedback's view count, the RMS
/// error it completed with, and the answer to a cancel sent after it ended
/// (`None` if it was rejected or did not complete).
async fn call(node_runner: &NodeRunner) -> Result<Option<(u32, f64, cam_calibrate::CancelState)>> {
    let goal = cam_calibrate::GoalRequest {
        board: cam_calibrate::GoalBoard { rows: 6, cols: 9 },
    };
    let mut handle = cam_calibrate::ActionHandle::fire_goal(
        node_runner,
        Duration::from_secs(1),
        goal,
        QoSProfile::Standard,
    )
    .await?;
    if !handle.data.accepted {
        println!("rejected: {:?}", handle.data.error_message);
        return Ok(None);
    }
    let feedback: cam_calibrate::FeedbackMessage = handle.on_next_feedback_message().await?;
    let views: u32 = feedback.views;
    let result = handle.get_result(Duration::from_secs(30)).await?;
    let _: (String, String) = (result.instance_id, result.core_node);
    let rms = match result.outcome {
        cam_calibrate::ResultOutcome::Completed(data) => data.rms_error,
        cam_calibrate::ResultOutcome::Cancelled(data) => {
            println!("partial {}", data.rms_error);
            return Ok(None);
        }
        cam_calibrate::ResultOutcome::Abandoned | cam_calibrate::ResultOutcome::Expired => {
            return Ok(None);
        }
    };
    let cancel = handle.cancel_goal(Duration::from_secs(1)).await?;
    match cancel.state {
        cam_calibrate::CancelState::Signalled
        | cam_calibrate::CancelState::AlreadyTerminal
        | cam_calibrate::CancelState::Unknown => {}
    }
    Ok(Some((views, rms, cancel.state)))
}

/// The node serves both its actions to a tool (a goal rejected, one
/// completed with feedback, a goal without data) and calls a camera's
/// `calibrate` through its interface slot.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_serves_its_actions_and_calls_one_through_a_slot() {
    let hub = hub().await;
    let ns = namespace("api-actions");
    let (_, zed) = start::<zed_2i::Parameters>(&hub, &ns, "zed", &[]).await;
    let mut calibrate = zed_2i::exposed_actions::calibrate::ActionHandle::expose(&zed)
        .await
        .unwrap();
    tokio::spawn(async move {
        while let Ok(Some(ctx)) = calibrate
            .handle_goal_next_request(|_| {
                Ok(zed_2i::exposed_actions::calibrate::GoalResponse::accept())
            })
            .await
        {
            ctx.publish_feedback(54).await.unwrap();
            ctx.complete(0.5).await.unwrap();
        }
    });
    let (_, node) = start::<peppygen::Parameters>(&hub, &ns, "arm", &["--bind", "cam@zed"]).await;
    let serving = [
        tokio::spawn({
            let node = node.clone();
            async move { serve_move_to(&node).await }
        }),
        tokio::spawn({
            let node = node.clone();
            async move { serve_home(&node).await }
        }),
    ];

    let info = describe(&hub, &ns, "arm").await;
    let tool = tool(&hub);
    let t = Duration::from_secs(2);
    let action = |name: &str| info.actions.iter().find(|a| a.name == name).unwrap();
    let goal = |speed| {
        to_bytes(&move_to::GoalRequestData {
            target: move_to::GoalTarget { x: 1.0, y: 2.0 },
            speed,
        })
    };
    let fast = until_up(async || tool.send_goal(action("move_to"), "arm", goal(3.0), t).await)
        .await
        .unwrap();
    assert!(!fast.accepted);
    assert_eq!(fast.error_message.as_deref(), Some("too fast"));
    let mut moving = tool
        .send_goal(action("move_to"), "arm", goal(1.0), t)
        .await
        .unwrap();
    assert!(moving.accepted, "{:?}", moving.error_message);
    let feedback: move_to::MoveToFeedback = moving.next_feedback().await.unwrap();
    assert_eq!(feedback.progress, 0.5);
    assert_eq!(
        moving.result(t).await.unwrap(),
        Outcome::Completed(move_to::MoveToResult { reached: true })
    );
    let homing = tool
        .send_goal(action("home"), "arm", Vec::new(), t)
        .await
        .unwrap();
    assert!(homing.accepted, "{:?}", homing.error_message);
    assert_eq!(
        homing.result::<()>(t).await.unwrap(),
        Outcome::Completed(())
    );

    let called = until_up(async || call(&node).await).await.unwrap();
    assert_eq!(
        called,
        Some((54, 0.5, cam_calibrate::CancelState::AlreadyTerminal))
    );

    node.shutdown().await;
    for task in serving {
        tokio::time::timeout(WAIT, task)
            .await
            .expect("serving ends once the node stops")
            .unwrap()
            .unwrap();
    }
    zed.shutdown().await;
}
