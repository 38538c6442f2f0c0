//! Actions through the generated modules: goal accepted or rejected with a
//! reason, feedback, results, cancel, and goals abandoned by their worker.

use std::sync::Arc;
use std::time::Duration;

use peppy::{NodeRunner, QoSProfile};

use crate::nodes::{shapes, shapes_client};
use crate::support::{WAIT, eventually, hub, namespace, start};

/// Serves the three actions of the `shapes` fixture until the node stops.
/// `move_to` and `home` are exposed here and their handles moved into the
/// serving tasks; `scan` is exposed inside its task. Returns the serving
/// tasks, which end when the node stops.
async fn serve(server: Arc<NodeRunner>) -> Vec<tokio::task::JoinHandle<()>> {
    use shapes::exposed_actions::{home, move_to, scan};
    let mut handle = move_to::ActionHandle::expose(&server).await.unwrap();
    let moving = tokio::spawn(async move {
        while let Ok(Some(goal)) = handle
            .handle_goal_next_request(|request| {
                if request.data.speed <= 0.0 {
                    return Ok(move_to::GoalResponse::reject("speed must be positive"));
                }
                Ok(move_to::GoalResponse::accept())
            })
            .await
        {
            tokio::spawn(async move {
                let target = goal.request().data.target.clone();
                for step in 1..=3u8 {
                    let progress = f32::from(step) / 3.0;
                    let pose = move_to::MoveToFeedbackPose {
                        x: target.x * f64::from(progress),
                        y: target.y * f64::from(progress),
                    };
                    goal.publish_feedback(progress, pose).await.unwrap();
                }
                goal.complete(true, None).await.unwrap();
            });
        }
    });
    let runner = server.clone();
    let scanning = tokio::spawn(async move {
        let mut handle = scan::ActionHandle::expose(&runner).await.unwrap();
        while let Ok(Some(goal)) = handle
            .handle_goal_next_request(|_| Ok(scan::GoalResponse::accept()))
            .await
        {
            tokio::spawn(async move {
                // Works until cancelled, then reports what it has.
                goal.cancel_signal().await;
                assert!(goal.is_cancelled());
                let passes = goal.request().data.passes;
                let partial = vec![scan::ScanResultPointsItem {
                    x: f32::from(passes),
                    y: 0.0,
                }];
                goal.complete_cancelled(partial).await.unwrap();
            });
        }
    });
    let mut handle = home::ActionHandle::expose(&server).await.unwrap();
    drop(server);
    let homing = tokio::spawn(async move {
        while let Ok(Some(goal)) = handle
            .handle_goal_next_request(|r| {
                assert_eq!(r.instance_id, "client");
                Ok(home::GoalResponse::new(true, None))
            })
            .await
        {
            // Dropped without a result: the caller sees `Abandoned`.
            drop(goal);
        }
    });
    vec![moving, scanning, homing]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn goals_feedback_results_cancel_and_abandon() {
    let hub = hub().await;
    let ns = namespace("actions");
    let (_, client) =
        start::<shapes_client::Parameters>(&hub, &ns, "client", &["--bind", "shapes@shapes"]).await;
    let (_, server) =
        start::<shapes::Parameters>(&hub, &ns, "shapes", &crate::params::SHAPES_ARGS).await;
    let serving = serve(server.clone()).await;

    use shapes_client::consumed_actions::{shapes_home, shapes_move_to, shapes_scan};
    let t = Duration::from_secs(2);

    // Accepted, three feedback messages, then the result.
    let mut moving = eventually("the action server to answer", async || {
        let goal =
            shapes_move_to::GoalRequest::new(shapes_move_to::GoalTarget { x: 3.0, y: 6.0 }, 1.0);
        shapes_move_to::ActionHandle::fire_goal(&client, t, goal, QoSProfile::Reliable)
            .await
            .ok()
    })
    .await;
    assert!(moving.data.accepted, "{:?}", moving.data);
    assert!(!moving.goal_id().is_empty());
    let mut progress = Vec::new();
    for _ in 0..3 {
        let f = tokio::time::timeout(WAIT, moving.on_next_feedback_message())
            .await
            .unwrap()
            .unwrap();
        progress.push((f.progress, f.pose.x));
    }
    assert_eq!(progress.last(), Some(&(1.0, 3.0)));
    let result = moving.get_result(WAIT).await.unwrap();
    assert_eq!(result.instance_id, "shapes");
    match result.outcome {
        shapes_move_to::ResultOutcome::Completed(data) => {
            assert!(data.reached);
            assert_eq!(data.error, None);
        }
        other => panic!("{other:?}"),
    }
    // After the result, the feedback stream has ended.
    let ended = moving.on_next_feedback_message().await.unwrap_err();
    assert!(
        matches!(ended, peppy::Error::ActionFeedbackChannelClosed),
        "{ended}"
    );

    // Rejected with the server's reason.
    let refused = shapes_move_to::ActionHandle::fire_goal(
        &client,
        t,
        shapes_move_to::GoalRequest {
            target: shapes_move_to::GoalTarget { x: 0.0, y: 0.0 },
            speed: -1.0,
        },
        QoSProfile::Standard,
    )
    .await
    .unwrap();
    assert!(!refused.data.accepted);
    assert_eq!(
        refused.data.error_message.as_deref(),
        Some("speed must be positive")
    );

    // Cancelled: the worker is signalled and reports a partial result.
    let scanning = shapes_scan::ActionHandle::fire_goal(
        &client,
        t,
        shapes_scan::GoalRequest::new(4),
        QoSProfile::Standard,
    )
    .await
    .unwrap();
    assert!(scanning.data.accepted);
    let cancel = scanning.cancel_goal(t).await.unwrap();
    assert_eq!(cancel.state, shapes_scan::CancelState::Signalled);
    assert_eq!(cancel.instance_id, "shapes");
    match scanning.get_result(WAIT).await.unwrap().outcome {
        shapes_scan::ResultOutcome::Cancelled(data) => assert_eq!(data.points[0].x, 4.0),
        other => panic!("{other:?}"),
    }
    let again = scanning.cancel_goal(t).await.unwrap();
    assert_eq!(again.state, shapes_scan::CancelState::AlreadyTerminal);

    // A goal without data whose worker drops it: abandoned.
    let homing = shapes_home::ActionHandle::fire_goal(&client, t, QoSProfile::Standard)
        .await
        .unwrap();
    assert!(homing.data.accepted);
    let outcome = homing.get_result(WAIT).await.unwrap().outcome;
    assert_eq!(outcome, shapes_home::ResultOutcome::Abandoned);

    client.shutdown().await;
    server.shutdown().await;
    for task in serving {
        tokio::time::timeout(WAIT, task)
            .await
            .expect("serving tasks end when the node stops")
            .unwrap();
    }
}
