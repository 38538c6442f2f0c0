"""Everything a node declares before its code runs (node.rs `NodeRunner::open`):
publishers, format queryables, subscriptions with their routing, service
and action queryables, the description queryable, and last the liveliness
token that tells the others the node is up."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import time
from typing import Any, Callable, Dict, List, Optional, Union

from .action_server import GoalIntake, Registry
from .bridge import END, TIMED_OUT, ReplyStream
from .describe import consumed_topic, instance_info
from .errors import ShuttingDown, StartupError
from .keys import ACTION, SERVICE, TOPIC, action_part_key, describe_key, format_key, liveliness_key
from .members import Members
from .pairing import check_slots, declare_pairings, describe_pairings
from .routing import ANY, SlotPlan
from .runner import NodeRunner
from .services import ServiceIntake
from .spec import ActionSpec, ConsumedTopicSpec
from .topics import Inbox, Intake, subscription_selector

log = logging.getLogger("peppy")


async def declare_all(runner: NodeRunner, retention: float) -> None:
    """Declares the whole node on `runner`'s session, token last."""
    d = runner.descriptor
    session = runner.session
    started_at_ms = int(time.time() * 1000)
    for spec in d.emitted_topics:
        key = runner._own_key(TOPIC, spec.owner, spec.name)
        # Declares the exact key to every peer, so messages on it travel
        # under a numeric id instead of text (docs/WIRE.md §1); it answers
        # no query.
        runner._declared.append(session.declare_queryable(key, _answer_nothing))
        publisher = session.declare_publisher(
            key,
            congestion_control=spec.qos.congestion_control,
            priority=spec.qos.priority,
            express=spec.qos.express,
        )
        runner._publishers[spec] = publisher
        runner._declared.append(publisher)
    _serve_formats(runner)
    consumes = await _subscribe(runner)
    for spec in d.exposed_services:
        key = runner._own_key(SERVICE, spec.owner, spec.name)
        mailbox = runner._mailbox(intake=True)
        runner._declared.append(session.declare_queryable(key, ServiceIntake(spec, key, mailbox), complete=True))
        runner._services[spec] = (mailbox, key)
    for spec in d.exposed_actions:
        _serve_action(runner, spec, retention)
    check_slots(runner)
    await declare_pairings(runner, runner.pairs)
    body = instance_info(
        d, runner.namespace, runner.core_node, runner.instance_id, os.getpid(), started_at_ms, runner.slots, consumes
    )
    key = describe_key(runner.namespace, runner.core_node, runner.instance_id)
    if not runner._pairings:
        _answer(runner, key, body.encode("utf-8"))
    else:
        # Pairs change while the node runs: each answer says how they are now.
        _answer(runner, key, lambda: _with_pairings(runner, body))
    # Presence: withdrawn when the node shuts down or dies.
    runner._token = session.liveliness().declare_token(
        liveliness_key(runner.namespace, runner.core_node, runner.instance_id, runner.node_name, runner.node_tag)
    )


def _answer_nothing(query: Any) -> None:
    try:
        query.drop()
    except Exception:
        pass


