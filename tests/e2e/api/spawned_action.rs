// An exposed action served from a spawned task: the handle owns what it
// needs, so it moves into `tokio::spawn` while the runner stays an `Arc`
// (the shape of the original's node code).
#![deny(warnings)]

#[peppy::node("tests/e2e/api/actions.json5")]
mod peppygen {}

use std::sync::Arc;

use peppygen::exposed_actions::{home, move_to};
use peppygen::{NodeBuilder, NodeRunner, Parameters, Result};

/// A handle kept in a struct: no lifetime to name.
struct Homing {
    action: home::ActionHandle,
}

fn node_main() -> Result<()> {
    NodeBuilder::new().run(|_: Parameters, runner: Arc<NodeRunner>| async move {
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

#[test]
fn compiles_and_runs() {
    let _ = node_main;
}
