"""Pairs and observers on the wire (docs/PAIRINGS.md §3).

Each participant slot holds one claim token naming the peer slot it pairs
with. Two slots are paired while each sees the other's claim on itself;
everything else follows from the tokens, which Zenoh withdraws when a
session closes or its link is lost: a side that stops dissolves the pair at
once, and the survivor, still claiming it, pairs again when it comes back.
A participant receives only its current peer's topics, and only while the
pair holds; each pair starts with empty queues. It publishes only while
paired (otherwise a publish succeeds and sends nothing).

An observer subscribes to each planned source's topics and follows the
source's liveliness token, so what was queued from a run that ended is
never handed out.

Zenoh runs the callbacks here on its own threads: a claim or a liveliness
change is handed to the loop, which alone changes a slot's state; message
callbacks only read the state (one attribute, replaced whole) and queue.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from typing import Any, Dict, List, NamedTuple, Optional, Set, Tuple

from . import attachment
from .bridge import END, TIMED_OUT, Mailbox, ReplyStream, should_yield
from .bridge import undeclare as _undeclare
from .errors import ShuttingDown, StartupError, Undeclared, WrongTopic
from .keys import (
    PairClaim,
    instance_liveliness_selector,
    pair_claim_key,
    pair_claims_of_selector,
    pair_claims_on_selector,
    pairing_topic_key,
    pairing_topic_selector,
    parse_liveliness_key,
    parse_pair_claim_key,
    parse_pairing_topic_key,
)
from .pair_plan import PairEnd, PairPlan
from .producer import ProducerRef
from .spec import PairingSlotSpec, PairingTopicSpec
from .topics import refused

log = logging.getLogger("peppy")


@dataclass(frozen=True)
class PeerInfo:
    """The peer of a pair: its instance (and the launch it runs in) and its
    pairing slot."""

    producer: ProducerRef
    peer_link_id: str


@dataclass(frozen=True)
class ObservedSource:
    """One source an observer watches: its instance and its pairing slot
    (empty until known, when the plan names only the instance)."""

    producer: ProducerRef
    source_link_id: str


class _Pair(NamedTuple):
    """The state a message callback reads: the peer and the pair's generation."""

    core: str
    instance: str
    link_id: str
    generation: int


class _Delivery(NamedTuple):
    generation: int
    who: Any
    payload: bytes


def _zenoh_kind_put(sample: Any) -> bool:
    import zenoh

    return sample.kind == zenoh.SampleKind.PUT


def _on_loop(runner: Any, fn: Any, *args: Any) -> None:
    """Runs `fn(*args)` on the node's loop (from a Zenoh thread)."""
    if runner.session_closed:
        return
    try:
        runner.loop.call_soon_threadsafe(fn, *args)
    except RuntimeError:  # the loop is closed: the node is gone
        pass


class _Undeclare:
    """What the runner undeclares at shutdown for one pairing slot."""

    def __init__(self, slot: Any) -> None:
        self._slot = slot

    def undeclare(self) -> None:
        self._slot.close()


class _Inbox:
    """The queue of one received pairing topic."""

    def __init__(self, runner: Any, spec: PairingTopicSpec) -> None:
        self.spec = spec
        self.mailbox = Mailbox(runner.loop, maxlen=spec.qos.keep_newest)
        runner._track_mailbox(self.mailbox, intake=True)
        self._warned: Set[str] = set()

    def admits(self, sample: Any, who: str) -> bool:
        """Whether the sample carries this topic's format (else dropped, logged once per sender)."""
        att = sample.attachment
        fingerprint = attachment.parse_topic(None if att is None else att.to_bytes())
        if fingerprint == self.spec.format.fingerprint:
            return True
        if who not in self._warned:
            self._warned.add(who)
            log.warning(
                "pairing topic `%s` (slot `%s`): dropping messages from `%s` in another format or "
                "without a peppy attachment",
                self.spec.name,
                self.spec.link_id,
                who,
            )
        return False


