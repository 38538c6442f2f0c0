"""Slots: what fills each one (its binding) and which producers' messages
it keeps (its route filter), as peppy-schema's binding engine decides them
(`assign` and `compute_filters` in peppy-schema/src/binding.rs)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, FrozenSet, List, Optional, Sequence, Tuple

from .errors import StartupError
from .spec import SlotSpec

PINNED = "pinned"
FROM_ANY_BOUND = "from_any_bound"
FROM_ANY_UNBOUND = "from_any_unbound"


@dataclass(frozen=True)
class SlotBinding:
    """What fills one slot: a pinned producer, listed producers, or none."""

    kind: str
    producers: Tuple[str, ...] = ()

    @classmethod
    def pinned(cls, producer: str) -> "SlotBinding":
        """A pinned slot bound to one producer."""
        return cls(PINNED, (producer,))

    @classmethod
    def from_json(cls, data: Any, link_id: str) -> "SlotBinding":
        """A binding as the launcher's runtime config writes it."""
        if not isinstance(data, dict):
            raise StartupError(f"binding `{link_id}` must be an object with a `kind`")
        kind = data.get("kind")
        allowed = {PINNED: {"kind", "producer"}, FROM_ANY_BOUND: {"kind", "producers"}, FROM_ANY_UNBOUND: {"kind"}}
        if kind not in allowed:
            raise StartupError(
                f"binding `{link_id}` has kind {kind!r}; expected pinned, from_any_bound or from_any_unbound"
            )
        extra = set(data) - allowed[kind]
        if extra:
            raise StartupError(f"binding `{link_id}` has unknown field(s) {sorted(extra)}")
        if kind == PINNED:
            producer = data.get("producer")
            if not isinstance(producer, str):
                raise StartupError(f"binding `{link_id}` (pinned) needs a `producer` string")
            return cls.pinned(producer)
        if kind == FROM_ANY_BOUND:
            producers = data.get("producers")
            if not isinstance(producers, list) or not all(isinstance(p, str) for p in producers):
                raise StartupError(f"binding `{link_id}` (from_any_bound) needs a `producers` list of strings")
            return cls(FROM_ANY_BOUND, tuple(producers))
        return cls(FROM_ANY_UNBOUND)

    def to_json(self) -> Dict[str, Any]:
        """The binding as instance descriptions and runtime configs show it."""
        if self.kind == PINNED:
            return {"kind": PINNED, "producer": self.producers[0]}
        if self.kind == FROM_ANY_BOUND:
            return {"kind": FROM_ANY_BOUND, "producers": list(self.producers)}
        return {"kind": FROM_ANY_UNBOUND}


@dataclass(frozen=True)
class RouteFilter:
    """Which producers' messages a consumer keeps for one slot:
    `pin` (one), `only_from` (these), `any_except` (all but these), `any`."""

    kind: str
    producers: FrozenSet[str] = frozenset()

    def accepts(self, producer: str) -> bool:
        """Whether a message from `producer` (already of the slot's kind) passes."""
        if self.kind == "any":
            return True
        if self.kind == "any_except":
            return producer not in self.producers
        return producer in self.producers

    @property
    def pinned(self) -> Optional[str]:
        """The one producer of a `pin` filter."""
        return next(iter(self.producers)) if self.kind == "pin" else None

    def to_json(self) -> Dict[str, Any]:
        """As serde writes `peppy_schema::RouteFilter` (sets sorted)."""
        if self.kind == "any":
            return {"kind": "any"}
        if self.kind == "pin":
            return {"kind": "pin", "producers": self.pinned}
        return {"kind": self.kind, "producers": sorted(self.producers)}


ANY = RouteFilter("any")


