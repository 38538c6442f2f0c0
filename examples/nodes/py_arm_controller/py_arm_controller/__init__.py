"""`py_arm_controller`: homes the Rust `robot_arm` with its `move_arm`
action, then sweeps the first joint between -1 and 1 rad from the arm's
joint states, exactly as the Rust `arm_controller` does."""

import asyncio
import sys

from peppy import PeppyError, ResultStatus
from peppygen import NodeBuilder, NodeRunner, QoSProfile
from peppygen.consumed_actions import robot_arm_move_arm
from peppygen.consumed_topics import robot_arm_joint_states
from peppygen.emitted_topics import joint_commands
from peppygen.parameters import Parameters


def say(text: str) -> None:
    print(text, flush=True)


async def home(node_runner: NodeRunner, max_velocity: float) -> None:
    """Sends the arm home, following its progress."""
    goal = robot_arm_move_arm.GoalRequest([0.5, 0.0, 0.0], max_velocity)
    while True:
        try:
            # The original Python order (goal, then timeout); the Rust-like
            # `ActionHandle.fire_goal(node_runner, 2.0, goal, qos)` is the same call.
            handle = await robot_arm_move_arm.fire_goal(
                node_runner, goal, 2.0, QoSProfile.STANDARD
            )
            break
        except PeppyError:
            # The arm may start after us.
            await asyncio.sleep(0.3)
    if not handle.data.accepted:
        say(f"homing refused: {handle.data.error_message or ''}")
        return
    try:
        while True:
            feedback = await handle.on_next_feedback_message()
            say(f"homing: {feedback.remaining:.2f} rad to go")
    except PeppyError:
        pass  # the feedback stream ends with the goal
    result = await handle.get_result(30.0)
    if result.outcome.status == ResultStatus.COMPLETED:
        r = result.outcome.data
        say(f"homed by {result.instance_id}: reached={r.reached} at {list(r.final_positions)}")
    else:
        say(f"homing ended: {result.outcome.status.name}")


def next_target(current: list, step: float, direction: float) -> tuple:
    """Sweeps the first joint, turning around at either end."""
    if current[0] >= 1.0 - 1e-9:
        direction = -1.0
    elif current[0] <= -1.0 + 1e-9:
        direction = 1.0
    target = list(current)
    target[0] = max(-1.0, min(1.0, current[0] + direction * step))
    return target, direction


async def control(params: Parameters, node_runner: NodeRunner) -> None:
    try:
        await home(node_runner, params.max_velocity)
    except PeppyError as e:
        print(f"homing failed: {e}", file=sys.stderr, flush=True)
    cycle, direction = 0, 1.0
    while True:
        arm, state = await robot_arm_joint_states.on_next_message_received(node_runner)
        cycle += 1
        target, direction = next_target(list(state.positions), params.step, direction)
        if cycle == 1 or cycle % 20 == 0:
            say(f"cycle {cycle}: {arm} at {list(state.positions)} -> target {target}")
        await joint_commands.emit(node_runner, target, params.max_velocity)


async def setup(params: Parameters, node_runner: NodeRunner) -> list:
    return [asyncio.create_task(control(params, node_runner))]


def main() -> None:
    NodeBuilder().run(setup)


if __name__ == "__main__":
    main()
