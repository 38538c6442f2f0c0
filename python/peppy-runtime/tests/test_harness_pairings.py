"""The test harness's pairing surfaces: a node's participant slot paired
with a mock peer (`h.mocks.pairings.<link_id>`) before its setup runs, and
its observer slots fed by mock sources (`h.mocks.observed.<link_id>`)."""

from __future__ import annotations

import asyncio
import dataclasses
import unittest
from typing import Any, List

from peppy_testing import READING, WAIT, Reading, model_of

from peppy import pairing, testing
from peppy import spec as s
from peppy.spec import QoSProfile

PAIRING, TAG = "arm_link", "v1"


def _topic(link: str, name: str, emitted: bool) -> s.PairingTopicSpec:
    return s.PairingTopicSpec(link, PAIRING, TAG, name, QoSProfile.RELIABLE, READING, emitted)


# follower:v1 plays `arm` with its `leader` slot: it answers each setpoint
# with a state of the same seq; it also watches other arms (`others`).
SETPOINT_IN = _topic("leader", "setpoint", False)
STATE_OUT = _topic("leader", "state", True)
OTHERS_STATE = _topic("others", "state", False)
FOLLOWER = s.NodeDescriptor(
    "follower",
    "v1",
    pairings=(
        s.PairingSlotSpec("leader", PAIRING, TAG, "arm", "commander"),
        s.PairingSlotSpec("others", PAIRING, TAG, "arm", "commander", observer=True, cardinality="zero_or_more"),
    ),
    pairing_topics=(SETPOINT_IN, STATE_OUT, OTHERS_STATE),
)
FOLLOWER = dataclasses.replace(FOLLOWER, model=model_of(FOLLOWER))

# spare:v1: an optional commander slot.
SPARE = s.NodeDescriptor(
    "spare",
    "v1",
    pairings=(s.PairingSlotSpec("arm", PAIRING, TAG, "commander", "arm", optional=True),),
    pairing_topics=(_topic("arm", "setpoint", True), _topic("arm", "state", False)),
)
SPARE = dataclasses.replace(SPARE, model=model_of(SPARE))


async def follower_setup(params: Any, node_runner: Any) -> List[Any]:
    # The harness pairs the slot before setup: no wait needed here.
    peer = pairing.paired(node_runner, "leader")
    assert peer is not None, "the harness starts setup once the pair holds"
    setpoints = await pairing.subscribe(node_runner, SETPOINT_IN)
    states = await pairing.declare_publisher(node_runner, STATE_OUT)
    others = await pairing.subscribe(node_runner, OTHERS_STATE)
    seen = node_runner.seen = []

    async def follow() -> None:
        async for _peer, setpoint in setpoints:
            await states.publish(pairing.build_message(STATE_OUT, Reading(setpoint.seq, "state")))

    async def watch() -> None:
        async for source, state in others:
            seen.append((source.producer.instance_id, source.source_link_id, state.label))

    return [asyncio.ensure_future(follow()), asyncio.ensure_future(watch())]


class PairingHarnessTests(unittest.IsolatedAsyncioTestCase):
    async def test_the_mock_peer_pairs_before_setup_and_talks_with_the_node(self) -> None:
        async with testing.start(FOLLOWER, follower_setup, others_instances=2) as h:
            leader = h.mocks.pairings.leader
            self.assertIsInstance(leader, testing.PairingMock)
            self.assertEqual(leader.instance_id, "mock-leader")
            self.assertTrue(leader.paired())
            info = pairing.paired(h.node_runner, "leader")
            self.assertEqual((info.producer.instance_id, info.peer_link_id), ("mock-leader", "mock_peer"))
            self.assertEqual(leader.peer_info(), info)
            for seq in range(5):
                await leader.setpoint.publish(Reading(seq, "go"))
            got = [await leader.state.next(WAIT) for _ in range(5)]
            self.assertEqual([(m.seq, m.label) for m in got], [(i, "state") for i in range(5)])

            others = h.mocks.observed.others
            self.assertEqual([m.instance_id for m in others], ["mock-others-0", "mock-others-1"])
            # Known from the start, with the launch each runs in.
            self.assertEqual(pairing.sources(h.node_runner, "others"), [m.source() for m in others])
            self.assertEqual(
                [(x.producer.instance_id, x.source_link_id) for x in pairing.sources(h.node_runner, "others")],
                [("mock-others-0", "mock_source"), ("mock-others-1", "mock_source")],
            )
            await others[0].state.publish(Reading(1, "zero"))
            await others[1].state.publish(Reading(1, "one"))
            loop = asyncio.get_running_loop()
            deadline = loop.time() + WAIT
            while len(h.node_runner.seen) < 2 and loop.time() < deadline:
                await asyncio.sleep(0.02)
            self.assertEqual(
                sorted(h.node_runner.seen),
                [("mock-others-0", "mock_source", "zero"), ("mock-others-1", "mock_source", "one")],
            )

    async def test_a_stopped_mock_peer_unpairs_the_node(self) -> None:
        async with testing.start(FOLLOWER, follower_setup) as h:
            self.assertEqual(h.mocks.observed.others, [])
            await h.mocks.pairings.leader.stop()
            loop = asyncio.get_running_loop()
            deadline = loop.time() + WAIT
            while pairing.paired(h.node_runner, "leader") is not None:
                self.assertLess(loop.time(), deadline, "the node stays paired with a stopped mock")
                await asyncio.sleep(0.02)

    async def test_an_optional_slot_left_vacant_starts_unpaired_beside_its_mock(self) -> None:
        # As PeppyOS's harness: the mock peer runs, but neither side claims
        # the other.
        async with testing.start(SPARE, lambda p, r: None, arm_vacant=True) as h:
            self.assertFalse(h.mocks.pairings.arm.paired())
            self.assertIsNone(pairing.paired(h.node_runner, "arm"))
            self.assertEqual(h.node_runner.pairs[0].vacant, "left vacant by the test harness")
        with self.assertRaises(TypeError):
            await testing.start(FOLLOWER, follower_setup, leader_vacant=True)


if __name__ == "__main__":
    unittest.main()
