"""PeppyOS's peppylib node API (`node/v1` documents) on the code `peppy-launch sync`
generates for tests/peppylib_api/{tcam,tviewer}: publishers and held
subscriptions, polls and goals aimed at a bound producer, GoalDecision,
shutdown hooks and their grace window, the stack clock (wall and sim) and
the runtime config's `use_sim_time` and `shutdown_grace_secs`. Real Zenoh
sessions on loopback; nodes planned by this build's `peppy-launch`."""

from __future__ import annotations

import asyncio
import importlib
import importlib.util
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest
from typing import Any, Dict, List, Optional

import peppy_testing as t

from peppy import ClockNotReady, ProducerRef, ShuttingDown, StartupError
from peppy import clock as peppy_clock
from peppy.keys import clock_sync_key, clock_tick_key
from peppy.startup import SHUTDOWN_GRACE_ENV, peppy_launch

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(os.path.dirname(HERE), "src")

_generated: Optional[str] = None


def setUpModule() -> None:
    """Generates the two packages once, in a copy of tests/peppylib_api."""
    global _generated
    program = peppy_launch()
    if program is None:
        raise unittest.SkipTest("the tests of the peppylib API generate their packages with peppy-launch: set PEPPY_LAUNCH")
    _generated = tempfile.mkdtemp(prefix="peppy-peppylib-")
    shutil.copytree(os.path.join(HERE, "peppylib_api"), _generated, dirs_exist_ok=True)
    for node in ("tcam", "tviewer"):
        subprocess.run(
            [program, "sync", os.path.join(_generated, node), "--repo", _generated],
            check=True,
            capture_output=True,
            timeout=60,
        )


def tearDownModule() -> None:
    if _generated is not None:
        shutil.rmtree(_generated, ignore_errors=True)