class Participant:
    """One participant slot of a running node: its claim, its pair, its
    publishers and its peer's topics."""

    def __init__(self, runner: Any, spec: PairingSlotSpec, plan: PairPlan, topics: List[PairingTopicSpec]) -> None:
        self.runner = runner
        self.spec = spec
        self.target: Optional[PairEnd] = plan.peers[0] if plan.peers else None
        self.vacant = plan.vacant
        self.generation = 0
        self._pair: Optional[_Pair] = None
        self._paired = asyncio.Event()
        self._claims: Set[PairClaim] = set()
        self._target_slots: Set[PairClaim] = set()
        self._ignored: Set[Tuple[str, str]] = set()
        self._ambiguous_logged = False
        self._token: Any = None
        self._claims_sub: Any = None
        self._lookup_sub: Any = None
        self._topic_subs: List[Any] = []
        self._publishers: Dict[str, Any] = {}
        self._inboxes: Dict[str, _Inbox] = {}
        self._closed = False
        # A test harness's mock peer says nothing of its pair's end: the
        # node under test stopping first is how every test ends.
        self.quiet = False
        self._emitted = [t for t in topics if t.emitted]
        self._received = [t for t in topics if not t.emitted]

    # -- set-up and shut-down, on the loop -----------------------------

    def start(self) -> None:
        """Declares the publishers, the claim watch and the claim."""
        r, s = self.runner, self.spec
        for t in self._emitted:
            key = pairing_topic_key(r.namespace, s.pairing, s.tag, t.name, r.core_node, r.instance_id, s.link_id)
            self._publishers[t.name] = r.session.declare_publisher(
                key, congestion_control=t.qos.congestion_control, priority=t.qos.priority, express=t.qos.express
            )
        for t in self._received:
            self._inboxes[t.name] = _Inbox(r, t)
        liveliness = r.session.liveliness()
        self._claims_sub = liveliness.declare_subscriber(
            pair_claims_on_selector(r.namespace, s.pairing, s.tag, s.counterpart, r.instance_id, s.link_id),
            self._claim_callback(self._on_claim),
            history=True,
        )
        if self.target is not None and self.target.link_id is None:
            self._lookup_sub = liveliness.declare_subscriber(
                pair_claims_of_selector(r.namespace, s.pairing, s.tag, s.counterpart, self.target.instance),
                self._claim_callback(self._on_target_slot),
                history=True,
            )
        self._claim(self.target)

    def close(self) -> None:
        """Withdraws everything the slot declared (the node is shutting down)."""
        self._closed = True
        self._pair = None
        for entity in [self._token, self._claims_sub, self._lookup_sub, *self._topic_subs, *self._publishers.values()]:
            _undeclare(entity)
        self._token = self._claims_sub = self._lookup_sub = None
        self._topic_subs = []

    def _claim_callback(self, handler: Any) -> Any:
        runner = self.runner

        def on_token(sample: Any) -> None:
            claim = parse_pair_claim_key(str(sample.key_expr))
            if claim is None:
                log.debug("ignoring a malformed claim token: %s", sample.key_expr)
                return
            _on_loop(runner, handler, _zenoh_kind_put(sample), claim)

        return on_token

    def _claim(self, end: Optional[PairEnd]) -> None:
        """Claims `end` (nobody while its slot is unknown), and listens to its topics."""
        r, s = self.runner, self.spec
        named = end if end is not None and end.link_id is not None else None
        key = pair_claim_key(
            r.namespace,
            s.pairing,
            s.tag,
            s.role,
            r.core_node,
            r.instance_id,
            s.link_id,
            named.instance if named else None,
            named.link_id if named else None,
        )
        old = self._token
        self._token = r.session.liveliness().declare_token(key)
        _undeclare(old)
        for sub in self._topic_subs:
            _undeclare(sub)
        self._topic_subs = []
        if named is None:
            return
        for t in self._received:
            selector = pairing_topic_selector(
                r.namespace, s.pairing, s.tag, t.name, None, named.instance, named.link_id
            )
            self._topic_subs.append(r.session.declare_subscriber(selector, self._intake(self._inboxes[t.name])))

    # -- the pair, on the loop -----------------------------------------

    def _on_claim(self, put: bool, claim: PairClaim) -> None:
        if self._closed:
            return
        if put:
            self._claims.add(claim)
        else:
            self._claims.discard(claim)
        self._update()

    def _on_target_slot(self, put: bool, claim: PairClaim) -> None:
        if self._closed:
            return
        if put:
            self._target_slots.add(claim)
        else:
            self._target_slots.discard(claim)
        self._update()

    def _update(self) -> None:
        pair = self._pair
        if pair is not None:
            if any((c.core, c.instance, c.link_id) == pair[:3] for c in self._claims):
                self._log_ignored(pair)
                return
            self._end_pair()
        target = self.target
        if target is not None and target.link_id is None:
            self._find_target_slot(target)
            target = self.target
        if target is not None and target.link_id is not None:
            for c in sorted(self._claims):
                if (c.instance, c.link_id) == (target.instance, target.link_id):
                    self._begin_pair(c)
                    return
        # Unpaired: a slot claiming this one is adopted (a new peer linked
        # to a survivor).
        others = sorted(self._claims)
        if others:
            c = others[0]
            log.info("pairing slot `%s`: `%s/%s` claims it; pairing with it", self.spec.link_id, c.instance, c.link_id)
            if self._lookup_sub is not None:
                _undeclare(self._lookup_sub)
                self._lookup_sub = None
            self.target = PairEnd(c.instance, c.link_id)
            self._claim(self.target)
            self._begin_pair(c)

    def _find_target_slot(self, target: PairEnd) -> None:
        """The plan named only the peer instance: its slot already claiming
        this one, else its one slot of the counterpart role."""
        claiming = sorted(c for c in self._claims if c.instance == target.instance)
        slots = sorted({c.link_id for c in self._target_slots})
        if claiming:
            link = claiming[0].link_id
        elif len(slots) == 1:
            link = slots[0]
        else:
            if len(slots) > 1 and not self._ambiguous_logged:
                self._ambiguous_logged = True
                log.warning(
                    "pairing slot `%s`: `%s` has several `%s` slots (%s) and none claims this one; "
                    "name one (`--link %s@%s/SLOT`)",
                    self.spec.link_id,
                    target.instance,
                    self.spec.counterpart,
                    ", ".join(slots),
                    self.spec.link_id,
                    target.instance,
                )
            return
        _undeclare(self._lookup_sub)
        self._lookup_sub = None
        self.target = PairEnd(target.instance, link)
        self._claim(self.target)

    def _begin_pair(self, claim: PairClaim) -> None:
        self.generation += 1
        for inbox in self._inboxes.values():
            inbox.mailbox.take_all()
        self._ignored.clear()
        self._pair = _Pair(claim.core, claim.instance, claim.link_id, self.generation)
        self._paired.set()
        log.info("pairing slot `%s`: paired with `%s/%s`", self.spec.link_id, claim.instance, claim.link_id)

    def _end_pair(self) -> None:
        pair = self._pair
        self.generation += 1
        self._pair = None
        self._paired.clear()
        for inbox in self._inboxes.values():
            inbox.mailbox.take_all()
        if pair is not None and not self.runner.is_stopping():
            (log.debug if self.quiet else log.warning)(
                "pairing slot `%s`: `%s/%s` is gone; unpaired (still claiming it)",
                self.spec.link_id,
                pair.instance,
                pair.link_id,
            )

    def _log_ignored(self, pair: _Pair) -> None:
        for c in self._claims:
            who = (c.instance, c.link_id)
            if who != (pair.instance, pair.link_id) and who not in self._ignored:
                self._ignored.add(who)
                log.warning(
                    "pairing slot `%s`: ignoring the claim of `%s/%s`: paired with `%s/%s`",
                    self.spec.link_id,
                    c.instance,
                    c.link_id,
                    pair.instance,
                    pair.link_id,
                )

    # -- what node code calls ------------------------------------------

    def info(self) -> Dict[str, Any]:
        """The slot and its state, as the instance description shows it
        (WIRE §9 `pairings`)."""
        s = self.spec
        out: Dict[str, Any] = {
            "link_id": s.link_id,
            "pairing": {"name": s.pairing, "tag": s.tag},
            "role": s.role,
            "observer": False,
        }
        if self.target is not None:
            out["claiming"] = str(self.target)
        pair = self._pair
        if pair is not None:
            out["peer"] = {"core_node": pair.core, "instance_id": pair.instance, "link_id": pair.link_id}
        return out

    def peer_info(self) -> Optional[PeerInfo]:
        """The peer while the pair holds."""
        pair = self._pair
        return None if pair is None else PeerInfo(ProducerRef(pair.core, pair.instance), pair.link_id)

    async def wait_paired(self) -> PeerInfo:
        """The peer, once the pair holds; `ShuttingDown` when the node stops first."""
        runner = self.runner
        while True:
            info = self.peer_info()
            if info is not None:
                return info
            if runner.is_stopping():
                raise await refused()
            paired = asyncio.ensure_future(self._paired.wait())
            stopped = asyncio.ensure_future(runner.stopped.wait())
            try:
                await asyncio.wait({paired, stopped}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                paired.cancel()
                stopped.cancel()

    async def publish(self, spec: PairingTopicSpec, message: Any) -> None:
        """Sends `message` to the peer while paired; unpaired, sends nothing."""
        payload = spec.format.encode(message)
        if self.runner.session_closed:
            raise await refused()
        try:
            publisher = self._publishers[spec.name]
        except KeyError:
            raise Undeclared(f"pairing topic `{spec.name}` emitted through slot `{spec.link_id}`") from None
        if self._pair is not None:
            publisher.put(payload, attachment=attachment.topic(spec.format.fingerprint))
        if should_yield():
            await asyncio.sleep(0)

    def _intake(self, inbox: _Inbox) -> Any:
        def on_sample(sample: Any) -> None:
            pair = self._pair
            if pair is None:
                return
            sender = parse_pairing_topic_key(str(sample.key_expr))
            if sender is None or (sender.core, sender.instance, sender.link_id) != pair[:3]:
                return
            if not inbox.admits(sample, sender.instance):
                return
            info = PeerInfo(ProducerRef(pair.core, pair.instance), pair.link_id)
            inbox.mailbox.put(_Delivery(pair.generation, info, sample.payload.to_bytes()))

        return on_sample

    async def next(self, spec: PairingTopicSpec) -> Tuple[PeerInfo, Any]:
        """The next message of the current pair; `ShuttingDown` once the node stops."""
        try:
            inbox = self._inboxes[spec.name]
        except KeyError:
            raise Undeclared(f"pairing topic `{spec.name}` received through slot `{spec.link_id}`") from None
        if self.runner.is_stopping():
            raise await refused()
        while True:
            d = await inbox.mailbox.get()
            if d.generation != self.generation:
                continue
            if should_yield():
                await asyncio.sleep(0)
            try:
                return d.who, spec.format.decode(d.payload)
            except ValueError as e:
                log.warning("pairing topic `%s`: dropping a message that does not decode: %s", spec.name, e)


class Observer:
    """One observer slot of a running node: its sources, their runs, and the
    watched role's topics fanned in."""

    def __init__(self, runner: Any, spec: PairingSlotSpec, plan: PairPlan, topics: List[PairingTopicSpec]) -> None:
        self.runner = runner
        self.spec = spec
        self.planned: List[PairEnd] = list(plan.peers)
        self._received = [t for t in topics if not t.emitted]
        # Per source instance: its run (bumped whenever its liveliness token
        # goes or comes back), the cores its token is on, its slot once known.
        self._runs: Dict[str, int] = {p.instance: 0 for p in self.planned}
        self._live: Dict[str, Set[str]] = {p.instance: set() for p in self.planned}
        self._seen: Set[str] = set()
        self._links: Dict[str, str] = {p.instance: p.link_id for p in self.planned if p.link_id}
        self._inboxes: Dict[str, _Inbox] = {}
        self._declared: List[Any] = []
        self._closed = False

    def start(self) -> None:
        """Follows each source's liveliness and subscribes to its topics."""
        r, s = self.runner, self.spec
        for t in self._received:
            self._inboxes[t.name] = _Inbox(r, t)
        liveliness = r.session.liveliness()
        for source in self.planned:
            self._declared.append(
                liveliness.declare_subscriber(
                    instance_liveliness_selector(r.namespace, source.instance), self._live_callback(), history=True
                )
            )
            if source.link_id is None:
                self._declared.append(
                    liveliness.declare_subscriber(
                        pair_claims_of_selector(r.namespace, s.pairing, s.tag, s.role, source.instance),
                        self._claim_callback(),
                        history=True,
                    )
                )
            for t in self._received:
                selector = pairing_topic_selector(
                    r.namespace, s.pairing, s.tag, t.name, None, source.instance, source.link_id
                )
                self._declared.append(r.session.declare_subscriber(selector, self._intake(self._inboxes[t.name])))

    async def learn_sources(self, timeout: float) -> None:
        """Asks once which sources are up, so `sources()` names their
        launches from the start (the liveliness watch follows them after)."""
        r = self.runner
        for source in self.planned:
            stream = ReplyStream(r.loop, r._track_mailbox)
            r.session.liveliness().get(
                instance_liveliness_selector(r.namespace, source.instance), stream.handler(), timeout=timeout
            )
            deadline = r.loop.time() + timeout + 0.5
            try:
                while True:
                    reply = await stream.next(deadline)
                    if reply is END or reply is TIMED_OUT:
                        break
                    who = parse_liveliness_key(reply.key)
                    if who is not None and who[1] == source.instance and who[0] not in self._live[who[1]]:
                        self._on_live(True, *who)
            finally:
                stream.close()

    def close(self) -> None:
        """Withdraws everything the slot declared."""
        self._closed = True
        for entity in self._declared:
            _undeclare(entity)
        self._declared = []

    def _live_callback(self) -> Any:
        runner = self.runner

        def on_token(sample: Any) -> None:
            who = parse_liveliness_key(str(sample.key_expr))
            if who is not None:
                _on_loop(runner, self._on_live, _zenoh_kind_put(sample), *who)

        return on_token

    def _claim_callback(self) -> Any:
        runner = self.runner

        def on_token(sample: Any) -> None:
            claim = parse_pair_claim_key(str(sample.key_expr))
            if claim is not None and _zenoh_kind_put(sample):
                _on_loop(runner, self._links.setdefault, claim.instance, claim.link_id)

        return on_token

    def _on_live(self, put: bool, core: str, instance: str) -> None:
        if self._closed or instance not in self._runs:
            return
        cores = self._live[instance]
        if put:
            if instance in self._seen and core not in cores:
                # A new run: what its previous run left queued is dropped.
                self._runs[instance] += 1
                log.info("observer slot `%s`: source `%s` restarted", self.spec.link_id, instance)
            self._seen.add(instance)
            cores.add(core)
        elif core in cores:
            cores.discard(core)
            self._runs[instance] += 1

    def _intake(self, inbox: _Inbox) -> Any:
        def on_sample(sample: Any) -> None:
            sender = parse_pairing_topic_key(str(sample.key_expr))
            if sender is None or sender.instance not in self._runs:
                return
            if not inbox.admits(sample, sender.instance):
                return
            source = ObservedSource(ProducerRef(sender.core, sender.instance), sender.link_id)
            inbox.mailbox.put(_Delivery(self._runs[sender.instance], source, sample.payload.to_bytes()))

        return on_sample

    def sources(self) -> List[ObservedSource]:
        """The planned sources, in link order (a source's core node is this
        node's until its presence is seen; its slot empty until known)."""
        out = []
        for p in self.planned:
            cores = sorted(self._live.get(p.instance, ()))
            core = cores[0] if cores else self.runner.core_node
            out.append(ObservedSource(ProducerRef(core, p.instance), p.link_id or self._links.get(p.instance, "")))
        return out

    def info(self) -> Dict[str, Any]:
        """The slot and its sources, as the instance description shows them."""
        s = self.spec
        sources = []
        for o in self.sources():
            entry: Dict[str, Any] = {"core_node": o.producer.core_node, "instance_id": o.producer.instance_id}
            if o.source_link_id:
                entry["link_id"] = o.source_link_id
            entry["live"] = bool(self._live.get(o.producer.instance_id))
            sources.append(entry)
        out: Dict[str, Any] = {
            "link_id": s.link_id,
            "pairing": {"name": s.pairing, "tag": s.tag},
            "role": s.role,
            "observer": True,
        }
        if sources:
            out["sources"] = sources
        return out

    async def next(self, spec: PairingTopicSpec) -> Tuple[ObservedSource, Any]:
        """The next message from any source's current run; `ShuttingDown` once the node stops."""
        try:
            inbox = self._inboxes[spec.name]
        except KeyError:
            raise Undeclared(f"pairing topic `{spec.name}` observed through slot `{spec.link_id}`") from None
        if self.runner.is_stopping():
            raise await refused()
        while True:
            d = await inbox.mailbox.get()
            if d.generation != self._runs.get(d.who.producer.instance_id):
                continue
            try:
                return d.who, spec.format.decode(d.payload)
            except ValueError as e:
                log.warning("pairing topic `%s`: dropping a message that does not decode: %s", spec.name, e)


INITIAL_QUERY = 2.0
"""How long start-up waits for an observer's sources already up (seconds)."""


async def declare_pairings(runner: Any, pairs: List[PairPlan]) -> None:
    """Starts every pairing slot of the node (before its liveliness token)."""
    d = runner.descriptor
    plans = {p.link_id: p for p in pairs}
    for spec in d.pairings:
        plan = plans.get(spec.link_id) or PairPlan(spec.link_id)
        topics = [t for t in d.pairing_topics if t.link_id == spec.link_id]
        slot: Any = (Observer if spec.observer else Participant)(runner, spec, plan, topics)
        runner._pairings[spec.link_id] = slot
        runner._declared.append(_Undeclare(slot))
        slot.start()
        if isinstance(slot, Observer):
            await slot.learn_sources(INITIAL_QUERY)


def describe_pairings(runner: Any) -> List[Dict[str, Any]]:
    """Every pairing slot of the node with its state, in the node's order."""
    return [runner._pairings[p.link_id].info() for p in runner.descriptor.pairings if p.link_id in runner._pairings]


def _participant(runner: Any, link_id: str) -> Participant:
    slot = runner._pairings.get(link_id)
    if not isinstance(slot, Participant):
        raise Undeclared(f"pairing slot `{link_id}`")
    return slot


def _observer(runner: Any, link_id: str) -> Observer:
    slot = runner._pairings.get(link_id)
    if not isinstance(slot, Observer):
        raise Undeclared(f"observer slot `{link_id}`")
    return slot


def paired(runner: Any, link_id: str) -> Optional[PeerInfo]:
    """The peer of participant slot `link_id` while the pair holds, else None."""
    return _participant(runner, link_id).peer_info()


async def wait_paired(runner: Any, link_id: str) -> PeerInfo:
    """The peer of participant slot `link_id`, once the pair holds."""
    return await _participant(runner, link_id).wait_paired()


async def publish(runner: Any, spec: PairingTopicSpec, message: Any) -> None:
    """Sends `message` on a pairing topic to the slot's peer; a successful
    no-op while the slot is not paired."""
    await _participant(runner, spec.link_id).publish(spec, message)


async def next_message(runner: Any, spec: PairingTopicSpec) -> Tuple[Any, Any]:
    """The next message of a received pairing topic: `(PeerInfo, message)`
    for a participant, `(ObservedSource, message)` for an observer."""
    slot = runner._pairings.get(spec.link_id)
    if slot is None:
        raise Undeclared(f"pairing slot `{spec.link_id}`")
    return await slot.next(spec)


def sources(runner: Any, link_id: str) -> List[ObservedSource]:
    """The sources observer slot `link_id` watches, in link order."""
    return _observer(runner, link_id).sources()


def source(runner: Any, link_id: str) -> Optional[ObservedSource]:
    """The one source of an observer slot of cardinality `one` or `zero_or_one`."""
    found = sources(runner, link_id)
    return found[0] if found else None


class Payload(bytes):
    """A pairing topic's message, encoded: what generated `build_message`
    returns; it remembers its topic, so a publisher of another refuses it."""

    topic: Optional[PairingTopicSpec] = None


def build_message(spec: PairingTopicSpec, message: Any) -> Payload:
    """`message` encoded for pairing topic `spec`."""
    payload = Payload(spec.format.encode(message))
    payload.topic = spec
    return payload


class PairedPublisher:
    """The publisher of one pairing topic this node's role emits:
    `await publisher.publish(payload)` sends to the peer while paired, and
    succeeds sending nothing while not."""

    def __init__(self, runner: Any, spec: PairingTopicSpec) -> None:
        self._slot = _participant(runner, spec.link_id)
        self._spec = spec
        if spec.name not in self._slot._publishers:
            raise Undeclared(f"pairing topic `{spec.name}` emitted through slot `{spec.link_id}`")

    def __repr__(self) -> str:
        return f"PairedPublisher(slot={self._spec.link_id!r}, topic={self._spec.name!r})"

    async def publish(self, payload: Any) -> None:
        """Sends one message built by this topic's `build_message` (or a
        message object, encoded here)."""
        topic = getattr(payload, "topic", None)
        if isinstance(payload, (bytes, bytearray)) and topic is not None and topic != self._spec:
            raise WrongTopic(self._spec.name, topic.name)
        slot = self._slot
        if slot.runner.session_closed:
            raise await refused()
        data = bytes(payload) if isinstance(payload, (bytes, bytearray)) else self._spec.format.encode(payload)
        if slot._pair is not None:
            slot._publishers[self._spec.name].put(data, attachment=attachment.topic(self._spec.format.fingerprint))
        if should_yield():
            await asyncio.sleep(0)


async def declare_publisher(runner: Any, spec: PairingTopicSpec) -> PairedPublisher:
    """The publisher of pairing topic `spec` (declared when the node started)."""
    return PairedPublisher(runner, spec)


class PairedSubscription:
    """A received pairing topic, held: `await sub.next()` gives `(PeerInfo,
    message)` (a participant) or `(ObservedSource, message)` (an observer),
    or None once the node stops; `async for who, message in sub` reads
    until then."""

    def __init__(self, runner: Any, spec: PairingTopicSpec) -> None:
        slot = runner._pairings.get(spec.link_id)
        if slot is None or spec.name not in slot._inboxes:
            raise Undeclared(f"pairing topic `{spec.name}` received through slot `{spec.link_id}`")
        self._runner = runner
        self._slot = slot
        self._spec = spec

    def __repr__(self) -> str:
        return f"PairedSubscription(slot={self._spec.link_id!r}, topic={self._spec.name!r})"

    async def next(self) -> Optional[Tuple[Any, Any]]:
        """The next message and who sent it; None once the node stops."""
        if self._runner.is_stopping():
            return None
        try:
            return await self._slot.next(self._spec)
        except ShuttingDown:
            return None

    def __aiter__(self) -> "PairedSubscription":
        return self

    async def __anext__(self) -> Tuple[Any, Any]:
        item = await self.next()
        if item is None:
            raise StopAsyncIteration
        return item


async def subscribe(runner: Any, spec: PairingTopicSpec) -> PairedSubscription:
    """Holds received pairing topic `spec` (subscribed when the node started)."""
    return PairedSubscription(runner, spec)


def check_slots(runner: Any) -> None:
    """Every pairing topic names a pairing slot of the node."""
    d = runner.descriptor
    for t in d.pairing_topics:
        if d.pairing(t.link_id) is None:
            raise StartupError(f"pairing topic `{t.name}` names slot `{t.link_id}`, which this node does not declare")


__all__ = [
    "ObservedSource",
    "Observer",
    "PairedPublisher",
    "PairedSubscription",
    "Participant",
    "Payload",
    "PeerInfo",
    "build_message",
    "declare_pairings",
    "declare_publisher",
    "next_message",
    "paired",
    "publish",
    "source",
    "sources",
    "subscribe",
    "wait_paired",
]
