"""Pairs and observers between Python nodes on loopback (docs/PAIRINGS.md):
two commanders and two arms paired one to one, an impostor refused, an
observer of both arms, a side that stops and comes back."""

from __future__ import annotations

import asyncio
import json
import unittest
from typing import List, Tuple

import peppy_testing as t
from peppy import attachment, pairing
from peppy import keys as k
from peppy import spec as s
from peppy.bridge import END, ReplyStream
from peppy.errors import StartupError, WrongTopic
from peppy.pair_plan import PairEnd, PairPlan, fit_pair_plans, pair_plan_from_json

PAIRING, TAG = "arm_link", "v1"


def _topic(link: str, name: str, emitted: bool) -> s.PairingTopicSpec:
    return s.PairingTopicSpec(link, PAIRING, TAG, name, s.QoSProfile.RELIABLE, t.READING, emitted)


SETPOINT_OUT = _topic("arm", "setpoint", True)
STATE_IN = _topic("arm", "state", False)
STATE_OUT = _topic("commander", "state", True)
SETPOINT_IN = _topic("commander", "setpoint", False)
STATE_OBSERVED = _topic("arms", "state", False)

COMMANDER = s.NodeDescriptor(
    "commander",
    "v1",
    pairings=(s.PairingSlotSpec("arm", PAIRING, TAG, "commander", "arm"),),
    pairing_topics=(SETPOINT_OUT, STATE_IN),
)
ARM = s.NodeDescriptor(
    "arm",
    "v1",
    pairings=(s.PairingSlotSpec("commander", PAIRING, TAG, "arm", "commander"),),
    pairing_topics=(STATE_OUT, SETPOINT_IN),
)
WATCHER = s.NodeDescriptor(
    "watcher",
    "v1",
    pairings=(s.PairingSlotSpec("arms", PAIRING, TAG, "arm", "commander", observer=True, cardinality="one_or_more"),),
    pairing_topics=(STATE_OBSERVED,),
)


async def keep_sending(runner, spec, label: str) -> None:
    """Publishes a numbered reading every 20 ms until cancelled (no-ops while unpaired)."""
    seq = 0
    while True:
        await pairing.publish(runner, spec, t.Reading(seq, label))
        seq += 1
        await asyncio.sleep(0.02)


class Senders:
    """Tasks publishing until the test ends."""

    def __init__(self) -> None:
        self.tasks: List[asyncio.Task] = []

    def start(self, runner, spec, label: str) -> asyncio.Task:
        task = asyncio.ensure_future(keep_sending(runner, spec, label))
        self.tasks.append(task)
        return task

    async def stop(self) -> None:
        for task in self.tasks:
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)


async def take(runner, spec, count: int) -> List[Tuple[object, str]]:
    """`count` messages as (who, label)."""
    out = []
    for _ in range(count):
        who, message = await asyncio.wait_for(pairing.next_message(runner, spec), t.WAIT)
        out.append((who, message.label))
    return out


