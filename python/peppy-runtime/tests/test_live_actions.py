"""Actions between Python nodes on loopback: goal, feedback, result,
cancel, rejection, abandonment and expiry."""

from __future__ import annotations

import asyncio
import gc
import unittest

import peppy_testing as t
from peppy import CancelState, FeedbackEnded, ResultStatus, ServiceError
from peppy.actions import GoalServer, fire_goal


class ActionTest(t.LiveTest):
    async def pair(self, retention=None):
        cam_a = await self.node(t.CAMERA_NODE, "cam_a", retention=retention)
        viewer = await self.node(t.VIEWER_NODE, "viewer_1", bindings={"cam": {"kind": "pinned", "producer": "cam_a"}})
        await self.sees(viewer, "camera", "cam_a")
        return cam_a, viewer

    def accept_up_to(self, limit):
        async def decide(goal):
            return (True, None) if goal.distance <= limit else (False, f"{goal.distance} m is too far")

        return decide

    async def test_goal_feedback_and_result(self):
        cam_a, viewer = await self.pair()
        server = GoalServer(cam_a, t.MOVE_SERVED)

        async def work():
            context = await server.next_goal(self.accept_up_to(10))
            self.assertEqual((context.instance_id, context.core_node), ("viewer_1", "lab"))
            self.assertEqual(context.request(), t.MoveGoal(3.0))
            for step in (1, 2, 3):
                await context.publish_feedback(t.MoveFeedback(step / 3))
            await context.complete(t.MoveResult(context.goal.distance))
            return context.goal_id

        worker = asyncio.ensure_future(work())
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(3.0), t.QoSProfile.RELIABLE)
        self.assertTrue(goal.accepted)
        self.assertIsNone(goal.error_message)
        self.assertEqual((goal.instance_id, goal.core_node), ("cam_a", "lab"))
        self.assertRegex(goal.goal_id, r"^[0-9a-f]{16}$")
        progress = []
        with self.assertRaises(FeedbackEnded):
            while True:
                progress.append((await asyncio.wait_for(goal.next_feedback(), t.WAIT)).progress)
        self.assertEqual([round(p, 3) for p in progress], [0.333, 0.667, 1.0])
        self.assertEqual(await asyncio.wait_for(worker, t.WAIT), goal.goal_id)
        status, result = await goal.get_result(5.0)
        self.assertEqual((status, result), (ResultStatus.COMPLETED, t.MoveResult(3.0)))
        self.assertEqual(await goal.cancel(5.0), CancelState.ALREADY_TERMINAL)

    async def test_a_rejected_goal_and_a_three_argument_decider(self):
        cam_a, viewer = await self.pair()
        server = GoalServer(cam_a, t.MOVE_SERVED)
        worker = asyncio.ensure_future(server.next_goal(self.accept_up_to(10)))
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(50.0))
        self.assertFalse(goal.accepted)
        self.assertEqual(goal.error_message, "50.0 m is too far")
        self.assertIsNone(await asyncio.wait_for(worker, t.WAIT))
        with self.assertRaises(FeedbackEnded):
            await goal.next_feedback()

        callers = []

        def decide(instance_id, core_node, goal):
            callers.append((instance_id, core_node, goal))
            return False, None

        worker = asyncio.ensure_future(server.next_goal(decide))
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(1.0))
        self.assertFalse(goal.accepted)
        await asyncio.wait_for(worker, t.WAIT)
        self.assertEqual(callers, [("viewer_1", "lab", t.MoveGoal(1.0))])

    async def test_cancel_then_a_parked_result(self):
        cam_a, viewer = await self.pair()
        server = GoalServer(cam_a, t.MOVE_SERVED)

        async def work():
            context = await server.next_goal(self.accept_up_to(10))
            await asyncio.wait_for(context.cancel_signal.wait(), t.WAIT)
            self.assertTrue(context.is_cancelled())
            await context.complete_cancelled(t.MoveResult(0.5))

        worker = asyncio.ensure_future(work())
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(2.0))
        self.assertTrue(goal.accepted)
        # Asked before the goal ends: the server parks the query.
        result = asyncio.ensure_future(goal.get_result(5.0))
        await asyncio.sleep(0.2)
        self.assertFalse(result.done())
        self.assertEqual(await goal.cancel(5.0), CancelState.SIGNALLED)
        self.assertEqual(await asyncio.wait_for(result, t.WAIT), (ResultStatus.CANCELLED, t.MoveResult(0.5)))
        await asyncio.wait_for(worker, t.WAIT)
        self.assertEqual(await goal.cancel(5.0), CancelState.ALREADY_TERMINAL)
        goal.goal_id = "0123456789abcdef"
        self.assertEqual(await goal.cancel(5.0), CancelState.UNKNOWN)
        with self.assertRaises(ServiceError) as caught:
            await goal.get_result(5.0)
        self.assertIn("no goal `0123456789abcdef`", caught.exception.reason)

    async def test_a_dropped_goal_is_abandoned_and_an_old_result_expires(self):
        cam_a, viewer = await self.pair(retention=0.3)
        server = GoalServer(cam_a, t.MOVE_SERVED)
        worker = asyncio.ensure_future(server.next_goal(self.accept_up_to(10)))
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(1.0))
        context = await asyncio.wait_for(worker, t.WAIT)
        del worker
        with self.assertLogs("peppy", "WARNING"):
            del context
            gc.collect()
        self.assertEqual(await goal.get_result(5.0), (ResultStatus.ABANDONED, None))
        with self.assertRaises(FeedbackEnded):
            await asyncio.wait_for(goal.next_feedback(), t.WAIT)

        worker = asyncio.ensure_future(server.next_goal(self.accept_up_to(10)))
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(2.0))
        context = await asyncio.wait_for(worker, t.WAIT)
        await context.complete(t.MoveResult(2.0))
        await asyncio.sleep(1.0)
        self.assertEqual(await goal.get_result(5.0), (ResultStatus.EXPIRED, None))
        self.assertEqual(await goal.cancel(5.0), CancelState.ALREADY_TERMINAL)

    async def test_goals_left_running_are_abandoned_when_the_node_stops(self):
        cam_a, viewer = await self.pair()
        server = GoalServer(cam_a, t.MOVE_SERVED)
        worker = asyncio.ensure_future(server.next_goal(self.accept_up_to(10)))
        goal = await fire_goal(viewer, t.MOVE_CALLED, 5.0, t.MoveGoal(1.0))
        context = await asyncio.wait_for(worker, t.WAIT)
        result = asyncio.ensure_future(goal.get_result(5.0))
        await asyncio.sleep(0.2)
        with self.assertLogs("peppy", "WARNING"):
            await cam_a.shutdown()
        self.assertEqual(await asyncio.wait_for(result, t.WAIT), (ResultStatus.ABANDONED, None))
        del context


if __name__ == "__main__":
    unittest.main()
