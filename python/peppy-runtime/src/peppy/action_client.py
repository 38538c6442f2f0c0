"""The consumed side of an action (docs/WIRE.md §4): sending a goal through
a slot, and the goal a caller holds (feedback, result, cancel)."""

from __future__ import annotations

import logging
from typing import Any, Optional

from . import attachment
from .action_states import (
    CancelState,
    ResultOutcome,
    ResultStatus,
    decode_decision_with_response,
    encode_string,
    new_goal_id,
)
from .attachment import QueryHeader, QueryKind
from .bridge import END, Mailbox, undeclare
from .errors import ActionFeedbackProducerGone, FeedbackEnded, ServiceError
from .keys import ACTION, action_part_key, entry_key, feedback_key
from .request import Request
from .spec import ConsumedActionSpec, QoSProfile
from .target import Entry, choose, header
from .topics import refused

log = logging.getLogger("peppy")


class _FeedbackIntake:
    """The feedback subscription's callback (Zenoh thread)."""

    def __init__(self, mailbox: Mailbox, fingerprint: int, on_end: Any) -> None:
        self.mailbox = mailbox
        self.fingerprint = fingerprint
        self.on_end = on_end

    def __call__(self, sample: Any) -> None:
        att = sample.attachment
        data = b"" if att is None else att.to_bytes()
        if data == attachment.END_OF_FEEDBACK:
            self.mailbox.put(END)
            self.on_end()
        elif attachment.parse_topic(data) == self.fingerprint:
            self.mailbox.put(sample.payload.to_bytes())
        else:
            log.debug("dropping feedback with another format")


class GoalClient:
    """A goal sent to an action server, seen from the caller."""

    def __init__(
        self,
        runner: Any,
        spec: ConsumedActionSpec,
        goal_id: str,
        base_key: str,
        feedback: Mailbox,
        subscriber: Any,
        accepted: bool,
        error_message: Optional[str],
        instance_id: str,
        core_node: str,
    ) -> None:
        self.spec = spec
        self.goal_id = goal_id
        self.accepted = accepted
        self.error_message = error_message
        #: The declared goal response the server sent, as encoded (b"" for none).
        self.response = b""
        #: That response decoded (None when none was sent).
        self.data: Any = None
        self.instance_id = instance_id
        self.core_node = core_node
        self._runner = runner
        self._base_key = base_key
        self._feedback = feedback
        self._subscriber = subscriber
        self._server_watch: Optional[_ServerWatch] = None
        self._ended = False

    @property
    def gone(self) -> bool:
        """Whether the server went away without finishing the goal."""
        return self._server_watch is not None and self._server_watch.gone

    def __repr__(self) -> str:
        return f"GoalClient(goal_id={self.goal_id!r}, accepted={self.accepted}, server={self.instance_id!r})"

    def close(self) -> None:
        """Stops following the goal's feedback (its result can still be asked)."""
        subscriber, self._subscriber = self._subscriber, None
        undeclare(subscriber)
        watch = getattr(self, "_server_watch", None)
        if watch is not None:
            watch.close()

    def __del__(self) -> None:
        self.close()

    async def next_feedback(self) -> Any:
        """The next feedback message; `FeedbackEnded` (a `RuntimeError`)
        once the goal is terminal and every feedback message was read,
        `ActionFeedbackProducerGone` (a `ConnectionError`) when the server
        went away first. Raises `ShuttingDown` once this node stops."""
        if self._runner.refuses_calls():
            raise await refused()
        while not self._ended:
            item = await self._feedback.get()
            if item is END:
                self._ended = True
                break
            if item is _GONE:
                self._ended = True
                raise ActionFeedbackProducerGone(self.spec.name, self.instance_id)
            try:
                return self.spec.feedback.decode(item)
            except ValueError as e:
                log.warning("action `%s`: dropping feedback that does not decode: %s", self.spec.name, e)
        raise FeedbackEnded(self.spec.name)

    async def _ask(self, part: str, timeout: float) -> bytes:
        result = self.spec.result
        answer = await Request(
            key=action_part_key(self._base_key, part),
            # As the Rust client: result and cancel queries name no caller.
            header=QueryHeader(QueryKind.REQUEST, 0, "", "").encode(),
            payload=encode_string(self.goal_id),
            deadline=self._runner.loop.time() + timeout,
            describe=f"{self.spec.name} (action {part})",
            instance=self.instance_id,
            request_format="a goal id",
            response=(result.fingerprint, result.canonical) if part == "result" else None,
        ).send(self._runner)
        return answer.body

    async def get_result(self, timeout: float) -> ResultOutcome:
        """Waits (up to `timeout` seconds) until the goal is terminal:
        `(status, result)`, the result None unless COMPLETED or CANCELLED.
        A server that went away took its goals' results with it: ABANDONED."""
        if self.gone:
            return ResultOutcome(ResultStatus.ABANDONED, None)
        body = await self._ask("result", timeout)
        if not body or body[0] > 3:
            raise ServiceError(self.spec.name, self.instance_id, "malformed result")
        status = ResultStatus(body[0])
        if status in (ResultStatus.ABANDONED, ResultStatus.EXPIRED):
            return ResultOutcome(status, None)
        try:
            return ResultOutcome(status, self.spec.result.decode(body[1:]))
        except ValueError as e:
            raise ServiceError(self.spec.name, self.instance_id, f"cannot decode the result: {e}") from None

    async def cancel(self, timeout: float) -> CancelState:
        """Asks the server to cancel the goal."""
        body = await self._ask("cancel", timeout)
        if body[:1] == b"\x00":
            return CancelState.SIGNALLED
        if body[:1] == b"\x01":
            return CancelState.ALREADY_TERMINAL
        return CancelState.UNKNOWN


