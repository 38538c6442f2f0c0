"""Testing one node without a stack: what a generated `peppygen.fixtures`
and `peppygen.mock` call.

`start(descriptor, setup, ...)` boots the node's own `setup` in this
process over the real wire: a private Zenoh router on a free loopback port,
one mock producer per slot (each its own session, declared as a real
producer of the slot: publishers, service queryables and action servers of
what the node consumes), taps on every topic the node emits, a clock served
as a launch serves it, and the node's plan (router, instance id,
parameters, each slot bound to its mocks). Nothing is shared between two
harnesses, so tests may run several at once.

Every wait is bounded and names what it waited for; once `setup` raised,
every pending wait fails with that error, and `shutdown()` raises it.
"""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
import json
import logging
import os
import socket
import tempfile
import time
from collections import deque
from typing import Any, Awaitable, Callable, Deque, Dict, Generic, List, Optional, Sequence, Set, Tuple, TypeVar

from . import attachment
from .action_client import GoalClient, fire_goal
from .action_server import DEFAULT_RESULT_RETENTION, GoalContext, PendingGoal, encode_goal_response
from .action_states import encode_decision
from .attachment import ReplyStatus
from .clock import ClockServer, encode_time, sim_time_of
from .declare import declare_all
from .errors import ShuttingDown
from .formats import Format
from .intake import finish, reply
from .keys import ACTION, SERVICE, action_part_key, clock_sync_key, clock_tick_key, entry_key
from .node import NodeBuilder, _call_setup
from .pair_plan import PairEnd, PairPlan
from .core_functions import CoreServer
from .pairing import ObservedSource, PairedSubscription, PeerInfo
from .producer import ProducerRef
from .routing import RouteFilter, SlotBinding, SlotPlan
from .runner import NodeRunner
from .services import call
from .spec import (
    ActionSpec,
    ConsumedActionSpec,
    ConsumedServiceSpec,
    ConsumedTopicSpec,
    NodeDescriptor,
    Owner,
    PairingSlotSpec,
    PairingTopicSpec,
    QoSProfile,
    ServiceSpec,
    SlotSpec,
    TopicSpec,
)
from .startup import Endpoints, Startup, plan_text_from_flags
from .peppylib_api import Subscription

log = logging.getLogger("peppy")

T = TypeVar("T")
Req = TypeVar("Req")
Resp = TypeVar("Resp")

READY_TIMEOUT = 10.0
"""How long readiness waits (a mock's first publish, the barrier before
`setup`, a first sim tick) take before failing loudly (seconds)."""

NODE_CORE = "standalone-core"
"""The core node of the node under test, as for any node started by hand."""
MOCK_CORE = "mock-core"
"""The core node of every mock producer."""
FIXTURE_CORE = "fixture-core"
"""The core node of the harness's own caller and observer session."""
FIXTURE_INSTANCE_ID = "fixture-observer"
"""The fixture session's instance id (each harness has its own router)."""
NAMESPACE = "local"
"""The namespace every harness uses (each has its own router)."""
ROUTER_ATTEMPTS = 20
"""How many free ports a router tries before giving up (another process may take one first)."""

_counter = itertools.count(1)


# ---------------------------------------------------------------- waits


class _Failure:
    """Where the setup's error lands, for every wait of one harness."""

    def __init__(self) -> None:
        self.error: Optional[BaseException] = None
        self.event = asyncio.Event()

    def fail(self, error: BaseException) -> None:
        if self.error is None:
            self.error = error
            self.event.set()


