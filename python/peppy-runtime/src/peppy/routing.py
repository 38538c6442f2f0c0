"""Slots: what fills each one (its binding) and which producers' messages
it keeps (its route filter). Both are decided by peppy-schema's binding
engine (`assign` in peppy-schema/src/binding.rs), in the launcher or in
`peppy-launch plan` for a node started by hand; a Python node reads its
plan and applies it (`slot_from_json`, `fit_plan`), never binding again."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, FrozenSet, List, Optional, Sequence, Tuple

from .errors import StartupError
from .spec import SlotSpec

PINNED = "pinned"
FROM_ANY_BOUND = "from_any_bound"
FROM_ANY_UNBOUND = "from_any_unbound"
SET = "set"


@dataclass(frozen=True)
class SlotBinding:
    """What fills one slot: a pinned producer, listed producers, or none;
    `set` is a slot of `node/v1`'s cardinality, with exactly its producers
    (none when it is empty, `vacant` saying why when it was vacated)."""

    kind: str
    producers: Tuple[str, ...] = ()
    vacant: Optional[str] = None

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
        allowed = {
            PINNED: {"kind", "producer"},
            FROM_ANY_BOUND: {"kind", "producers"},
            FROM_ANY_UNBOUND: {"kind"},
            SET: {"kind", "producers", "vacant"},
        }
        if kind not in allowed:
            raise StartupError(
                f"binding `{link_id}` has kind {kind!r}; expected pinned, from_any_bound, from_any_unbound or set"
            )
        extra = set(data) - allowed[kind]
        if extra:
            raise StartupError(f"binding `{link_id}` has unknown field(s) {sorted(extra)}")
        if kind == PINNED:
            producer = data.get("producer")
            if not isinstance(producer, str):
                raise StartupError(f"binding `{link_id}` (pinned) needs a `producer` string")
            return cls.pinned(producer)
        if kind in (FROM_ANY_BOUND, SET):
            producers = data.get("producers")
            if not isinstance(producers, list) or not all(isinstance(p, str) for p in producers):
                raise StartupError(f"binding `{link_id}` ({kind}) needs a `producers` list of strings")
            vacant = data.get("vacant")
            if vacant is not None and not isinstance(vacant, str):
                raise StartupError(f"binding `{link_id}` (set) has a `vacant` that is not a string")
            return cls(kind, tuple(producers), vacant)
        return cls(FROM_ANY_UNBOUND)

    def to_json(self) -> Dict[str, Any]:
        """The binding as instance descriptions and runtime configs show it."""
        if self.kind == PINNED:
            return {"kind": PINNED, "producer": self.producers[0]}
        if self.kind == FROM_ANY_BOUND:
            return {"kind": FROM_ANY_BOUND, "producers": list(self.producers)}
        if self.kind == SET:
            out: Dict[str, Any] = {"kind": SET, "producers": list(self.producers)}
            if self.vacant is not None:
                out["vacant"] = self.vacant
            return out
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

    @classmethod
    def from_json(cls, data: Any, link_id: str) -> "RouteFilter":
        """A filter as serde writes `peppy_schema::RouteFilter`."""
        if not isinstance(data, dict) or data.get("kind") not in ("any", "pin", "only_from", "any_except"):
            raise StartupError(f"slot `{link_id}`: `filter` must be an object with kind any, pin, only_from or any_except")
        kind = data["kind"]
        extra = set(data) - ({"kind"} if kind == "any" else {"kind", "producers"})
        if extra:
            raise StartupError(f"slot `{link_id}`: `filter` has unknown field(s) {sorted(extra)}")
        producers = data.get("producers")
        if kind == "any":
            return ANY
        if kind == "pin":
            if not isinstance(producers, str):
                raise StartupError(f"slot `{link_id}`: a `pin` filter names one producer (a string)")
            return cls("pin", frozenset((producers,)))
        if not isinstance(producers, list) or not all(isinstance(p, str) for p in producers):
            raise StartupError(f"slot `{link_id}`: an `{kind}` filter lists its producers (strings)")
        return cls(kind, frozenset(producers))

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


_SLOT_FIELDS = ("link_id", "kind", "target", "binding", "filter")


def slot_from_json(data: Any) -> SlotPlan:
    """One slot of a plan, as serde writes `peppy_schema::SlotPlan`."""
    if not isinstance(data, dict):
        raise StartupError("every entry of `slots` must be an object")
    link_id = data.get("link_id")
    if not isinstance(link_id, str):
        raise StartupError("every entry of `slots` needs a `link_id` string")
    extra = [k for k in data if k not in _SLOT_FIELDS]
    missing = [k for k in _SLOT_FIELDS if k not in data]
    if extra or missing:
        raise StartupError(f"slot `{link_id}`: expected the fields {', '.join(_SLOT_FIELDS)}")
    target = data["target"]
    if (
        not isinstance(target, dict)
        or set(target) != {"name", "tag"}
        or not all(isinstance(v, str) for v in target.values())
    ):
        raise StartupError(f"slot `{link_id}`: `target` must be {{ name, tag }}")
    if data["kind"] not in ("node", "interface"):
        raise StartupError(f"slot `{link_id}`: `kind` must be node or interface")
    return SlotPlan(
        link_id,
        data["kind"],
        target["name"],
        target["tag"],
        SlotBinding.from_json(data["binding"], link_id),
        RouteFilter.from_json(data["filter"], link_id),
    )


def fit_plan(slots: Sequence[SlotPlan], declared: Sequence[SlotSpec]) -> List[SlotPlan]:
    """`slots` in `depends_on` order, once they are exactly the declared
    slots (link_ids, kinds, targets; a pinned slot pinned, a from_any slot
    not), as peppy-schema's `fit_plan` checks. Bindings and filters are
    taken as the plan gives them. A mismatch means this package was
    generated from other documents than the launcher read."""
    by_id: Dict[str, SlotPlan] = {}
    declared_ids = {d.link_id for d in declared}
    for slot in slots:
        if slot.link_id not in declared_ids:
            raise _mismatch(f"the plan fills slot `{slot.link_id}`, which this node does not declare")
        if slot.link_id in by_id:
            raise _mismatch(f"the plan fills slot `{slot.link_id}` twice")
        by_id[slot.link_id] = slot
    ordered: List[SlotPlan] = []
    for d in declared:
        slot = by_id.get(d.link_id)
        if slot is None:
            raise _mismatch(f"the plan leaves slot `{d.link_id}` out")
        if (slot.kind, slot.name, slot.tag) != (d.kind, d.name, d.tag):
            raise _mismatch(
                f"the plan's slot `{d.link_id}` wants {slot.kind} `{slot.name}:{slot.tag}`, "
                f"this node's wants {d.kind} `{d.name}:{d.tag}`"
            )
        if not _binding_fits(slot.binding, d):
            what = {PINNED: "pinned", SET: "a set of producers"}.get(slot.binding.kind, "from_any")
            raise _mismatch(f"the plan binds slot `{d.link_id}` as {what}, which its declaration does not allow")
        ordered.append(slot)
    return ordered


def _binding_fits(binding: SlotBinding, d: SlotSpec) -> bool:
    """As peppy-schema's `fit_plan`: pinned for a `one` slot, from_any for a
    from_any slot, a set within its cardinality for `node/v1`'s slots."""
    if binding.kind == PINNED:
        return not d.from_any and d.cardinality == "one"
    if binding.kind in (FROM_ANY_BOUND, FROM_ANY_UNBOUND):
        return d.from_any
    n = len(binding.producers)
    return (
        not d.from_any
        and d.cardinality != "one"
        and (d.cardinality not in ("one", "zero_or_one") or n <= 1)
        and (d.cardinality != "one_or_more" or n > 0)
        and (binding.vacant is None or d.cardinality == "zero_or_one")
    )


def _mismatch(why: str) -> StartupError:
    return StartupError(
        f"the runtime config does not fit this node: {why}; "
        "was its peppygen generated from another peppy.json5 than the launcher read?"
    )
