// The action API of SPEC 4, written the way the original's node code was.
#![deny(warnings)]

#[peppy::node("tests/e2e/api/actions.json5")]
mod peppygen {}

use std::time::Duration;

use peppygen::consumed_actions::cam_calibrate;
use peppygen::exposed_actions::{home, move_to};
use peppygen::{NodeRunner, QoSProfile, Result};

async fn serve(node_runner: &NodeRunner) -> Result<()> {
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
    let mut homing = home::ActionHandle::expose(node_runner).await?;
    if let Some(ctx) = homing
        .handle_goal_next_request(|_| Ok(home::GoalResponse::new(true, None)))
        .await?
    {
        ctx.complete().await?;
    }
    Ok(())
}

async fn call(node_runner: &NodeRunner) -> Result<()> {
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
        return Ok(());
    }
    let feedback: cam_calibrate::FeedbackMessage = handle.on_next_feedback_message().await?;
    let _: u32 = feedback.views;
    let result = handle.get_result(Duration::from_secs(30)).await?;
    let _: (String, String) = (result.instance_id, result.core_node);
    match result.outcome {
        cam_calibrate::ResultOutcome::Completed(data) => println!("rms {}", data.rms_error),
        cam_calibrate::ResultOutcome::Cancelled(data) => println!("partial {}", data.rms_error),
        cam_calibrate::ResultOutcome::Abandoned | cam_calibrate::ResultOutcome::Expired => {}
    }
    let cancel = handle.cancel_goal(Duration::from_secs(1)).await?;
    match cancel.state {
        cam_calibrate::CancelState::Signalled
        | cam_calibrate::CancelState::AlreadyTerminal
        | cam_calibrate::CancelState::Unknown => {}
    }
    Ok(())
}

#[test]
fn compiles_and_runs() {
    let _ = (serve, call);
}