async def _bounded(failure: _Failure, awaitable: Awaitable[T], timeout: Optional[float], what: str) -> T:
    """`awaitable`'s result; `TimeoutError` naming `what` after `timeout`
    seconds (None: no bound); the setup's error once it raised."""
    task = asyncio.ensure_future(awaitable)
    failed = asyncio.ensure_future(failure.event.wait())
    try:
        done, _ = await asyncio.wait({task, failed}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    except BaseException:
        task.cancel()
        raise
    finally:
        failed.cancel()
    if task in done:
        return task.result()
    task.cancel()
    if failure.error is not None:
        raise failure.error
    raise TimeoutError(f"timed out after {timeout:g} s waiting for {what}")


async def _matched(entity: Any, timeout: float) -> bool:
    """Whether `entity` (a publisher or querier) matches a subscriber or
    queryable within `timeout` seconds."""
    loop = asyncio.get_running_loop()
    seen = asyncio.Event()

    def on_status(status: Any) -> None:
        if status.matching:
            try:
                loop.call_soon_threadsafe(seen.set)
            except RuntimeError:
                pass

    listener = entity.declare_matching_listener(on_status)
    try:
        if entity.matching_status.matching:
            return True
        try:
            await asyncio.wait_for(seen.wait(), timeout)
        except asyncio.TimeoutError:
            pass
        return bool(entity.matching_status.matching)
    finally:
        try:
            listener.undeclare()
        except Exception:
            pass


async def _reachable(session: Any, selector: str, timeout: float, what: str) -> None:
    """Returns once a queryable on `selector` is reachable from `session`."""
    querier = session.declare_querier(selector)
    try:
        if not await _matched(querier, timeout):
            raise TimeoutError(f"timed out after {timeout:g} s waiting for {what} to be reachable")
    finally:
        try:
            querier.undeclare()
        except Exception:
            pass


# ---------------------------------------------------------------- router


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _open_router() -> Tuple[Any, str]:
    """A Zenoh router on a free loopback port, multicast scouting off:
    `(session, endpoint)`. A port taken between choosing and binding it is
    tried again with another."""
    import zenoh

    loop = asyncio.get_running_loop()
    last: Optional[Exception] = None
    for _ in range(ROUTER_ATTEMPTS):
        endpoint = f"tcp/127.0.0.1:{_free_port()}"
        config = zenoh.Config()
        config.insert_json5("mode", json.dumps("router"))
        config.insert_json5("listen/endpoints", json.dumps([endpoint]))
        config.insert_json5("scouting/multicast/enabled", "false")
        try:
            session = await loop.run_in_executor(None, zenoh.open, config)
        except Exception as e:
            last = e
            if "in use" in str(e).lower() or "addrinuse" in str(e).lower().replace(" ", ""):
                continue
            raise RuntimeError(f"cannot start the harness's zenoh router on {endpoint}: {e}") from None
        return session, endpoint
    raise RuntimeError(f"cannot start the harness's zenoh router: no free port after {ROUTER_ATTEMPTS} tries ({last})")


def _endpoints(router: str) -> Endpoints:
    # Clients: every message goes through the harness's router, so
    # readiness seen there is readiness.
    return Endpoints(mode="client", connect=(router,))


async def _open_runner(
    descriptor: NodeDescriptor,
    core: str,
    instance: str,
    router: str,
    slots: List[SlotPlan],
    pairs: Optional[List[PairPlan]] = None,
) -> NodeRunner:
    """A runner of `descriptor` on its own session, everything declared."""
    import zenoh

    endpoints = _endpoints(router)
    startup = Startup(instance, core, NAMESPACE, endpoints, slots, {}, pairs=list(pairs or ()))
    loop = asyncio.get_running_loop()
    session = await loop.run_in_executor(None, zenoh.open, endpoints.zenoh_config())
    runner = NodeRunner(descriptor, startup, session, {})
    try:
        await declare_all(runner, DEFAULT_RESULT_RETENTION)
    except BaseException:
        await runner.shutdown()
        raise
    return runner


# ---------------------------------------------------------------- mocks


class TopicMock(Generic[T]):
    """A topic the node consumes, played by a mock producer:
    `await publish(message)`."""

    def __init__(self, mock: "SlotMock", spec: TopicSpec) -> None:
        self._mock = mock
        self._spec = spec
        self._subscribed = False

    def __repr__(self) -> str:
        return f"TopicMock({self._spec.name!r}, instance={self._mock.instance_id!r})"

    async def wait_for_subscriber(self, timeout: float = READY_TIMEOUT) -> bool:
        """Whether the node's subscription to this topic is seen within `timeout` seconds."""
        runner = self._mock._runner
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        matched = await _bounded(
            self._mock._failure,
            _matched(runner._publisher(self._spec), timeout),
            None,
            f"a subscriber of topic `{self._spec.name}`",
        )
        # Under a harness, also until the node's code reads the topic
        # (subscribe, or a first next): a returned publish then means the
        # node's code got that far, as PeppyOS's harness has it.
        inbox = self._subject_inbox()
        while matched and inbox is not None and not inbox.read:
            if loop.time() >= deadline:
                return False
            await _bounded(self._mock._failure, asyncio.sleep(0.005), None, f"the node to read topic `{self._spec.name}`")
        if matched:
            self._subscribed = True
        return matched

    def _subject_inbox(self) -> Optional[Any]:
        node = self._mock._subject
        if node is None:
            return None
        link = self._mock.link_id or None
        for c in node.descriptor.consumed_topics:
            if (c.link_id or None) == link and c.name == self._spec.name:
                return node._inbox(c)
        return None

    async def publish(self, message: T) -> None:
        """Publishes `message` as the slot's producer. The first call waits
        (up to 10 s) for the node's subscription, so nothing is lost to the
        node's start; a node that never subscribes is an error naming the topic."""
        await self._ready()
        await self._mock._put(self._spec, self._spec.format, message)

    async def publish_as(self, fmt: Format, message: Any) -> None:
        """Publishes `message` in another format `fmt` on this topic's key:
        what a producer built against other documents sends (the node
        drops it and logs the mismatch)."""
        await self._ready()
        await self._mock._put(self._spec, fmt, message)

    async def _ready(self) -> None:
        if self._subscribed:
            return
        if not await self.wait_for_subscriber(READY_TIMEOUT):
            raise TimeoutError(
                f"mock `{self._mock.instance_id}`: the node did not subscribe to topic `{self._spec.name}` "
                f"within {READY_TIMEOUT:g} s; does its setup subscribe to it?"
            )


class Responder:
    """The answer to one request a service mock received: `respond` or `respond_error`, once."""

    def __init__(self, service: "ServiceMock[Any, Any]", pending: Any) -> None:
        self._service = service
        self._pending = pending
        self._done = False

    async def respond(self, response: Any) -> None:
        """Answers with `response`."""
        spec = self._service._spec
        self._answer(ReplyStatus.OK, spec.response.encode(response))

    async def respond_error(self, reason: str) -> None:
        """Answers with an error; the node's call raises it (`RuntimeError`)."""
        self._answer(ReplyStatus.HANDLER_ERROR, str(reason).encode("utf-8"))

    def _answer(self, status: ReplyStatus, body: bytes) -> None:
        if self._done:
            raise RuntimeError(f"service `{self._service._spec.name}`: this request was answered already")
        self._done = True
        self._service._unanswered.discard(id(self))
        spec = self._service._spec
        reply(self._pending.query, self._service._key, status, spec.response.fingerprint, body, spec.name)
        finish(self._pending.query)


class ServiceMock(Generic[Req, Resp]):
    """A service the node calls, served by a mock producer: answer requests
    one by one (`next_request`) or script them (`enqueue_response`)."""

    def __init__(self, mock: "SlotMock", spec: ServiceSpec) -> None:
        self._mock = mock
        self._spec = spec
        self._scripted: Deque[Any] = deque()
        self._captured: List[Any] = []
        self._requests: "asyncio.Queue[Tuple[Any, Responder]]" = asyncio.Queue()
        self._unanswered: set = set()
        self._mailbox, self._key = mock._runner._service_inbox(spec)
        mock._runner._spawn(self._pump())

    def __repr__(self) -> str:
        return f"ServiceMock({self._spec.name!r}, instance={self._mock.instance_id!r})"

    async def _pump(self) -> None:
        while True:
            try:
                pending = await self._mailbox.get()
            except ShuttingDown:
                return
            try:
                request = self._spec.request.decode(pending.payload)
            except ValueError as e:
                body = f"request does not decode: {e}".encode("utf-8")
                reply(pending.query, self._key, ReplyStatus.HANDLER_ERROR, self._spec.response.fingerprint, body, "")
                finish(pending.query)
                continue
            self._captured.append(request)
            responder = Responder(self, pending)
            if self._scripted:
                await responder.respond(self._scripted.popleft())
            else:
                self._unanswered.add(id(responder))
                self._requests.put_nowait((request, responder))

    async def next_request(self, timeout: float = READY_TIMEOUT) -> Tuple[Any, Responder]:
        """The next request no scripted response answered, and its responder."""
        return await _bounded(
            self._mock._failure,
            self._requests.get(),
            timeout,
            f"a request to service `{self._spec.name}` on mock `{self._mock.instance_id}`",
        )

    def enqueue_response(self, response: Any) -> None:
        """Answers the next request not yet answered with `response` (first in, first out)."""
        self._spec.response.encode(response)  # a wrong type fails here, not in the pump
        self._scripted.append(response)

    def captured(self) -> List[Any]:
        """Every request received so far, in arrival order."""
        return list(self._captured)

    def captured_count(self) -> int:
        """How many requests were received so far."""
        return len(self._captured)

    def _leftovers(self) -> List[str]:
        out = []
        if self._scripted:
            out.append(f"{len(self._scripted)} scripted response(s) of `{self._spec.name}` never used")
        if self._unanswered:
            out.append(f"{len(self._unanswered)} request(s) to `{self._spec.name}` never answered")
        return out


class ActiveGoal:
    """A goal the mock accepted: feed it, then complete it."""

    def __init__(self, context: GoalContext) -> None:
        self._context = context
        self.request = context.goal

    def goal_id(self) -> str:
        return self._context.goal_id

    async def publish_feedback(self, feedback: Any) -> None:
        """Publishes one feedback message to the node."""
        await self._context.publish_feedback(feedback)

    async def complete(self, result: Any) -> None:
        """Ends the goal with `result`."""
        await self._context.complete(result)

    async def complete_cancelled(self, result: Any) -> None:
        """Ends the goal as cancelled, with a (partial) `result`."""
        await self._context.complete_cancelled(result)

    async def cancel_signal(self) -> None:
        """Returns once the node asks to cancel the goal."""
        await self._context.cancel_signal.wait()

    def is_cancelled(self) -> bool:
        """Whether the node asked to cancel the goal."""
        return self._context.is_cancelled()


class PendingGoalMock:
    """A goal the node sent, waiting for the mock's decision: `accept` or `reject`."""

    def __init__(self, action: "ActionMock", pending: PendingGoal, request: Any) -> None:
        self._action = action
        self._pending = pending
        self._decided = False
        self.request = request

    def goal_id(self) -> str:
        return self._pending.goal_id

    def _decide(self, accepted: bool, reason: Optional[str], response: Any) -> None:
        if self._decided:
            raise RuntimeError(f"action `{self._action._spec.name}`: goal {self.goal_id()} was decided already")
        body = encode_goal_response(self._action._spec, response)
        self._decided = True
        key = action_part_key(self._action._registry.base_key, "goal")
        reply(
            self._pending.query, key, ReplyStatus.OK, 0, encode_decision(accepted, reason, body), self._action._spec.name
        )
        finish(self._pending.query)

    async def accept(self, response: Any = None) -> ActiveGoal:
        """Accepts the goal, with the action's declared goal response when it
        has one (the node's handle reads it as `data`)."""
        context = GoalContext(self._action._mock._runner, self._action._registry, self._pending, self.request)
        self._decide(True, None, response)
        return ActiveGoal(context)

    async def reject(self, reason: Optional[str] = None, response: Any = None) -> None:
        """Rejects the goal with `reason` and, optionally, a goal response."""
        self._decide(False, reason, response)


class ActionMock:
    """An action the node calls, served by a mock producer on the runtime's
    action engine: `await next_goal(timeout)`."""

    def __init__(self, mock: "SlotMock", spec: ActionSpec) -> None:
        self._mock = mock
        self._spec = spec
        self._mailbox, self._registry = mock._runner._action_server(spec)
        self._goals: "asyncio.Queue[PendingGoalMock]" = asyncio.Queue()
        mock._runner._spawn(self._pump())

    def __repr__(self) -> str:
        return f"ActionMock({self._spec.name!r}, instance={self._mock.instance_id!r})"

    async def _pump(self) -> None:
        key = action_part_key(self._registry.base_key, "goal")
        while True:
            try:
                pending: PendingGoal = await self._mailbox.get()
            except ShuttingDown:
                return
            try:
                request = self._spec.goal.decode(pending.body)
            except ValueError as e:
                log.warning("mock action `%s`: rejecting a goal that does not decode: %s", self._spec.name, e)
                reply(pending.query, key, ReplyStatus.OK, 0, encode_decision(False, f"goal does not decode: {e}"), "")
                finish(pending.query)
                continue
            self._goals.put_nowait(PendingGoalMock(self, pending, request))

    async def next_goal(self, timeout: float = READY_TIMEOUT) -> PendingGoalMock:
        """The next goal the node sends, waiting for the mock's decision."""
        return await _bounded(
            self._mock._failure,
            self._goals.get(),
            timeout,
            f"a goal of action `{self._spec.name}` on mock `{self._mock.instance_id}`",
        )


class SlotMock:
    """One mock producer of a slot: a member per entry the node consumes
    through it (topics, services, actions, by name), on its own session.
    Generated `Mock` classes name the members' types."""

    def __init__(self, runner: NodeRunner, link_id: str, failure: _Failure) -> None:
        self._runner = runner
        self._failure = failure
        self.link_id = link_id
        self.instance_id = runner.instance_id
        # The node under test, once the harness started it.
        self._subject: Optional[Any] = None
        self._services: List[ServiceMock[Any, Any]] = []
        self._actions: List[ActionMock] = []
        d = runner.descriptor
        # A generated Mock names its members (entry name -> attribute).
        members: Dict[str, str] = getattr(type(self), "MEMBERS", {})

        def attr(name: str) -> str:
            return members.get(name) or _attr(name)

        for spec in d.emitted_topics:
            setattr(self, attr(spec.name), TopicMock(self, spec))
        for s in d.exposed_services:
            service: ServiceMock[Any, Any] = ServiceMock(self, s)
            self._services.append(service)
            setattr(self, attr(s.name), service)
        for a in d.exposed_actions:
            action = ActionMock(self, a)
            self._actions.append(action)
            setattr(self, attr(a.name), action)
        self._stopped = False

    def __repr__(self) -> str:
        return f"{type(self).__name__}(link_id={self.link_id!r}, instance_id={self.instance_id!r})"

    def producer_ref(self) -> ProducerRef:
        """This mock's identity on the wire."""
        return ProducerRef(MOCK_CORE, self.instance_id)

    async def _put(self, spec: TopicSpec, fmt: Format, message: Any) -> None:
        if self._runner.session_closed:
            raise RuntimeError(f"mock `{self.instance_id}` is stopped")
        self._runner._publisher(spec).put(fmt.encode(message), attachment=attachment.topic(fmt.fingerprint))
        await asyncio.sleep(0)

    async def stop(self) -> None:
        """The producer is lost: every declaration and the session go at
        once, and goals still running end without a clean close. Stays stopped."""
        if self._stopped:
            return
        self._stopped = True
        for _, registry in self._runner._actions.values():
            registry.disarm()
        for line in [x for s in self._services for x in s._leftovers()]:
            log.warning("mock `%s`: %s", self.instance_id, line)
        await self._runner.shutdown()


MOCK_PEER = "mock_peer"
"""The pairing slot of a pairing mock (`h.mocks.pairings.<link_id>`)."""
MOCK_SOURCE = "mock_source"
"""The pairing slot of an observed source's mock (`h.mocks.observed.<link_id>`)."""


class PeerTopicMock(Generic[T]):
    """A pairing topic the node receives, played by a mock:
    `await publish(message)`."""

    def __init__(self, mock: "_PairingMockBase", spec: PairingTopicSpec) -> None:
        self._mock = mock
        self._spec = spec
        self._subscribed = False

    def __repr__(self) -> str:
        return f"PeerTopicMock({self._spec.name!r}, instance={self._mock.instance_id!r})"

    async def wait_for_subscriber(self, timeout: float = READY_TIMEOUT) -> bool:
        """Whether the node's subscription to this topic is seen within `timeout` seconds."""
        publisher = self._mock._slot()._publishers[self._spec.name]
        matched = await _bounded(
            self._mock._failure, _matched(publisher, timeout), None, f"a subscriber of `{self._spec.name}`"
        )
        if matched:
            self._subscribed = True
        return matched

    async def publish(self, message: T) -> None:
        """Sends `message` to the node. The first call waits (up to 10 s)
        for the node's subscription, so nothing is lost to its start."""
        if not self._subscribed and not await self.wait_for_subscriber(READY_TIMEOUT):
            raise TimeoutError(
                f"mock `{self._mock.instance_id}`: the node did not subscribe to pairing topic "
                f"`{self._spec.name}` within {READY_TIMEOUT:g} s"
            )
        runner = self._mock._runner
        if runner.session_closed:
            raise RuntimeError(f"mock `{self._mock.instance_id}` is stopped")
        fmt = self._spec.format
        # Straight onto the slot's publisher: an observed source's mock
        # plays a source whatever its own pair, and the pairing mock's pair
        # holds from before setup.
        self._mock._slot()._publishers[self._spec.name].put(
            fmt.encode(message), attachment=attachment.topic(fmt.fingerprint)
        )
        await asyncio.sleep(0)


class PeerTap(Generic[T]):
    """A pairing topic the node sends its peer, received by the pairing
    mock: `await tap.next()`."""

    def __init__(self, mock: "_PairingMockBase", spec: PairingTopicSpec) -> None:
        self._mock = mock
        self._spec = spec
        self._subscription = PairedSubscription(mock._runner, spec)

    def __repr__(self) -> str:
        return f"PeerTap({self._spec.name!r}, instance={self._mock.instance_id!r})"

    async def next(self, timeout: Optional[float] = None) -> Optional[T]:
        """The node's next message on this topic, in order; None once the
        mock is stopped. `timeout` in seconds (None: no bound)."""
        got = await _bounded(
            self._mock._failure, self._subscription.next(), timeout, f"a message on pairing topic `{self._spec.name}`"
        )
        return None if got is None else got[1]


class _PairingMockBase:
    """A mock instance with one pairing slot, on its own session."""

    SLOT = MOCK_PEER

    def __init__(self, runner: NodeRunner, link_id: str, failure: _Failure) -> None:
        self._runner = runner
        self._failure = failure
        self.link_id = link_id
        self.instance_id = runner.instance_id
        self._stopped = False
        slot = self._slot()
        if hasattr(slot, "quiet"):
            slot.quiet = True
        members: Dict[str, str] = getattr(type(self), "MEMBERS", {})
        for spec in runner.descriptor.pairing_topics:
            member = PeerTopicMock(self, spec) if spec.emitted else PeerTap(self, spec)
            setattr(self, members.get(spec.name) or _attr(spec.name), member)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(link_id={self.link_id!r}, instance_id={self.instance_id!r})"

    def _slot(self) -> Any:
        return self._runner._pairings[self.SLOT]

    def producer_ref(self) -> ProducerRef:
        """This mock's identity on the wire."""
        return ProducerRef(MOCK_CORE, self.instance_id)

    async def stop(self) -> None:
        """The mock is lost: its claim, its declarations and its session go
        at once (the node's pair dissolves). Stays stopped."""
        if self._stopped:
            return
        self._stopped = True
        await self._runner.shutdown()


class PairingMock(_PairingMockBase):
    """The peer of one of the node's participant slots (instance
    `mock-<link_id>`, slot `mock_peer`): a member per pairing topic,
    `publish` for those the node receives, `next()` for those it sends.
    Generated `Mock` classes name the members' types."""

    def peer_info(self) -> PeerInfo:
        """The mock as the node sees its peer."""
        return PeerInfo(self.producer_ref(), MOCK_PEER)

    def paired(self) -> bool:
        """Whether the mock's pair with the node holds."""
        return self._slot().peer_info() is not None


class ObservedMock(_PairingMockBase):
    """A source one of the node's observer slots watches (slot
    `mock_source`): a member per observed topic, `publish`."""

    SLOT = MOCK_SOURCE

    def source(self) -> ObservedSource:
        """The mock as the node sees this source."""
        return ObservedSource(self.producer_ref(), MOCK_SOURCE)


def pairing_mock_descriptor(node: NodeDescriptor, slot: PairingSlotSpec) -> NodeDescriptor:
    """What plays the other side of pairing slot `slot` of `node`: the
    counterpart role through slot `mock_peer` (a participant's peer),
    or the watched role through `mock_source` (an observer's source),
    sending what the node receives and receiving what the node sends."""
    if slot.observer:
        mine = PairingSlotSpec(MOCK_SOURCE, slot.pairing, slot.tag, slot.role, slot.counterpart)
    else:
        mine = PairingSlotSpec(MOCK_PEER, slot.pairing, slot.tag, slot.counterpart, slot.role)
    topics = tuple(
        PairingTopicSpec(mine.link_id, t.pairing, t.tag, t.name, t.qos, t.format, not t.emitted)
        for t in node.pairing_topics
        if t.link_id == slot.link_id
    )
    return NodeDescriptor(name=f"mock_{slot.link_id}", tag="v1", pairings=(mine,), pairing_topics=topics)


def _observed_ids(slot: PairingSlotSpec, options: Dict[str, Any]) -> List[str]:
    """The mock source instance ids of observer slot `slot`."""
    link = slot.link_id
    count = options.pop(f"{link}_instances", None)
    ids = options.pop(f"{link}_instance_ids", None)
    vacant = bool(options.pop(f"{link}_vacant", False))
    many = slot.cardinality in ("one_or_more", "zero_or_more")
    if vacant:
        if slot.cardinality != "zero_or_one":
            raise TypeError(
                f"`{link}_vacant`: observer slot `{link}` is `{slot.cardinality}`; only a `zero_or_one` slot can be vacant"
            )
        return []
    if ids:
        ids = [str(i) for i in ids]
        if len(set(ids)) != len(ids):
            raise ValueError(f"`{link}_instance_ids` names an instance twice: {ids}")
    elif many:
        n = (0 if slot.cardinality == "zero_or_more" else 1) if count is None else int(count)
        ids = [f"mock-{link}-{i}" for i in range(n)]
    else:
        n = 1 if count is None else int(count)
        ids = [f"mock-{link}"] if n else []
    fits = {
        "one": len(ids) == 1,
        "zero_or_one": len(ids) <= 1,
        "one_or_more": len(ids) >= 1,
    }.get(slot.cardinality, True)
    if not fits:
        raise ValueError(f"observer slot `{link}` is `{slot.cardinality}`: {len(ids)} source(s) do not fit it")
    return ids


def _attr(name: str) -> str:
    return "".join(c if c.isalnum() or c == "_" else "_" for c in name)


def mock_descriptor(node: NodeDescriptor, slot: SlotSpec) -> NodeDescriptor:
    """What a producer of `slot` provides to `node`: each topic the node
    consumes through it emitted, each service and action it calls
    exposed, under the owners the node reads them from. A node slot's
    producer runs that node (so the node's membership checks take it)."""
    link = slot.link_id

    def owner(o: Owner) -> Owner:
        return o if o.kind in ("node", "interface") else Owner.node(slot.name, slot.tag)

    name = slot.name if slot.kind == "node" else f"mock_{link}"
    return NodeDescriptor(
        name=name,
        tag=slot.tag,
        emitted_topics=tuple(
            TopicSpec(owner(t.owner), t.name, t.qos, t.format) for t in node.consumed_topics if t.link_id == link
        ),
        exposed_services=tuple(
            ServiceSpec(owner(s.owner), s.name, s.request, s.response)
            for s in node.consumed_services
            if s.link_id == link
        ),
        exposed_actions=tuple(
            ActionSpec(owner(a.owner), a.name, a.goal, a.feedback, a.result, a.goal_response)
            for a in node.consumed_actions
            if a.link_id == link
        ),
    )


class _Group:
    """An attribute bag: `h.mocks.deps.<link_id>`, `h.emitted.<topic>`."""

    def __init__(self, what: str) -> None:
        self._what = what

    def __getattr__(self, name: str) -> Any:
        raise AttributeError(f"{self._what} has no `{name}`")


# ---------------------------------------------------------------- taps and callers


class Tap(Generic[T]):
    """A topic the node emits, seen from outside: `await tap.next()`."""

    def __init__(self, harness: "Harness", spec: ConsumedTopicSpec) -> None:
        self._harness = harness
        self._spec = spec
        self._subscription = Subscription(harness._fixture, spec)

    def __repr__(self) -> str:
        return f"Tap({self._spec.name!r})"

    async def next(self, timeout: Optional[float] = None) -> Optional[T]:
        """The node's next message on this topic, in order; None once the
        harness is shut down. `timeout` in seconds (None: no bound)."""
        got = await _bounded(
            self._harness._failure, self._subscription.next(), timeout, f"a message on topic `{self._spec.name}`"
        )
        return None if got is None else got[1]


class GoalHandle:
    """A goal a fixture sent to the node: `accepted`, `reason`, `data`,
    then feedback, result and cancel."""

    def __init__(self, client: GoalClient) -> None:
        self._client = client
        self.accepted: bool = client.accepted
        self.reason: Optional[str] = client.error_message
        self.data: Any = client.data

    def goal_id(self) -> str:
        return self._client.goal_id

    async def on_next_feedback(self) -> Any:
        """The next feedback message; `RuntimeError` once the goal ended."""
        return await self._client.next_feedback()

    async def get_result(self, timeout: float = READY_TIMEOUT) -> "GoalResult":
        """How the goal ended (`status`, `data`), waiting up to `timeout` seconds."""
        status, data = await self._client.get_result(timeout)
        return GoalResult(status, data)

    async def cancel_goal(self, timeout: float = READY_TIMEOUT) -> "CancelAnswer":
        """Asks the node to cancel the goal (`state`)."""
        return CancelAnswer(await self._client.cancel(timeout))


@dataclasses.dataclass
class GoalResult:
    """How a goal ended: `status` (a `ResultStatus`), `data` for completed and cancelled goals."""

    status: Any
    data: Any


@dataclasses.dataclass
class CancelAnswer:
    """The node's answer to a cancel: `state` (a `CancelState`)."""

    state: Any


def _own(spec_owner: Owner, node: NodeDescriptor) -> Owner:
    return Owner.node(node.name, node.tag) if spec_owner.kind == "own" else spec_owner


async def poll_service(harness: "Harness", spec: ServiceSpec, request: Any, timeout: float) -> Any:
    """Calls the node's exposed service `spec` from the fixture session, as
    a consumer would: waits (within `timeout`) until it is reachable, then
    returns the response data."""
    h = harness
    node = h.node_runner.descriptor
    consumed = ConsumedServiceSpec(_FIXTURE_LINK, _own(spec.owner, node), spec.name, spec.request, spec.response)
    owner = consumed.owner.segments(node.name, node.tag)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    # The exact key: Zenoh's matching status does not see through a wildcard.
    selector = entry_key(NAMESPACE, SERVICE, owner or "", spec.name, NODE_CORE, h.instance_id)
    await _bounded(h._failure, _reachable(h.session, selector, timeout, f"service `{spec.name}`"), None, "")
    left = max(deadline - loop.time(), 0.001)
    call_ = call(h._fixture, consumed, left, request, target=h.instance_id)
    _, _, data = await _bounded(h._failure, call_, None, f"service `{spec.name}`")
    return data


async def send_goal(
    harness: "Harness", spec: ActionSpec, request: Any, qos: Optional[QoSProfile], timeout: float
) -> GoalHandle:
    """Sends a goal to the node's exposed action `spec` from the fixture
    session: waits (within `timeout`) until it is reachable, then returns
    once the node decided."""
    h = harness
    node = h.node_runner.descriptor
    consumed = ConsumedActionSpec(
        _FIXTURE_LINK, _own(spec.owner, node), spec.name, spec.goal, spec.feedback, spec.result, spec.goal_response
    )
    owner = consumed.owner.segments(node.name, node.tag)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    selector = action_part_key(entry_key(NAMESPACE, ACTION, owner or "", spec.name, NODE_CORE, h.instance_id), "goal")
    await _bounded(h._failure, _reachable(h.session, selector, timeout, f"action `{spec.name}`"), None, "")
    left = max(deadline - loop.time(), 0.001)
    goal = fire_goal(h._fixture, consumed, left, request, qos, target=h.instance_id)
    return GoalHandle(await _bounded(h._failure, goal, None, f"action `{spec.name}`"))


_FIXTURE_LINK = "node_under_test"


# ---------------------------------------------------------------- clock


class TestClock:
    """The launch clock the node under test sees, served by the harness.
    Wall mode: `set_offset_ns(n)` skews what it serves. Sim mode (the
    harness's `use_sim_time=True`): no time until `await tick(ns)`."""

    __test__ = False  # not a pytest test class

    def __init__(self, harness: "Harness", server: ClockServer, sim: bool) -> None:
        self._harness = harness
        self._server = server
        self.sim = sim
        self._tick_publisher: Any = None
        self._subscribed = False

    def set_offset_ns(self, offset_ns: int) -> None:
        """Wall mode: serves the wall clock `offset_ns` ahead (negative: behind)."""
        if self.sim:
            raise RuntimeError("set_offset_ns: the harness clock is in sim mode (use tick)")
        self._server.offset_ns = int(offset_ns)

    async def tick(self, ns: int) -> None:
        """Sim mode: makes `ns` the sim time, publishes it, and returns once
        the node's clock reads it. The first tick waits (up to 10 s) for the
        node's clock subscription (`clock.init`); a node that never reads
        sim time is an error."""
        if not self.sim:
            raise RuntimeError("tick: the harness clock is in wall mode (start the harness with use_sim_time=True)")
        h = self._harness
        encode_time(ns)
        self._server.set_sim_time(ns)
        if self._tick_publisher is None:
            self._tick_publisher = h.session.declare_publisher(clock_tick_key(NAMESPACE, "sim"))
            h._fixture._declared.append(self._tick_publisher)
        if not self._subscribed:
            matched = await _bounded(h._failure, _matched(self._tick_publisher, READY_TIMEOUT), None, "")
            if not matched:
                raise TimeoutError(
                    f"tick: the node did not subscribe to sim time within {READY_TIMEOUT:g} s; "
                    "does its setup call `clock.init(node_runner)`?"
                )
            self._subscribed = True
        latest = sim_time_of(h.node_runner)
        if latest is None:
            raise RuntimeError("tick: the node's clock is not bound to sim time (`clock.init` in another node?)")
        reached = latest.reached(ns)
        self._tick_publisher.put(encode_time(ns))
        await _bounded(h._failure, reached, READY_TIMEOUT, f"the node's clock to read sim time {ns}")


# ---------------------------------------------------------------- harness


class Harness:
    """The node under test, running: `mocks`, `emitted`, `clock`,
    `node_runner`, `session` (the fixture session), `instance_id`; end
    with `await shutdown()` (automatic in `async with`)."""

    def __init__(self) -> None:
        self._failure = _Failure()
        self._router: Any = None
        self._fixture: Any = None
        self._mock_list: List[Any] = []
        self._unpaired: Set[str] = set()
        self._clock_server: Optional[ClockServer] = None
        self._core_server: Optional[CoreServer] = None
        self._started = time.monotonic()
        self._setup_task: Optional["asyncio.Task[Any]"] = None
        self._closed = False
        self.router_endpoint = ""
        self.node_runner: NodeRunner = None  # type: ignore[assignment]
        self.session: Any = None
        self.instance_id = ""
        self.mocks = _Group("the harness's mocks")
        self.mocks.deps = _Group("mocks.deps")
        self.mocks.pairings = _Group("mocks.pairings")
        self.mocks.observed = _Group("mocks.observed")
        self.emitted = _Group("the harness's taps (emitted)")
        self.clock: TestClock = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Harness(instance_id={self.instance_id!r}, router={self.router_endpoint!r})"

    def node_producer_ref(self) -> ProducerRef:
        """The node's identity on the wire."""
        return ProducerRef(NODE_CORE, self.instance_id)

    def _core_info(self) -> Dict[str, Any]:
        """What the harness answers `info` with, as the node's core node."""
        port = self.router_endpoint.rsplit(":", 1)[-1] if self.router_endpoint else "0"
        return {
            "uptime_secs": int(time.monotonic() - self._started),
            "core_node_name": NODE_CORE,
            "core_node_instance_id": f"harness-{self.instance_id}",
            "host_name": "",
            "node_count": 1,
            "git_version": "peppy test harness",
            "container_info": {"apptainer_version": "", "lima_version": ""},
            "messaging_port": int(port) if port.isdigit() else 0,
        }

    def _core_graph(self) -> Dict[str, Any]:
        """The stack the harness answers `stack.list` with: the node under test."""
        runner = self.node_runner
        running = runner is not None and not runner.is_stopping()
        d = runner.descriptor if runner is not None else None
        return {
            "nodes": [
                {
                    "name": d.name if d else "",
                    "tag": d.tag if d else "",
                    "core_node": NODE_CORE,
                    "config_path": "",
                    "artifact_path": None,
                    "stage": "Ready",
                    "instances": [
                        {
                            "instance_id": self.instance_id,
                            "state": "running" if running else "starting",
                            "healthy": running,
                        }
                    ],
                }
            ],
            "edges": [],
        }

    def setup_finished(self) -> bool:
        """Whether `setup` has returned (without raising)."""
        t = self._setup_task
        return t is not None and t.done() and not t.cancelled() and t.exception() is None

    async def shutdown(self) -> None:
        """Stops the node (its token cancelled, its shutdown hooks run),
        then the fixture session, the mocks and the router; raises the
        error `setup` raised, if it did. Idempotent."""
        if self._closed:
            if self._failure.error is not None:
                raise self._failure.error
            return
        self._closed = True
        try:
            task = self._setup_task
            if task is not None and not task.done():
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)
            if self.node_runner is not None:
                await self.node_runner.shutdown()
            if self._clock_server is not None:
                self._clock_server.close()
            if self._core_server is not None:
                self._core_server.close()
            if self._fixture is not None:
                await self._fixture.shutdown()
            for mock in self._mock_list:
                await mock.stop()
        finally:
            if self._router is not None:
                router, self._router = self._router, None
                try:
                    await asyncio.get_running_loop().run_in_executor(None, router.close)
                except Exception as e:
                    log.debug("closing the harness router: %s", e)
        if self._failure.error is not None:
            raise self._failure.error

    def _setup_done(self, task: "asyncio.Task[Any]") -> None:
        if task.cancelled():
            return
        error = task.exception()
        if error is not None:
            log.error("the setup of the node under test failed: %r", error)
            self._failure.fail(error)
            self.node_runner.stop()
            return
        try:
            self.node_runner.adopt(task.result())
        except TypeError as e:
            self._failure.fail(e)
            self.node_runner.stop()


