"""PeppyOS's `peppylib` node API (`node/v1` nodes): what their generated `peppygen`
calls. Built messages and held publishers (`build_message`,
`declare_publisher`), held subscriptions yielding `(ProducerRef, message)`,
and service calls and goals sent to a named producer of a slot. The wire
is the one the `emit` API speaks (docs/WIRE.md)."""

from __future__ import annotations

import asyncio
import inspect
import logging
from typing import Any, Callable, Optional, Tuple

from . import attachment
from .action_client import GoalClient, fire_goal
from .action_server import GoalContext, GoalServer
from .bridge import should_yield
from .errors import ShuttingDown, WrongTopic
from .producer import ProducerRef
from .services import call
from .spec import ConsumedActionSpec, ConsumedServiceSpec, ConsumedTopicSpec, QoSProfile, TopicSpec
from .topics import refused

log = logging.getLogger("peppy")


class Payload(bytes):
    """A message of one topic, encoded: what `build_message` returns. It
    is `bytes`; it also remembers its topic, so a publisher of another
    topic refuses it."""

    topic: Optional[TopicSpec] = None


def build_message(spec: TopicSpec, message: Any) -> Payload:
    """`message` encoded for topic `spec` (docs/WIRE.md §5)."""
    payload = Payload(spec.format.encode(message))
    payload.topic = spec
    return payload


class Publisher:
    """The publisher of one emitted topic: `await publisher.publish(payload)`."""

    def __init__(self, runner: Any, spec: TopicSpec) -> None:
        self._runner = runner
        self._spec = spec
        self._publisher = runner._publisher(spec)
        self._attachment = attachment.topic(spec.format.fingerprint)

    def __repr__(self) -> str:
        return f"Publisher(topic={self._spec.name!r})"

    async def publish(self, payload: bytes) -> None:
        """Publishes one message built by this topic's `build_message`.
        Works while the node stops (its shutdown hooks can still publish);
        once messaging is closed, raises `ShuttingDown` after a short pause."""
        topic = getattr(payload, "topic", None)
        if topic is not None and topic != self._spec:
            raise WrongTopic(self._spec.name, topic.name)
        if self._runner.session_closed:
            raise await refused()
        self._publisher.put(bytes(payload), attachment=self._attachment)
        if should_yield():
            await asyncio.sleep(0)


async def declare_publisher(runner: Any, spec: TopicSpec) -> Publisher:
    """The publisher of emitted topic `spec` (declared when the node started)."""
    return Publisher(runner, spec)


class Subscription:
    """A consumed topic, held: messages are queued from the node's start,
    so none is lost between calls. `await sub.next()` gives
    `(ProducerRef, message)`, or None once the node stops; `async for
    producer, message in sub` reads until then."""

    def __init__(self, runner: Any, spec: ConsumedTopicSpec) -> None:
        self._runner = runner
        self._spec = spec
        self._inbox = runner._inbox(spec)
        # The node's code reads the topic (what a harness mock waits for).
        self._inbox.read = True

    def __repr__(self) -> str:
        return f"Subscription(topic={self._spec.name!r})"

    async def next(self) -> Optional[Tuple[ProducerRef, Any]]:
        """The next message and who sent it; None once the node stops. A
        message that does not decode is logged and skipped."""
        inbox = self._inbox
        while True:
            if self._runner.is_stopping():
                return None
            try:
                delivery = await inbox.mailbox.get()
            except ShuttingDown:
                return None
            inbox.taken(delivery)
            try:
                message = self._spec.format.decode(delivery.payload)
            except ValueError as e:
                log.warning(
                    "topic `%s`: dropping a message from `%s` that does not decode: %s",
                    self._spec.name,
                    delivery.instance,
                    e,
                )
                continue
            if should_yield():
                await asyncio.sleep(0)
            return ProducerRef(delivery.core, delivery.instance), message

    def __aiter__(self) -> "Subscription":
        return self

    async def __anext__(self) -> Tuple[ProducerRef, Any]:
        item = await self.next()
        if item is None:
            raise StopAsyncIteration
        return item


async def subscribe(runner: Any, spec: ConsumedTopicSpec) -> Subscription:
    """Holds consumed topic `spec` (subscribed when the node started)."""
    return Subscription(runner, spec)


async def poll(
    runner: Any, spec: ConsumedServiceSpec, target: Any, request: Any, timeout: float
) -> Tuple[str, str, Any]:
    """Calls a consumed service on `target`, one of its slot's bound
    producers: `(server instance id, server core node, response)`. Raises
    `TargetNotBound` (`ValueError`), `ServiceUnreachable`
    (`ConnectionError`), `ServiceTimeout` (`TimeoutError`) or
    `ServiceError` (`RuntimeError`, the handler's text)."""
    instance = runner.ensure_target_bound(spec.link_id, target)
    return await call(runner, spec, timeout, request, target=instance)


async def fire_goal_at(
    runner: Any,
    spec: ConsumedActionSpec,
    target: Any,
    request: Any,
    timeout: float,
    feedback_qos: Optional[QoSProfile] = None,
) -> GoalClient:
    """Sends a goal to `target`, one of the slot's bound producers, and
    waits for its decision (`.accepted`, `.error_message`)."""
    instance = runner.ensure_target_bound(spec.link_id, target)
    return await fire_goal(runner, spec, timeout, request, feedback_qos, target=instance)


async def next_accepted_goal(server: GoalServer, decide: Callable[[str, str, Any], Any]) -> Optional[GoalContext]:
    """The next goal `decide` accepts; rejected goals are answered and
    skipped. `decide(instance_id, core_node, goal)` returns an object with
    `accepted` and `reason` (or an awaitable of one). None once the node
    stops."""

    async def decision(instance_id: str, core_node: str, goal: Any) -> Tuple[bool, Optional[str], Any]:
        answer = decide(instance_id, core_node, goal)
        if inspect.isawaitable(answer):
            answer = await answer
        if not hasattr(answer, "accepted"):
            raise TypeError(
                f"a goal decider returns GoalDecision.accept() or GoalDecision.reject(reason), got {answer!r}"
            )
        return bool(answer.accepted), getattr(answer, "reason", None), getattr(answer, "response", None)

    while True:
        if server._runner.is_stopping():
            return None
        try:
            context = await server.next_goal(decision)
        except ShuttingDown:
            return None
        if context is not None:
            return context