@dataclass(frozen=True)
class SlotPlan:
    """One slot of this instance, filled: its binding and route filter."""

    link_id: str
    kind: str
    name: str
    tag: str
    binding: SlotBinding
    filter: RouteFilter

    def to_json(self) -> Dict[str, Any]:
        """As instance descriptions show it (WIRE §9 `slots`)."""
        return {
            "link_id": self.link_id,
            "kind": self.kind,
            "target": {"name": self.name, "tag": self.tag},
            "binding": self.binding.to_json(),
            "filter": self.filter.to_json(),
        }


def _describe(slot: SlotSpec) -> str:
    return f"{slot.kind} `{slot.name}:{slot.tag}`"


def assign(consumer: str, slots: Sequence[SlotSpec], binds: Sequence[Tuple[str, str]]) -> List[SlotPlan]:
    """Fills `slots` from `(link_id, producer)` binds in order, then computes
    each slot's filter. A from_any slot collects its producers; a pinned slot
    takes exactly one. Every refusal is reported at once, each with its help."""
    pinned: Dict[str, str] = {}
    producers: Dict[str, List[str]] = {s.link_id: [] for s in slots}
    errors: List[str] = []
    by_id = {s.link_id: s for s in slots}
    for key, instance in binds:
        slot = by_id.get(key)
        if slot is None:
            declared = ", ".join(f"`{s.link_id}` ({_describe(s)}{', from_any' if s.from_any else ''})" for s in slots)
            errors.append(
                f"binding `{key}` on instance `{consumer}` matches no slot (DeadBindingKey)\n"
                f"    help: {'slots: ' + declared if declared else 'this node declares no slots; remove the binding'}"
            )
        elif slot.from_any:
            producers[key].append(instance)
        elif key in pinned:
            errors.append(
                f"instance `{consumer}`: pinned slot `{key}` is bound twice, to `{pinned[key]}` and `{instance}`"
                f" (DuplicateBindingKey)\n    help: a pinned slot takes one producer; pass --bind {key}@... once"
            )
        else:
            pinned[key] = instance
    plans: List[SlotPlan] = []
    for s in slots:
        if s.from_any:
            got = producers[s.link_id]
            binding = SlotBinding(FROM_ANY_BOUND, tuple(got)) if got else SlotBinding(FROM_ANY_UNBOUND)
        elif s.link_id in pinned:
            binding = SlotBinding.pinned(pinned[s.link_id])
        else:
            errors.append(
                f"instance `{consumer}`: pinned slot `{s.link_id}` ({_describe(s)}) is unbound (PinnedSlotUnbound)\n"
                f"    help: pass --bind {s.link_id}@<producer instance id>"
            )
            continue
        plans.append(SlotPlan(s.link_id, s.kind, s.name, s.tag, binding, ANY))
    if errors:
        raise StartupError("invalid bindings:" + "".join(f"\n  - {e}" for e in errors))
    return compute_filters(plans)


def compute_filters(slots: Sequence[SlotPlan]) -> List[SlotPlan]:
    """Per slot: pinned -> that producer; from_any bound -> the listed
    producers minus those pinned by a sibling; from_any unbound -> any except
    producers claimed by siblings. Siblings are the other slots of the same
    kind and `name:tag`."""
    out: List[SlotPlan] = []
    for slot in slots:
        siblings = [
            s
            for s in slots
            if s.kind == slot.kind and (s.name, s.tag) == (slot.name, slot.tag) and s.link_id != slot.link_id
        ]
        b = slot.binding
        if b.kind == PINNED:
            f = RouteFilter("pin", frozenset(b.producers))
        elif b.kind == FROM_ANY_BOUND:
            pinned_elsewhere = {s.binding.producers[0] for s in siblings if s.binding.kind == PINNED}
            f = RouteFilter("only_from", frozenset(p for p in b.producers if p not in pinned_elsewhere))
        else:
            claimed = frozenset(p for s in siblings for p in s.binding.producers)
            f = RouteFilter("any_except", claimed) if claimed else ANY
        out.append(SlotPlan(slot.link_id, slot.kind, slot.name, slot.tag, slot.binding, f))
    return out