class Starting:
    """A harness being started: `h = await start(...)`, or
    `async with start(...) as h:` (shut down on leaving)."""

    def __init__(self, coro: Awaitable[Harness]) -> None:
        self._coro = coro
        self._harness: Optional[Harness] = None

    def __await__(self) -> Any:
        return self._coro.__await__()

    async def __aenter__(self) -> Harness:
        self._harness = await self._coro
        return self._harness

    async def __aexit__(self, kind: Any, error: Any, tb: Any) -> None:
        assert self._harness is not None
        if error is None:
            await self._harness.shutdown()
            return
        # The test failed: its own error counts, the teardown's is logged.
        try:
            await self._harness.shutdown()
        except BaseException as e:
            if e is not error:
                log.warning("harness shutdown after a failed test: %r", e)


def start(
    descriptor: NodeDescriptor,
    setup: Callable[[Any, NodeRunner], Any],
    *,
    mocks: Optional[Dict[str, type]] = None,
    emitted: Optional[Dict[str, TopicSpec]] = None,
    parameters: Any = None,
    instance_id: Optional[str] = None,
    use_sim_time: bool = False,
    node_dir: Optional[str] = None,
    **slot_options: Any,
) -> Starting:
    """Starts `setup` of the node `descriptor` describes under a harness.

    `mocks` maps a slot's link_id to its generated `Mock` class (default
    `SlotMock`), `emitted` a tap's name to the emitted topic it taps (default:
    each topic's name). `parameters` (a `Parameters` or a dict) are
    checked, and completed with the document's defaults, by `peppy-launch
    plan`, which also binds each slot to its mocks (it must be on `PATH`
    or in `PEPPY_LAUNCH`). Per slot:
    `<link_id>_instances=N` and `<link_id>_instance_ids=[...]` (slots of
    several producers), `<link_id>_vacant=True` (a `zero_or_one` slot).
    Each participant pairing slot is paired with a `PairingMock` (the
    class `mocks` names for its link_id; `<link_id>_vacant=True` leaves an
    optional one vacant), each observer slot watches `ObservedMock`s
    (`<link_id>_instances=N`, `<link_id>_instance_ids=[...]`); `setup` starts
    once every pair holds.
    `node_dir` is where relative paths of the node resolve (the working
    directory while `setup` starts)."""
    return Starting(
        _start(
            descriptor,
            setup,
            mocks or {},
            emitted,
            parameters,
            instance_id,
            use_sim_time,
            node_dir,
            slot_options,
        )
    )


