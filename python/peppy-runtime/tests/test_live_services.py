"""Services between Python nodes on loopback: direct and probed calls,
handler errors, timeouts, unreachable servers, format mismatches."""

from __future__ import annotations

import asyncio
import unittest

import peppy_testing as t
from peppy import ServiceError, ServiceTimeout, ServiceUnreachable, services
from peppy import spec as s
from peppy.attachment import QueryHeader, QueryKind, ReplyStatus, parse_reply
from peppy.bridge import END, TIMED_OUT, ReplyStream


async def serve(runner, spec, seen=None, delay=0.0):
    """Serves `spec` until cancelled: a + b, refusing negative numbers."""

    async def add(instance_id, core_node, request):
        if seen is not None:
            seen.append((instance_id, core_node, request))
        if request.a < 0:
            raise ValueError("negative numbers are not served")
        if delay:
            await asyncio.sleep(delay)
        return t.AddResponse(request.a + request.b)

    while True:
        await services.handle_next(runner, spec, add)


class ServiceTest(t.LiveTest):
    def serving(self, runner, spec, **kw):
        task = asyncio.ensure_future(serve(runner, spec, **kw))
        self.addAsyncCleanup(self._cancel, task)
        return task

    async def _cancel(self, task):
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)

    async def test_pinned_call_handler_error_and_caller_identity(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(viewer, "camera", "cam_a")
        seen = []
        self.serving(cam_a, t.ADD_SERVED, seen=seen)
        instance, core, response = await services.call(viewer, t.ADD_PINNED, 5.0, t.AddRequest(2, 40))
        self.assertEqual((instance, core, response), ("cam_a", "lab", t.AddResponse(42)))
        self.assertEqual(seen, [("viewer_1", "lab", t.AddRequest(2, 40))])
        with self.assertRaises(ServiceError) as caught:
            await services.call(viewer, t.ADD_PINNED, 5.0, t.AddRequest(-1, 1))
        self.assertEqual(caught.exception.reason, "negative numbers are not served")
        self.assertEqual(caught.exception.instance, "cam_a")
        self.assertEqual((caught.exception.instance_id, caught.exception.service_name), ("cam_a", "add"))
        # The server keeps serving after a handler error.
        _, _, response = await services.call(viewer, t.ADD_PINNED, 5.0, t.AddRequest(1, 1))
        self.assertEqual(response, t.AddResponse(2))

    async def test_probed_calls_follow_the_slot_filter_and_node_membership(self):
        lidar = await self.node(t.LIDAR_NODE, "lidar_1")
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        cam_b = await self.node(t.CAMERA_NODE, "cam_b", core="other")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        for name, instance in (("lidar", "lidar_1"), ("camera", "cam_a"), ("camera", "cam_b")):
            await self.sees(viewer, name, instance)
        for node in (lidar, cam_a, cam_b):
            self.serving(node, t.ADD_SERVED_IFACE)
        # The interface slot takes any conforming server.
        instance, _, response = await services.call(viewer, t.ADD_PROBED, 5.0, t.AddRequest(3, 4))
        self.assertIn(instance, {"lidar_1", "cam_a", "cam_b"})
        self.assertEqual(response, t.AddResponse(7))
        # The node slot on the interface's key: camera instances only, and
        # not cam_a, which its sibling `cam` pins.
        for _ in range(5):
            instance, core, _ = await services.call(viewer, t.ADD_PROBED_CAMERA, 5.0, t.AddRequest(1, 2))
            self.assertEqual((instance, core), ("cam_b", "other"))

    async def test_a_slot_bound_to_one_producer_goes_straight_to_it(self):
        lidar = await self.node(t.LIDAR_NODE, "lidar_1")
        cam_b = await self.node(t.CAMERA_NODE, "cam_b")
        viewer = await self.node(
            t.VIEWER_NODE,
            "viewer_1",
            bindings={
                "cam": {"kind": "pinned", "producer": "cam_a"},
                "cams": {"kind": "from_any_bound", "producers": ["lidar_1"]},
            },
        )
        await self.sees(viewer, "lidar", "lidar_1")
        await self.sees(viewer, "camera", "cam_b")
        self.serving(lidar, t.ADD_SERVED_IFACE)
        self.serving(cam_b, t.ADD_SERVED_IFACE)
        for _ in range(3):
            instance, _, _ = await services.call(viewer, t.ADD_PROBED, 5.0, t.AddRequest(1, 1))
            self.assertEqual(instance, "lidar_1")

    async def test_unreachable_timeout_and_format_mismatch(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(viewer, "camera", "cam_a")
        loop = asyncio.get_running_loop()
        # Nobody serves `missing`: unreachable as soon as Zenoh says so.
        started = loop.time()
        with self.assertRaises(ServiceUnreachable):
            await services.call(viewer, t.MISSING_CALLED, 5.0, t.AddRequest(1, 1))
        self.assertLess(loop.time() - started, 4.0)
        # A probe that finds nobody: unreachable within the probe's 500 ms.
        started = loop.time()
        nobody = s.ConsumedServiceSpec("cams", t.DEPTH, "missing", t.ADD_REQUEST, t.ADD_RESPONSE)
        with self.assertRaises(ServiceUnreachable):
            await services.call(viewer, nobody, 5.0, t.AddRequest(1, 1))
        self.assertLess(loop.time() - started, 2.0)
        # Acked, but the handler is slower than the caller's budget.
        self.serving(cam_a, t.ADD_SERVED, delay=2.0)
        with self.assertRaises(ServiceTimeout):
            await services.call(viewer, t.ADD_PINNED, 0.5, t.AddRequest(1, 1))
        # A caller built against another request format is told both formats.
        other = s.ConsumedServiceSpec("cam", t.CAMERA, "add", t.WIDE, t.ADD_RESPONSE)
        with self.assertRaises(ServiceError) as caught, self.assertLogs("peppy", "WARNING"):
            await services.call(viewer, other, 5.0, t.Wide(1))
        self.assertIn(t.ADD_REQUEST.canonical, caught.exception.reason)
        self.assertIn(t.WIDE.canonical, caught.exception.reason)

    async def test_requests_queued_when_the_server_stops_end_at_once(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(viewer, "camera", "cam_a")
        loop = asyncio.get_running_loop()
        started = loop.time()
        # Nobody serves cam_a's `add`: the request is acked and stays queued.
        call = asyncio.ensure_future(services.call(viewer, t.ADD_PINNED, 8.0, t.AddRequest(1, 1)))
        await asyncio.sleep(0.3)
        await cam_a.shutdown()
        with self.assertRaises(ServiceTimeout):
            await asyncio.wait_for(call, t.WAIT)
        self.assertLess(loop.time() - started, 4.0)

    async def test_a_probe_is_answered_present_without_running_the_handler(self):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a")
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(viewer, "camera", "cam_a")
        seen = []
        self.serving(cam_a, t.ADD_SERVED, seen=seen)
        stream = ReplyStream(viewer.loop, viewer._track_mailbox)
        viewer.session.get(
            f"peppy/{self.namespace}/service/node/camera/v1/add/*/*",
            stream.handler(),
            timeout=2.0,
            attachment=QueryHeader(QueryKind.PROBE, t.ADD_REQUEST.fingerprint, "cli", "probe").encode(),
        )
        replies = []
        while True:
            reply = await stream.next(viewer.loop.time() + t.WAIT)
            if reply is END or reply is TIMED_OUT:
                break
            replies.append(reply)
        self.assertEqual(len(replies), 1)
        self.assertEqual(replies[0].key, f"peppy/{self.namespace}/service/node/camera/v1/add/lab/cam_a")
        self.assertEqual(parse_reply(replies[0].attachment), (ReplyStatus.PRESENT, t.ADD_RESPONSE.fingerprint))
        self.assertEqual(replies[0].payload, b"")
        await asyncio.sleep(0.1)
        self.assertEqual(seen, [])


if __name__ == "__main__":
    unittest.main()
