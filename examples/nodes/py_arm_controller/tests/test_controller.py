"""py_arm_controller booted through its generated harness: the mock
robot_arm plays the arm, answering the homing goal and feeding joint states."""

import pytest

from peppygen.consumed_actions import robot_arm_move_arm as move_arm
from peppygen.consumed_topics import robot_arm_joint_states as joint_states
from peppygen.fixtures import harness

from py_arm_controller import setup

WAIT = 10.0
PARAMETERS = {"step": 0.25, "max_velocity": 2.0}


async def test_homes_the_arm_then_steps_the_first_joint():
    async with harness.start(setup, parameters=PARAMETERS) as h:
        arm = h.mocks.deps.robot_arm
        pending = await arm.move_arm.next_goal(WAIT)
        assert pending.request.target_positions == [0.5, 0.0, 0.0]
        assert pending.request.max_velocity == 2.0
        active = await pending.accept()
        await active.publish_feedback(move_arm.FeedbackMessage(remaining=0.25))
        await active.complete(move_arm.ResultResponseData(reached=True, final_positions=[0.5, 0.0, 0.0]))

        await arm.joint_states.publish(
            joint_states.Message(positions=[0.5, 0.0, 0.0], velocities=[0.0, 0.0, 0.0], timestamp=1.0)
        )
        command = await h.emitted.joint_commands.next(WAIT)
        assert command.target_positions == pytest.approx([0.75, 0.0, 0.0])
        assert command.max_velocity == 2.0


async def test_a_rejected_homing_still_follows_joint_states():
    async with harness.start(setup, parameters=PARAMETERS) as h:
        arm = h.mocks.deps.robot_arm
        await (await arm.move_arm.next_goal(WAIT)).reject("busy")
        await arm.joint_states.publish(
            joint_states.Message(positions=[1.0, 0.0, 0.0], velocities=[0.0, 0.0, 0.0], timestamp=1.0)
        )
        command = await h.emitted.joint_commands.next(WAIT)
        # At the end of its sweep the first joint turns around.
        assert command.target_positions == pytest.approx([0.75, 0.0, 0.0])

