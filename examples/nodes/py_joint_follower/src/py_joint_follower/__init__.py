"""`py_joint_follower`: the follower of a `joint_link` pair. It moves its
joint toward each setpoint of its leader (only its own leader's reach it)
and streams the joint's state back; while unpaired it hears nothing and its
state goes nowhere."""

import asyncio

from peppygen import NodeRunner
from peppygen.paired_topics.leader import joint_setpoint, joint_state
from peppygen.parameters import Parameters


def step(position: float, target: float, gain: float) -> float:
    """The joint after one setpoint: `gain` of the way to `target`."""
    return position + gain * (target - position)


async def follow(params: Parameters, node_runner: NodeRunner) -> None:
    publisher = await joint_state.declare_publisher(node_runner)
    setpoints = await joint_setpoint.subscribe(node_runner)
    position = 0.0
    leader = None
    while True:
        received = await setpoints.next()
        if received is None:
            return
        peer, setpoint = received
        who = f"{peer.producer.instance_id}/{peer.peer_link_id}"
        if who != leader:
            print(f"paired with {who}", flush=True)
            leader = who
        position = step(position, setpoint.position, params.gain)
        await publisher.publish(joint_state.build_message(position, setpoint.sequence))


async def setup(params: Parameters, node_runner: NodeRunner) -> list:
    """The node's entry point, for `NodeBuilder.run` and the test harness."""
    return [asyncio.create_task(follow(params, node_runner))]