def package(node: str) -> Any:
    """Node `node`'s generated `peppygen`, imported as `gen_<node>` (two
    packages of one name cannot share a process)."""
    name = f"gen_{node}"
    if name in sys.modules:
        return sys.modules[name]
    assert _generated is not None
    path = os.path.join(_generated, node, "peppygen")
    spec = importlib.util.spec_from_file_location(
        name, os.path.join(path, "__init__.py"), submodule_search_locations=[path]
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def entry(node: str, dotted: str) -> Any:
    """A module of node `node`'s generated package."""
    package(node)
    return importlib.import_module(f"gen_{node}.{dotted}")


class PeppylibTest(t.LiveTest):
    async def start(
        self,
        node: str,
        instance: str,
        links: Optional[Dict[str, List[str]]] = None,
        core: str = "lab",
        **config: Any,
    ) -> Any:
        """Starts a `node/v1` node from a runtime config planned
        with `--link` (extra top-level `config` fields as given)."""
        gen = package(node)
        args = ["--instance-id", instance]
        for link_id, producers in (links or {}).items():
            for producer in producers:
                args += ["--link", f"{link_id}@{producer}"]
        plan = t.plan(gen.DESCRIPTOR, args)
        endpoint = f"tcp/127.0.0.1:{t.free_port()}"
        plan.update(
            core_node=core,
            namespace=self.namespace,
            zenoh={"mode": "peer", "listen": [endpoint], "connect": list(self.endpoints), "multicast_scouting": False},
            **config,
        )
        self.endpoints.append(endpoint)
        path = os.path.join(self.tmp.name, f"{instance}.json")
        with open(path, "w") as f:
            json.dump(plan, f)
        runner = await asyncio.wait_for(gen.NodeBuilder().with_runtime_config(path).start(), t.WAIT)
        self.runners.append(runner)
        return runner

    async def pair(self) -> Any:
        cam = await self.start("tcam", "cam_a")
        viewer = await self.start("tviewer", "viewer_1", {"camera": ["cam_a"]})
        await self.sees(viewer, "tcam", "cam_a")
        return cam, viewer


class TopicTest(PeppylibTest):
    async def test_published_messages_reach_a_held_subscription_with_their_producer(self):
        frames = entry("tcam", "emitted_topics.frames")
        frames_in = entry("tviewer", "consumed_topics.camera.frames")
        cam, viewer = await self.pair()
        self.assertEqual(frames_in.bound_producer(viewer), ProducerRef("lab", "cam_a"))
        sub = await frames_in.subscribe(viewer)
        publisher = await frames.declare_publisher(cam)
        for i in range(3):
            payload = frames.build_message(frames.MessageHeader(stamp=1.5 + i, frame_id=i), bytes([i, 255]))
            self.assertIsInstance(payload, bytes)
            await publisher.publish(payload)
        producer, first = await asyncio.wait_for(sub.next(), t.WAIT)
        self.assertEqual(producer, ProducerRef("lab", "cam_a"))
        self.assertEqual((producer.core_node, producer.instance_id), ("lab", "cam_a"))
        self.assertEqual(
            first, frames_in.Message(header=frames_in.MessageHeader(stamp=1.5, frame_id=0), data=b"\x00\xff")
        )
        seen = []
        async for producer, message in sub:
            seen.append((producer.instance_id, message.header.frame_id, message.data))
            if len(seen) == 2:
                break
        self.assertEqual(seen, [("cam_a", 1, b"\x01\xff"), ("cam_a", 2, b"\x02\xff")])
        # Stopping the node (its token) ends the subscription: None, and `async for` ends.
        waiting = asyncio.ensure_future(sub.next())
        viewer.cancellation_token().cancel()
        self.assertIsNone(await asyncio.wait_for(waiting, t.WAIT))
        self.assertEqual([m async for m in sub], [])

    async def test_a_message_built_for_another_topic_is_refused(self):
        from peppy import peppylib_api

        frames = entry("tcam", "emitted_topics.frames")
        cam = await self.start("tcam", "cam_a")
        publisher = await frames.declare_publisher(cam)
        with self.assertRaises(ValueError) as caught:
            await publisher.publish(peppylib_api.build_message(t.READINGS_OUT, t.Reading(1, "x")))
        self.assertIn("topic `readings` cannot be published on topic `frames`", str(caught.exception))


class ServiceTest(PeppylibTest):
    async def serve(self, cam: Any) -> "asyncio.Task[None]":
        info = entry("tcam", "exposed_services.info")

        def handler(request: Any) -> Any:
            if request.data.scale == 0:
                raise ValueError("scale 0 is no scale")
            return info.Response(width=request.data.scale * 10, note=f"for {request.instance_id}@{request.core_node}")

        async def loop() -> None:
            while True:
                await info.handle_next_request(cam, handler)

        return asyncio.ensure_future(loop())

    async def test_poll_reaches_the_target_and_fails_as_documented(self):
        info = entry("tviewer", "consumed_services.camera.info")
        cam, viewer = await self.pair()
        server = await self.serve(cam)
        try:
            target = info.bound_producer(viewer)
            response = await info.poll(viewer, target, info.Request(scale=4), t.WAIT)
            self.assertEqual((response.instance_id, response.core_node), ("cam_a", "lab"))
            self.assertEqual(response.data, info.ResponseData(width=40, note="for viewer_1@lab"))
            with self.assertRaises(RuntimeError) as failed:
                await info.poll(viewer, target, info.Request(scale=0), t.WAIT)
            self.assertIn("scale 0 is no scale", str(failed.exception))
            with self.assertRaises(ValueError) as unbound:
                await info.poll(viewer, ProducerRef("lab", "cam_z"), info.Request(scale=1), t.WAIT)
            self.assertIn("`cam_z` is not bound to slot `camera` (it is bound to cam_a)", str(unbound.exception))
        finally:
            server.cancel()

    async def test_an_absent_target_is_unreachable_and_a_silent_one_times_out(self):
        info = entry("tviewer", "consumed_services.camera.info")
        # cam_b is up but never serves: its queue acks the request.
        cam_b = await self.start("tcam", "cam_b")
        lonely = await self.start("tviewer", "viewer_2", {"camera": ["ghost"]})
        silent = await self.start("tviewer", "viewer_3", {"camera": ["cam_b"]})
        await self.sees(silent, "tcam", "cam_b")
        with self.assertRaises(ConnectionError):
            await info.poll(lonely, info.bound_producer(lonely), info.Request(scale=1), 1.0)
        with self.assertRaises(TimeoutError):
            await info.poll(silent, info.bound_producer(silent), info.Request(scale=1), 1.0)
        del cam_b


class ActionTest(PeppylibTest):
    async def test_goal_decision_feedback_result_and_cancel_with_a_target(self):
        move = entry("tcam", "exposed_actions.move")
        move_c = entry("tviewer", "consumed_actions.camera.move")
        cam, viewer = await self.pair()
        action = await move.ActionHandle.expose(cam)
        decided: List[Any] = []

        async def decide(request: Any) -> Any:
            decided.append((request.instance_id, request.core_node, request.data.distance))
            if request.data.distance > 10:
                return move.GoalDecision.reject(f"{request.data.distance} m is too far")
            return move.GoalDecision.accept()

        async def serve_one(cancel_expected: bool) -> Any:
            ctx = await action.handle_goal_next_request(decide)
            self.assertEqual(ctx.request().data.distance, 3.0)
            self.assertEqual((ctx.request().instance_id, ctx.request().core_node), ("viewer_1", "lab"))
            if cancel_expected:
                await asyncio.wait_for(ctx.cancel_signal(), t.WAIT)
                self.assertTrue(ctx.is_cancelled())
                await ctx.complete_cancelled(1.0)
            else:
                await ctx.publish_feedback(0.5)
                await ctx.publish_feedback(1.0)
                await ctx.complete(3.0)
            return ctx.goal_id()

        # A rejected goal is answered and skipped: the server waits on.
        worker = asyncio.ensure_future(serve_one(cancel_expected=False))
        target = move_c.bound_producer(viewer)
        far = await move_c.ActionHandle.fire_goal(
            viewer, target, move_c.GoalRequest(distance=50.0), t.WAIT, t.QoSProfile.Standard
        )
        self.assertFalse(far.accepted)
        self.assertEqual(far.reason, "50.0 m is too far")
        self.assertFalse(worker.done())
        goal = await move_c.ActionHandle.fire_goal(
            viewer, target, move_c.GoalRequest(distance=3.0), t.WAIT, t.QoSProfile.Reliable
        )
        self.assertTrue(goal.accepted)
        self.assertIsNone(goal.reason)
        progress = [(await asyncio.wait_for(goal.on_next_feedback_message(), t.WAIT)).progress for _ in range(2)]
        self.assertEqual(progress, [0.5, 1.0])
        with self.assertRaises(RuntimeError):
            await asyncio.wait_for(goal.on_next_feedback_message(), t.WAIT)
        self.assertEqual(await asyncio.wait_for(worker, t.WAIT), goal.goal_id())
        result = await goal.get_result(t.WAIT)
        self.assertEqual(result.status, move_c.ResultStatus.COMPLETED)
        self.assertEqual(result.data, move_c.ResultResponseData(travelled=3.0))
        self.assertEqual((result.instance_id, result.core_node), ("cam_a", "lab"))
        self.assertEqual((await goal.cancel_goal(t.WAIT)).state, move_c.CancelState.ALREADY_TERMINAL)
        self.assertEqual(decided, [("viewer_1", "lab", 50.0), ("viewer_1", "lab", 3.0)])

        worker = asyncio.ensure_future(serve_one(cancel_expected=True))
        goal = await move_c.ActionHandle.fire_goal(
            viewer, target, move_c.GoalRequest(distance=3.0), t.WAIT, t.QoSProfile.Standard
        )
        self.assertTrue(goal.accepted)
        self.assertEqual((await goal.cancel_goal(t.WAIT)).state, move_c.CancelState.SIGNALLED)
        await asyncio.wait_for(worker, t.WAIT)
        result = await goal.get_result(t.WAIT)
        self.assertEqual((result.status, result.data.travelled), (move_c.ResultStatus.CANCELLED, 1.0))

        with self.assertRaises(ValueError):
            await move_c.ActionHandle.fire_goal(
                viewer, ProducerRef("lab", "cam_z"), move_c.GoalRequest(distance=1.0), 1.0
            )
        # The server's wait ends with None once its node stops.
        waiting = asyncio.ensure_future(action.handle_goal_next_request(decide))
        cam.cancellation_token().cancel()
        self.assertIsNone(await asyncio.wait_for(waiting, t.WAIT))


class ShutdownTest(PeppylibTest):
    async def test_hooks_run_last_first_with_messaging_still_up(self):
        frames = entry("tcam", "emitted_topics.frames")
        frames_in = entry("tviewer", "consumed_topics.camera.frames")
        cam, viewer = await self.pair()
        sub = await frames_in.subscribe(viewer)
        publisher = await frames.declare_publisher(cam)
        order: List[str] = []
        token = cam.cancellation_token()

        def first() -> None:
            order.append(f"first (token cancelled: {token.is_cancelled()})")

        async def last_words() -> None:
            order.append("last_words")
            await publisher.publish(frames.build_message(frames.MessageHeader(stamp=9.0, frame_id=99), b""))

        def broken() -> None:
            order.append("broken")
            raise RuntimeError("a hook that fails")

        cam.on_shutdown(first)
        cam.on_shutdown(last_words)
        cam.on_shutdown(broken)
        with self.assertLogs("peppy", "ERROR") as logs:
            await asyncio.wait_for(cam.shutdown(), t.WAIT)
        self.assertEqual(order, ["broken", "last_words", "first (token cancelled: True)"])
        self.assertTrue(
            any(
                "shutdown hook `ShutdownTest.test_hooks_run_last_first_with_messaging_still_up.<locals>.broken` failed"
                in r
                for r in logs.output
            ),
            logs.output,
        )
        producer, message = await asyncio.wait_for(sub.next(), t.WAIT)
        self.assertEqual((producer.instance_id, message.header.frame_id), ("cam_a", 99))
        # Once messaging is closed, publishing is refused.
        with self.assertRaises(ShuttingDown):
            await publisher.publish(frames.build_message(frames.MessageHeader(stamp=1.0, frame_id=1), b""))

    async def test_a_hook_overrunning_the_grace_window_is_cut_off_and_the_rest_skipped(self):
        cam = await self.start("tcam", "cam_a", shutdown_grace_secs=0.5)
        ran: List[str] = []

        async def never_called() -> None:
            ran.append("never_called")

        async def stuck() -> None:
            ran.append("stuck")
            await asyncio.sleep(60)

        cam.on_shutdown(never_called)
        cam.on_shutdown(stuck)
        started = time.monotonic()
        with self.assertLogs("peppy", "WARNING") as logs:
            await asyncio.wait_for(cam.shutdown(), t.WAIT)
        self.assertLess(time.monotonic() - started, 5.0)
        self.assertEqual(ran, ["stuck"])
        text = "\n".join(logs.output)
        self.assertRegex(text, r"shutdown hook `[^`]*\.stuck` overran the 0\.5 s grace window; cut off")
        self.assertRegex(text, r"shutdown hooks skipped, the 0\.5 s grace window being over: `[^`]*\.never_called`")

    async def test_the_grace_window_is_checked_and_the_environment_overrides_it(self):
        with self.assertRaises(StartupError) as caught:
            await self.start("tcam", "cam_a", shutdown_grace_secs=0)
        self.assertIn("`shutdown_grace_secs` must be a number of seconds above 0", str(caught.exception))
        with self.assertRaises(StartupError) as caught:
            await self.start("tcam", "cam_b", use_sim_time="yes")
        self.assertIn("`use_sim_time` must be true or false", str(caught.exception))
        os.environ[SHUTDOWN_GRACE_ENV] = "0.25"
        try:
            cam = await self.start("tcam", "cam_c", shutdown_grace_secs=3)
        finally:
            del os.environ[SHUTDOWN_GRACE_ENV]
        self.assertEqual(cam.shutdown_grace, 0.25)
        self.assertFalse(cam.use_sim_time())


class StandaloneTest(PeppylibTest):
    async def standalone(self, node: str, config: Any, args: List[str], grace: Optional[float] = None) -> Any:
        gen = package(node)
        builder = gen.NodeBuilder().with_runtime_config(None).standalone(config)
        builder.with_args(["--listen", f"tcp/127.0.0.1:{t.free_port()}", "--namespace", self.namespace, *args])
        if grace is not None:
            builder.shutdown_grace(grace)
        runner = await asyncio.wait_for(builder.start(), t.WAIT)
        self.runners.append(runner)
        return runner

    async def test_a_standalone_config_gives_defaults_the_command_line_overrides(self):
        gen = package("tviewer")
        config = gen.StandaloneConfig().with_instance_id("solo").with_bound_producer("camera", "lab", "cam_x")
        solo = await self.standalone("tviewer", config, [], grace=1.5)
        self.assertEqual(solo.instance_id, "solo")
        self.assertEqual(entry("tviewer", "consumed_topics.camera.frames").bound_producer(solo).instance_id, "cam_x")
        self.assertEqual(solo.shutdown_grace, 1.5)
        self.assertFalse(solo.use_sim_time())
        config = gen.StandaloneConfig().with_instance_id("solo").with_bound_producer("camera", "lab", "cam_x")
        other = await self.standalone(
            "tviewer", config, ["--instance-id", "solo_2", "--link", "camera@cam_y", "--use-sim-time"]
        )
        self.assertEqual(other.instance_id, "solo_2")
        self.assertEqual(other.bound_producers("camera"), [ProducerRef(other.core_node, "cam_y")])
        self.assertTrue(other.use_sim_time())
        self.assertEqual(other.shutdown_grace, 5.0)
        sim = await self.standalone("tcam", package("tcam").StandaloneConfig().with_use_sim_time(True), [])
        self.assertTrue(sim.use_sim_time())


NODE_SCRIPT = """
import asyncio, sys
sys.path[:0] = [{src!r}, {gen!r}]
from peppygen import NodeBuilder, NodeRunner
from peppygen.parameters import Parameters

def setup(params: Parameters, node_runner: NodeRunner):
    token = node_runner.cancellation_token()

    def first():
        print("hook first", flush=True)

    async def second():
        print("hook second, token cancelled:", token.is_cancelled(), flush=True)
        if {slow!r}:
            await asyncio.sleep(60)

    async def watch():
        await token.cancelled()
        print("token cancelled", flush=True)

    node_runner.on_shutdown(first)
    node_runner.on_shutdown(second)
    print("ready", flush=True)
    return [asyncio.ensure_future(watch())]

NodeBuilder().run(setup)
"""


class ProcessTest(unittest.TestCase):
    """`NodeBuilder.run` as a process, stopped by signals."""

    def setUp(self) -> None:
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def spawn(self, slow: bool) -> subprocess.Popen:
        assert _generated is not None
        gen = package("tcam")
        config = t.plan(gen.DESCRIPTOR, ["--instance-id", "cam_p"])
        config.update(
            namespace="t" + os.urandom(6).hex(),
            shutdown_grace_secs=30,
            zenoh={"mode": "peer", "listen": [f"tcp/127.0.0.1:{t.free_port()}"], "multicast_scouting": False},
        )
        path = os.path.join(self.tmp.name, "cam_p.json")
        with open(path, "w") as f:
            json.dump(config, f)
        script = NODE_SCRIPT.format(src=SRC, gen=os.path.join(_generated, "tcam"), slow=slow)
        env = dict(os.environ, PEPPY_RUNTIME_CONFIG=path)
        return subprocess.Popen(
            [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )

    def test_sigterm_runs_the_hooks_then_exits_zero(self):
        proc = self.spawn(slow=False)
        try:
            self.assertEqual(proc.stdout.readline().strip(), "ready")
            proc.send_signal(signal.SIGTERM)
            out, err = proc.communicate(timeout=t.WAIT)
        finally:
            proc.kill()
        self.assertEqual(proc.returncode, 0, err)
        self.assertEqual(out.splitlines(), ["token cancelled", "hook second, token cancelled: True", "hook first"])

    def test_a_second_signal_during_the_hooks_exits_at_once(self):
        proc = self.spawn(slow=True)
        try:
            self.assertEqual(proc.stdout.readline().strip(), "ready")
            proc.send_signal(signal.SIGTERM)
            self.assertEqual(proc.stdout.readline().strip(), "token cancelled")
            self.assertEqual(proc.stdout.readline().strip(), "hook second, token cancelled: True")
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=t.WAIT)
        finally:
            proc.kill()
        self.assertEqual(proc.returncode, 128 + signal.SIGINT, err)
        self.assertNotIn("hook first", out)


class ClockTest(PeppylibTest):
    def setUp(self) -> None:
        # The clock binds one node per process; each test starts unbound.
        peppy_clock._bound = None

    async def test_wall_time_is_the_os_clock_once_initialised(self):
        clock = entry("tcam", "clock")
        with self.assertRaises(RuntimeError):
            clock.now_ns()
        cam = await self.start("tcam", "cam_a")
        self.assertFalse(cam.use_sim_time())
        await clock.init(cam)
        await clock.init(cam)
        before = time.time_ns()
        now = clock.now_ns()
        self.assertLessEqual(before, now)
        self.assertLessEqual(now, time.time_ns())

    async def test_sim_time_is_not_ready_before_the_first_tick_then_is_the_published_one(self):
        clock = entry("tcam", "clock")
        sim = await self.start("tcam", "cam_sim", use_sim_time=True)
        simulator = await self.start("tcam", "simulator")
        await self.sees(simulator, "tcam", "cam_sim")
        self.assertTrue(sim.use_sim_time())
        await clock.init(sim)
        with self.assertRaises(ClockNotReady) as caught:
            clock.now_ns()
        self.assertIsInstance(caught.exception, RuntimeError)
        # A simulator publishes each step; the first that arrives is the time.
        deadline = time.monotonic() + t.WAIT
        while True:
            await peppy_clock.publish_sim_time(simulator, 123_456_789)
            try:
                self.assertEqual(clock.now_ns(), 123_456_789)
                break
            except ClockNotReady:
                self.assertLess(time.monotonic(), deadline, "no sim tick arrived")
                await asyncio.sleep(0.02)

    async def test_ticks_of_the_nodes_mode_and_malformed_ones_dropped(self):
        cam = await self.start("tcam", "cam_a")
        launcher = await self.start("tcam", "launcher")
        await self.sees(launcher, "tcam", "cam_a")
        sub = await peppy_clock.subscribe(cam)
        key = clock_tick_key(self.namespace, "wall")
        deadline = time.monotonic() + t.WAIT
        got = None
        with self.assertLogs("peppy", "WARNING") as logs:
            # Until the subscription is known and has seen a malformed tick:
            # a malformed tick, then a good one (the subscription may become
            # known between the two puts, and see only the good one).
            while got is None or not any("not 8 bytes" in r for r in logs.output):
                self.assertLess(time.monotonic(), deadline, "no tick arrived")
                launcher.session.put(key, b"\x01\x02\x03\x04")
                launcher.session.put(key, struct.pack("<Q", 42))
                try:
                    got = await asyncio.wait_for(sub.on_next_tick(), 0.1)
                except asyncio.TimeoutError:
                    pass
        self.assertEqual(got, peppy_clock.ClockTick(time=42))
        self.assertEqual(len([r for r in logs.output if "not 8 bytes" in r]), 1, logs.output)
        cam.cancellation_token().cancel()
        self.assertIsNone(await asyncio.wait_for(sub.on_next_tick(), t.WAIT))

    def serve_sync(self, launcher: Any, sim_time: List[Optional[int]]) -> Any:
        """A stand-in for the launcher's `clock/sync` queryable, as docs/WIRE.md says it answers."""

        def answer(query: Any) -> None:
            body = query.payload.to_bytes() if query.payload is not None else b""
            received = time.time_ns()
            if len(body) != 9:
                query.reply_err(b"a clock sync query is 9 bytes")
                return
            (t0,) = struct.unpack("<Q", body[:8])
            if body[8] == 1:
                if sim_time[0] is None:
                    query.reply_err(b"no sim tick seen yet")
                    return
                t1 = t2 = sim_time[0]
            else:
                t1, t2 = received, time.time_ns()
            query.reply(query.key_expr, struct.pack("<QQQ", t0, t1, t2))

        key = clock_sync_key(self.namespace)
        queryable = launcher.session.declare_queryable(key, answer)
        launcher._declared.append(queryable)
        return queryable

    async def test_synchronize_against_a_sync_queryable(self):
        cam = await self.start("tcam", "cam_a")
        with self.assertRaises(ConnectionError):
            await peppy_clock.synchronize(cam, 0.5)
        launcher = await self.start("tcam", "launcher")
        await self.sees(cam, "tcam", "launcher")
        self.serve_sync(launcher, [None])
        sync = await peppy_clock.synchronize(cam)
        self.assertLess(abs(sync.offset_ns), 1_000_000_000)
        self.assertGreaterEqual(sync.round_trip_delay_ns, 0)
        self.assertLessEqual(sync.raw.server_recv_time, sync.raw.server_send_time)

    async def test_synchronize_in_sim_mode_is_not_ready_without_a_tick(self):
        sim = await self.start("tcam", "cam_sim", use_sim_time=True)
        launcher = await self.start("tcam", "launcher")
        await self.sees(sim, "tcam", "launcher")
        latest: List[Optional[int]] = [None]
        self.serve_sync(launcher, latest)
        with self.assertRaises(RuntimeError) as caught:
            await peppy_clock.synchronize(sim)
        self.assertIn("no sim tick seen yet", str(caught.exception))
        latest[0] = 5_000_000_000
        sync = await peppy_clock.synchronize(sim)
        self.assertEqual((sync.raw.server_recv_time, sync.raw.server_send_time), (5_000_000_000, 5_000_000_000))
        # The node has no sim time of its own yet (t0 = t3 = 0): the whole offset.
        self.assertEqual((sync.raw.client_send_time, sync.offset_ns, sync.round_trip_delay_ns), (0, 5_000_000_000, 0))


class ClockMathTest(unittest.TestCase):
    def test_offset_and_delay_follow_ntp_and_saturate(self):
        raw = peppy_clock.ClockResponse(100, 150, 160)
        sync = peppy_clock.clock_sync(raw, 210)
        self.assertEqual((sync.offset_ns, sync.round_trip_delay_ns), (0, 100))
        sync = peppy_clock.clock_sync(peppy_clock.ClockResponse(0, (1 << 64) - 1, (1 << 64) - 1), 0)
        self.assertEqual(sync.offset_ns, (1 << 63) - 1)
        sync = peppy_clock.clock_sync(peppy_clock.ClockResponse(10, 0, 0), 5)
        self.assertEqual(sync.round_trip_delay_ns, 0)


class SyncTest(unittest.TestCase):
    def test_a_second_sync_changes_nothing(self):
        program = peppy_launch()
        assert program is not None and _generated is not None
        root = os.path.join(_generated, "tviewer", "peppygen")
        before = {p: os.stat(p).st_mtime_ns for p in _files(root)}
        done = subprocess.run(
            [program, "sync", os.path.join(_generated, "tviewer"), "--repo", _generated],
            capture_output=True,
            text=True,
            timeout=60,
        )
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn("(0 file(s) changed)", done.stdout)
        self.assertEqual({p: os.stat(p).st_mtime_ns for p in _files(root)}, before)


def _files(root: str) -> List[str]:
    return sorted(os.path.join(d, f) for d, _, fs in os.walk(root) for f in fs if f.endswith(".py"))


if __name__ == "__main__":
    unittest.main()
