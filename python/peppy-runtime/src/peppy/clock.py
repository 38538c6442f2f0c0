"""The stack clock (docs/WIRE.md, "Clock"): one time for every node of a
launch, wall or simulated.

Each launch publishes its OS clock ten times a second on
`peppy/<ns>/clock/tick/wall` and answers synchronization queries on
`peppy/<ns>/clock/sync`; a simulator publishes its time on
`peppy/<ns>/clock/tick/sim` (`publish_sim_time`). A node follows one of
the two, fixed at start-up (`node_runner.use_sim_time()`: the instance's
`framework.use_sim_time`, or `--use-sim-time`):

- wall time: `now_ns()` is this host's OS clock (ns since the Unix
  epoch); `synchronize` measures how far it is from the launcher's;
- sim time: `now_ns()` is the latest sim tick this node has received, and
  `ClockNotReady` (a `RuntimeError`) until the first arrives.

Every payload is u64 little-endian nanoseconds. One of the wrong length is
dropped, with one warning per subscription.
"""

from __future__ import annotations

import asyncio
import logging
import struct
import threading
import time
from dataclasses import dataclass
from typing import Any, List, Optional, Tuple

from .bridge import END, TIMED_OUT, Mailbox, ReplyError, ReplyStream
from .errors import ClockNotReady, ServiceUnreachable, ShuttingDown
from .keys import CLOCK_SIM, CLOCK_WALL, clock_sync_key, clock_tick_key

log = logging.getLogger("peppy")

DEFAULT_SYNC_TIMEOUT = 10.0
"""How long `synchronize` waits for the launcher's answer by default (seconds)."""

_U64 = struct.Struct("<Q")
_QUERY_LEN = 9
_REPLY = struct.Struct("<QQQ")
_I64_MIN, _I64_MAX = -(1 << 63), (1 << 63) - 1
_U64_MAX = (1 << 64) - 1


def os_now_ns() -> int:
    """This host's OS clock, ns since the Unix epoch."""
    return max(time.time_ns(), 0)


def decode_time(data: bytes) -> Optional[int]:
    """A tick's time, if `data` is one: exactly 8 bytes."""
    return _U64.unpack(data)[0] if len(data) == 8 else None


def encode_time(ns: int) -> bytes:
    """`ns` as a tick payload."""
    if not 0 <= ns <= _U64_MAX:
        raise ValueError(f"a clock time is a u64 of nanoseconds, got {ns}")
    return _U64.pack(ns)


class _Latest:
    """The latest tick seen, written on Zenoh's threads."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.value: Optional[int] = None
        self._waiters: List[Tuple[int, asyncio.AbstractEventLoop, "asyncio.Future[None]"]] = []

    def set(self, t: int) -> None:
        with self._lock:
            self.value = t
            reached = [w for w in self._waiters if w[0] == t]
            self._waiters = [w for w in self._waiters if w[0] != t]
        for _, loop, fut in reached:
            try:
                loop.call_soon_threadsafe(_resolve, fut)
            except RuntimeError:
                pass

    def get(self) -> Optional[int]:
        with self._lock:
            return self.value

    def reached(self, t: int) -> "asyncio.Future[None]":
        """A future done once the latest tick is `t` (at once if it is now)."""
        loop = asyncio.get_running_loop()
        fut: "asyncio.Future[None]" = loop.create_future()
        with self._lock:
            if self.value == t:
                fut.set_result(None)
            else:
                self._waiters.append((t, loop, fut))
        return fut


def _resolve(fut: "asyncio.Future[None]") -> None:
    if not fut.done():
        fut.set_result(None)


class _TickIntake:
    """A tick subscription's callback: well-formed ticks go on, others are
    dropped with one warning."""

    def __init__(self, key: str, sink: Any) -> None:
        self.key = key
        self.sink = sink
        self.warned = False

    def __call__(self, sample: Any) -> None:
        t = decode_time(sample.payload.to_bytes())
        if t is None:
            if not self.warned:
                self.warned = True
                log.warning("dropping clock ticks on `%s` that are not 8 bytes (u64 little-endian ns)", self.key)
            return
        self.sink(t)


@dataclass
class _Binding:
    node: Tuple[str, str]
    sim: Optional[_Latest]


_bound: Optional[_Binding] = None


def _node_of(runner: Any) -> Tuple[str, str]:
    return (runner.core_node, runner.instance_id)


def sim_time_of(runner: Any) -> Optional[_Latest]:
    """The sim time `now_ns` reads for `runner`'s node, once `init` bound
    it there in sim mode; None otherwise (a test clock waits on it)."""
    b = _bound
    if b is None or b.node != _node_of(runner):
        return None
    return b.sim


async def init(runner: Any) -> None:
    """Binds `now_ns` to this node's clock: following sim time, subscribes
    to the stack's sim ticks and keeps the latest; following wall time,
    nothing to set up. Idempotent for one node; another node (another
    runner in this process) takes the clock over."""
    global _bound
    node = _node_of(runner)
    if _bound is not None and _bound.node == node:
        return
    sim: Optional[_Latest] = None
    if runner.use_sim_time():
        sim = _Latest()
        key = clock_tick_key(runner.namespace, CLOCK_SIM)
        # Lives as long as the node's session.
        runner._declared.append(runner.session.declare_subscriber(key, _TickIntake(key, sim.set)))
    _bound = _Binding(node, sim)


def now_ns() -> int:
    """The stack time now, in ns: the OS clock following wall time, the
    latest sim tick following sim time. `ClockNotReady` (a `RuntimeError`)
    before `init`, and following sim time until the first tick arrives."""
    b = _bound
    if b is None:
        raise ClockNotReady("the clock is not ready: call `await clock.init(node_runner)` first")
    if b.sim is None:
        return os_now_ns()
    t = b.sim.get()
    if t is None:
        raise ClockNotReady("the clock is not ready: no sim tick has arrived yet")
    return t


def _client_now(runner: Any) -> int:
    if not runner.use_sim_time():
        return os_now_ns()
    b = _bound
    if b is not None and b.node == _node_of(runner) and b.sim is not None:
        return b.sim.get() or 0
    return 0


async def publish_sim_time(runner: Any, ns: int) -> None:
    """Publishes `ns` as the stack's simulated time
    (`peppy/<ns>/clock/tick/sim`): what a simulator calls at each step."""
    payload = encode_time(ns)
    if runner.session_closed:
        raise ShuttingDown()
    runner.session.put(clock_tick_key(runner.namespace, CLOCK_SIM), payload)


@dataclass(frozen=True)
class ClockResponse:
    """The launcher's answer to a sync query: t0 echoed, t1 (received), t2 (sent)."""

    client_send_time: int
    server_recv_time: int
    server_send_time: int


