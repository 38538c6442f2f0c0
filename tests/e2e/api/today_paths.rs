//! Today's `node/v1` module paths compile, as PeppyOS's nodes write them:
//! a contract's members under the `implements` link_id, consumed entries
//! under their slot's link_id next to its typed bound-producer accessor.
#![deny(warnings)]

#[peppy::node("peppy-build/tests/fixtures/gripper_driver/peppy.json5")]
mod driver {}

#[peppy::node("peppy-build/tests/fixtures/grasp_planner/peppy.json5")]
mod planner {}

use std::time::Duration;

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
    let _ = driver::exposed_actions::hand::grasp::ActionHandle::expose(runner).await?;
    Ok(())
}

async fn plan(runner: &planner::NodeRunner) -> planner::Result<()> {
    let main: &str = planner::consumed_topics::main_hand::bound_producer(runner);
    let spares: &[String] = planner::consumed_topics::spare_hands::bound_producers(runner);
    let _ = (main, spares);
    let _ = planner::consumed_services::main_hand::bound_producer(runner);
    let _ = planner::consumed_actions::spare_hands::bound_producers(runner);
    let (_, message) =
        planner::consumed_topics::main_hand::joint_state::on_next_message_received(runner, None)
            .await?;
    let _: f64 = message.position;
    let _ =
        planner::consumed_topics::spare_hands::joint_state::on_next_message_received(runner, None)
            .await?;
    let reply = planner::consumed_services::main_hand::set_force::poll(
        runner,
        Duration::from_secs(1),
        planner::consumed_services::main_hand::set_force::Request::new(2.0),
    )
    .await?;
    let _: bool = reply.data.ok;
    Ok(())
}

#[test]
fn todays_paths_compile() {
    // Compiling is the check; naming the functions keeps them used.
    let _ = (drive, plan);
}
