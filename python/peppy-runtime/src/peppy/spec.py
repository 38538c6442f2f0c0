"""What generated code tells the runtime about a node: its entries, slots
and parameters, as plain frozen values."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Optional, Tuple

from .formats import Format
from .keys import owner_segments


@dataclass(frozen=True)
class Owner:
    """Whose contract an entry belongs to: this node (`own`), another node,
    an interface, or anyone (`any`, external consumed topics)."""

    kind: str
    name: Optional[str] = None
    tag: Optional[str] = None

    @classmethod
    def own(cls) -> "Owner":
        """This node's own declaration (name and tag filled in at run time)."""
        return cls("own")

    @classmethod
    def node(cls, name: str, tag: str) -> "Owner":
        """Another node's declaration (a node slot's producer)."""
        return cls("node", name, tag)

    @classmethod
    def interface(cls, name: str, tag: str) -> "Owner":
        """An interface's entry."""
        return cls("interface", name, tag)

    @classmethod
    def any(cls) -> "Owner":
        """Any owner (external consumed topics)."""
        return cls("any")

    def resolve(self, node_name: str, node_tag: str) -> Optional[Tuple[str, str, str]]:
        """`(kind, name, tag)` of the owner on the wire; None for `any`."""
        if self.kind == "own":
            return ("node", node_name, node_tag)
        if self.kind in ("node", "interface"):
            return (self.kind, self.name or "", self.tag or "")
        return None

    def segments(self, node_name: str, node_tag: str) -> Optional[str]:
        """`<kind>/<name>/<tag>` for keys; None for `any`."""
        r = self.resolve(node_name, node_tag)
        return None if r is None else owner_segments(*r)


class QoSProfile(enum.Enum):
    """How a topic's messages travel (docs/WIRE.md §7)."""

    SENSOR_DATA = "sensor_data"
    STANDARD = "standard"
    RELIABLE = "reliable"
    CRITICAL = "critical"
    # The peppylib API spells them so (`QoSProfile.Standard`): the same members.
    SensorData = "sensor_data"
    Standard = "standard"
    Reliable = "reliable"
    Critical = "critical"

    @property
    def congestion_control(self) -> Any:
        """Zenoh's congestion control: drop for bulk data, block for control."""
        import zenoh

        if self in (QoSProfile.SENSOR_DATA, QoSProfile.STANDARD):
            return zenoh.CongestionControl.DROP
        return zenoh.CongestionControl.BLOCK

    @property
    def priority(self) -> Any:
        """Zenoh's priority, so bulk data and control traffic do not starve each other."""
        import zenoh

        return {
            QoSProfile.SENSOR_DATA: zenoh.Priority.DATA_LOW,
            QoSProfile.STANDARD: zenoh.Priority.DATA,
            QoSProfile.RELIABLE: zenoh.Priority.DATA_HIGH,
            QoSProfile.CRITICAL: zenoh.Priority.REAL_TIME,
        }[self]

    @property
    def express(self) -> bool:
        """Whether Zenoh sends without batching."""
        return self in (QoSProfile.SENSOR_DATA, QoSProfile.CRITICAL)

    @property
    def keep_newest(self) -> Optional[int]:
        """The consumer queue's size for drop profiles (oldest dropped);
        None when every message is kept."""
        return {QoSProfile.SENSOR_DATA: 5, QoSProfile.STANDARD: 10}.get(self)


@dataclass(frozen=True)
class TopicSpec:
    """A topic this node emits."""

    owner: Owner
    name: str
    qos: QoSProfile
    format: Format


@dataclass(frozen=True)
class ConsumedTopicSpec:
    """A topic this node consumes; `link_id` None for an external topic."""

    link_id: Optional[str]
    owner: Owner
    name: str
    qos: QoSProfile
    format: Format


@dataclass(frozen=True)
class ServiceSpec:
    """A service this node exposes."""

    owner: Owner
    name: str
    request: Format
    response: Format


