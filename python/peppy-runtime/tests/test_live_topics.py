"""Topics between Python nodes on loopback: routing, filtering, fingerprints."""

from __future__ import annotations

import asyncio
import json
import logging
import unittest

import peppy_testing as t
from peppy import ShuttingDown, attachment, topics
from peppy.bridge import END, ReplyStream
from peppy.keys import describe_key
from peppy.routing import ANY


class _Payload:
    def __init__(self, data: bytes) -> None:
        self._data = data

    def to_bytes(self) -> bytes:
        return self._data


class _Sample:
    def __init__(self, key: str, fingerprint: int) -> None:
        self.key_expr = key
        self.attachment = _Payload(attachment.topic(fingerprint))
        self.payload = _Payload(b"")


class IntakeKeysTest(unittest.IsolatedAsyncioTestCase):
    async def test_each_producer_key_is_parsed_and_declared_once_up_to_a_bound(self):
        spec = t.EXTERNAL_READINGS_IN
        declared = []
        inbox = topics.Inbox(asyncio.get_running_loop(), spec)
        intake = topics.Intake(spec, ANY, None, inbox, lambda *a: None, declared.append)
        key = "peppy/lab/topic/node/cam/v1/readings/c1/cam_a"
        for _ in range(3):
            intake(_Sample(key, spec.format.fingerprint))
        intake(_Sample("peppy/lab/topic/other/x/v1/t/c/i", spec.format.fingerprint))
        self.assertEqual(declared, [key])
        self.assertEqual(inbox.mailbox.take_all()[0].instance, "cam_a")
        for n in range(topics.REMEMBERED + 5):
            intake(_Sample(f"peppy/lab/topic/node/cam/v1/readings/c1/cam_{n}", spec.format.fingerprint))
        self.assertEqual(len(declared), topics.REMEMBERED)


