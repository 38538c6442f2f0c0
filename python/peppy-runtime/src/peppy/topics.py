"""Topics: publishing, and consumer inboxes that apply the slot's routing
filter and the format fingerprint before anything is queued."""

from __future__ import annotations

import asyncio
import logging
import threading
from typing import Any, Callable, Dict, NamedTuple, Optional, Set, Tuple

from . import attachment
from .bridge import Mailbox, should_yield
from .errors import ShuttingDown
from .keys import TOPIC, entry_selector, parse_entry_key
from .members import Members
from .routing import RouteFilter
from .spec import ConsumedTopicSpec, QoSProfile, TopicSpec

log = logging.getLogger("peppy")

WARN_AT = 256
"""A keep-all reader this many messages behind earns a warning (then at each eightfold growth)."""

KEEP_ALL_BYTES = 1 << 30
"""Past this many unread bytes on one keep-all topic, arrivals are dropped (a reader that stopped)."""

REMEMBERED = 1024
"""How many producer keys one consumed topic remembers (parsed once, declared
to the session once); past it a key is parsed per message, never stored."""

REFUSAL_PAUSE = 0.1
"""How long a call made on an already stopped node waits before raising
`ShuttingDown`, so a loop that ignores the error parks instead of spinning."""


async def refused() -> ShuttingDown:
    """`ShuttingDown`, after the refusal pause."""
    await asyncio.sleep(REFUSAL_PAUSE)
    return ShuttingDown()


class Delivery(NamedTuple):
    """One received message, not yet decoded."""

    core: str
    instance: str
    payload: bytes


class Backlog:
    """What a keep-all inbox holds unread, for its warnings and its bound."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.bytes = 0
        self.next_warning = 0
        self.dropped = 0


class Inbox:
    """The queue of one consumed topic, filled by the subscription callback."""

    def __init__(self, loop: asyncio.AbstractEventLoop, spec: ConsumedTopicSpec) -> None:
        self.spec = spec
        # External topics have no producer contract to follow: the standard queue.
        qos = QoSProfile.STANDARD if spec.owner.kind == "any" else spec.qos
        self.keep_newest = qos.keep_newest
        self.mailbox = Mailbox(loop, maxlen=self.keep_newest)
        self.backlog = Backlog()
        # Whether the node's code asked for the topic's messages (subscribe,
        # or a first next): what a test harness's mock waits for.
        self.read = False

    def put(self, delivery: Delivery) -> None:
        """Queues a message; never blocks (a keep-all queue drops only past its byte bound)."""
        if self.keep_newest is not None:
            self.mailbox.put(delivery)
            return
        size = len(delivery.payload)
        b = self.backlog
        with b.lock:
            if b.bytes + size > KEEP_ALL_BYTES:
                b.dropped += 1
                dropped = b.dropped
                unread_mib = (b.bytes + size) >> 20
            else:
                b.bytes += size
                dropped = 0
        if dropped:
            if dropped & (dropped - 1) == 0:
                log.error(
                    "topic `%s`: the reader of this reliable topic is not reading (%d MiB unread); "
                    "dropping what arrives until it does (%d dropped)",
                    self.spec.name,
                    unread_mib,
                    dropped,
                )
            return
        self.mailbox.put(delivery)
        unread = len(self.mailbox)
        with b.lock:
            threshold = b.next_warning or WARN_AT
            warn = unread >= threshold
            if warn:
                b.next_warning = threshold * 8
            queued_kib = b.bytes >> 10
        if warn:
            log.warning(
                "topic `%s`: the reader of this reliable topic is falling behind (%d unread, %d KiB); "
                "every message is kept, the node's other traffic goes on",
                self.spec.name,
                unread,
                queued_kib,
            )

    def taken(self, delivery: Delivery) -> None:
        """The reader took `delivery`; an emptied queue ends a warning episode."""
        if self.keep_newest is not None:
            return
        b = self.backlog
        empty = len(self.mailbox) == 0
        with b.lock:
            b.bytes -= len(delivery.payload)
            ended = empty and b.next_warning != 0
            if ended:
                b.next_warning = 0
                dropped, b.dropped = b.dropped, 0
        if ended:
            log.info("topic `%s`: the reader has caught up with its queue (%d dropped)", self.spec.name, dropped)


class Intake:
    """The subscription callback of one consumed topic: route, check the
    fingerprint, queue. Runs on Zenoh's threads."""

    def __init__(
        self,
        spec: ConsumedTopicSpec,
        filter: RouteFilter,
        members: Optional[Members],
        inbox: Inbox,
        mismatch: Callable[[ConsumedTopicSpec, str, int], None],
        declare: Optional[Callable[[str], None]] = None,
    ) -> None:
        self.spec = spec
        self.filter = filter
        self.members = members
        self.inbox = inbox
        self.mismatch = mismatch
        self.fingerprint = spec.format.fingerprint
        self._warned: Set[str] = set()
        self._lock = threading.Lock()
        # A consumer subscribes with a wildcard, so no resource of its
        # session has a producer's exact key and Zenoh would match each
        # message's key against every subscription; a declared key has its
        # route cached. Each key is also parsed once.
        self._producers: Dict[str, Tuple[str, str]] = {}
        self._declare = declare

    def _first_warning(self, producer: str) -> bool:
        with self._lock:
            if producer in self._warned:
                return False
            self._warned.add(producer)
            return True

    def __call__(self, sample: Any) -> None:
        key = str(sample.key_expr)
        producer = self._producers.get(key)
        if producer is None:
            sender = parse_entry_key(key)
            if sender is None:
                log.debug("dropping a sample with a malformed key: %s", key)
                return
            producer = (sender.core, sender.instance)
            if len(self._producers) < REMEMBERED:
                self._producers[key] = producer
                if self._declare is not None:
                    self._declare(key)
        core, instance = producer
        if not self.filter.accepts(instance):
            return
        if self.members is not None and not self.members.contains(core, instance):
            return
        att = sample.attachment
        fingerprint = attachment.parse_topic(None if att is None else att.to_bytes())
        if fingerprint != self.fingerprint:
            if self._first_warning(instance):
                if fingerprint is None:
                    log.warning(
                        "topic `%s`: dropping messages from `%s` without a valid peppy attachment",
                        self.spec.name,
                        instance,
                    )
                else:
                    self.mismatch(self.spec, instance, fingerprint)
            return
        self.inbox.put(Delivery(core, instance, sample.payload.to_bytes()))


