"""The exposed side of an action (docs/WIRE.md §4): the goal registry
(accept, feedback, parked results, cancel, abandon, retention), the goal
queryable's intake, and what the node's code holds while serving a goal."""

from __future__ import annotations

import asyncio
import inspect
import logging
import threading
import time
from collections import deque
from typing import Any, Callable, Deque, Dict, List, NamedTuple, Optional, Set, Tuple

from . import attachment
from .action_states import (
    CancelState,
    ResultStatus,
    encode_decision,
    goal_id_of,
    split_goal_id,
)
from .attachment import QueryHeader, ReplyStatus
from .bridge import Mailbox
from .intake import admit, enqueue, finish, payload_of, reply
from .keys import action_part_key, feedback_key
from .spec import ActionSpec
from .topics import refused

log = logging.getLogger("peppy")

DEFAULT_RESULT_RETENTION = 30.0
"""How long a terminal goal's result stays available (seconds); then `EXPIRED`."""

EXPIRED_MEMORY = 4096
"""How many expired goal ids are remembered (to answer `EXPIRED`, not unknown)."""


class _Active:
    """A goal being worked on: its cancel signal and the parked result queries."""

    def __init__(self, signal: Callable[[], None]) -> None:
        self.signal = signal
        self.waiters: List[Any] = []


class _Done(NamedTuple):
    how: ResultStatus
    body: bytes
    at: float


class Registry:
    """The goals of one exposed action. Its queryable callbacks run on
    Zenoh's threads and its workers on the loop, so state sits under a lock."""

    def __init__(self, spec: ActionSpec, base_key: str, session: Any, retention: float) -> None:
        self.spec = spec
        self.base_key = base_key
        self.session = session
        self.retention = retention
        self._lock = threading.Lock()
        self._goals: Dict[str, Any] = {}
        self._expired: Deque[str] = deque()
        self._expired_set: Set[str] = set()

    def key(self, part: str) -> str:
        """The key of one of the action's queryables."""
        return action_part_key(self.base_key, part)

    def feedback_key(self, goal_id: str) -> str:
        """The key of a goal's feedback stream."""
        return feedback_key(self.base_key, goal_id)

    def register(self, goal_id: str, signal: Callable[[], None]) -> None:
        """Registers an accepted goal, before its caller hears back."""
        with self._lock:
            self._goals[goal_id] = _Active(signal)

    def finish(self, goal_id: str, how: ResultStatus, body: bytes) -> bool:
        """Makes a goal terminal (the first call wins), answers its parked
        result queries and ends its feedback stream."""
        with self._lock:
            state = self._goals.get(goal_id)
            if not isinstance(state, _Active):
                return False
            self._goals[goal_id] = _Done(how, body, time.monotonic())
        key = self.key("result")
        for q in state.waiters:
            self._reply_result(q, key, how, body)
        try:
            self.session.put(self.feedback_key(goal_id), b"", attachment=attachment.END_OF_FEEDBACK)
        except Exception as e:
            log.debug("action `%s`: end-of-feedback publish failed: %s", self.spec.name, e)
        return True

    def _reply_result(self, query: Any, key: str, how: ResultStatus, body: bytes) -> None:
        reply(query, key, ReplyStatus.OK, self.spec.result.fingerprint, bytes([int(how)]) + body, self.spec.name)
        finish(query)

    def disarm(self) -> None:
        """Forgets the goals still running without ending them: their callers
        see no clean close, as when the server's process dies (a test's
        producer loss)."""
        with self._lock:
            for goal_id in [g for g, s in self._goals.items() if isinstance(s, _Active)]:
                del self._goals[goal_id]

    def active_goals(self) -> List[str]:
        """The ids of goals not yet terminal."""
        with self._lock:
            return [g for g, s in self._goals.items() if isinstance(s, _Active)]

    def sweep(self) -> None:
        """Drops results older than the retention period, remembering their ids."""
        now = time.monotonic()
        with self._lock:
            old = [g for g, s in self._goals.items() if isinstance(s, _Done) and now - s.at > self.retention]
            for g in old:
                del self._goals[g]
                self._expired.append(g)
                self._expired_set.add(g)
                if len(self._expired) > EXPIRED_MEMORY:
                    self._expired_set.discard(self._expired.popleft())

    def on_cancel(self, query: Any) -> None:
        """The cancel queryable (Zenoh thread)."""
        goal_id = goal_id_of(payload_of(query))
        if goal_id is None:
            finish(query)
            return
        with self._lock:
            state = self._goals.get(goal_id)
            if isinstance(state, _Active):
                answer = CancelState.SIGNALLED
            elif state is not None or goal_id in self._expired_set:
                answer = CancelState.ALREADY_TERMINAL
            else:
                answer = CancelState.UNKNOWN
        if isinstance(state, _Active):
            state.signal()
        reply(query, self.key("cancel"), ReplyStatus.OK, 0, bytes([int(answer)]), self.spec.name)
        finish(query)

    def on_result(self, query: Any) -> None:
        """The result queryable (Zenoh thread): answer at once when terminal, else park."""
        goal_id = goal_id_of(payload_of(query))
        if goal_id is None:
            finish(query)
            return
        key = self.key("result")
        with self._lock:
            state = self._goals.get(goal_id)
            if isinstance(state, _Active):
                # Acked and parked under the lock, so `finish` cannot miss it.
                reply(query, key, ReplyStatus.ACK, 0, b"", self.spec.name)
                state.waiters.append(query)
                return
            expired = goal_id in self._expired_set
        if isinstance(state, _Done):
            self._reply_result(query, key, state.how, state.body)
        elif expired:
            self._reply_result(query, key, ResultStatus.EXPIRED, b"")
        else:
            reply(
                query,
                key,
                ReplyStatus.HANDLER_ERROR,
                0,
                f"no goal `{goal_id}` on this server".encode("utf-8"),
                self.spec.name,
            )
            finish(query)