def _with_pairings(runner: NodeRunner, body: str) -> bytes:
    info = json.loads(body)
    info["pairings"] = describe_pairings(runner)
    return json.dumps(info, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def _answer(runner: NodeRunner, key: str, body: Union[bytes, Callable[[], bytes]]) -> None:
    """A queryable answering every query with `body` (or what it returns), no attachment."""

    def on_query(query: Any) -> None:
        try:
            query.reply(key, body() if callable(body) else body)
        except Exception as e:
            log.debug("reply on %s failed: %s", key, e)
        finally:
            try:
                query.drop()
            except Exception:
                pass

    runner._declared.append(runner.session.declare_queryable(key, on_query))


def _serve_formats(runner: NodeRunner) -> None:
    # Other nodes ask for the text of a format whose fingerprint they do
    # not know, to name both sides of a mismatch.
    served = set()
    for spec in runner.descriptor.emitted_topics:
        fp = spec.format.fingerprint
        if fp not in served:
            served.add(fp)
            _answer(runner, format_key(runner.namespace, fp, runner.instance_id), spec.format.canonical.encode("utf-8"))


async def _subscribe(runner: NodeRunner) -> List[Dict[str, Any]]:
    """One subscription and inbox per consumed topic, for the node's life;
    returns how each is routed, for the description."""
    routes: List[Dict[str, Any]] = []
    trackers: Dict[str, Members] = {}
    declarer = _key_declarer(runner)
    for spec in runner.descriptor.consumed_topics:
        slot: Optional[SlotPlan] = None
        if spec.link_id is not None:
            slot = runner._slots.get(spec.link_id)
            if slot is None:
                raise StartupError(
                    f"consumed topic `{spec.name}` names slot `{spec.link_id}`, which this node does not declare"
                )
        route_filter = slot.filter if slot is not None else ANY
        # An interface's key is shared by every conforming node: a node slot
        # keeps only live instances of its own node.
        members = None
        if slot is not None and slot.kind == "node" and spec.owner.kind == "interface":
            members = trackers.get(slot.link_id)
            if members is None:
                members = await Members.track(runner, slot.name, slot.tag)
                runner._declared.append(members.subscriber)
                trackers[slot.link_id] = members
        owner = spec.owner.segments(runner.node_name, runner.node_tag)
        selector = subscription_selector(runner.namespace, owner, spec, route_filter)
        members_of = slot if members is not None else None
        routes.append(consumed_topic(spec, runner.node_name, runner.node_tag, selector, route_filter, members_of))
        inbox = Inbox(runner.loop, spec)
        runner._track_mailbox(inbox.mailbox, intake=True)
        intake = Intake(spec, route_filter, members, inbox, lambda *a: _mismatch(runner, *a), declarer)
        runner._declared.append(runner.session.declare_subscriber(selector, intake))
        runner._inboxes[spec] = inbox
    return routes


class _DeclaredKey:
    """A key expression declared to the session, undeclared with the node."""

    def __init__(self, session: Any, key_expr: Any) -> None:
        self._session = session
        self._key_expr = key_expr

    def undeclare(self) -> None:
        self._session.undeclare(self._key_expr)


def _key_declarer(runner: NodeRunner) -> Any:
    """Declares producer keys on the loop thread: Zenoh's delivery thread,
    which hears of a new producer, holds the routing tables a declaration
    needs."""

    def on_loop(key: str) -> None:
        if runner.session_closed:
            return
        try:
            runner._declared.append(_DeclaredKey(runner.session, runner.session.declare_keyexpr(key)))
        except Exception as e:  # the session closed meanwhile
            log.debug("could not declare producer key %s: %s", key, e)

    def declare(key: str) -> None:
        try:
            runner.loop.call_soon_threadsafe(on_loop, key)
        except RuntimeError:  # the loop is closed: the node is gone
            pass

    return declare


def _serve_action(runner: NodeRunner, spec: ActionSpec, retention: float) -> None:
    """An action's goal, cancel and result queryables, its registry, and the
    sweep that expires kept results."""
    base = runner._own_key(ACTION, spec.owner, spec.name)
    registry = Registry(spec, base, runner.session, retention)
    mailbox = runner._mailbox(intake=True)
    goal_key = action_part_key(base, "goal")
    for key, callback in (
        (goal_key, GoalIntake(spec, goal_key, mailbox)),
        (action_part_key(base, "cancel"), registry.on_cancel),
        (action_part_key(base, "result"), registry.on_result),
    ):
        runner._declared.append(runner.session.declare_queryable(key, callback, complete=True))
    runner._actions[spec] = (mailbox, registry)
    runner._spawn(_sweep(runner, registry))


async def _sweep(runner: NodeRunner, registry: Registry) -> None:
    period = min(max(registry.retention / 4, 0.01), 1.0)
    while not runner.stopped.is_set():
        await asyncio.sleep(period)
        registry.sweep()


def _mismatch(runner: NodeRunner, spec: ConsumedTopicSpec, producer: str, theirs: int) -> None:
    """Zenoh thread: a producer sends another format. Reported once, with
    the producer's own text asked from the producer."""
    try:
        asyncio.run_coroutine_threadsafe(_report_mismatch(runner, spec, producer, theirs), runner.loop)
    except RuntimeError:
        pass


async def _report_mismatch(runner: NodeRunner, spec: ConsumedTopicSpec, producer: str, theirs: int) -> None:
    their_text = f"(fingerprint {theirs:016x})"
    if not runner.stopped.is_set():
        stream = ReplyStream(runner.loop, runner._track_mailbox)
        try:
            runner.session.get(format_key(runner.namespace, theirs, producer), stream.handler(), timeout=2.0)
            reply = await stream.next(runner.loop.time() + 2.5)
            if reply is not END and reply is not TIMED_OUT:
                their_text = f"{reply.payload.decode('utf-8', 'replace')} (fingerprint {theirs:016x})"
        except (ShuttingDown, Exception):
            pass
        finally:
            stream.close()
    log.warning(
        "dropping topic `%s` from `%s`: it sends %s, this node expects %s (fingerprint %016x); "
        "rebuild the two nodes against the same format",
        spec.name,
        producer,
        their_text,
        spec.format.canonical,
        spec.format.fingerprint,
    )
