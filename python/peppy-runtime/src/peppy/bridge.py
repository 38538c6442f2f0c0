"""Handing what Zenoh delivers on its threads to the asyncio loop.

Zenoh runs Python callbacks on its own threads. They must never block
(one stalled callback would stall the node's other traffic), so they only
append to a `Mailbox` under a short lock; a reader on the loop is woken
with `call_soon_threadsafe` only when one is waiting.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from typing import Any, Callable, Deque, List, NamedTuple, Optional

from .errors import ShuttingDown

TIMED_OUT: Any = type("TimedOut", (), {"__repr__": lambda self: "TIMED_OUT"})()
"""What `Mailbox.get` returns when its deadline passes first."""


YIELD_EVERY = 64
"""Calls that finish at once (an item already queued, a publish) before one
yields to the loop anyway."""

_budget = [YIELD_EVERY]


def should_yield() -> bool:
    """Whether the caller should `await asyncio.sleep(0)` now.

    asyncio has no budget like tokio's: a reader whose queue is never empty
    (or a tight publishing loop) would never suspend, and the node's other
    tasks (its service handlers, its other readers) would starve.
    """
    _budget[0] -= 1
    if _budget[0] > 0:
        return False
    _budget[0] = YIELD_EVERY
    return True


def _resolve(fut: "asyncio.Future[None]") -> None:
    if not fut.done():
        fut.set_result(None)


class Mailbox:
    """A queue filled from any thread and read on one asyncio loop.

    `maxlen` keeps only the newest items (the oldest is dropped to make
    room); without it every item is kept. Once closed, readers get
    `ShuttingDown` (what is still queued is not handed out).
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, maxlen: Optional[int] = None) -> None:
        self._loop = loop
        self._lock = threading.Lock()
        self._items: Deque[Any] = deque(maxlen=maxlen)
        self._waiters: List["asyncio.Future[None]"] = []
        self._closed = False

    def __len__(self) -> int:
        return len(self._items)

    @property
    def closed(self) -> bool:
        """Whether the mailbox was closed."""
        return self._closed

    def put(self, item: Any) -> None:
        """Queues `item` (dropping the oldest when full); never blocks."""
        with self._lock:
            if self._closed:
                return
            self._items.append(item)
            waiters, self._waiters = self._waiters, []
        self._wake(waiters)

    def offer(self, item: Any, capacity: int) -> bool:
        """Queues `item` unless `capacity` items are already queued."""
        with self._lock:
            if self._closed or len(self._items) >= capacity:
                return False
            self._items.append(item)
            waiters, self._waiters = self._waiters, []
        self._wake(waiters)
        return True

    def take_all(self) -> List[Any]:
        """Empties the mailbox, returning what it held."""
        with self._lock:
            items = list(self._items)
            self._items.clear()
        return items

    def close(self) -> None:
        """Wakes every reader with `ShuttingDown`; later puts are ignored."""
        with self._lock:
            self._closed = True
            waiters, self._waiters = self._waiters, []
        self._wake(waiters)

    def _wake(self, waiters: List["asyncio.Future[None]"]) -> None:
        for fut in waiters:
            try:
                self._loop.call_soon_threadsafe(_resolve, fut)
            except RuntimeError:  # the loop is closed: nobody is waiting any more
                pass

    async def get(self, deadline: Optional[float] = None) -> Any:
        """The oldest item, waiting for one until `deadline` (loop time),
        then `TIMED_OUT`. Raises `ShuttingDown` once closed."""
        loop = self._loop
        if should_yield():
            # Before taking an item: a task cancelled here loses nothing.
            await asyncio.sleep(0)
        while True:
            with self._lock:
                if self._closed:
                    raise ShuttingDown()
                if self._items:
                    return self._items.popleft()
                if deadline is not None and loop.time() >= deadline:
                    return TIMED_OUT
                fut = loop.create_future()
                self._waiters.append(fut)
            timer = loop.call_at(deadline, _resolve, fut) if deadline is not None else None
            try:
                await fut
            finally:
                if timer is not None:
                    timer.cancel()
                with self._lock:
                    if fut in self._waiters:
                        self._waiters.remove(fut)


class ReceivedReply(NamedTuple):
    """One `Ok` reply of a query, copied out of Zenoh's objects."""

    key: str
    attachment: Optional[bytes]
    payload: bytes


class ReplyError(NamedTuple):
    """A replier's `reply_err`: its reason, as UTF-8 text."""

    reason: str


END: Any = type("End", (), {"__repr__": lambda self: "END"})()
"""Queued by a `ReplyStream` once its query has no more replies."""


class ReplyStream:
    """The replies of one query, read on the loop.

    Pass `handler()` as the query's handler; then `await next(deadline)`
    gives each reply, `END` when the query is finished (its timeout or the
    last replier), `TIMED_OUT` at the deadline; `ShuttingDown` once the
    node stops (`register` ties the stream to it). With `errors`, a
    replier's `reply_err` comes as a `ReplyError`; without, it is dropped.
    Zenoh's report of the query's own timeout is never one: `END` follows.
    """

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        register: Callable[[Mailbox], None],
        errors: bool = False,
    ) -> None:
        self._mailbox = Mailbox(loop)
        self._errors = errors
        register(self._mailbox)

    def handler(self) -> Any:
        """The Zenoh handler that fills this stream."""
        import zenoh

        return zenoh.handlers.Callback(self._on_reply, self._on_done)

    def _on_reply(self, reply: Any) -> None:
        sample = reply.ok
        if sample is None:
            if self._errors:
                reason = reply.err.payload.to_bytes().decode("utf-8", "replace")
                if reason != "Timeout":
                    self._mailbox.put(ReplyError(reason))
            return
        attachment = sample.attachment
        self._mailbox.put(
            ReceivedReply(
                str(sample.key_expr),
                None if attachment is None else attachment.to_bytes(),
                sample.payload.to_bytes(),
            )
        )

    def _on_done(self) -> None:
        self._mailbox.put(END)

    async def next(self, deadline: Optional[float] = None) -> Any:
        """The next reply, `END`, or `TIMED_OUT`."""
        return await self._mailbox.get(deadline)

    def close(self) -> None:
        """Stops handing out replies (the query itself runs to its timeout)."""
        self._mailbox.close()


def undeclare(entity: Any) -> None:
    """Undeclares a Zenoh entity (a subscriber, queryable, token), if any;
    a session already closed has undeclared it."""
    if entity is None:
        return
    try:
        entity.undeclare()
    except Exception:
        pass