class PendingGoal(NamedTuple):
    """A goal waiting for the server's decision."""

    query: Any
    header: QueryHeader
    goal_id: str
    body: bytes


class GoalIntake:
    """The goal queryable: check the header and format, ack, queue for the decider."""

    def __init__(self, spec: ActionSpec, key: str, mailbox: Mailbox) -> None:
        self.spec = spec
        self.key = key
        self.mailbox = mailbox

    def __call__(self, query: Any) -> None:
        # A goal's status replies carry no format of their own.
        h = admit(query, self.key, self.spec.name, self.spec.goal, 0)
        if h is None:
            return
        split = split_goal_id(payload_of(query))
        if split is None:
            reply(query, self.key, ReplyStatus.HANDLER_ERROR, 0, b"malformed goal envelope", self.spec.name)
            finish(query)
            return
        goal_id, body = split
        enqueue(self.mailbox, PendingGoal(query, h, goal_id, body), self.key, 0, self.spec.name, "goals")  # type: ignore[arg-type]


def _arity(decider: Callable[..., Any]) -> int:
    """How many arguments the decider takes: 3 (caller's instance id, core node, goal) or 1 (the goal)."""
    try:
        params = inspect.signature(decider).parameters.values()
    except (TypeError, ValueError):
        return 1
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if any(p.kind == p.VAR_POSITIONAL for p in params) or len(positional) >= 3:
        return 3
    return 1


def _decision(answer: Any) -> Tuple[bool, Optional[str], Any]:
    """`(accepted, reason, response)` of a decider's answer: a bool, a pair
    `(accepted, reason)`, a triple with the goal response, or an object
    with `accepted` (and `error_message` or `reason`, and `response`)."""
    if isinstance(answer, bool):
        return answer, None, None
    if isinstance(answer, tuple) and len(answer) in (2, 3):
        return bool(answer[0]), answer[1], answer[2] if len(answer) == 3 else None
    if hasattr(answer, "accepted"):
        reason = getattr(answer, "error_message", None)
        if reason is None:
            reason = getattr(answer, "reason", None)
        return bool(answer.accepted), reason, getattr(answer, "response", None)
    raise TypeError(f"a goal decider returns (accepted, error_message), got {answer!r}")


def encode_goal_response(spec: Any, response: Any) -> bytes:
    """A decision's goal response, encoded with the action's declared
    format; empty when there is none to send. A response for an action
    that declares none is refused, as is one that does not encode."""
    if response is None:
        return b""
    if spec.goal_response is None:
        raise TypeError(f"action `{spec.name}` declares no goal response; decide without one")
    return spec.goal_response.encode(response)


