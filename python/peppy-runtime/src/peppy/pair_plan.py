"""What each pairing slot of an instance starts with (`peppy_schema::PairPlan`,
the `pairs` of a plan): the peer a participant is linked with, or the
sources an observer watches. The launcher or `peppy-launch plan` decided
them; a Python node reads them (`pair_plan_from_json`) and lays them out over its
slots (`fit_pair_plans`), never linking or checking them again."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .errors import StartupError
from .spec import PairingSlotSpec


@dataclass(frozen=True)
class PairEnd:
    """One end of a pair, or an observed source: an instance and its pairing
    slot; `link_id` None when the plan names only the instance (its one slot
    of the right pairing and role is found on the wire)."""

    instance: str
    link_id: Optional[str] = None

    def __str__(self) -> str:
        return self.instance if self.link_id is None else f"{self.instance}/{self.link_id}"

    def to_json(self) -> Dict[str, Any]:
        """As serde writes `peppy_schema::PairEnd`."""
        out: Dict[str, Any] = {"instance": self.instance}
        if self.link_id is not None:
            out["link_id"] = self.link_id
        return out


@dataclass(frozen=True)
class PairPlan:
    """One pairing slot as it starts: a participant's peer (at most one), an
    observer's sources (in link order); `vacant` says why an optional slot
    is left empty on purpose."""

    link_id: str
    peers: Tuple[PairEnd, ...] = ()
    vacant: Optional[str] = None

    def to_json(self) -> Dict[str, Any]:
        """As serde writes `peppy_schema::PairPlan`."""
        out: Dict[str, Any] = {"link_id": self.link_id}
        if self.peers:
            out["peers"] = [p.to_json() for p in self.peers]
        if self.vacant is not None:
            out["vacant"] = self.vacant
        return out


def _end_from_json(data: Any, link_id: str) -> PairEnd:
    if not isinstance(data, dict) or not isinstance(data.get("instance"), str) or set(data) - {"instance", "link_id"}:
        raise StartupError(f"pairing slot `{link_id}`: every peer is {{ instance, link_id? }}")
    peer_link = data.get("link_id")
    if peer_link is not None and not isinstance(peer_link, str):
        raise StartupError(f"pairing slot `{link_id}`: a peer's `link_id` must be a string")
    return PairEnd(data["instance"], peer_link)


def pair_plan_from_json(data: Any) -> PairPlan:
    """One entry of a plan's `pairs`."""
    if not isinstance(data, dict) or not isinstance(data.get("link_id"), str):
        raise StartupError("every entry of `pairs` is an object with a `link_id` string")
    link_id = data["link_id"]
    extra = set(data) - {"link_id", "peers", "vacant"}
    if extra:
        raise StartupError(f"pairing slot `{link_id}`: unknown field(s) {sorted(extra)}")
    peers = data.get("peers", [])
    if not isinstance(peers, list):
        raise StartupError(f"pairing slot `{link_id}`: `peers` must be a list")
    vacant = data.get("vacant")
    if vacant is not None and not isinstance(vacant, str):
        raise StartupError(f"pairing slot `{link_id}`: `vacant` must be a string")
    return PairPlan(link_id, tuple(_end_from_json(p, link_id) for p in peers), vacant)


def fit_pair_plans(plans: Sequence[PairPlan], declared: Sequence[PairingSlotSpec]) -> List[PairPlan]:
    """`plans` in the node's pairing-slot order, one per slot, a slot the
    plan leaves out filled in empty (no peer, not vacant: a participant
    waits for one), as peppy-schema's `fit_pair_plans` fills them. What a
    plan holds (peers, sources, vacancy) the launcher already checked
    against the slots; this only checks that the plan is for this node's
    slots: each one it fills is declared, and filled once."""
    by_id: Dict[str, PairPlan] = {}
    declared_ids = {d.link_id for d in declared}
    for plan in plans:
        if plan.link_id not in declared_ids:
            raise _mismatch(f"the plan fills pairing slot `{plan.link_id}`, which this node does not declare")
        if plan.link_id in by_id:
            raise _mismatch(f"the plan fills pairing slot `{plan.link_id}` twice")
        by_id[plan.link_id] = plan
    return [by_id.get(d.link_id) or PairPlan(d.link_id) for d in declared]


def _mismatch(why: str) -> StartupError:
    return StartupError(
        f"the runtime config does not fit this node: {why}; "
        "was its peppygen generated from another peppy.json5 than the launcher read?"
    )