@dataclass(frozen=True)
class ConsumedServiceSpec:
    """A service this node calls through a slot."""

    link_id: str
    owner: Owner
    name: str
    request: Format
    response: Format


@dataclass(frozen=True)
class ActionSpec:
    """An action this node exposes. `goal_response`: the goal response it
    declares (`node/v1`), sent with each decision; None for none."""

    owner: Owner
    name: str
    goal: Format
    feedback: Format
    result: Format
    goal_response: Optional[Format] = None


@dataclass(frozen=True)
class ConsumedActionSpec:
    """An action this node calls through a slot."""

    link_id: str
    owner: Owner
    name: str
    goal: Format
    feedback: Format
    result: Format
    goal_response: Optional[Format] = None


@dataclass(frozen=True)
class SlotSpec:
    """One `depends_on` entry: a slot named by its link_id, taking instances
    of node (`kind` "node") or interface (`kind` "interface") `name:tag`;
    `from_any` slots take any number of producers and free-form keys;
    others as many as their `cardinality` (`one`, `zero_or_one`,
    `one_or_more`, `zero_or_more`) says."""

    link_id: str
    kind: str
    name: str
    tag: str
    from_any: bool = False
    cardinality: str = "one"


@dataclass(frozen=True)
class PairingSlotSpec:
    """One pairing slot (docs/PAIRINGS.md): a participant playing `role` of
    pairing `pairing:tag` with a peer playing `counterpart`, or an observer
    (`observer`) watching `role`'s topics of `cardinality` sources."""

    link_id: str
    pairing: str
    tag: str
    role: str
    counterpart: str
    observer: bool = False
    optional: bool = False
    cardinality: str = "one"


@dataclass(frozen=True)
class PairingTopicSpec:
    """A topic of a pairing, through one pairing slot: `emitted` when this
    node's role sends it (a participant), else one it receives (from its
    peer, or from an observed source)."""

    link_id: str
    pairing: str
    tag: str
    name: str
    qos: QoSProfile
    format: Format
    emitted: bool = False


@dataclass(frozen=True)
class NodeDescriptor:
    """Everything the runtime sets up before the node's code runs.

    `parameters` is the generated Parameters class (`from_json(dict)`), or
    None for a node whose parameters stay plain JSON; `document` is the
    node document's path, for messages; `model` is the node's model as JSON
    (`peppy_schema::NodeModel`, what a Rust binary embeds), which a node
    started by hand hands `peppy-launch plan`. `pairings` are its pairing
    slots and `pairing_topics` the topics it sends or receives through them.
    `engine` is the `peppy-launch` that wrote the generated package (what
    `sync` records), the one a node started by hand plans with.
    """

    name: str
    tag: str
    slots: Tuple[SlotSpec, ...] = ()
    emitted_topics: Tuple[TopicSpec, ...] = ()
    consumed_topics: Tuple[ConsumedTopicSpec, ...] = ()
    exposed_services: Tuple[ServiceSpec, ...] = ()
    exposed_actions: Tuple[ActionSpec, ...] = ()
    consumed_services: Tuple[ConsumedServiceSpec, ...] = ()
    consumed_actions: Tuple[ConsumedActionSpec, ...] = ()
    parameters: Any = None
    document: str = "peppy.json5"
    model: Optional[str] = None
    pairings: Tuple[PairingSlotSpec, ...] = ()
    pairing_topics: Tuple[PairingTopicSpec, ...] = ()
    engine: Optional[str] = None

    def slot(self, link_id: str) -> Optional[SlotSpec]:
        """The slot named `link_id`, if the node has one."""
        return next((s for s in self.slots if s.link_id == link_id), None)

    def pairing(self, link_id: str) -> Optional[PairingSlotSpec]:
        """The pairing slot named `link_id`, if the node has one."""
        return next((p for p in self.pairings if p.link_id == link_id), None)