class GoalServer:
    """The goal queue of one exposed action on this node."""

    def __init__(self, runner: Any, spec: ActionSpec) -> None:
        self.spec = spec
        self._runner = runner
        self._mailbox, self._registry = runner._action_server(spec)

    async def next_goal(self, decider: Callable[..., Any]) -> Optional["GoalContext"]:
        """Waits for the next goal and lets `decider` accept or reject it.

        `decider(goal)` (or `decider(instance_id, core_node, goal)`) returns
        `(accepted, error_message)`, or an awaitable of it. Returns the
        accepted goal's context, None when it was rejected. A goal that does
        not decode is rejected and skipped; an exception in the decider
        rejects the goal with its text. Raises `ShuttingDown` once the node stops.
        """
        if self._runner.is_stopping():
            raise await refused()
        registry = self._registry
        goal_key = registry.key("goal")
        while True:
            pending: PendingGoal = await self._mailbox.get()
            try:
                try:
                    goal = self.spec.goal.decode(pending.body)
                except ValueError as e:
                    log.warning(
                        "action `%s`: rejecting a goal from `%s` that does not decode: %s",
                        self.spec.name,
                        pending.header.instance,
                        e,
                    )
                    reply(
                        pending.query,
                        goal_key,
                        ReplyStatus.OK,
                        0,
                        encode_decision(False, f"goal does not decode: {e}"),
                        self.spec.name,
                    )
                    continue
                try:
                    if _arity(decider) == 3:
                        answer = decider(pending.header.instance, pending.header.core, goal)
                    else:
                        answer = decider(goal)
                    if inspect.isawaitable(answer):
                        answer = await answer
                    accepted, error, response = _decision(answer)
                    body = encode_goal_response(self.spec, response)
                except Exception as e:
                    log.warning("action `%s`: the goal decider failed: %s", self.spec.name, e)
                    accepted, error, body = False, str(e) or type(e).__name__, b""
                if not accepted:
                    reply(pending.query, goal_key, ReplyStatus.OK, 0, encode_decision(False, error, body), self.spec.name)
                    return None
                context = GoalContext(self._runner, registry, pending, goal)
                reply(pending.query, goal_key, ReplyStatus.OK, 0, encode_decision(True, None, body), self.spec.name)
                return context
            finally:
                finish(pending.query)


class GoalContext:
    """An accepted goal on the server. Finish it with `complete` or
    `complete_cancelled`; a context dropped unfinished (or left so when the
    node stops) reports `ABANDONED` to its caller."""

    def __init__(self, runner: Any, registry: Registry, pending: PendingGoal, goal: Any) -> None:
        self.goal = goal
        self.goal_id: str = pending.goal_id
        self.instance_id: str = pending.header.instance
        self.core_node: str = pending.header.core
        self.cancel_signal = event = asyncio.Event()
        self._runner = runner
        self._registry = registry
        self._cancelled = cancelled = threading.Event()
        self._finished = False
        loop = runner.loop

        # The registry keeps this signal while the goal runs: it must not
        # hold the context, or a dropped context would never be collected
        # (and never reported abandoned).
        def signal() -> None:
            cancelled.set()
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:
                pass

        registry.register(self.goal_id, signal)

    def request(self) -> Any:
        """The goal's data."""
        return self.goal

    def is_cancelled(self) -> bool:
        """Whether the caller asked to cancel."""
        return self._cancelled.is_set()

    async def publish_feedback(self, message: Any) -> None:
        """Publishes one message on this goal's feedback stream."""
        spec = self._registry.spec
        payload = spec.feedback.encode(message)
        if self._runner.session_closed:
            raise await refused()
        self._registry.session.put(
            self._registry.feedback_key(self.goal_id),
            payload,
            attachment=attachment.topic(spec.feedback.fingerprint),
        )

    async def complete(self, result: Any) -> None:
        """Finishes the goal with its result."""
        self._finish(ResultStatus.COMPLETED, self._registry.spec.result.encode(result))

    async def complete_cancelled(self, result: Any) -> None:
        """Finishes the goal as cancelled, with a (partial) result."""
        self._finish(ResultStatus.CANCELLED, self._registry.spec.result.encode(result))

    def _finish(self, how: ResultStatus, body: bytes) -> None:
        self._finished = True
        if not self._registry.finish(self.goal_id, how, body):
            log.debug("action `%s`: goal %s was already terminal", self._registry.spec.name, self.goal_id)

    def __del__(self) -> None:
        try:
            if not self._finished and self._registry.finish(self.goal_id, ResultStatus.ABANDONED, b""):
                log.warning(
                    "action `%s`: goal %s dropped without a result: reported as abandoned",
                    self._registry.spec.name,
                    self.goal_id,
                )
        except Exception:
            pass