@dataclass(frozen=True)
class ClockSync:
    """How far this node's clock is from the launcher's (`offset_ns`: add it
    to this node's clock), the query's round trip, and the raw answer."""

    offset_ns: int
    round_trip_delay_ns: int
    raw: ClockResponse


def clock_sync(raw: ClockResponse, t3: int) -> ClockSync:
    """NTP's offset and delay, `t3` being when the answer arrived (by the
    client's clock); saturated to i64 / u64, the delay never negative."""
    t0, t1, t2 = raw.client_send_time, raw.server_recv_time, raw.server_send_time
    offset = ((t1 - t0) + (t2 - t3)) // 2
    delay = (t3 - t0) - (t2 - t1)
    return ClockSync(
        offset_ns=min(max(offset, _I64_MIN), _I64_MAX),
        round_trip_delay_ns=min(max(delay, 0), _U64_MAX),
        raw=raw,
    )


async def synchronize(runner: Any, response_timeout_secs: Optional[float] = None) -> ClockSync:
    """Asks the launcher for its clock: a query on `clock/sync` carrying
    this node's time and mode (t0, wall or sim); the first answer counts.
    Following sim time, the launcher answers with its latest sim tick, or
    refuses when it has seen none (`ClockNotReady`). No answer within
    `response_timeout_secs` (default 10 s): `ServiceUnreachable` (a
    `ConnectionError`)."""
    if runner.refuses_calls():
        raise ShuttingDown()
    timeout = DEFAULT_SYNC_TIMEOUT if response_timeout_secs is None else float(response_timeout_secs)
    loop = runner.loop
    deadline = loop.time() + timeout
    while True:
        sync = await _ask_clock(runner, max(deadline - loop.time(), 0.001))
        if sync is not None:
            return sync
        # Nobody answered. A query that reaches no queryable ends at once,
        # and a node just started may not have heard of the launcher's yet:
        # ask again until the timeout is spent.
        left = deadline - loop.time()
        if left <= 0:
            raise ServiceUnreachable("clock sync")
        await asyncio.sleep(min(left, _SYNC_RETRY))
        if runner.refuses_calls():
            raise ShuttingDown()


#: How long `synchronize` waits before asking again when nobody answered.
_SYNC_RETRY = 0.05


async def _ask_clock(runner: Any, timeout: float) -> Optional[ClockSync]:
    """One `clock/sync` query: the first answer, or None when none came
    within `timeout`."""
    import zenoh

    loop = runner.loop
    key = clock_sync_key(runner.namespace)
    t0 = _client_now(runner)
    query = _U64.pack(t0) + bytes([1 if runner.use_sim_time() else 0])
    replies = ReplyStream(loop, runner._track_mailbox, errors=True)
    runner.session.get(
        key,
        replies.handler(),
        target=zenoh.QueryTarget.ALL,
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=max(timeout, 0.001),
        payload=query,
    )
    deadline = loop.time() + timeout + 0.25
    try:
        while True:
            item = await replies.next(deadline)
            if item is END or item is TIMED_OUT:
                return None
            t3 = _client_now(runner)
            if isinstance(item, ReplyError):
                raise ClockNotReady(f"the launcher cannot synchronize: {item.reason}")
            payload = item.payload
            if len(payload) != _REPLY.size:
                log.debug("dropping a clock sync reply of %d bytes (expected 24)", len(payload))
                continue
            return clock_sync(ClockResponse(*_REPLY.unpack(payload)), t3)
    finally:
        replies.close()