def _instances(slot: SlotSpec, options: Dict[str, Any]) -> Tuple[List[str], bool]:
    """The mock instance ids of `slot`, and whether it is left vacant."""
    link = slot.link_id
    vacant = bool(options.pop(f"{link}_vacant", False))
    count = options.pop(f"{link}_instances", None)
    ids = options.pop(f"{link}_instance_ids", None)
    many = slot.from_any or slot.cardinality in ("one_or_more", "zero_or_more")
    if vacant and slot.cardinality != "zero_or_one":
        raise TypeError(
            f"`{link}_vacant`: slot `{link}` is `{slot.cardinality}`; only a `zero_or_one` slot can be vacant"
        )
    if (count is not None or ids is not None) and not many:
        raise TypeError(f"`{link}_instances` / `{link}_instance_ids`: slot `{link}` takes one producer")
    if vacant:
        return [], True
    if ids is not None:
        ids = [str(i) for i in ids]
        if len(set(ids)) != len(ids):
            raise ValueError(f"`{link}_instance_ids` names an instance twice: {ids}")
    elif many:
        n = (0 if slot.cardinality == "zero_or_more" else 1) if count is None else int(count)
        ids = [f"mock-{link}-{i}" for i in range(n)]
    else:
        ids = [f"mock-{link}"]
    if slot.cardinality == "one_or_more" and not ids:
        raise ValueError(f"slot `{link}` is `one_or_more`: it needs at least one mock")
    return ids, False


