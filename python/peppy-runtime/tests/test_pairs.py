"""Generated pairing code (`peppygen.paired_topics`, `mock.pairings`,
`mock.observed`) on the packages `peppy-launch sync` writes for
tests/pairs/{tarm,tcmd,twatch}: a node's setup under the generated harness
with its mock peer, and three generated nodes paired and observed over
real Zenoh sessions on loopback."""

from __future__ import annotations

import asyncio
import importlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest
from typing import Any, Dict, List, Optional

import peppy_testing as t

from peppy import ObservedSource, PeerInfo
from peppy.startup import peppy_launch

HERE = os.path.dirname(os.path.abspath(__file__))
NODES = ("tarm", "tcmd", "twatch")

_generated: Optional[str] = None


def setUpModule() -> None:
    """Generates the three packages once, in a copy of tests/pairs."""
    global _generated
    program = peppy_launch()
    if program is None:
        raise unittest.SkipTest("the tests of generated pairing code generate with peppy-launch: set PEPPY_LAUNCH")
    _generated = tempfile.mkdtemp(prefix="peppy-pairs-")
    shutil.copytree(os.path.join(HERE, "pairs"), _generated, dirs_exist_ok=True)
    for node in NODES:
        subprocess.run(
            [program, "sync", os.path.join(_generated, node), "--repo", _generated],
            check=True,
            capture_output=True,
            timeout=60,
        )


def tearDownModule() -> None:
    if _generated is not None:
        shutil.rmtree(_generated, ignore_errors=True)


def entry(node: str, dotted: Optional[str] = None) -> Any:
    """Node `node`'s generated package (imported as `pairs_<node>`), or one of its modules."""
    name = f"pairs_{node}"
    if name not in sys.modules:
        assert _generated is not None
        path = os.path.join(_generated, node, "peppygen")
        spec = importlib.util.spec_from_file_location(
            name, os.path.join(path, "__init__.py"), submodule_search_locations=[path]
        )
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return importlib.import_module(f"{name}.{dotted}") if dotted else sys.modules[name]


def arm_setup_of(replies: List[Any]) -> Any:
    """tarm's setup: answers each setpoint of its commander with a state of the same seq."""
    setpoint = entry("tarm", "paired_topics.commander.setpoint")
    state = entry("tarm", "paired_topics.commander.state")

    async def setup(params: Any, node_runner: Any) -> List[Any]:
        setpoints = await setpoint.subscribe(node_runner)
        states = await state.declare_publisher(node_runner)

        async def follow() -> None:
            async for peer, message in setpoints:
                replies.append(peer)
                joint = state.MessageJoint(name=f"from-{peer.producer.instance_id}")
                await states.publish(state.build_message(message.position * 2, message.seq, joint))

        return [asyncio.ensure_future(follow())]

    return setup


class GeneratedHarnessTest(unittest.IsolatedAsyncioTestCase):
    async def test_the_node_talks_with_its_mock_peer(self) -> None:
        harness = entry("tarm", "fixtures.harness")
        setpoint = entry("tarm", "paired_topics.commander.setpoint")
        state = entry("tarm", "paired_topics.commander.state")
        self.assertEqual(
            (state.TOPIC_NAME, state.LINK_ID, state.PAIRING_NAME, state.PAIRING_TAG),
            ("state", "commander", "tarm_link", "v1"),
        )
        peers: List[Any] = []
        async with harness.start(arm_setup_of(peers)) as h:
            commander = h.mocks.pairings.commander
            self.assertEqual(commander.instance_id, "mock-commander")
            info = state.paired(h.node_runner)
            self.assertIsInstance(info, PeerInfo)
            self.assertEqual(info, commander.peer_info())
            self.assertEqual((info.producer.instance_id, info.peer_link_id), ("mock-commander", "mock_peer"))
            for seq in range(3):
                await commander.setpoint.publish(setpoint.Message(position=seq + 0.5, seq=seq))
            got = [await commander.state.next(t.WAIT) for _ in range(3)]
            self.assertEqual([(m.seq, m.position) for m in got], [(0, 1.0), (1, 3.0), (2, 5.0)])
            self.assertEqual(got[0].joint.name, "from-mock-commander")
            self.assertEqual(peers[0], info)

    async def test_an_optional_slot_left_vacant_publishes_nothing(self) -> None:
        harness = entry("tcmd", "fixtures.harness")
        setpoint = entry("tcmd", "paired_topics.arm.setpoint")

        async def setup(params: Any, node_runner: Any) -> None:
            publisher = await setpoint.declare_publisher(node_runner)
            # Unpaired: a successful no-op.
            await publisher.publish(setpoint.build_message(1.0, 1))

        async with harness.start(setup, arm_vacant=True) as h:
            # The mock peer runs unpaired, and hears nothing.
            self.assertIsNone(setpoint.paired(h.node_runner))
            with self.assertRaises(TimeoutError):
                await h.mocks.pairings.arm.setpoint.next(0.3)


