"""The test harness (`peppy.testing`): a node's own setup booted against
mock producers over a private router, with hand-written descriptors as
generated code writes them."""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import unittest
from typing import Any, List

from peppy_testing import (
    ADD_REQUEST,
    ADD_RESPONSE,
    CAMERA,
    MOVE_FEEDBACK,
    MOVE_GOAL,
    MOVE_RESULT,
    READING,
    WAIT,
    WIDE,
    AddRequest,
    AddResponse,
    MoveGoal,
    MoveResult,
    Reading,
    Wide,
    model_of,
)

from peppy import ResultStatus, clock, testing
from peppy import spec as s
from peppy.spec import QoSProfile
from peppy.peppylib_api import Subscription, declare_publisher, poll, subscribe

# relay:v1: reads `readings` (reliable) from its `cam` slot and re-emits
# each on its own `echo`; calls `add` and `move` on the same slot; serves
# `double` itself.
READINGS_IN = s.ConsumedTopicSpec("cam", CAMERA, "readings", QoSProfile.RELIABLE, READING)
ADD_CALLED = s.ConsumedServiceSpec("cam", CAMERA, "add", ADD_REQUEST, ADD_RESPONSE)
MOVE_CALLED = s.ConsumedActionSpec("cam", CAMERA, "move", MOVE_GOAL, MOVE_FEEDBACK, MOVE_RESULT)
ECHO_OUT = s.TopicSpec(s.Owner.own(), "echo", QoSProfile.RELIABLE, READING)
DOUBLE_SERVED = s.ServiceSpec(s.Owner.own(), "double", ADD_REQUEST, ADD_RESPONSE)

RELAY = s.NodeDescriptor(
    name="relay",
    tag="v1",
    slots=(s.SlotSpec("cam", "node", "camera", "v1", False, "one"),),
    emitted_topics=(ECHO_OUT,),
    consumed_topics=(READINGS_IN,),
    exposed_services=(DOUBLE_SERVED,),
    consumed_services=(ADD_CALLED,),
)
MOVER = s.NodeDescriptor(
    name="mover",
    tag="v1",
    slots=(s.SlotSpec("cam", "node", "camera", "v1", False, "zero_or_one"),),
    consumed_actions=(MOVE_CALLED,),
)
# The harness asks `peppy-launch plan` for each node's plan, from its model.
RELAY = dataclasses.replace(RELAY, model=model_of(RELAY))
MOVER = dataclasses.replace(MOVER, model=model_of(MOVER))


async def relay_setup(params: Any, node_runner: Any) -> List[Any]:
    sub: Subscription = await subscribe(node_runner, READINGS_IN)
    publisher = await declare_publisher(node_runner, ECHO_OUT)

    async def relay() -> None:
        async for _producer, reading in sub:
            await publisher.publish(ECHO_OUT.format.encode(reading))

    from peppy.services import handle_next

    async def serve() -> None:
        while not node_runner.is_stopping():
            await handle_next(node_runner, DOUBLE_SERVED, lambda _i, _c, r: AddResponse(2 * r.a))

    return [asyncio.ensure_future(relay()), asyncio.ensure_future(serve())]