def _plan_flags(
    descriptor: NodeDescriptor,
    instance_id: str,
    wanted: Sequence[Tuple[SlotSpec, List[str], bool]],
    parameters_file: Optional[str],
    pair_links: Sequence[Tuple[str, Optional[str]]] = (),
) -> List[str]:
    """The standalone command line that binds each slot to its mocks (or
    leaves it vacant): `peppy-launch plan` turns it into the node's plan,
    so the binding engine and the parameter checker decide, as for any
    node started by hand."""
    flags = ["--instance-id", instance_id]
    for slot, ids, vacant in wanted:
        if vacant:
            flags += ["--vacant-link", f"{slot.link_id}=left vacant by the test harness"]
        flags += [a for i in ids for a in ("--link", f"{slot.link_id}@{i}")]
    for link_id, target in pair_links:
        if target is None:
            flags += ["--vacant-link", f"{link_id}=left vacant by the test harness"]
        else:
            flags += ["--link", f"{link_id}@{target}"]
    if parameters_file is not None:
        flags += ["--params", parameters_file]
    return flags


def _parameters_given(given: Any) -> Optional[Dict[str, Any]]:
    """The parameters a test gives, as JSON values (a `Parameters` or a
    dict; `None`: the document's defaults)."""
    if given is None:
        return None
    if dataclasses.is_dataclass(given) and not isinstance(given, type):
        given = dataclasses.asdict(given)
    if not isinstance(given, dict):
        raise TypeError(f"parameters: a Parameters or a dict, got {type(given).__name__}")

    def plain(v: Any) -> Any:
        if isinstance(v, (bytes, bytearray)):
            return list(v)
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    return plain(given)


