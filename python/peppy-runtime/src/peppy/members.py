"""Which instances run a given node, learned from their liveliness tokens.

A node slot that consumes an entry its producer inherited from an
interface receives on the interface's key, which every conforming node
shares: the key alone cannot tell one node from another. Each instance
holds `peppy/<ns>/live/<core>/<instance>/<node>/<tag>`, so such a
consumer follows the tokens of the slot's node and keeps only senders
that hold one.
"""

from __future__ import annotations

import logging
import threading
from typing import Any, Dict, Set

from .bridge import END, TIMED_OUT, ReplyStream
from .keys import liveliness_selector, parse_liveliness_key

log = logging.getLogger("peppy")

INITIAL_QUERY = 2.0
"""How long start-up waits for the instances already running (seconds)."""


class Live:
    """Instances as `instance id -> core nodes`, safe to read from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_instance: Dict[str, Set[str]] = {}

    def insert(self, core: str, instance: str) -> None:
        """Marks `(core, instance)` up."""
        with self._lock:
            self._by_instance.setdefault(instance, set()).add(core)

    def remove(self, core: str, instance: str) -> None:
        """Marks `(core, instance)` gone."""
        with self._lock:
            cores = self._by_instance.get(instance)
            if cores is not None:
                cores.discard(core)
                if not cores:
                    del self._by_instance[instance]

    def contains(self, core: str, instance: str) -> bool:
        """Whether `(core, instance)` is up."""
        with self._lock:
            return core in self._by_instance.get(instance, ())


async def live_instances(runner: Any, name: str, tag: str, timeout: float) -> Live:
    """The instances of node `name:tag` that are up now, asked once."""
    out = Live()
    stream = ReplyStream(runner.loop, runner._track_mailbox)
    runner.session.liveliness().get(
        liveliness_selector(runner.namespace, name, tag), stream.handler(), timeout=max(timeout, 0.001)
    )
    deadline = runner.loop.time() + max(timeout, 0.001) + 0.5
    try:
        while True:
            reply = await stream.next(deadline)
            if reply is END or reply is TIMED_OUT:
                break
            who = parse_liveliness_key(reply.key)
            if who is not None:
                out.insert(*who)
    finally:
        stream.close()
    return out


class Members:
    """The live instances of one node, followed for the node's life."""

    def __init__(self, live: Live, subscriber: Any) -> None:
        self.live = live
        self.subscriber = subscriber

    @classmethod
    async def track(cls, runner: Any, name: str, tag: str) -> "Members":
        """Follows node `name:tag`. The instances already running are known
        when this returns, so a stream's first samples are not dropped."""
        import zenoh

        live = Live()

        def on_token(sample: Any) -> None:
            who = parse_liveliness_key(str(sample.key_expr))
            if who is None:
                return
            if sample.kind == zenoh.SampleKind.PUT:
                live.insert(*who)
            else:
                live.remove(*who)

        subscriber = runner.session.liveliness().declare_subscriber(
            liveliness_selector(runner.namespace, name, tag), on_token
        )
        running = await live_instances(runner, name, tag, INITIAL_QUERY)
        with running._lock:
            for instance, cores in running._by_instance.items():
                for core in cores:
                    live.insert(core, instance)
        return cls(live, subscriber)

    def contains(self, core: str, instance: str) -> bool:
        """Whether `(core, instance)` runs the tracked node."""
        known = self.live.contains(core, instance)
        if not known:
            log.debug("%s/%s is not an instance of this slot's node", core, instance)
        return known