def subscription_selector(namespace: str, owner: Optional[str], spec: ConsumedTopicSpec, filter: RouteFilter) -> str:
    """The key expression a consumed topic subscribes to: a pinned slot
    narrows it to its producer; other filters apply per sample."""
    return entry_selector(namespace, TOPIC, owner, spec.name, None, filter.pinned)


async def emit(runner: Any, spec: TopicSpec, message: Any) -> None:
    """Publishes one message on an emitted topic, once; producers never know
    who listens. Works while the node is stopping (a last message on the
    way out); once its session is closed, raises `ShuttingDown` after a
    short pause."""
    payload = spec.format.encode(message)
    if runner.session_closed:
        raise await refused()
    # On the loop thread, even for a `block` profile: a hop through a worker
    # thread costs about a millisecond per message under the GIL (a
    # fifteenth of the rate, and the latency `critical` is for). Zenoh
    # releases the GIL while a congested link makes it wait, so deliveries
    # to this node go on meanwhile; only its coroutines wait, as the
    # link's back-pressure asks.
    runner._publisher(spec).put(payload, attachment=attachment.topic(spec.format.fingerprint))
    if should_yield():
        await asyncio.sleep(0)


async def next_message(
    runner: Any,
    spec: ConsumedTopicSpec,
    from_core_node: Optional[str] = None,
    from_instance_id: Optional[str] = None,
) -> Tuple[str, Any]:
    """The next message of a consumed topic: `(producer instance id, message)`.

    Messages are queued from start-up, so none is lost between calls. The
    `from_*` arguments keep only messages from that launch (core node) or
    producer instance; others are taken off the queue and dropped. A
    message that does not decode is logged and skipped. Raises
    `ShuttingDown` once the node stops.
    """
    inbox: Inbox = runner._inbox(spec)
    inbox.read = True
    if runner.is_stopping():
        raise await refused()
    while True:
        delivery = await inbox.mailbox.get()
        inbox.taken(delivery)
        if from_core_node is not None and delivery.core != from_core_node:
            continue
        if from_instance_id is not None and delivery.instance != from_instance_id:
            continue
        try:
            return delivery.instance, spec.format.decode(delivery.payload)
        except ValueError as e:
            log.warning(
                "topic `%s`: dropping a message from `%s` that does not decode: %s", spec.name, delivery.instance, e
            )