#: What the feedback mailbox gets when the goal's server goes away.
_GONE = object()


class _ServerWatch:
    """Follows a goal's server's liveliness token: its withdrawal (the
    server's process died, its host was lost) ends the goal's feedback
    stream after what already arrived, and marks the goal gone."""

    def __init__(self, runner: Any, feedback: Mailbox, instance: str) -> None:
        from .keys import instance_liveliness_selector

        self.gone = False
        self._feedback = feedback
        self._subscriber: Any = None
        try:
            self._subscriber = runner.session.liveliness().declare_subscriber(
                instance_liveliness_selector(runner.namespace, instance), self._on_sample, history=True
            )
        except Exception as e:
            log.debug("cannot follow the server of a goal: %s", e)

    def _on_sample(self, sample: Any) -> None:
        import zenoh

        if sample.kind == zenoh.SampleKind.DELETE and not self.gone:
            self.gone = True
            self._feedback.put(_GONE)

    def close(self) -> None:
        subscriber, self._subscriber = self._subscriber, None
        undeclare(subscriber)


async def fire_goal(
    runner: Any,
    spec: ConsumedActionSpec,
    timeout: float,
    goal: Any,
    feedback_qos: Optional[QoSProfile] = None,
    target: Optional[str] = None,
) -> GoalClient:
    """Sends a goal through the action's slot and waits for the server's
    decision (`.accepted`, `.error_message`). The feedback stream is
    subscribed before the goal is sent, so none is missed; `feedback_qos`
    sets its queue (drop profiles keep the newest, others everything).
    `target` (an instance id the caller checked is bound to the slot)
    names the server; without it the slot chooses."""
    body = spec.goal.encode(goal)
    if runner.refuses_calls():
        raise await refused()
    loop = runner.loop
    deadline = loop.time() + timeout
    entry = Entry(
        spec.link_id, spec.owner, ACTION, spec.name, "goal", spec.goal.fingerprint, f"{spec.name} (action goal)"
    )
    server = target if target is not None else await choose(runner, entry, deadline)
    goal_id = new_goal_id()
    keep = feedback_qos.keep_newest if isinstance(feedback_qos, QoSProfile) else None
    feedback = Mailbox(loop, maxlen=keep)
    runner._track_mailbox(feedback)
    holder: list = []

    def ended() -> None:
        # Undeclared on the loop: not from inside its own callback.
        def close() -> None:
            if holder:
                try:
                    holder[0].undeclare()
                except Exception:
                    pass

        try:
            loop.call_soon_threadsafe(close)
        except RuntimeError:
            pass

    subscriber = runner.session.declare_subscriber(
        feedback_key(entry.base(runner, server), goal_id),
        _FeedbackIntake(feedback, spec.feedback.fingerprint, ended),
    )
    holder.append(subscriber)
    # Followed from before the goal is sent: a server lost at any time
    # after it accepts ends the feedback stream.
    watch = _ServerWatch(runner, feedback, server)
    try:
        answer = await Request(
            key=entry.selector(runner, server),
            header=header(runner, QueryKind.REQUEST, spec.goal.fingerprint),
            payload=encode_string(goal_id) + body,
            deadline=deadline,
            describe=entry.describe,
            instance=server,
            request_format=spec.goal.canonical,
            response=None,  # the decision is a status reply without a format of its own
        ).send(runner)
        accepted, error_message, response = decode_decision_with_response(answer.body)
        data = spec.goal_response.decode(response) if response and spec.goal_response is not None else None
    except ValueError as e:
        subscriber.undeclare()
        watch.close()
        raise ServiceError(entry.describe, server, f"cannot decode the goal response: {e}") from None
    except BaseException:
        subscriber.undeclare()
        watch.close()
        raise
    owner = spec.owner.segments(runner.node_name, runner.node_tag)
    base_key = entry_key(runner.namespace, ACTION, owner or "", spec.name, answer.core, answer.instance)
    client = GoalClient(
        runner,
        spec,
        goal_id,
        base_key,
        feedback,
        subscriber,
        accepted,
        error_message,
        answer.instance,
        answer.core,
    )
    client.response = response
    client.data = data
    client._server_watch = watch
    if not accepted:
        client._ended = True
        client.close()
    return client
