"""The one request/reply client (docs/WIRE.md §2-§3). A request goes to
one server; the client follows its status replies until an answer, the
deadline or the node's stop, and tells a server that never answered
(unreachable) from one that acked and went quiet (timeout). Service
calls, goals, and a goal's result and cancel queries all come through
here, so they fail the same way with the same words."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple, Optional, Tuple

from . import attachment
from .attachment import ReplyStatus
from .bridge import END, TIMED_OUT, ReplyStream
from .errors import ServiceError, ServiceTimeout, ServiceUnreachable
from .keys import parse_entry_key
from .topics import refused


class Answer(NamedTuple):
    """A server's `ok` reply: its identity and the undecoded body."""

    core: str
    instance: str
    body: bytes


@dataclass
class Request:
    """One request to one server.

    `response` is the fingerprint and canonical text an `ok` must carry,
    or None for status replies without a format (a goal's decision, a
    cancel's answer).
    """

    key: str
    header: bytes
    payload: bytes
    deadline: float
    describe: str
    instance: Optional[str]
    request_format: str
    response: Optional[Tuple[int, str]]

    async def send(self, runner: Any) -> Answer:
        """Sends the request and waits for the answer."""
        import zenoh

        if runner.refuses_calls():
            raise await refused()
        loop = runner.loop
        budget = max(self.deadline - loop.time(), 0.001)
        stream = ReplyStream(loop, runner._track_mailbox)
        runner.session.get(
            self.key,
            stream.handler(),
            target=zenoh.QueryTarget.ALL,
            consolidation=zenoh.ConsolidationMode.NONE,
            timeout=budget,
            payload=self.payload,
            attachment=self.header,
        )
        acked = False
        try:
            while True:
                reply = await stream.next(self.deadline)
                if reply is END or reply is TIMED_OUT:
                    break
                sender = parse_entry_key(reply.key)
                parsed = attachment.parse_reply(reply.attachment)
                if sender is None or parsed is None:
                    continue
                status, fingerprint = parsed
                if status in (ReplyStatus.ACK, ReplyStatus.PRESENT):
                    acked = True
                elif status == ReplyStatus.OK:
                    if self.response is not None and fingerprint != self.response[0]:
                        raise ServiceError(
                            self.describe,
                            sender.instance,
                            f"the server's response format differs from this node's ({self.response[1]}); "
                            "rebuild one side",
                        )
                    return Answer(sender.core, sender.instance, reply.payload)
                elif status == ReplyStatus.HANDLER_ERROR:
                    raise ServiceError(self.describe, sender.instance, reply.payload.decode("utf-8", "replace"))
                else:
                    raise ServiceError(
                        self.describe,
                        sender.instance,
                        f"the server expects request format {reply.payload.decode('utf-8', 'replace')}, "
                        f"this node sends {self.request_format}; rebuild one side",
                    )
        finally:
            stream.close()
        if acked:
            raise ServiceTimeout(self.describe, self.instance)
        raise ServiceUnreachable(self.describe, self.instance)