async def _start(
    descriptor: NodeDescriptor,
    setup: Callable[[Any, NodeRunner], Any],
    mock_classes: Dict[str, type],
    emitted: Optional[Dict[str, TopicSpec]],
    parameters: Any,
    instance_id: Optional[str],
    use_sim_time: bool,
    node_dir: Optional[str],
    options: Dict[str, Any],
) -> Harness:
    options = dict(options)
    chosen: List[Tuple[SlotSpec, List[str], bool]] = []
    for slot in descriptor.slots:
        ids, vacant = _instances(slot, options)
        chosen.append((slot, ids, vacant))
    wanted = [(slot, ids) for slot, ids, _ in chosen]
    # Pairing slots: a participant's peer (None: left vacant), an observer's sources.
    pairing_wanted: List[Tuple[PairingSlotSpec, List[str]]] = []
    unpaired: Set[str] = set()
    for p in descriptor.pairings:
        if p.observer:
            pairing_wanted.append((p, _observed_ids(p, options)))
            continue
        vacant = bool(options.pop(f"{p.link_id}_vacant", False))
        if vacant and not p.optional:
            raise TypeError(f"`{p.link_id}_vacant`: pairing slot `{p.link_id}` is not optional")
        # Vacant, the mock peer still runs, but neither side claims the
        # other: the node's slot stays unpaired.
        pairing_wanted.append((p, [f"mock-{p.link_id}"]))
        if vacant:
            unpaired.add(p.link_id)
    if options:
        allowed = sorted(
            [f"{s.link_id}_{k}" for s in descriptor.slots for k in ("instances", "instance_ids", "vacant")]
            + [
                f"{p.link_id}_{k}"
                for p in descriptor.pairings
                for k in (("instances", "instance_ids", "vacant") if p.observer else ("vacant",))
            ]
        )
        raise TypeError(f"harness.start: unknown option(s) {sorted(options)}; slot options are {allowed}")
    h = Harness()
    h._unpaired = unpaired
    h.instance_id = instance_id or f"test-{os.getpid()}-{next(_counter)}"
    try:
        h._router, h.router_endpoint = await _open_router()
        # The fixture session: taps on the node's topics, caller of its
        # services and actions, server of the clock.
        fixture = NodeDescriptor(
            name="peppy_harness",
            tag="v1",
            slots=(SlotSpec(_FIXTURE_LINK, "interface", descriptor.name, descriptor.tag),),
            consumed_topics=tuple(
                ConsumedTopicSpec(_FIXTURE_LINK, _own(t.owner, descriptor), t.name, t.qos, t.format)
                for t in descriptor.emitted_topics
            ),
        )
        pin = SlotPlan(
            _FIXTURE_LINK,
            "interface",
            descriptor.name,
            descriptor.tag,
            SlotBinding.pinned(h.instance_id),
            RouteFilter("pin", frozenset((h.instance_id,))),
        )
        h._fixture = await _open_runner(fixture, FIXTURE_CORE, FIXTURE_INSTANCE_ID, h.router_endpoint, [pin])
        h.session = h._fixture.session
        by_spec = dict(zip(descriptor.emitted_topics, fixture.consumed_topics))
        names = emitted if emitted is not None else {_attr(t.name): t for t in descriptor.emitted_topics}
        for name, spec in names.items():
            setattr(h.emitted, name, Tap(h, by_spec[spec]))
        h._clock_server = ClockServer(h.session, NAMESPACE)
        h.clock = TestClock(h, h._clock_server, use_sim_time)
        # The harness is the node's core node: a datastore of the test's
        # own, `info`, and a stack of the node under test.
        h._core_server = CoreServer(h.session, NAMESPACE, NODE_CORE, h._core_info, h._core_graph)
        for slot, ids in wanted:
            cls = mock_classes.get(slot.link_id, SlotMock)
            made = []
            for mock_id in ids:
                runner = await _open_runner(
                    mock_descriptor(descriptor, slot), MOCK_CORE, mock_id, h.router_endpoint, []
                )
                mock = cls(runner, slot.link_id, h._failure)
                h._mock_list.append(mock)
                made.append(mock)
            many = slot.from_any or slot.cardinality in ("one_or_more", "zero_or_more")
            setattr(h.mocks.deps, _attr(slot.link_id), made if many else (made[0] if made else None))
        pair_links: List[Tuple[str, Optional[str]]] = []
        for p, ids in pairing_wanted:
            base = ObservedMock if p.observer else PairingMock
            cls = mock_classes.get(p.link_id, base)
            made = []
            for mock_id in ids:
                d = pairing_mock_descriptor(descriptor, p)
                # A pairing mock claims the node's slot from the start
                # (unless the slot starts unpaired); a source's mock pairs
                # with nobody.
                claims = not p.observer and p.link_id not in unpaired
                peers = (PairEnd(h.instance_id, p.link_id),) if claims else ()
                runner = await _open_runner(
                    d, MOCK_CORE, mock_id, h.router_endpoint, [], [PairPlan(d.pairings[0].link_id, peers)]
                )
                mock = cls(runner, p.link_id, h._failure)
                h._mock_list.append(mock)
                made.append(mock)
                if p.observer or p.link_id not in unpaired:
                    pair_links.append((p.link_id, f"{mock_id}/{d.pairings[0].link_id}"))
            if p.observer:
                many = p.cardinality in ("one_or_more", "zero_or_more")
                setattr(h.mocks.observed, _attr(p.link_id), made if many else (made[0] if made else None))
            else:
                if p.link_id in unpaired:
                    pair_links.append((p.link_id, None))
                setattr(h.mocks.pairings, _attr(p.link_id), made[0] if made else None)
        given = _parameters_given(parameters)
        params_file = None
        if given is not None:
            with tempfile.NamedTemporaryFile("w", suffix=".json", prefix="peppy-params-", delete=False) as f:
                json.dump(given, f)
                params_file = f.name
        try:
            flags = _plan_flags(descriptor, h.instance_id, chosen, params_file, pair_links)
            plan_text = await asyncio.get_running_loop().run_in_executor(None, plan_text_from_flags, flags, descriptor)
        finally:
            if params_file is not None:
                os.remove(params_file)
        # The engine's plan, placed on the harness: its identity, its router.
        plan = json.loads(plan_text)
        plan["core_node"] = NODE_CORE
        # The mocks run on the harness's mock core node.
        plan["producer_cores"] = {m.instance_id: MOCK_CORE for m in h._mock_list if isinstance(m, SlotMock)}
        plan["namespace"] = NAMESPACE
        plan["zenoh"] = {"mode": "client", "connect": [h.router_endpoint], "multicast_scouting": False}
        plan["use_sim_time"] = bool(use_sim_time)
        with tempfile.NamedTemporaryFile("w", suffix=".json", prefix="peppy-harness-", delete=False) as f:
            json.dump(plan, f)
            path = f.name
        try:
            h.node_runner = await NodeBuilder(descriptor).with_runtime_config(path).with_args([]).start()
        finally:
            os.remove(path)
        for m in h._mock_list:
            if isinstance(m, SlotMock):
                m._subject = h.node_runner
        await _barrier(h, wanted)
        await _pairs_barrier(h)
        cwd = os.getcwd()
        if node_dir is not None:
            os.chdir(node_dir)
        try:
            h._setup_task = asyncio.get_running_loop().create_task(
                _call_setup(setup, h.node_runner.parameters, h.node_runner)
            )
            h._setup_task.add_done_callback(h._setup_done)
            # Let setup begin under node_dir before returning.
            await asyncio.sleep(0)
        finally:
            os.chdir(cwd)
    except BaseException:
        try:
            await h.shutdown()
        except BaseException as e:
            log.debug("harness teardown after a failed start: %r", e)
        raise
    return h