class HarnessTests(unittest.IsolatedAsyncioTestCase):
    async def test_a_reliable_topic_from_a_mock_arrives_whole_and_in_order(self) -> None:
        async with testing.start(RELAY, relay_setup) as h:
            cam = h.mocks.deps.cam
            self.assertEqual(cam.instance_id, "mock-cam")
            for i in range(1000):
                await cam.readings.publish(Reading(i, f"r{i}"))
            got = [await h.emitted.echo.next(WAIT) for _ in range(1000)]
            self.assertEqual([r.seq for r in got], list(range(1000)))
            self.assertTrue(h.setup_finished())
            self.assertTrue(h.instance_id.startswith("test-"))
            self.assertEqual(await testing.poll_service(h, DOUBLE_SERVED, AddRequest(21, 0), WAIT), AddResponse(42))

    async def test_a_publish_returns_once_the_nodes_code_reads_the_topic(self) -> None:
        # The node's subscription is on the router from its start; the
        # publish still waits until setup, after slow work, subscribes.
        async def slow_setup(params: Any, node_runner: Any) -> List[Any]:
            await asyncio.sleep(0.3)
            return await relay_setup(params, node_runner)

        async with testing.start(RELAY, slow_setup) as h:
            self.assertFalse(h.setup_finished())
            await h.mocks.deps.cam.readings.publish(Reading(7, "late"))
            self.assertTrue(h.setup_finished())
            self.assertEqual((await h.emitted.echo.next(WAIT)).seq, 7)

    async def test_two_harnesses_run_at_once_without_sharing_anything(self) -> None:
        async def one(label: str) -> Reading:
            async with testing.start(RELAY, relay_setup) as h:
                await h.mocks.deps.cam.readings.publish(Reading(1, label))
                return await h.emitted.echo.next(WAIT)

        a, b = await asyncio.gather(one("a"), one("b"))
        self.assertEqual((a.label, b.label), ("a", "b"))

    async def test_a_message_in_another_format_is_dropped_not_delivered(self) -> None:
        async with testing.start(RELAY, relay_setup) as h:
            cam = h.mocks.deps.cam
            dropped = "dropping topic `readings` from `mock-cam`"
            with self.assertLogs("peppy", logging.WARNING) as logs:
                await cam.readings.publish_as(WIDE, Wide(7))
                await cam.readings.publish(Reading(8, "right"))
                got = await h.emitted.echo.next(WAIT)
                # The warning names the producer's own format text, asked
                # of it first: it may come after the right message.
                loop = asyncio.get_running_loop()
                deadline = loop.time() + WAIT
                while not any(dropped in line for line in logs.output) and loop.time() < deadline:
                    await asyncio.sleep(0.02)
            self.assertEqual(got, Reading(8, "right"))
            self.assertTrue(any(dropped in line for line in logs.output), logs)

    async def test_a_wait_that_times_out_names_what_it_waited_for(self) -> None:
        async with testing.start(RELAY, relay_setup) as h:
            with self.assertRaises(TimeoutError) as e:
                await h.mocks.deps.cam.add.next_request(0.2)
            self.assertIn("a request to service `add` on mock `mock-cam`", str(e.exception))

    async def test_services_scripted_and_manual_and_the_node_exposed_one(self) -> None:
        async def caller(params: Any, node_runner: Any) -> List[Any]:
            target = node_runner.bound_producer("cam")

            async def go() -> None:
                for a in (1, 2, 3):
                    try:
                        _, _, r = await poll(node_runner, ADD_CALLED, target, AddRequest(a, 10), WAIT)
                        print("sum", r.sum)
                    except RuntimeError as e:
                        print("error", e)

            return [asyncio.ensure_future(go())]

        async with testing.start(RELAY, caller) as h:
            add = h.mocks.deps.cam.add
            add.enqueue_response(AddResponse(11))
            request, responder = await add.next_request(WAIT)
            self.assertEqual(request, AddRequest(2, 10))
            await responder.respond(AddResponse(12))
            request, responder = await add.next_request(WAIT)
            await responder.respond_error("broken")
            self.assertEqual([r.a for r in add.captured()], [1, 2, 3])
            self.assertEqual(add.captured_count(), 3)
            # `caller` never serves its `double`: the call names it when it times out.
            with self.assertRaises(TimeoutError) as e:
                await testing.poll_service(h, DOUBLE_SERVED, AddRequest(21, 0), 2.0)
            self.assertIn("double", str(e.exception))

    async def test_a_setup_that_raises_fails_through_shutdown_and_pending_waits(self) -> None:
        async def broken(params: Any, node_runner: Any) -> None:
            await asyncio.sleep(0.05)
            raise RuntimeError("hardware missing")

        h = await testing.start(RELAY, broken)
        with self.assertRaisesRegex(RuntimeError, "hardware missing"):
            await h.mocks.deps.cam.add.next_request(WAIT)
        self.assertFalse(h.setup_finished())
        with self.assertRaisesRegex(RuntimeError, "hardware missing"):
            await h.shutdown()

    async def test_actions_from_a_mock_and_a_vacant_slot(self) -> None:
        results: List[Any] = []

        async def mover(params: Any, node_runner: Any) -> List[Any]:
            from peppy.peppylib_api import fire_goal_at

            async def go() -> None:
                target = node_runner.bound_producer("cam")
                client = await fire_goal_at(node_runner, MOVE_CALLED, target, MoveGoal(2.0), WAIT)
                results.append(await client.next_feedback())
                results.append(await client.get_result(WAIT))

            return [asyncio.ensure_future(go())]

        async with testing.start(MOVER, mover) as h:
            pending = await h.mocks.deps.cam.move.next_goal(WAIT)
            self.assertEqual(pending.request, MoveGoal(2.0))
            active = await pending.accept()
            await active.publish_feedback(MOVE_FEEDBACK.cls(0.5))
            await active.complete(MoveResult(2.0))
            async def both() -> None:
                while len(results) < 2:
                    await asyncio.sleep(0.01)

            await asyncio.wait_for(both(), WAIT)
            self.assertEqual(results[1], (ResultStatus.COMPLETED, MoveResult(2.0)))

        async with testing.start(MOVER, lambda p, n: None, cam_vacant=True) as h:
            self.assertIsNone(h.mocks.deps.cam)
            self.assertIsNone(h.node_runner.bound_producer("cam"))

    async def test_a_goals_server_lost_ends_its_feedback_with_a_connection_error(self) -> None:
        ended: List[Any] = []

        async def mover(params: Any, node_runner: Any) -> List[Any]:
            from peppy.peppylib_api import fire_goal_at

            async def go() -> None:
                target = node_runner.bound_producer("cam")
                client = await fire_goal_at(node_runner, MOVE_CALLED, target, MoveGoal(1.0), WAIT)
                try:
                    while True:
                        await client.next_feedback()
                except ConnectionError as e:
                    ended.append(e)
                ended.append(await client.get_result(WAIT))

            return [asyncio.ensure_future(go())]

        async with testing.start(MOVER, mover) as h:
            pending = await h.mocks.deps.cam.move.next_goal(WAIT)
            active = await pending.accept()
            # The server is lost with the goal running: no clean close.
            await h.mocks.deps.cam.stop()

            async def both() -> None:
                while len(ended) < 2:
                    await asyncio.sleep(0.01)

            await asyncio.wait_for(both(), WAIT)
            del active
            self.assertIn("went away before closing the feedback stream", str(ended[0]))
            self.assertEqual(ended[1], (ResultStatus.ABANDONED, None))

    async def test_sim_ticks_reach_the_node_clock_and_wall_offsets_skew_sync(self) -> None:
        async def reader(params: Any, node_runner: Any) -> None:
            await clock.init(node_runner)

        async with testing.start(RELAY, reader, use_sim_time=True) as h:
            await h.clock.tick(1_000_000_000)
            self.assertEqual(clock.now_ns(), 1_000_000_000)
            await h.clock.tick(2_500_000_000)
            self.assertEqual(clock.now_ns(), 2_500_000_000)
            sync = await clock.synchronize(h.node_runner)
            self.assertEqual(sync.raw.server_recv_time, 2_500_000_000)
        async with testing.start(RELAY, lambda p, n: None) as h:
            h.clock.set_offset_ns(3_600_000_000_000)
            sync = await clock.synchronize(h.node_runner)
            self.assertGreater(sync.offset_ns, 1_800_000_000_000)