class TopicRoutingTest(t.LiveTest):
    async def collect(self, runner, spec, count, **filters):
        """`count` messages as (producer, label, seq)."""
        out = []
        for _ in range(count):
            producer, m = await asyncio.wait_for(topics.next_message(runner, spec, **filters), t.WAIT)
            out.append((producer, m.label, m.seq))
        return out

    async def start_cameras_and_viewer(self, bindings):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        cam_b = await self.node(t.CAMERA_NODE, "cam_b", core="other")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings=bindings)
        for cam in (cam_a, cam_b):
            await self.sees(cam, "viewer", "viewer_1")
        return cam_a, cam_b, viewer

    async def test_pinned_from_any_and_external_routing(self):
        cam_a, cam_b, viewer = await self.start_cameras_and_viewer(
            {"cam": {"kind": "pinned", "producer": "cam_a"}, "cams": {"kind": "from_any_bound", "producers": ["cam_b"]}}
        )
        tasks = [
            asyncio.ensure_future(t.keep_emitting(cam_a, t.READINGS_OUT, "a")),
            asyncio.ensure_future(t.keep_emitting(cam_b, t.READINGS_OUT, "b")),
            asyncio.ensure_future(t.keep_emitting(cam_a, t.VIDEO_OUT, "video-a")),
            asyncio.ensure_future(t.keep_emitting(cam_b, t.VIDEO_OUT, "video-b")),
        ]
        try:
            # Pinned: only cam_a's readings reach the node slot.
            got = await self.collect(viewer, t.READINGS_IN, 6)
            self.assertEqual({(p, label) for p, label, _ in got}, {("cam_a", "a")})
            seqs = [seq for _, _, seq in got]
            self.assertEqual(seqs, sorted(seqs), "one producer's messages keep their order")
            # from_any bound to cam_b: cam_a's interface stream is filtered out.
            got = await self.collect(viewer, t.VIDEO_IN, 6)
            self.assertEqual({(p, label) for p, label, _ in got}, {("cam_b", "video-b")})
            # External: any owner, any producer; from_instance_id narrows it.
            got = await self.collect(viewer, t.EXTERNAL_READINGS_IN, 30)
            self.assertEqual({p for p, _, _ in got}, {"cam_a", "cam_b"})
            got = await self.collect(viewer, t.EXTERNAL_READINGS_IN, 5, from_instance_id="cam_b")
            self.assertEqual({p for p, _, _ in got}, {"cam_b"})
            got = await self.collect(viewer, t.EXTERNAL_READINGS_IN, 5, from_core_node="lab")
            self.assertEqual({p for p, _, _ in got}, {"cam_a"})
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def test_a_node_slot_on_an_interface_key_keeps_its_node_only(self):
        # any_cam (node camera:v1, from_any) reads the interface's `video`
        # key, shared with lidar:v1; cam_a is claimed by the sibling `cam`.
        lidar = await self.node(t.LIDAR_NODE, "lidar_1")
        cam_a, cam_b, viewer = await self.start_cameras_and_viewer({"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(lidar, "viewer", "viewer_1")
        tasks = [
            asyncio.ensure_future(t.keep_emitting(node, t.VIDEO_OUT, node.instance_id))
            for node in (lidar, cam_a, cam_b)
        ]
        try:
            got = await self.collect(viewer, t.VIDEO_ANY_CAMERA_IN, 8)
            self.assertEqual({p for p, _, _ in got}, {"cam_b"})
            # The interface slot itself (unbound, no sibling) takes every conforming node.
            got = await self.collect(viewer, t.VIDEO_IN, 40)
            self.assertEqual({p for p, _, _ in got}, {"lidar_1", "cam_a", "cam_b"})
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
        info = await self.describe(viewer)
        routes = {c["slot"] or "external": c for c in info["consumes"] if c["name"] == "video"}
        self.assertEqual(routes["any_cam"]["members_of"], {"name": "camera", "tag": "v1"})
        self.assertEqual(routes["any_cam"]["filter"], {"kind": "any_except", "producers": ["cam_a"]})
        self.assertIsNone(routes["cams"]["members_of"])

    async def describe(self, runner):
        stream = ReplyStream(runner.loop, runner._track_mailbox)
        runner.session.get(
            describe_key(self.namespace, runner.core_node, runner.instance_id), stream.handler(), timeout=2
        )
        reply = await stream.next(runner.loop.time() + t.WAIT)
        self.assertIsNot(reply, END)
        return json.loads(reply.payload)

    async def test_the_description_and_a_format_mismatch(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(cam_a, "viewer", "viewer_1")
        info = await self.describe(viewer)
        self.assertEqual(info["version"], 1)
        self.assertEqual(
            (info["instance_id"], info["core_node"], info["namespace"]), ("viewer_1", "lab", self.namespace)
        )
        self.assertEqual(info["node"], {"name": "viewer", "tag": "v1"})
        self.assertEqual(
            info["slots"][0],
            {
                "link_id": "cam",
                "kind": "node",
                "target": {"name": "camera", "tag": "v1"},
                "binding": {"kind": "pinned", "producer": "cam_a"},
                "filter": {"kind": "pin", "producers": "cam_a"},
            },
        )
        readings = next(c for c in info["consumes"] if c["slot"] == "cam" and c["name"] == "readings")
        self.assertEqual(readings["selector"], f"peppy/{self.namespace}/topic/node/camera/v1/readings/*/cam_a")
        external = next(c for c in info["consumes"] if c["slot"] is None)
        self.assertEqual(external["selector"], f"peppy/{self.namespace}/topic/*/*/*/readings/*/*")
        self.assertIsNone(external["owner"])
        cam_info = await self.describe(cam_a)
        emitted = {e["name"]: e for e in cam_info["emits"]}
        self.assertEqual(
            emitted["video"]["key"], f"peppy/{self.namespace}/topic/interface/depth_camera/v1/video/lab/cam_a"
        )
        self.assertEqual(
            emitted["readings"]["format"], {"canonical": t.READING.canonical, "fingerprint": t.READING.fingerprint}
        )
        self.assertEqual(cam_info["actions"][0]["key"], f"peppy/{self.namespace}/action/node/camera/v1/move/lab/cam_a")

        # cam_a sends `mismatch` as {seq:u64}; the viewer expects {seq:u32,label:string}.
        with self.assertLogs("peppy", logging.WARNING) as logs:
            task = asyncio.ensure_future(t.keep_emitting(cam_a, t.MISMATCH_OUT, "", make=t.Wide))
            try:
                with self.assertRaises(asyncio.TimeoutError):
                    await asyncio.wait_for(topics.next_message(viewer, t.MISMATCH_IN), 1.5)
                for _ in range(60):
                    if any("{seq:u64}" in line for line in logs.output):
                        break
                    await asyncio.sleep(0.05)
            finally:
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)
        warnings = [line for line in logs.output if "mismatch" in line]
        self.assertEqual(len(warnings), 1, logs.output)
        self.assertIn("{seq:u64}", warnings[0])
        self.assertIn(t.READING.canonical, warnings[0])

    async def test_a_sample_without_attachment_or_that_does_not_decode_is_dropped(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(cam_a, "viewer", "viewer_1")
        key = f"peppy/{self.namespace}/topic/node/camera/v1/readings/lab/cam_a"
        from peppy import attachment

        with self.assertLogs("peppy", logging.WARNING) as logs:
            cam_a.session.put(key, b"no attachment")
            cam_a.session.put(key, b"\x01", attachment=attachment.topic(t.READING.fingerprint))
            await topics.emit(cam_a, t.READINGS_OUT, t.Reading(7, "good"))
            producer, m = await asyncio.wait_for(topics.next_message(viewer, t.READINGS_IN), t.WAIT)
            # The external subscription sees the same samples on its own thread.
            external = await asyncio.wait_for(topics.next_message(viewer, t.EXTERNAL_READINGS_IN), t.WAIT)
        self.assertEqual((producer, m), ("cam_a", t.Reading(7, "good")))
        self.assertEqual(external, ("cam_a", t.Reading(7, "good")))
        self.assertTrue(any("attachment" in line for line in logs.output), logs.output)
        self.assertTrue(any("does not decode" in line for line in logs.output), logs.output)

    async def test_reads_end_with_shutting_down(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        reader = asyncio.ensure_future(topics.next_message(viewer, t.READINGS_IN))
        await asyncio.sleep(0.1)
        viewer.stop()
        with self.assertRaises(ShuttingDown):
            await asyncio.wait_for(reader, t.WAIT)
        with self.assertRaises(ShuttingDown):
            await topics.next_message(viewer, t.READINGS_IN)
        await viewer.shutdown()
        with self.assertRaises(ShuttingDown):
            await topics.next_message(viewer, t.READINGS_IN)
        await cam_a.shutdown()
        with self.assertRaises(ShuttingDown):
            await topics.emit(cam_a, t.READINGS_OUT, t.Reading(1, "x"))


class QueuePolicyTest(t.LiveTest):
    async def test_standard_keeps_the_newest_ten(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(cam_a, "viewer", "viewer_1")
        for seq in range(30):
            await topics.emit(cam_a, t.READINGS_OUT, t.Reading(seq, "burst"))
        inbox = viewer._inbox(t.READINGS_IN)
        for _ in range(100):
            if len(inbox.mailbox) and (inbox.mailbox._items[-1].payload == t.READING.encode(t.Reading(29, "burst"))):
                break
            await asyncio.sleep(0.02)
        got = []
        while len(inbox.mailbox):
            _, m = await topics.next_message(viewer, t.READINGS_IN)
            got.append(m.seq)
        self.assertEqual(got, list(range(20, 30)))

    async def test_reliable_keeps_everything(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(cam_a, "viewer", "viewer_1")
        inbox = viewer._inbox(t.VIDEO_IN)
        got = []
        with self.assertLogs("peppy", logging.INFO) as logs:
            for seq in range(300):
                await topics.emit(cam_a, t.VIDEO_OUT, t.Reading(seq, "all"))
            for _ in range(250):
                if len(inbox.mailbox) == 300:
                    break
                await asyncio.sleep(0.02)
            ticks = []

            async def other_task():
                while True:
                    ticks.append(len(got))
                    await asyncio.sleep(0)

            ticker = asyncio.ensure_future(other_task())
            await asyncio.sleep(0)

            async def drain():
                for _ in range(300):
                    _, m = await topics.next_message(viewer, t.VIDEO_IN)
                    got.append(m.seq)

            await asyncio.wait_for(drain(), t.WAIT)
            ticker.cancel()
        self.assertEqual(got, list(range(300)))
        # A reader whose queue is never empty still lets the node's other tasks run.
        self.assertGreater(len([n for n in ticks if 0 < n < 300]), 2)
        self.assertTrue(any("falling behind" in line for line in logs.output), logs.output)
        self.assertTrue(any("caught up" in line for line in logs.output), logs.output)


if __name__ == "__main__":
    unittest.main()
