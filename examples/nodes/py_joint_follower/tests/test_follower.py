"""py_joint_follower booted through its generated harness, its leader
played by the generated pairing mock over the real wire."""

from peppygen.fixtures import harness
from peppygen.paired_topics.leader import joint_setpoint

from py_joint_follower import setup, step

WAIT = 10.0


async def test_the_joint_tracks_its_leaders_setpoints():
    async with harness.start(setup, parameters={"gain": 0.5}) as h:
        leader = h.mocks.pairings.leader
        position = 0.0
        for sequence, target in enumerate([1.0, 1.0, -1.0]):
            await leader.joint_setpoint.publish(
                joint_setpoint.Message(position=target, sequence=sequence)
            )
            state = await leader.joint_state.next(WAIT)
            position = step(position, target, 0.5)
            assert state.setpoint_sequence == sequence
            assert abs(state.position - position) < 1e-12
