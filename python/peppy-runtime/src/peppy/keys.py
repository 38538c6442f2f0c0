"""Key expressions of docs/WIRE.md §1: where every entry, token and
queryable of a node lives."""

from __future__ import annotations

from typing import NamedTuple, Optional, Tuple

# Unicode's White_Space, which Rust's `char::is_whitespace` reads:
# `str.isspace` also counts U+001C to U+001F, which the Rust runtime takes
# in a segment.
_WHITESPACE = (
    "\t\n\x0b\x0c\r \x85\xa0\u1680"
    "\u2000\u2001\u2002\u2003\u2004\u2005\u2006\u2007\u2008\u2009\u200a"
    "\u2028\u2029\u202f\u205f\u3000"
)
_FORBIDDEN = frozenset("/*$#?@" + _WHITESPACE)

TOPIC = "topic"
SERVICE = "service"
ACTION = "action"


def is_segment(s: str) -> bool:
    """Whether `s` can be one key segment: non-empty, no `/`, no Zenoh
    special character, no whitespace."""
    return bool(s) and not any(c in _FORBIDDEN for c in s)


def owner_segments(kind: str, name: str, tag: str) -> str:
    """`<kind>/<name>/<tag>`: the owner part of an entry's key."""
    return f"{kind}/{name}/{tag}"


def entry_key(ns: str, channel: str, owner: str, entry: str, core: str, instance: str) -> str:
    """The key one producer instance publishes on (or serves) for an entry;
    `owner` is `<kind>/<name>/<tag>`."""
    return f"peppy/{ns}/{channel}/{owner}/{entry}/{core}/{instance}"


def entry_selector(
    ns: str,
    channel: str,
    owner: Optional[str],
    entry: str,
    core: Optional[str] = None,
    instance: Optional[str] = None,
) -> str:
    """A selector over producers: a `None` part matches any value."""
    return f"peppy/{ns}/{channel}/{owner or '*/*/*'}/{entry}/{core or '*'}/{instance or '*'}"


def action_part_key(action: str, part: str) -> str:
    """`<action key or selector>/<goal|cancel|result>`."""
    return f"{action}/{part}"


def feedback_key(action: str, goal_id: str) -> str:
    """`<action key or selector>/feedback/<goal_id>`."""
    return f"{action}/feedback/{goal_id}"


def format_key(ns: str, fingerprint: int, instance: str) -> str:
    """Where an instance answers the canonical text of a format it emits."""
    return f"peppy/{ns}/format/{fingerprint:016x}/{instance}"


def liveliness_key(ns: str, core: str, instance: str, node: str, tag: str) -> str:
    """The token an instance holds while it is up."""
    return f"peppy/{ns}/live/{core}/{instance}/{node}/{tag}"


def liveliness_selector(ns: str, node: str, tag: str) -> str:
    """The tokens of every instance of node `node:tag`."""
    return f"peppy/{ns}/live/*/*/{node}/{tag}"


def describe_key(ns: str, core: str, instance: str) -> str:
    """Where an instance answers its description (WIRE §9)."""
    return f"peppy/{ns}/describe/{core}/{instance}"


CLOCK_WALL = "wall"
CLOCK_SIM = "sim"


def clock_tick_key(ns: str, source: str) -> str:
    """`peppy/<ns>/clock/tick/<wall|sim>`: where a launch publishes its wall
    ticks, or a simulator its sim ticks (8 bytes, u64 LE ns)."""
    return f"peppy/{ns}/clock/tick/{source}"


def clock_sync_key(ns: str) -> str:
    """`peppy/<ns>/clock/sync`: the launcher's clock synchronization queryable."""
    return f"peppy/{ns}/clock/sync"


def parse_liveliness_key(key: str) -> Optional[Tuple[str, str]]:
    """`(core, instance)` of a liveliness token's key."""
    parts = key.split("/")
    if len(parts) < 5 or parts[0] != "peppy" or parts[2] != "live":
        return None
    core, instance = parts[3], parts[4]
    return (core, instance) if is_segment(core) and is_segment(instance) else None


class Sender(NamedTuple):
    """The identity at the end of an entry key."""

    kind: str
    name: str
    tag: str
    entry: str
    core: str
    instance: str


def parse_entry_key(key: str) -> Optional[Sender]:
    """Parses `peppy/<ns>/<channel>/<kind>/<name>/<tag>/<entry>/<core>/<instance>[/...]`."""
    parts = key.split("/", 9)
    if len(parts) < 9 or parts[0] != "peppy" or parts[3] not in ("node", "interface"):
        return None
    s = Sender(parts[3], parts[4], parts[5], parts[6], parts[7], parts[8])
    return s if is_segment(s.core) and is_segment(s.instance) else None