class PairKeysTest(unittest.TestCase):
    def test_keys_are_built_and_read_back(self):
        key = k.pair_claim_key("lab", PAIRING, TAG, "arm", "c1", "arm_1", "commander", None, None)
        self.assertEqual(key, "peppy/lab/pair/arm_link/v1/arm/c1/arm_1/commander/~/~")
        claim = k.parse_pair_claim_key(key)
        self.assertEqual((claim.instance, claim.peer_instance, claim.peer_link_id), ("arm_1", None, None))
        key = k.pair_claim_key("lab", PAIRING, TAG, "arm", "c1", "arm_1", "commander", "cmd_1", "arm")
        self.assertEqual(k.parse_pair_claim_key(key).peer_link_id, "arm")
        self.assertIsNone(k.parse_pair_claim_key("peppy/lab/pair/arm_link/v1/arm/c1/arm_1/commander/~/arm"))
        self.assertIsNone(k.parse_pair_claim_key("peppy/lab/live/c1/arm_1/arm/v1"))
        topic = k.pairing_topic_key("lab", PAIRING, TAG, "state", "c1", "arm_1", "commander")
        self.assertEqual(topic, "peppy/lab/topic/pairing/arm_link/v1/state/c1/arm_1/commander")
        self.assertEqual(k.parse_pairing_topic_key(topic).link_id, "commander")
        self.assertIsNone(k.parse_entry_key(topic), "a pairing topic is no node or interface entry")
        self.assertEqual(
            k.pair_claims_on_selector("lab", PAIRING, TAG, "commander", "arm_1", "commander"),
            "peppy/lab/pair/arm_link/v1/commander/*/*/*/arm_1/commander",
        )
        self.assertEqual(
            k.pair_claims_of_selector("lab", PAIRING, TAG, "arm", "arm_1"),
            "peppy/lab/pair/arm_link/v1/arm/*/arm_1/*/*/*",
        )

    def test_plans_fit_the_slots(self):
        plan = pair_plan_from_json({"link_id": "arms", "peers": [{"instance": "a"}, {"instance": "b", "link_id": "x"}]})
        self.assertEqual(plan.peers, (PairEnd("a"), PairEnd("b", "x")))
        self.assertEqual(plan.to_json()["peers"][1], {"instance": "b", "link_id": "x"})
        # A slot the plan leaves out starts empty: no peer, not vacant.
        self.assertEqual(fit_pair_plans([], COMMANDER.pairings), [PairPlan("arm")])
        self.assertEqual(fit_pair_plans([], WATCHER.pairings), [PairPlan("arms")])
        # In the node's slot order, whatever the plan's.
        both = (*COMMANDER.pairings, *WATCHER.pairings)
        planned = [PairPlan("arms", (PairEnd("a"), PairEnd("b", "x"))), PairPlan("arm", (PairEnd("a", "commander"),))]
        self.assertEqual(fit_pair_plans(planned, both), planned[::-1])
        self.assertEqual(fit_pair_plans(planned[:1], both), [PairPlan("arm"), planned[0]])
        # What a plan holds the launcher decided (peppy_schema::check_pair_plan):
        # the node takes it as it is.
        vacant = PairPlan("arm", vacant="bench")
        self.assertEqual(fit_pair_plans([vacant], COMMANDER.pairings), [vacant])
        # A plan for other slots: the node was generated from another document.
        for plans, words in (
            ([PairPlan("nope")], "fills pairing slot `nope`, which this node does not declare"),
            ([PairPlan("arm"), PairPlan("arm", (PairEnd("a"),))], "fills pairing slot `arm` twice"),
        ):
            with self.assertRaises(StartupError) as caught:
                fit_pair_plans(plans, COMMANDER.pairings)
            self.assertIn(words, str(caught.exception))
            self.assertIn("another peppy.json5", str(caught.exception))


