"""Services (docs/WIRE.md §3): a queryable per exposed service that lives
as long as the node and queues requests, and calls that go straight to a
bound producer or discover one."""

from __future__ import annotations

import inspect
import logging
from typing import Any, Awaitable, Callable, Optional, Tuple, Union

from .attachment import QueryKind, ReplyStatus
from .bridge import Mailbox
from .errors import ServiceError
from .intake import Pending, admit, enqueue, finish, payload_of, reply
from .keys import SERVICE
from .request import Request
from .spec import ConsumedServiceSpec, ServiceSpec
from .target import Entry, choose, header
from .topics import refused

log = logging.getLogger("peppy")

Handler = Callable[[str, str, Any], Union[Any, Awaitable[Any]]]


class ServiceIntake:
    """The queryable callback of one exposed service: answer probes, check
    the request format, ack and queue requests. Runs on Zenoh's threads."""

    def __init__(self, spec: ServiceSpec, key: str, mailbox: Mailbox) -> None:
        self.spec = spec
        self.key = key
        self.mailbox = mailbox

    def __call__(self, query: Any) -> None:
        fingerprint = self.spec.response.fingerprint
        h = admit(query, self.key, self.spec.name, self.spec.request, fingerprint)
        if h is None:
            return
        enqueue(self.mailbox, Pending(query, h, payload_of(query)), self.key, fingerprint, self.spec.name, "requests")


async def handle_next(runner: Any, spec: ServiceSpec, handler: Handler) -> None:
    """Serves the next request of an exposed service.

    `handler(instance_id, core_node, request)` gets the caller's identity
    and the decoded request and returns the response (or an awaitable of
    it). An exception it raises is sent to the caller as a handler error
    with its text, and this returns normally, so a serving loop goes on; a
    request that does not decode is answered the same way. Raises
    `ShuttingDown` once the node stops.
    """
    mailbox, key = runner._service_inbox(spec)
    if runner.is_stopping():
        raise await refused()
    pending: Pending = await mailbox.get()
    try:
        status, body = await _answer(spec, handler, pending)
        reply(pending.query, key, status, spec.response.fingerprint, body, spec.name)
    finally:
        finish(pending.query)


async def _answer(spec: ServiceSpec, handler: Handler, pending: Pending) -> Tuple[ReplyStatus, bytes]:
    caller = pending.header.instance
    try:
        request = spec.request.decode(pending.payload)
    except ValueError as e:
        log.warning("service `%s`: refusing a request from `%s` that does not decode: %s", spec.name, caller, e)
        return ReplyStatus.HANDLER_ERROR, f"request does not decode: {e}".encode("utf-8")
    try:
        response = handler(pending.header.instance, pending.header.core, request)
        if inspect.isawaitable(response):
            response = await response
        return ReplyStatus.OK, spec.response.encode(response)
    except Exception as e:
        return ReplyStatus.HANDLER_ERROR, (str(e) or type(e).__name__).encode("utf-8")


def _entry(spec: ConsumedServiceSpec) -> Entry:
    return Entry(spec.link_id, spec.owner, SERVICE, spec.name, None, spec.request.fingerprint, spec.name)


async def call(
    runner: Any, spec: ConsumedServiceSpec, timeout: float, request: Any, target: Optional[str] = None
) -> Tuple[str, str, Any]:
    """Calls a consumed service through its slot: `(server instance id,
    server core node, response)`.

    Pinned slots (and from_any slots bound to one producer) go straight to
    their producer; others go to the first server the slot accepts.
    `target` (an instance id the caller checked is bound to the slot)
    names the server instead. Raises `ServiceError` (the handler's text),
    `ServiceTimeout` (acked, no answer in `timeout` seconds) or
    `ServiceUnreachable`.
    """
    payload = spec.request.encode(request)
    if runner.refuses_calls():
        raise await refused()
    deadline = runner.loop.time() + timeout
    entry = _entry(spec)
    server = target if target is not None else await choose(runner, entry, deadline)
    answer = await Request(
        key=entry.selector(runner, server),
        header=header(runner, QueryKind.REQUEST, spec.request.fingerprint),
        payload=payload,
        deadline=deadline,
        describe=entry.describe,
        instance=server,
        request_format=spec.request.canonical,
        response=(spec.response.fingerprint, spec.response.canonical),
    ).send(runner)
    try:
        data = spec.response.decode(answer.body)
    except ValueError as e:
        raise ServiceError(spec.name, answer.instance, f"cannot decode the response: {e}") from None
    return answer.instance, answer.core, data
