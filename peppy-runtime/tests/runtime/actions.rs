//! Actions: accept and reject, per-goal feedback, results that park until
//! terminal, cancel states, abandoned and expired goals, concurrent goals.

use std::time::Duration;

use peppy_runtime::codegen::{
    ActionSpec, ConsumedActionSpec, FormatSpec, OwnerSpec, next_goal, send_goal,
};
use peppy_runtime::{CancelState, Error, NodeBuilder, Outcome};

use crate::support::{WAIT, hub, namespace, start, test_node};

const GOAL: FormatSpec = FormatSpec {
    fingerprint: 0xa1,
    canonical: "{steps:u32}",
};
const FEEDBACK: FormatSpec = FormatSpec {
    fingerprint: 0xa2,
    canonical: "{done:u32}",
};
const RESULT: FormatSpec = FormatSpec {
    fingerprint: 0xa3,
    canonical: "{total:u32}",
};

static MOVE: ActionSpec = ActionSpec {
    owner: OwnerSpec::Own,
    name: "move_arm",
    goal: GOAL,
    feedback: FEEDBACK,
    result: RESULT,
};
static MOVE_CALL: ConsumedActionSpec = ConsumedActionSpec {
    link_id: "arm",
    owner: OwnerSpec::Node {
        name: "robot_arm",
        tag: "v1",
    },
    name: "move_arm",
    goal: GOAL,
    feedback: FEEDBACK,
    result: RESULT,
};