class PairingTest(t.LiveTest):
    async def asyncSetUp(self) -> None:
        await super().asyncSetUp()
        self.senders = Senders()

    async def asyncTearDown(self) -> None:
        await self.senders.stop()
        await super().asyncTearDown()

    async def paired(self, runner, link_id: str):
        return await asyncio.wait_for(pairing.wait_paired(runner, link_id), t.WAIT)

    async def unpaired(self, runner, link_id: str) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + t.WAIT
        while pairing.paired(runner, link_id) is not None:
            self.assertLess(loop.time(), deadline, f"{runner.instance_id} stays paired")
            await asyncio.sleep(0.02)

    async def two_pairs(self):
        # The arms name no peer: each adopts the commander that claims it.
        arm_1 = await self.node(ARM, "arm_1")
        arm_2 = await self.node(ARM, "arm_2")
        cmd_1 = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        # Only the instance: its one `arm` slot is found on the wire.
        cmd_2 = await self.node(COMMANDER, "cmd_2", links=["arm@arm_2"])
        return arm_1, arm_2, cmd_1, cmd_2

    async def test_two_commanders_and_two_arms_pair_one_to_one(self):
        arm_1, arm_2, cmd_1, cmd_2 = await self.two_pairs()
        for runner, link, peer, peer_link in (
            (arm_1, "commander", "cmd_1", "arm"),
            (arm_2, "commander", "cmd_2", "arm"),
            (cmd_1, "arm", "arm_1", "commander"),
            (cmd_2, "arm", "arm_2", "commander"),
        ):
            info = await self.paired(runner, link)
            self.assertEqual((info.producer.instance_id, info.peer_link_id), (peer, peer_link))
            self.assertEqual(info.producer.core_node, "lab")
        for runner, spec, label in (
            (cmd_1, SETPOINT_OUT, "c1"),
            (cmd_2, SETPOINT_OUT, "c2"),
            (arm_1, STATE_OUT, "a1"),
            (arm_2, STATE_OUT, "a2"),
        ):
            self.senders.start(runner, spec, label)
        for runner, spec, peer, label in (
            (arm_1, SETPOINT_IN, "cmd_1", "c1"),
            (arm_2, SETPOINT_IN, "cmd_2", "c2"),
            (cmd_1, STATE_IN, "arm_1", "a1"),
            (cmd_2, STATE_IN, "arm_2", "a2"),
        ):
            got = await take(runner, spec, 10)
            self.assertEqual({(who.producer.instance_id, lab) for who, lab in got}, {(peer, label)})

    async def test_an_impostor_is_refused(self):
        arm_1, _, cmd_1, _ = await self.two_pairs()
        await self.paired(arm_1, "commander")
        await self.paired(cmd_1, "arm")
        # A third commander linked to the paired arm: its claim is ignored,
        # it never pairs, and what it puts on its own pairing keys is dropped.
        impostor = await self.node(COMMANDER, "cmd_3", links=["arm@arm_1/commander"])
        key = k.pairing_topic_key(self.namespace, PAIRING, TAG, "setpoint", "lab", "cmd_3", "arm")
        forged = impostor.session.declare_publisher(key)
        self.senders.start(cmd_1, SETPOINT_OUT, "c1")

        async def forge() -> None:
            seq = 0
            while True:
                forged.put(
                    t.READING.encode(t.Reading(seq, "forged")), attachment=attachment.topic(t.READING.fingerprint)
                )
                seq += 1
                await asyncio.sleep(0.01)

        self.senders.tasks.append(asyncio.ensure_future(forge()))
        got = await take(arm_1, SETPOINT_IN, 20)
        self.assertEqual({(who.producer.instance_id, lab) for who, lab in got}, {("cmd_1", "c1")})
        self.assertIsNone(pairing.paired(impostor, "arm"))
        self.assertEqual(pairing.paired(arm_1, "commander").producer.instance_id, "cmd_1")
        # Unpaired, the impostor's own publish succeeds and sends nothing.
        await pairing.publish(impostor, SETPOINT_OUT, t.Reading(0, "never"))
        forged.undeclare()

    async def test_an_observer_sees_both_arms(self):
        arm_1, arm_2, _, _ = await self.two_pairs()
        watcher = await self.node(WATCHER, "watcher_1", links=["arms@arm_1/commander", "arms@arm_2"])
        await self.paired(arm_1, "commander")
        await self.paired(arm_2, "commander")
        self.senders.start(arm_1, STATE_OUT, "a1")
        self.senders.start(arm_2, STATE_OUT, "a2")
        got = await take(watcher, STATE_OBSERVED, 40)
        self.assertEqual(
            {(who.producer.instance_id, who.source_link_id, lab) for who, lab in got},
            {("arm_1", "commander", "a1"), ("arm_2", "commander", "a2")},
        )
        self.assertEqual(
            [(x.producer.instance_id, x.source_link_id) for x in pairing.sources(watcher, "arms")],
            [("arm_1", "commander"), ("arm_2", "commander")],
        )
        # Observing takes no part: the pairs are the same.
        self.assertEqual(pairing.paired(arm_1, "commander").producer.instance_id, "cmd_1")
        # The descriptions show each slot's state.
        arm_info = (await self.describe(arm_1))["pairings"]
        self.assertEqual(
            arm_info,
            [
                {
                    "link_id": "commander",
                    "pairing": {"name": PAIRING, "tag": TAG},
                    "role": "arm",
                    "observer": False,
                    "claiming": "cmd_1/arm",
                    "peer": {"core_node": "lab", "instance_id": "cmd_1", "link_id": "arm"},
                }
            ],
        )
        watch_info = (await self.describe(watcher))["pairings"][0]
        self.assertEqual((watch_info["observer"], watch_info["role"]), (True, "arm"))
        self.assertEqual(
            watch_info["sources"],
            [
                {"core_node": "lab", "instance_id": "arm_1", "link_id": "commander", "live": True},
                {"core_node": "lab", "instance_id": "arm_2", "link_id": "commander", "live": True},
            ],
        )

    async def describe(self, runner):
        stream = ReplyStream(runner.loop, runner._track_mailbox)
        runner.session.get(
            k.describe_key(self.namespace, runner.core_node, runner.instance_id), stream.handler(), timeout=2
        )
        reply = await stream.next(runner.loop.time() + t.WAIT)
        self.assertIsNot(reply, END)
        return json.loads(reply.payload)

    async def test_closing_a_side_silences_the_survivor_and_a_restart_pairs_again(self):
        arm = await self.node(ARM, "arm_1")
        cmd = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        await self.paired(arm, "commander")
        sending = self.senders.start(cmd, SETPOINT_OUT, "first")
        await take(arm, SETPOINT_IN, 3)
        sending.cancel()
        await self.stop(cmd)
        await self.unpaired(arm, "commander")
        # The survivor's publish is a no-op; its subscription hears nothing.
        await pairing.publish(arm, STATE_OUT, t.Reading(0, "alone"))
        with self.assertRaises(asyncio.TimeoutError):
            await asyncio.wait_for(pairing.next_message(arm, SETPOINT_IN), 0.3)
        # The same instance comes back with the same plan: the pair forms
        # again without anyone's help, and nothing of the first run is handed out.
        cmd = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        info = await self.paired(arm, "commander")
        self.assertEqual(info.producer.instance_id, "cmd_1")
        await self.paired(cmd, "arm")
        self.senders.start(cmd, SETPOINT_OUT, "again")
        got = await take(arm, SETPOINT_IN, 5)
        self.assertEqual({lab for _, lab in got}, {"again"})

    async def test_a_new_peer_pairs_with_a_survivor(self):
        arm = await self.node(ARM, "arm_1")
        cmd = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        await self.paired(arm, "commander")
        await self.stop(cmd)
        await self.unpaired(arm, "commander")
        other = await self.node(COMMANDER, "cmd_9", links=["arm@arm_1"])
        info = await self.paired(arm, "commander")
        self.assertEqual((info.producer.instance_id, info.peer_link_id), ("cmd_9", "arm"))
        self.senders.start(other, SETPOINT_OUT, "nine")
        got = await take(arm, SETPOINT_IN, 3)
        self.assertEqual({(who.producer.instance_id, lab) for who, lab in got}, {("cmd_9", "nine")})

    async def test_held_publishers_and_subscriptions(self):
        arm = await self.node(ARM, "arm_1")
        cmd = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        publisher = await pairing.declare_publisher(cmd, SETPOINT_OUT)
        subscription = await pairing.subscribe(arm, SETPOINT_IN)
        with self.assertRaises(WrongTopic):
            await publisher.publish(pairing.build_message(STATE_OUT, t.Reading(0, "wrong topic")))
        await self.paired(cmd, "arm")
        await self.paired(arm, "commander")

        async def send() -> None:
            seq = 0
            while True:
                await publisher.publish(pairing.build_message(SETPOINT_OUT, t.Reading(seq, "held")))
                seq += 1
                await asyncio.sleep(0.02)

        self.senders.tasks.append(asyncio.ensure_future(send()))
        peer, message = await asyncio.wait_for(subscription.next(), t.WAIT)
        self.assertEqual((peer.producer.instance_id, peer.peer_link_id, message.label), ("cmd_1", "arm", "held"))
        arm.stop()
        self.assertIsNone(await asyncio.wait_for(subscription.next(), t.WAIT))

    async def test_an_observer_drops_what_a_stopped_source_left(self):
        arm = await self.node(ARM, "arm_1")
        watcher = await self.node(WATCHER, "watcher_1", links=["arms@arm_1/commander"])
        cmd = await self.node(COMMANDER, "cmd_1", links=["arm@arm_1/commander"])
        await self.paired(arm, "commander")
        self.senders.start(arm, STATE_OUT, "old")
        await take(watcher, STATE_OBSERVED, 2)
        await self.stop(arm)
        await self.unpaired(cmd, "arm")
        arm = await self.node(ARM, "arm_1")
        await self.paired(arm, "commander")
        self.senders.start(arm, STATE_OUT, "new")
        got = await take(watcher, STATE_OBSERVED, 3)
        self.assertEqual({lab for _, lab in got}, {"new"})


if __name__ == "__main__":
    unittest.main()