if __name__ == "__main__":
    unittest.main()


class CoreNodeTests(unittest.IsolatedAsyncioTestCase):
    """The harness is the node's core node: its datastore, `info` and
    stack listing answer as a launch's do (docs/WIRE.md, "Core node functions")."""

    async def test_the_datastore_keeps_values_with_their_writer_and_info_and_stack_answer(self) -> None:
        from peppy import datastore, stack
        from peppy.info import info

        async with testing.start(RELAY, lambda p, n: None) as h:
            runner = h.node_runner
            self.assertIsNone(await datastore.get(runner, "calibration/wrist", 3.0))
            await datastore.store(runner, "calibration/wrist", b'{"x": 0.1}', datastore.Encoding.APPLICATION_JSON, 3.0)
            await datastore.store(runner, "lock", b"locked", "text/plain")
            stored = await datastore.get(runner, "calibration/wrist", 3.0)
            self.assertEqual(stored.value, b'{"x": 0.1}')
            self.assertEqual(stored.encoding, datastore.Encoding.APPLICATION_JSON)
            self.assertEqual(stored.last_modified_by, h.instance_id)
            entries = await datastore.list(runner, 3.0)
            self.assertEqual([e.key for e in entries], ["calibration/wrist", "lock"])
            self.assertTrue(await datastore.remove(runner, "lock", 3.0))
            self.assertFalse(await datastore.remove(runner, "lock", 3.0))
            with self.assertRaises(ValueError):
                await datastore.get(runner, "", 3.0)

            facts = await info(runner, 3.0)
            self.assertEqual((facts.core_node_name, facts.node_count), ("standalone-core", 1))
            listed = await stack.list(runner, 3.0)
            self.assertEqual(listed.core_node, "standalone-core")
            self.assertEqual(listed.running_instance_ids_by_node("relay", "v1"), [h.instance_id])
            with self.assertRaises(KeyError):
                listed.running_instance_ids_by_node("nobody", "v1")
