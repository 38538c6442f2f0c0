"""What a core node (a launch, `peppy-launch run`'s hub, a test harness)
answers its nodes (docs/WIRE.md, "Core node functions"): the datastore,
`info` and the stack listing. Each is a query on
`peppy/<ns>/stack/<core>/<function>` to the core node that started this
node; the Rust runtime's `core_functions` answers and asks the same way."""

from __future__ import annotations

import asyncio
import json
import logging
import struct
import threading
from typing import Any, Callable, Dict, List, Optional, Tuple

from .bridge import END, TIMED_OUT, ReplyError, ReplyStream, undeclare
from .errors import ServiceError, ServiceUnreachable, ShuttingDown
from .keys import core_function_key

log = logging.getLogger("peppy")

DEFAULT_RESPONSE_TIMEOUT = 10.0
"""How long a call waits for its core node by default (seconds)."""

#: How long a call waits before asking again when nobody answered (a node
#: just started may not know its core node's queryables yet).
_RETRY = 0.05


async def ask(runner: Any, function: str, payload: bytes, timeout: Optional[float]) -> bytes:
    """Asks this node's core node `function` with `payload`: the answer's
    payload. `ServiceUnreachable` (a `ConnectionError`) when nobody answers
    within `timeout` seconds (None: 10), `ServiceError` when the core node
    refuses."""
    if runner.refuses_calls():
        raise ShuttingDown()
    timeout = DEFAULT_RESPONSE_TIMEOUT if timeout is None else float(timeout)
    loop = runner.loop
    deadline = loop.time() + timeout
    while True:
        answer = await _ask_once(runner, function, payload, max(deadline - loop.time(), 0.001))
        if answer is not None:
            return answer
        left = deadline - loop.time()
        if left <= 0:
            raise ServiceUnreachable(f"{function} of core node `{runner.core_node}`")
        await asyncio.sleep(min(left, _RETRY))
        if runner.refuses_calls():
            raise ShuttingDown()


async def _ask_once(runner: Any, function: str, payload: bytes, timeout: float) -> Optional[bytes]:
    import zenoh

    loop = runner.loop
    key = core_function_key(runner.namespace, runner.core_node, function)
    stream = ReplyStream(loop, runner._track_mailbox, errors=True)
    runner.session.get(
        key,
        stream.handler(),
        target=zenoh.QueryTarget.BEST_MATCHING,
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=max(timeout, 0.001),
        payload=payload,
    )
    try:
        item = await stream.next(loop.time() + timeout + 0.25)
        if item is END or item is TIMED_OUT:
            return None
        if isinstance(item, ReplyError):
            raise ServiceError(function, runner.core_node, item.reason)
        return item.payload
    finally:
        stream.close()


class Store:
    """One core node's datastore (docs/WIRE.md §12): `answer(request)`
    gives the reply, or raises `ValueError` with the refusal."""

    def __init__(self) -> None:
        self._values: Dict[str, Tuple[bytes, str, str]] = {}
        self._lock = threading.Lock()

    def answer(self, payload: bytes) -> bytes:
        from .datastore import MAX_VALUE_BYTES, _bytes, _Reader, _string

        r = _Reader(payload)
        op = r.u8()
        with self._lock:
            if op == 0:
                key, value, encoding, writer = r.string(), bytes(r.bytes()), r.string(), r.string()
                r.end()
                if not key:
                    raise ValueError("a datastore key cannot be empty")
                if len(value) > MAX_VALUE_BYTES:
                    raise ValueError(f"the datastore keeps values of at most {MAX_VALUE_BYTES} bytes")
                self._values[key] = (value, encoding, writer)
                return bytes([0])
            if op == 1:
                key = r.string()
                r.end()
                out = bytearray([1])
                found = self._values.get(key)
                if found is None:
                    out.append(0)
                else:
                    out.append(1)
                    _bytes(found[0], out)
                    _string(found[1], out)
                    _string(found[2], out)
                return bytes(out)
            if op == 2:
                r.end()
                out = bytearray([2])
                out += struct.pack("<I", len(self._values))
                for key in sorted(self._values):
                    _string(key, out)
                    _string(self._values[key][1], out)
                    _string(self._values[key][2], out)
                return bytes(out)
            if op == 3:
                key = r.string()
                r.end()
                return bytes([3, 1 if self._values.pop(key, None) is not None else 0])
        raise ValueError(f"unknown datastore operation {op}")


class CoreServer:
    """A core node's functions served in this process (what a launch
    serves, for a test harness): a datastore of its own, `info` and the
    stack listing (`graph()`, a dict of the `stack.list` graph), on
    `session` for core node `core` of namespace `ns`. Close it with
    `close()`."""

    def __init__(
        self,
        session: Any,
        ns: str,
        core: str,
        info: Callable[[], Dict[str, Any]],
        graph: Callable[[], Dict[str, Any]],
    ) -> None:
        self.store = Store()
        self._declared: List[Any] = []
        for function, answer in (
            ("datastore", self.store.answer),
            ("info", lambda _payload: json.dumps(info()).encode()),
            ("list", lambda _payload: json.dumps(_stack_list(info(), graph())).encode()),
        ):
            self._declared.append(session.declare_queryable(core_function_key(ns, core, function), _answering(answer)))

    def close(self) -> None:
        for d in self._declared:
            undeclare(d)
        self._declared.clear()


def _stack_list(info: Dict[str, Any], graph: Dict[str, Any]) -> Dict[str, Any]:
    return {
        "graph": graph,
        "core_node": info["core_node_name"],
        "instance_id": info["core_node_instance_id"],
        "host_name": info["host_name"],
    }


def _answering(answer: Callable[[bytes], bytes]) -> Callable[[Any], None]:
    """A queryable's callback: the answer's bytes, or its error's text."""

    def on_query(query: Any) -> None:
        payload = b"" if query.payload is None else query.payload.to_bytes()
        try:
            try:
                body = answer(bytes(payload))
            except Exception as e:  # a refusal, said to the caller
                query.reply_err(str(e) or type(e).__name__)
            else:
                query.reply(query.key_expr, body)
        except Exception as e:
            log.debug("a core node answer was not sent: %s", e)
        finally:
            try:
                query.drop()
            except Exception:
                pass

    return on_query