# Pairings (docs/PAIRINGS.md §3): a pairing topic is published under its
# sender's instance and pairing slot; each participant slot holds a claim
# token naming the peer it pairs with, `~/~` while it names nobody.
PAIRING = "pairing"
PAIR = "pair"
NOBODY = "~"


def pairing_topic_key(ns: str, pairing: str, tag: str, topic: str, core: str, instance: str, link_id: str) -> str:
    """`peppy/<ns>/topic/pairing/<pairing>/<tag>/<topic>/<core>/<instance>/<link_id>`:
    where slot `link_id` of an instance publishes a pairing topic."""
    return f"peppy/{ns}/{TOPIC}/{PAIRING}/{pairing}/{tag}/{topic}/{core}/{instance}/{link_id}"


def pairing_topic_selector(
    ns: str,
    pairing: str,
    tag: str,
    topic: str,
    core: Optional[str],
    instance: Optional[str],
    link_id: Optional[str],
) -> str:
    """A selector over a pairing topic's senders (a paired slot pins its
    peer's instance and slot, on any core); a `None` part matches any value."""
    return pairing_topic_key(ns, pairing, tag, topic, core or "*", instance or "*", link_id or "*")


def pair_claim_key(
    ns: str,
    pairing: str,
    tag: str,
    role: str,
    core: str,
    instance: str,
    link_id: str,
    peer_instance: Optional[str],
    peer_link_id: Optional[str],
) -> str:
    """The claim token of participant slot `instance/link_id` (role `role`),
    naming the peer slot it pairs with; `~/~` when it names none."""
    peer = f"{peer_instance or NOBODY}/{peer_link_id or NOBODY}"
    return f"peppy/{ns}/{PAIR}/{pairing}/{tag}/{role}/{core}/{instance}/{link_id}/{peer}"


def claim_selector(ns: str, pairing: str, tag: str) -> str:
    """Every claim of one pairing, whoever makes it."""
    return f"peppy/{ns}/{PAIR}/{pairing}/{tag}/*/*/*/*/*/*"


def pair_claims_on_selector(ns: str, pairing: str, tag: str, role: str, instance: str, link_id: str) -> str:
    """Every claim of a slot of role `role` on slot `instance/link_id`."""
    return f"peppy/{ns}/{PAIR}/{pairing}/{tag}/{role}/*/*/*/{instance}/{link_id}"


def pair_claims_of_selector(ns: str, pairing: str, tag: str, role: str, instance: str) -> str:
    """The claims of every slot of role `role` of instance `instance`."""
    return f"peppy/{ns}/{PAIR}/{pairing}/{tag}/{role}/*/{instance}/*/*/*"


def instance_liveliness_selector(ns: str, instance: str) -> str:
    """The liveliness token of instance `instance`, on any core."""
    return f"peppy/{ns}/live/*/{instance}/*/*"


class PairClaim(NamedTuple):
    """What a claim token says: who claims (`core`, `instance`, `link_id`,
    in `role` of `pairing:tag`) and which slot it names (`None` for `~`)."""

    pairing: str
    tag: str
    role: str
    core: str
    instance: str
    link_id: str
    peer_instance: Optional[str]
    peer_link_id: Optional[str]


def parse_pair_claim_key(key: str) -> Optional[PairClaim]:
    """Parses a claim token's key; None when it is not one."""
    parts = key.split("/")
    if len(parts) != 11 or parts[0] != "peppy" or parts[2] != PAIR:
        return None
    pairing, tag, role, core, instance, link_id, peer_instance, peer_link_id = parts[3:]
    if not all(is_segment(s) for s in parts[3:]):
        return None
    if (peer_instance == NOBODY) != (peer_link_id == NOBODY):
        return None
    return PairClaim(
        pairing,
        tag,
        role,
        core,
        instance,
        link_id,
        None if peer_instance == NOBODY else peer_instance,
        None if peer_link_id == NOBODY else peer_link_id,
    )


class PairingSender(NamedTuple):
    """The identity at the end of a pairing topic's key."""

    pairing: str
    tag: str
    topic: str
    core: str
    instance: str
    link_id: str


def parse_pairing_topic_key(key: str) -> Optional[PairingSender]:
    """Parses `peppy/<ns>/topic/pairing/<pairing>/<tag>/<topic>/<core>/<instance>/<link_id>`."""
    parts = key.split("/")
    if len(parts) != 10 or parts[0] != "peppy" or parts[2] != TOPIC or parts[3] != PAIRING:
        return None
    s = PairingSender(*parts[4:])
    return s if all(is_segment(p) for p in s) else None


def core_function_key(ns: str, core: str, function: str) -> str:
    """`peppy/<ns>/stack/<core>/<function>`: where core node `core` answers
    its nodes' calls of `function` (`datastore`, `info`, `list`)."""
    return f"peppy/{ns}/stack/{core}/{function}"
