//! The `node/v1` module paths and the peppylib API compile, as PeppyOS's
//! nodes write them (compiled, not run; tests/e2e/peppyos_api.rs runs the
//! API): a contract's members under the `implements` link_id,
//! consumed entries under their slot's link_id next to its typed
//! bound-producer accessor, declared publishers, held subscriptions, calls
//! to an explicit target and `GoalDecision`.
#![deny(warnings)]

#[peppy::node("peppy-build/tests/fixtures/gripper_driver/peppy.json5")]
mod driver {}

#[peppy::node("peppy-build/tests/fixtures/grasp_planner/peppy.json5")]
mod planner {}

use std::time::Duration;

#[allow(dead_code)] // compiled, not run: the paths are the check
async fn drive(runner: &driver::NodeRunner) -> driver::Result<()> {
    driver::emitted_topics::status::emit(runner, true).await?;
    driver::emitted_topics::hand::joint_state::emit(runner, 0.5).await?;
    driver::exposed_services::hand::set_force::handle_next_request(runner, |request| {
        let _: f32 = request.data.newtons;
        Ok(driver::exposed_services::hand::set_force::Response::new(
            true,
        ))
    })
    .await?;
    let publisher = driver::emitted_topics::status::declare_publisher(runner).await?;
    publisher
        .publish(driver::emitted_topics::status::build_message(true)?)
        .await?;
    use driver::exposed_actions::hand::grasp;
    let mut action = grasp::ActionHandle::expose(runner).await?;
    let mut seen = 0;
    let next = action
        .handle_goal_next_request(|request: &grasp::GoalRequest| {
            seen += 1;
            if request.data.width > 0.1 {
                Ok(grasp::GoalDecision::reject("too wide"))
            } else {
                Ok(grasp::GoalDecision::accept())
            }
        })
        .await?;
    if let Some(ctx) = next {
        ctx.publish_feedback(0.5).await?;
        ctx.complete(true).await?;
    }
    let _ = seen;
    Ok(())
}

#[allow(dead_code)] // compiled, not run: the paths are the check
async fn plan(runner: &planner::NodeRunner) -> planner::Result<()> {
    let main: &planner::ProducerRef = planner::consumed_topics::main_hand::bound_producer(runner);
    let spares: &[planner::ProducerRef] =
        planner::consumed_topics::spare_hands::bound_producers(runner);
    let _ = (main, spares);
    // Each entry module repeats its slot's accessor.
    let main = planner::consumed_services::main_hand::set_force::bound_producer(runner);
    let _ = planner::consumed_actions::spare_hands::bound_producers(runner);
    let mut subscription =
        planner::consumed_topics::main_hand::joint_state::subscribe(runner).await?;
    if let Some((producer, message)) = subscription.next().await? {
        let _: (&str, f64) = (&producer.instance_id, message.position);
    }
    let (_, message) =
        planner::consumed_topics::main_hand::joint_state::on_next_message_received(runner, None)
            .await?;
    let _: f64 = message.position;
    let _ =
        planner::consumed_topics::spare_hands::joint_state::on_next_message_received(runner, None)
            .await?;
    let reply = planner::consumed_services::main_hand::set_force::poll(
        runner,
        main,
        Duration::from_secs(1),
        planner::consumed_services::main_hand::set_force::Request::new(2.0),
    )
    .await?;
    let _: bool = reply.data.ok;
    use planner::consumed_actions::spare_hands::grasp;
    if let Some(hand) = grasp::bound_producers(runner).first() {
        let handle = grasp::ActionHandle::fire_goal(
            runner,
            hand,
            Duration::from_secs(1),
            grasp::GoalRequest::new(0.05),
            planner::QoSProfile::Standard,
        )
        .await?;
        let (_, _): (bool, Option<String>) = (handle.accepted, handle.reason.clone());
        let _ = handle.get_result(Duration::from_secs(1)).await?;
    }
    Ok(())
}