@dataclass(frozen=True)
class ClockTick:
    """One tick: the stack time it carries, ns."""

    time: int


class ClockSubscription:
    """The ticks of this node's mode (the launcher's wall ticks, or sim
    ticks): `await sub.on_next_tick()`, None once the node stops."""

    def __init__(self, runner: Any, key: str) -> None:
        self._runner = runner
        self._mailbox = Mailbox(runner.loop, maxlen=64)
        runner._track_mailbox(self._mailbox, intake=True)
        self._subscriber = runner.session.declare_subscriber(key, _TickIntake(key, self._mailbox.put))
        runner._declared.append(self._subscriber)

    async def on_next_tick(self) -> Optional[ClockTick]:
        """The next tick; None once the node stops."""
        if self._runner.is_stopping():
            return None
        try:
            return ClockTick(await self._mailbox.get())
        except ShuttingDown:
            return None

    def close(self) -> None:
        """Stops receiving ticks."""
        try:
            self._subscriber.undeclare()
        except Exception:
            pass


async def subscribe(runner: Any) -> ClockSubscription:
    """Follows the ticks of this node's mode (wall ticks, about ten a
    second, from the launcher; or sim ticks)."""
    source = CLOCK_SIM if runner.use_sim_time() else CLOCK_WALL
    return ClockSubscription(runner, clock_tick_key(runner.namespace, source))


WALL_TICK_PERIOD = 0.1
"""How often a clock server publishes wall ticks (seconds)."""


def answer_sync(query: bytes, received: int, sim: Optional[int], ns: str, offset_ns: int = 0) -> Tuple[bool, bytes]:
    """A clock server's answer to one sync query: `(True, reply)` or
    `(False, why)`. Wall queries get this host's clock (skewed by
    `offset_ns`), sim queries the latest sim tick (`sim`), refused while
    there is none."""
    if len(query) != _QUERY_LEN or query[8] not in (0, 1):
        why = (
            "a clock sync query is 9 bytes (t0 as u64 little-endian, then 0 for wall or 1 for sim); "
            f"got {len(query)} bytes"
        )
        return False, why.encode("utf-8")
    t0 = _U64.unpack(query[:8])[0]
    if query[8] == 0:

        def skew(t: int) -> int:
            return min(max(t + offset_ns, 0), _U64_MAX)

        t1, t2 = skew(received), skew(os_now_ns())
    else:
        if sim is None:
            return False, f"no sim tick has been published on {clock_tick_key(ns, CLOCK_SIM)} yet".encode("utf-8")
        t1 = t2 = sim
    return True, _REPLY.pack(t0, t1, t2)


class ClockServer:
    """A launch's clock, served in this process on `session` for namespace
    `ns` (what the launcher serves, for a test harness): answers on
    `clock/sync`, wall ticks ten times a second, and the latest sim tick
    followed for sim answers. `offset_ns` skews the wall answers and ticks;
    `set_sim_time` makes a time the sim answers' at once. Close it with `close()`."""

    def __init__(self, session: Any, ns: str) -> None:
        self.namespace = ns
        self.offset_ns = 0
        self.sim = _Latest()
        self._session = session
        self._declared: List[Any] = []
        sync_key = clock_sync_key(ns)

        def on_query(query: Any) -> None:
            received = os_now_ns()
            payload = b"" if query.payload is None else query.payload.to_bytes()
            ok, body = answer_sync(payload, received, self.sim.get(), ns, self.offset_ns)
            try:
                if ok:
                    query.reply(sync_key, body)
                else:
                    query.reply_err(body)
            except Exception as e:
                log.debug("clock sync reply failed: %s", e)
            finally:
                try:
                    query.drop()
                except Exception:
                    pass

        sim_key = clock_tick_key(ns, CLOCK_SIM)
        self._declared.append(session.declare_subscriber(sim_key, _TickIntake(sim_key, self.sim.set)))
        self._declared.append(session.declare_queryable(sync_key, on_query))
        self._wall = session.declare_publisher(clock_tick_key(ns, CLOCK_WALL))
        self._declared.append(self._wall)
        self._ticker: Optional["asyncio.Task[None]"] = asyncio.get_running_loop().create_task(self._tick_wall())

    def set_sim_time(self, ns: int) -> None:
        """Makes `ns` the sim time sync answers give, before any tick carrying it arrives."""
        encode_time(ns)
        self.sim.set(ns)

    async def _tick_wall(self) -> None:
        while True:
            try:
                self._wall.put(encode_time(min(max(os_now_ns() + self.offset_ns, 0), _U64_MAX)))
            except Exception:
                return  # the session closed
            await asyncio.sleep(WALL_TICK_PERIOD)

    def close(self) -> None:
        """Stops serving (the session stays open)."""
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None
        for entity in reversed(self._declared):
            try:
                entity.undeclare()
            except Exception:
                pass
        self._declared.clear()


__all__ = [
    "ClockResponse",
    "ClockServer",
    "ClockSubscription",
    "ClockSync",
    "ClockTick",
    "DEFAULT_SYNC_TIMEOUT",
    "init",
    "now_ns",
    "publish_sim_time",
    "subscribe",
    "synchronize",
]
