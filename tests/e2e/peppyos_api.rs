//! PeppyOS's current node API as its most complete robot code uses it,
//! end to end under the generated harness: `refine` pinning joint vectors
//! to `[f64; 7]` (while the wire keeps the contract's open arrays), declared
//! goal responses both ways, goals finished through a reference, one
//! `TopicPublisher` for pairing topics, an optional pairing slot left
//! unpaired beside its mock, a request-less service's mock, the mocks'
//! identities, a mock stopped without `.await`, and PeppyOS's error
//! variants. The nodes are the `limb_backbone` and `limb_panel` fixtures.
#![deny(warnings)]

use std::sync::Arc;
use std::time::Duration;

use peppy::{NodeRunner, QoSProfile, Result};

use crate::nodes::{limb_backbone, limb_panel};

const TIMEOUT: Duration = Duration::from_secs(10);

const HOME: [f64; 7] = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6];

/// The backbone: ready once asked twice; moves arm 0 only, with an
/// estimate; finishes each goal through a reference to its context.
async fn backbone(p: limb_backbone::Parameters, runner: Arc<NodeRunner>) -> Result<()> {
    use limb_backbone::exposed_actions::motion::move_joints;
    use limb_backbone::exposed_services::motion::is_ready;
    use limb_backbone::paired_topics::arm::joint_setpoints;
    use limb_backbone::parameters::limits::{Limits, LimitsVelocity};

    // A parameter group's types live in the group's module, defaults filled.
    let limits: &Limits = &p.limits;
    let velocity: &LimitsVelocity = &limits.velocity;
    assert_eq!((p.control_rate_hz, velocity.max_rad_s), (250, 1.5));
    assert_eq!(limits.torque_nm, 12.0);

    // A pairing topic's publisher is the one publisher type.
    let setpoints: peppy::TopicPublisher = joint_setpoints::declare_publisher(&runner).await?;
    // Unpaired (the slot is optional and left so): a successful no-op.
    // A built message is a value: cloned, it goes out twice.
    let home = joint_setpoints::build_message(HOME)?;
    setpoints.publish(home.clone()).await?;
    setpoints.publish(home).await?;
    assert!(setpoints.peer().is_none());

    let serving = runner.clone();
    tokio::spawn(async move {
        while is_ready::handle_next_request(&serving, |_req| Ok(is_ready::Response::new(true)))
            .await
            .is_ok()
        {}
    });
    let mut action = move_joints::ActionHandle::expose(&runner).await?;
    tokio::spawn(async move {
        loop {
            let next = action
                .handle_goal_next_request(|req: &move_joints::GoalRequest| {
                    let target: &[f64; 7] = &req.data.joint_positions;
                    if req.data.arm_id != 0 {
                        // A rejection may carry the response too.
                        return Ok(move_joints::GoalDecision::Reject {
                            reason: None,
                            response: Some(move_joints::GoalResponse { eta_s: -1.0 }),
                        });
                    }
                    let eta = target.iter().map(|q| q.abs()).sum::<f64>();
                    Ok(move_joints::GoalDecision::accept(
                        move_joints::GoalResponse { eta_s: eta },
                    ))
                })
                .await;
            let Ok(Some(ctx)) = next else { return };
            let ctx = Arc::new(ctx);
            let finishing = ctx.clone();
            tokio::spawn(async move {
                let ctx: &move_joints::GoalContext = &finishing;
                let target = ctx.request().data.joint_positions;
                let _ = ctx.publish_feedback(target).await;
                let _ = ctx.complete(true, target).await;
                // Only the first finish counts.
                let _ = ctx.complete_cancelled(false, HOME).await;
            });
        }
    });
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_backbone_pins_its_vectors_answers_with_its_estimate_and_starts_unpaired() -> Result<()> {
    use limb_backbone::fixtures::exposed_actions::motion::move_joints;
    use limb_backbone::fixtures::exposed_services::motion::is_ready;
    use limb_backbone::fixtures::harness::{Config, Harness};

    // The harness names the node, its document and its own session.
    {
        use limb_backbone::fixtures::harness as h;
        assert_eq!((h::NODE_NAME, h::NODE_TAG), ("limb_backbone", "v1"));
        assert!(std::fs::read_to_string(h::PEPPY_CONFIG_PATH)?.contains("limb_backbone"));
        assert_eq!(
            (h::FIXTURE_CORE_NODE, h::FIXTURE_INSTANCE_ID),
            ("fixture-core", "fixture-observer")
        );
    }
    let config = Config {
        arm_vacant: true,
        ..Config::default()
    };
    let (harness, mocks) = Harness::start_with(config, backbone).await?;
    // The optional slot's mock peer runs (not an `Option`), unpaired.
    let arm: &limb_backbone::mock::pairings::arm::Mock = &mocks.pairings.arm;
    assert!(!arm.inner().paired());
    assert_eq!(
        limb_backbone::mock::pairings::arm::peer_info().peer_link_id,
        limb_backbone::mock::pairings::arm::PEER_LINK_ID
    );
    assert!(is_ready::poll(&harness, TIMEOUT).await?.ready);

    let target = [0.5, -0.5, 0.25, 0.0, 0.0, 0.0, 1.0];
    let mut goal = move_joints::send_goal(
        &harness,
        &move_joints::GoalRequestData {
            arm_id: 0,
            joint_positions: target,
        },
        QoSProfile::Standard,
        TIMEOUT,
    )
    .await?;
    assert!(goal.accepted);
    assert_eq!(goal.data, Some(move_joints::GoalResponse { eta_s: 2.25 }));
    let feedback: move_joints::Feedback = goal.on_next_feedback().await?;
    assert_eq!(feedback.joint_positions, target);
    let result = goal.get_result(TIMEOUT).await?;
    assert_eq!(
        result.outcome,
        move_joints::ResultOutcome::Completed(move_joints::ResultData {
            success: true,
            final_joint_positions: target,
        })
    );

    let refused = move_joints::send_goal(
        &harness,
        &move_joints::GoalRequestData {
            arm_id: 3,
            joint_positions: HOME,
        },
        QoSProfile::Standard,
        TIMEOUT,
    )
    .await?;
    assert!(!refused.accepted);
    assert_eq!(refused.reason, None);
    assert_eq!(
        refused.data,
        Some(move_joints::GoalResponse { eta_s: -1.0 })
    );
    harness.shutdown().await
}

/// What the panel's calls came back with.
#[derive(Debug)]
struct Seen {
    ready: bool,
    accepted: bool,
    eta: Option<f64>,
    outcome: limb_panel::consumed_actions::motion::move_joints::ResultOutcome,
    bound: peppy::ProducerRef,
}

/// The panel: asks the backbone whether it is ready, sends one goal, and
/// reports what came back; then sends a second goal and drains its
/// feedback until the stream ends, reporting how it ended and the goal's
/// result.
async fn panel(
    runner: Arc<NodeRunner>,
    seen: tokio::sync::mpsc::Sender<Seen>,
    lost: tokio::sync::oneshot::Sender<(peppy::Error, ResultOutcome)>,
) -> Result<()> {
    use limb_panel::consumed_actions::motion::move_joints;
    use limb_panel::consumed_services::motion::is_ready;

    assert!(limb_panel::paired_topics::arms::source(&runner)?.is_none());
    let backbone = move_joints::bound_producer(&runner).clone();
    let ready = is_ready::poll(&runner, &backbone, TIMEOUT)
        .await?
        .data
        .ready;
    let handle = move_joints::ActionHandle::fire_goal(
        &runner,
        &backbone,
        TIMEOUT,
        move_joints::GoalRequest::new(0, HOME),
        QoSProfile::Standard,
    )
    .await?;
    let outcome = handle.get_result(TIMEOUT).await?.outcome;
    let _ = seen
        .send(Seen {
            ready,
            accepted: handle.accepted,
            eta: handle.data.as_ref().map(|d| d.eta_s),
            outcome,
            bound: backbone.clone(),
        })
        .await;
    let mut second = move_joints::ActionHandle::fire_goal(
        &runner,
        &backbone,
        TIMEOUT,
        move_joints::GoalRequest::new(0, HOME),
        QoSProfile::Standard,
    )
    .await?;
    // As PeppyOS's guide drains feedback: until a terminal error.
    let ended = loop {
        match second.on_next_feedback_message().await {
            Ok(_) => continue,
            Err(e) => break e,
        }
    };
    let outcome = second.get_result(TIMEOUT).await?.outcome;
    let _ = lost.send((ended, outcome));
    Ok(())
}

type ResultOutcome = limb_panel::consumed_actions::motion::move_joints::ResultOutcome;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panel_calls_its_mock_backbone_and_learns_of_its_loss() -> Result<()> {
    use limb_panel::fixtures::harness::{Config, Harness};
    use limb_panel::mock::deps::motion;

    let (seen_tx, mut seen_rx) = tokio::sync::mpsc::channel(1);
    let (lost_tx, lost_rx) = tokio::sync::oneshot::channel();
    let config = Config {
        arms_vacant: true,
        ..Config::default()
    };
    let (harness, mocks) = Harness::start_with(config, move |_p, runner| async move {
        tokio::spawn(async move {
            if let Err(e) = panel(runner, seen_tx, lost_tx).await {
                panic!("the panel failed: {e}");
            }
        });
        Ok(())
    })
    .await?;
    assert!(mocks.observed.arms.is_none());
    let backbone: &motion::Mock = &mocks.deps.motion;

    // A service without request data: a request is only a responder.
    let service: &motion::is_ready::Service = &backbone.is_ready;
    let responder: motion::is_ready::Responder = service.next_request(TIMEOUT).await?;
    responder
        .respond(motion::is_ready::ResponseData::new(true))
        .await?;
    assert_eq!(service.captured_count(), 1);

    let pending = backbone.move_joints.next_goal(TIMEOUT).await?;
    let asked: [f64; 7] = pending.request.joint_positions;
    assert_eq!(asked, HOME);
    let active = pending
        .accept(motion::move_joints::GoalResponseData::new(4.0))
        .await?;
    let active = &active;
    active
        .complete(&motion::move_joints::ResultResponseData::new(true, asked))
        .await?;

    let seen = tokio::time::timeout(TIMEOUT, seen_rx.recv())
        .await
        .expect("the panel reports")
        .expect("the panel runs");
    assert!(seen.ready && seen.accepted);
    assert_eq!(seen.eta, Some(4.0));
    assert_eq!(
        seen.outcome,
        limb_panel::consumed_actions::motion::move_joints::ResultOutcome::Completed(
            limb_panel::consumed_actions::motion::move_joints::ResultResponseData::new(true, HOME)
        )
    );
    // The slot's producer is the mock, core node and all.
    assert_eq!(seen.bound, motion::producer_ref());
    assert_eq!(seen.bound.core_node, motion::MOCK_CORE_NODE);

    // The second goal is accepted, then its server dies (stopped without
    // awaiting, PeppyOS's spelling): the panel's feedback loop ends with
    // `ActionFeedbackProducerGone`, and the goal is abandoned.
    let pending = backbone.move_joints.next_goal(TIMEOUT).await?;
    let _active = pending
        .accept(motion::move_joints::GoalResponseData::new(1.0))
        .await?;
    backbone.stop();
    let (ended, outcome) = tokio::time::timeout(TIMEOUT, lost_rx)
        .await
        .expect("the panel's feedback loop ends")
        .expect("the panel reports");
    assert!(
        matches!(ended, peppy::Error::ActionFeedbackProducerGone { .. }),
        "{ended:?}"
    );
    assert_eq!(outcome, ResultOutcome::Abandoned);
    harness.shutdown().await
}
