// An exposed action served from a spawned task: the handle owns what it
// needs, so it moves into `tokio::spawn` while the runner stays an `Arc`
// (the shape of the original's node code).
#![deny(warnings)]

#[peppy::node("tests/e2e/api/actions.json5")]
mod peppygen {}

use std::sync::Arc;
use std::sync::mpsc;
use std::time::Duration;

use peppy::CancellationToken;
use peppy::runtime::Outcome;
use peppy::runtime::wire::codec::to_bytes;
use peppygen::exposed_actions::{home, move_to};
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

use crate::support::{WAIT, describe, hub, namespace, node_args, tool, until_up};

/// A handle kept in a struct: no lifetime to name.
struct Homing {
    action: home::ActionHandle,
}

/// The node's `main`, given its command line; `up` gets the node's
/// cancellation token once both actions are exposed, to stop it with.
fn node_main(args: Vec<String>, up: mpsc::Sender<CancellationToken>) -> Result<()> {
    NodeBuilder::new()
        .with_args(args)
        .with_runtime_config(None)
        .run(|_: Parameters, runner: Arc<NodeRunner>| async move {
            let mut action = move_to::ActionHandle::expose(&runner).await?;
            tokio::spawn(async move {
                while let Ok(Some(ctx)) = action
                    .handle_goal_next_request(|request| {
                        if request.data.speed > 2.0 {
                            return Ok(move_to::GoalResponse::reject("too fast"));
                        }
                        Ok(move_to::GoalResponse::accept())
                    })
                    .await
                {
                    tokio::spawn(async move {
                        ctx.publish_feedback(1.0).await?;
                        ctx.complete(true).await
                    });
                }
            });
            let mut homing = Homing {
                action: home::ActionHandle::expose(&runner).await?,
            };
            let _ = up.send(runner.cancellation_token().clone());
            drop(runner);
            tokio::spawn(async move {
                while let Ok(Some(ctx)) = homing
                    .action
                    .handle_goal_next_request(|_| Ok(home::GoalResponse::accept()))
                    .await
                {
                    let _ = ctx.complete().await;
                }
            });
            Ok(())
        })
}

/// The node runs as a program would (`NodeBuilder::run` on a thread of its
/// own, which owns its runtime) and serves a tool's goals from the spawned
/// tasks after `setup` returned and dropped the runner.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn spawned_goal_handlers_serve_after_setup_returned() {
    let hub = hub().await;
    let ns = namespace("api-spawned-action");
    let args = node_args(&hub, &ns, "arm", &["--bind", "cam@zed"]);
    let (up, token) = mpsc::channel();
    let node = std::thread::spawn(move || node_main(args, up));
    let token = tokio::task::spawn_blocking(move || token.recv_timeout(WAIT))
        .await
        .unwrap()
        .expect("the node comes up");

    let info = describe(&hub, &ns, "arm").await;
    let tool = tool(&hub);
    let t = Duration::from_secs(2);
    let action = |name: &str| info.actions.iter().find(|a| a.name == name).unwrap();
    let goal = |speed| {
        to_bytes(&move_to::GoalRequestData {
            target: move_to::GoalTarget { x: 0.0, y: 1.0 },
            speed,
        })
    };
    let fast = until_up(async || tool.send_goal(action("move_to"), "arm", goal(2.5), t).await)
        .await
        .unwrap();
    assert_eq!(
        (fast.accepted, fast.error_message.as_deref()),
        (false, Some("too fast"))
    );
    let mut moving = tool
        .send_goal(action("move_to"), "arm", goal(1.0), t)
        .await
        .unwrap();
    assert!(moving.accepted, "{:?}", moving.error_message);
    let feedback: move_to::MoveToFeedback = moving.next_feedback().await.unwrap();
    assert_eq!(feedback.progress, 1.0);
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

    token.cancel();
    let stopped = tokio::time::timeout(WAIT, tokio::task::spawn_blocking(move || node.join()))
        .await
        .expect("run returns once the node is cancelled")
        .unwrap()
        .expect("the node's thread does not panic");
    stopped.unwrap();
}