test_node!(
    Arm,
    r#"{ peppy_schema: "node_v1", manifest: { name: "robot_arm", tag: "v1" },
         interfaces: { actions: { exposes: [{ name: "move_arm",
           goal_service: { request_message_format: { steps: "u32" } },
           feedback_topic: { message_format: { done: "u32" } },
           result_service: { response_message_format: { total: "u32" } } }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [], actions: [MOVE]
);

test_node!(
    Planner,
    r#"{ peppy_schema: "node_v1", manifest: { name: "planner", tag: "v1", depends_on: { nodes: [{ name: "robot_arm", tag: "v1", link_id: "arm" }] } },
         interfaces: { actions: { consumes: [{ link_id: "arm", name: "move_arm" }] } },
         execution: { language: "rust", run_cmd: ["x"] } }"#,
    emits: [], consumes: [], serves: [], actions: []
);

/// Serves goals: rejects 0 steps, abandons 13, otherwise publishes one
/// feedback per step and completes (or completes cancelled when asked).
fn serve(runner: std::sync::Arc<peppy_runtime::NodeRunner>) {
    tokio::spawn(async move {
        while let Ok(goal) = next_goal::<u32>(&runner, &MOVE).await {
            let steps = goal.data;
            if steps == 0 {
                let _ = goal.reject("nothing to do");
                continue;
            }
            let Ok(ctx) = goal.accept() else { continue };
            tokio::spawn(async move {
                if steps == 13 {
                    drop(ctx);
                    return;
                }
                for done in 1..=steps {
                    if ctx.is_cancelled() {
                        let _ = ctx.complete_cancelled(&done);
                        return;
                    }
                    let _ = ctx.publish_feedback(&done).await;
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
                let _ = ctx.complete(&(steps * 10));
            });
        }
    });
}

async fn goal_until_up(
    planner: &peppy_runtime::NodeRunner,
    steps: u32,
) -> peppy_runtime::GoalClient {
    tokio::time::timeout(WAIT, async {
        loop {
            match send_goal(planner, &MOVE_CALL, Duration::from_secs(2), &steps).await {
                Ok(g) => return g,
                Err(Error::ServiceUnreachable { .. }) => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                Err(e) => panic!("{e}"),
            }
        }
    })
    .await
    .expect("the action server became reachable")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn goals_feedback_results_cancel_and_abandon() {
    let hub = hub().await;
    let ns = namespace("actions");
    let (_, arm) = start::<Arm>(&hub, &ns, "arm", &[]).await;
    let (_, planner) = start::<Planner>(&hub, &ns, "planner", &["--bind", "arm@arm"]).await;
    serve(arm.clone());

    // Rejected with a reason.
    let rejected = goal_until_up(&planner, 0).await;
    assert!(!rejected.accepted);
    assert_eq!(rejected.error_message.as_deref(), Some("nothing to do"));

    // Accepted: every feedback in order, then the stream ends, and the
    // result (fetched twice) is Completed.
    let mut g = goal_until_up(&planner, 5).await;
    assert!(g.accepted && g.instance_id == "arm");
    let result = tokio::time::timeout(WAIT, g.result::<u32>(WAIT))
        .await
        .unwrap()
        .unwrap();
    assert_eq!(result, Outcome::Completed(50));
    let mut feedback = Vec::new();
    loop {
        match tokio::time::timeout(WAIT, g.next_feedback::<u32>())
            .await
            .unwrap()
        {
            Ok(f) => feedback.push(f),
            Err(Error::ActionFeedbackChannelClosed) => break,
            Err(e) => panic!("{e}"),
        }
    }
    assert_eq!(feedback, [1, 2, 3, 4, 5]);
    assert_eq!(g.result::<u32>(WAIT).await.unwrap(), Outcome::Completed(50));
    assert_eq!(g.cancel(WAIT).await.unwrap(), CancelState::AlreadyTerminal);

    // Cancelled mid-way: Signalled, then a Cancelled result.
    let long = goal_until_up(&planner, 1000).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(long.cancel(WAIT).await.unwrap(), CancelState::Signalled);
    match long.result::<u32>(WAIT).await.unwrap() {
        Outcome::Cancelled(done) => assert!(done < 1000),
        other => panic!("{other:?}"),
    }

    // A worker that drops its goal: Abandoned.
    let dropped = goal_until_up(&planner, 13).await;
    assert_eq!(
        dropped.result::<u32>(WAIT).await.unwrap(),
        Outcome::Abandoned
    );

    // Concurrent goals on one server are independent.
    let (a, b) = tokio::join!(goal_until_up(&planner, 3), goal_until_up(&planner, 4));
    assert_ne!(a.goal_id(), b.goal_id());
    let (ra, rb) = tokio::join!(a.result::<u32>(WAIT), b.result::<u32>(WAIT));
    assert_eq!(
        (ra.unwrap(), rb.unwrap()),
        (Outcome::Completed(30), Outcome::Completed(40))
    );

    // A result that is not ready in time is a timeout (PeppyOS's
    // `ActionResultTimeout`: ask again), not unreachable.
    let slow = goal_until_up(&planner, 1000).await;
    assert!(matches!(
        slow.result::<u32>(Duration::from_millis(200)).await,
        Err(Error::ActionResultTimeout { .. })
    ));
    let _ = slow.cancel(WAIT).await;

    arm.shutdown().await;
    planner.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn results_expire_after_retention() {
    let hub = hub().await;
    let ns = namespace("expire");
    let args = [
        "node",
        "--instance-id",
        "arm",
        "--namespace",
        &ns,
        "--connect",
        &hub.endpoint,
    ];
    let (_, arm) = NodeBuilder::<Arm>::new()
        .with_runtime_config(None)
        .with_args(args)
        .action_result_retention(Duration::from_millis(300))
        .start()
        .await
        .unwrap();
    let (_, planner) = start::<Planner>(&hub, &ns, "planner", &["--bind", "arm@arm"]).await;
    serve(arm.clone());
    let g = goal_until_up(&planner, 1).await;
    assert_eq!(g.result::<u32>(WAIT).await.unwrap(), Outcome::Completed(10));
    tokio::time::sleep(Duration::from_millis(800)).await;
    assert_eq!(g.result::<u32>(WAIT).await.unwrap(), Outcome::Expired);
    arm.shutdown().await;
    planner.shutdown().await;
}

/// The planner's side of `move_arm`, built from another goal format.
static MOVE_CALL_STALE: ConsumedActionSpec = ConsumedActionSpec {
    link_id: "arm",
    owner: OwnerSpec::Node {
        name: "robot_arm",
        tag: "v1",
    },
    name: "move_arm",
    goal: FormatSpec {
        fingerprint: 0xbad,
        canonical: "{steps:u16}",
    },
    feedback: FEEDBACK,
    result: RESULT,
};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_goal_in_another_format_names_both_formats() {
    let hub = hub().await;
    let ns = namespace("actions-format");
    let (_, arm) = start::<Arm>(&hub, &ns, "arm", &[]).await;
    let (_, planner) = start::<Planner>(&hub, &ns, "planner", &["--bind", "arm@arm"]).await;
    serve(arm.clone());
    let err = tokio::time::timeout(WAIT, async {
        loop {
            match send_goal(&planner, &MOVE_CALL_STALE, Duration::from_secs(2), &5u16).await {
                Err(Error::ServiceUnreachable { .. }) => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                other => return other,
            }
        }
    })
    .await
    .expect("the action server became reachable")
    .unwrap_err();
    match err {
        Error::ServiceError {
            service_name,
            instance_id,
            reason,
        } => {
            assert_eq!(service_name, "move_arm (action goal)");
            assert_eq!(instance_id.as_deref(), Some("arm"));
            assert_eq!(
                reason,
                "the server expects request format {steps:u32}, this node sends {steps:u16}; rebuild one side"
            );
        }
        other => panic!("{other}"),
    }
    planner.shutdown().await;
    arm.shutdown().await;
}