class GeneratedNodesTest(t.LiveTest):
    async def generated(self, node: str, instance: str, links: Optional[Dict[str, List[str]]] = None) -> Any:
        """Starts generated node `node` from a runtime config planned with `--link`."""
        gen = entry(node)
        args = ["--instance-id", instance]
        for link_id, targets in (links or {}).items():
            for target in targets:
                args += ["--link", f"{link_id}@{target}"]
        plan = t.plan(gen.DESCRIPTOR, args)
        endpoint = f"tcp/127.0.0.1:{t.free_port()}"
        plan.update(
            core_node="lab",
            namespace=self.namespace,
            zenoh={"mode": "peer", "listen": [endpoint], "connect": list(self.endpoints), "multicast_scouting": False},
        )
        self.endpoints.append(endpoint)
        path = os.path.join(self.tmp.name, f"{instance}.json")
        with open(path, "w") as f:
            json.dump(plan, f)
        runner = await asyncio.wait_for(gen.NodeBuilder().with_runtime_config(path).start(), t.WAIT)
        self.runners.append(runner)
        return runner

    async def test_a_commander_drives_its_arm_and_an_observer_watches(self) -> None:
        peers: List[Any] = []
        arm = await self.generated("tarm", "arm_1")
        task = asyncio.ensure_future(arm_setup_of(peers)(None, arm))
        watch = await self.generated("twatch", "watch_1", {"arms": ["arm_1/commander"]})
        cmd = await self.generated("tcmd", "cmd_1", {"arm": ["arm_1"]})
        setpoint = entry("tcmd", "paired_topics.arm.setpoint")
        state = entry("tcmd", "paired_topics.arm.state")
        watched = entry("twatch", "paired_topics.arms.state")
        tasks = await task
        try:
            info = await asyncio.wait_for(setpoint.wait_paired(cmd), t.WAIT)
            self.assertEqual((info.producer.instance_id, info.peer_link_id), ("arm_1", "commander"))
            states = await state.subscribe(cmd)
            observed = await watched.subscribe(watch)
            publisher = await setpoint.declare_publisher(cmd)

            async def drive() -> None:
                seq = 0
                while True:
                    await publisher.publish(setpoint.build_message(float(seq), seq))
                    seq += 1
                    await asyncio.sleep(0.02)

            tasks.append(asyncio.ensure_future(drive()))
            peer, message = await asyncio.wait_for(states.next(), t.WAIT)
            self.assertEqual((peer.producer.instance_id, message.joint.name), ("arm_1", "from-cmd_1"))
            self.assertEqual(message.position, 2 * message.seq)
            source, message = await asyncio.wait_for(observed.next(), t.WAIT)
            self.assertIsInstance(source, ObservedSource)
            self.assertEqual((source.producer.instance_id, source.source_link_id), ("arm_1", "commander"))
            self.assertEqual(
                [(s.producer.instance_id, s.source_link_id) for s in watched.sources(watch)], [("arm_1", "commander")]
            )
        finally:
            for x in tasks:
                x.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)


if __name__ == "__main__":
    unittest.main()