async def _barrier(h: Harness, wanted: Sequence[Tuple[SlotSpec, List[str]]]) -> None:
    """Before `setup`: the node's publishers see the taps, and the mocks'
    services and actions and the clock are reachable from its session."""
    runner = h.node_runner
    checks = []
    for spec, publisher in runner._publishers.items():
        checks.append((_matched(publisher, READY_TIMEOUT), f"the harness's tap on topic `{spec.name}`"))
    session = runner.session
    for slot, ids in wanted:
        d = mock_descriptor(runner.descriptor, slot)
        for mock_id in ids:
            for s in d.exposed_services:
                owner = s.owner.segments(d.name, d.tag) or ""
                key = entry_key(NAMESPACE, SERVICE, owner, s.name, MOCK_CORE, mock_id)
                checks.append((_reach(session, key), f"service `{s.name}` of mock `{mock_id}`"))
            for a in d.exposed_actions:
                owner = a.owner.segments(d.name, d.tag) or ""
                key = action_part_key(entry_key(NAMESPACE, ACTION, owner, a.name, MOCK_CORE, mock_id), "goal")
                checks.append((_reach(session, key), f"action `{a.name}` of mock `{mock_id}`"))
    checks.append((_reach(session, clock_sync_key(NAMESPACE)), "the harness's clock"))
    results = await asyncio.gather(*(c for c, _ in checks))
    missing = [what for (_, what), ok in zip(checks, results) if not ok]
    if missing:
        raise TimeoutError(f"harness: not ready within {READY_TIMEOUT:g} s: {', '.join(missing)}")


