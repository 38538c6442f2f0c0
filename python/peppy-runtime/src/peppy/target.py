"""Which server a request through a slot goes to (docs/WIRE.md §3): the one
place services and actions choose it.

A pinned slot, or a from_any slot bound to exactly one producer, names its
server. Otherwise the caller probes every server of the entry and takes
the first that the slot's filter accepts and, for a node slot reached on
an interface's key, that runs the slot's node.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from .attachment import QueryHeader, QueryKind
from .bridge import END, TIMED_OUT, ReplyStream
from .errors import ServiceUnreachable
from .keys import action_part_key, entry_selector, parse_entry_key
from .members import live_instances
from .routing import PINNED, SlotPlan
from .spec import Owner

PROBE_TIMEOUT = 0.5
"""How long discovery waits for servers to say they are there (seconds)."""


@dataclass(frozen=True)
class Entry:
    """What is being reached: through which slot, on which keys."""

    link_id: str
    owner: Owner
    channel: str
    name: str
    part: Optional[str]
    fingerprint: int
    describe: str

    def base(self, runner: Any, instance: Optional[str] = None) -> str:
        """The key expression of this entry's servers (`instance`: one of them), without an action's part."""
        owner = self.owner.segments(runner.node_name, runner.node_tag)
        return entry_selector(runner.namespace, self.channel, owner, self.name, None, instance)

    def selector(self, runner: Any, instance: Optional[str] = None) -> str:
        """The key expression requests go to."""
        base = self.base(runner, instance)
        return base if self.part is None else action_part_key(base, self.part)


def header(runner: Any, kind: QueryKind, fingerprint: int) -> bytes:
    """A query header naming this node as the caller."""
    return QueryHeader(kind, fingerprint, runner.core_node, runner.instance_id).encode()


def named_server(slot: SlotPlan) -> Optional[str]:
    """The server a request through `slot` goes to without asking anyone
    (`peppy_schema::SlotPlan::named_server`): the pinned producer, or the
    one producer an `only_from` filter lets through. None: requests probe
    every server and take the first the filter accepts."""
    if slot.binding.kind == PINNED:
        return slot.binding.producers[0]
    if slot.filter.kind == "only_from" and len(slot.filter.producers) == 1:
        return next(iter(slot.filter.producers))
    return None


async def choose(runner: Any, entry: Entry, deadline: float) -> str:
    """The server instance a request through `entry`'s slot goes to."""
    import zenoh

    slot = runner.slot(entry.link_id)
    server = named_server(slot)
    if server is not None:
        return server
    loop = runner.loop
    budget = min(max(deadline - loop.time(), 0.0), PROBE_TIMEOUT)
    # An interface's key is shared by every conforming node: a node slot
    # keeps only instances of its own node.
    members = None
    if slot.kind == "node" and entry.owner.kind == "interface":
        members = await live_instances(runner, slot.name, slot.tag, budget)
    stream = ReplyStream(loop, runner._track_mailbox)
    runner.session.get(
        entry.selector(runner),
        stream.handler(),
        target=zenoh.QueryTarget.ALL,
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=max(budget, 0.001),
        attachment=header(runner, QueryKind.PROBE, entry.fingerprint),
    )
    # Zenoh ends the query at its timeout; the margin only guards that.
    until = loop.time() + max(budget, 0.001) + 0.25
    try:
        while True:
            reply = await stream.next(until)
            if reply is END or reply is TIMED_OUT:
                break
            sender = parse_entry_key(reply.key)
            if sender is None:
                continue
            if members is not None and not members.contains(sender.core, sender.instance):
                continue
            if slot.filter.accepts(sender.instance):
                return sender.instance
    finally:
        stream.close()
    raise ServiceUnreachable(entry.describe)