async def _pairs_barrier(h: Harness) -> None:
    """Before `setup`: every participant slot of the node is paired with
    its mock (both sides see the pair), and every observed source's mock
    sees the node's subscriptions."""
    waits = []
    for mock in h._mock_list:
        if isinstance(mock, PairingMock):
            if mock.link_id in h._unpaired:
                continue
            for runner, link in ((h.node_runner, mock.link_id), (mock._runner, MOCK_PEER)):
                waits.append((runner._pairings[link].wait_paired(), f"the pair of slot `{mock.link_id}`"))
        elif isinstance(mock, ObservedMock):
            for publisher in mock._slot()._publishers.values():
                waits.append(
                    (_matched(publisher, READY_TIMEOUT), f"the observer `{mock.link_id}` of `{mock.instance_id}`")
                )
    for awaitable, what in waits:
        result = await _bounded(h._failure, awaitable, READY_TIMEOUT, what)
        if result is False:
            raise TimeoutError(f"harness: not ready within {READY_TIMEOUT:g} s: {what}")


async def _reach(session: Any, key: str) -> bool:
    querier = session.declare_querier(key)
    try:
        return await _matched(querier, READY_TIMEOUT)
    finally:
        try:
            querier.undeclare()
        except Exception:
            pass


__all__ = [
    "ActionMock",
    "ActiveGoal",
    "CancelAnswer",
    "GoalHandle",
    "GoalResult",
    "Harness",
    "ObservedMock",
    "PairingMock",
    "PeerTap",
    "PeerTopicMock",
    "PendingGoalMock",
    "Responder",
    "ServiceMock",
    "SlotMock",
    "Starting",
    "Tap",
    "TestClock",
    "TopicMock",
    "mock_descriptor",
    "pairing_mock_descriptor",
    "poll_service",
    "send_goal",
    "start",
]
