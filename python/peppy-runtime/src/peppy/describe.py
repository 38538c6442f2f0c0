"""What a running instance says about itself (docs/WIRE.md §9): the JSON
document `peppy_runtime::describe::InstanceInfo` answered on
`peppy/<ns>/describe/<core>/<instance>`, field for field."""

from __future__ import annotations

import json
from typing import Any, Dict, List, Optional, Sequence

from .keys import ACTION, SERVICE, TOPIC, entry_key
from .routing import RouteFilter, SlotPlan
from .spec import ConsumedTopicSpec, NodeDescriptor, Owner

DESCRIBE_VERSION = 1


def owner_info(owner: Owner, node_name: str, node_tag: str) -> Optional[Dict[str, str]]:
    """`{kind, name, tag}` of an entry's owner; None for any owner."""
    r = owner.resolve(node_name, node_tag)
    return None if r is None else {"kind": r[0], "name": r[1], "tag": r[2]}


def consumed_topic(
    spec: ConsumedTopicSpec,
    node_name: str,
    node_tag: str,
    selector: str,
    filter: RouteFilter,
    members_of: Optional[SlotPlan],
) -> Dict[str, Any]:
    """How one consumed topic is routed, as `consumes` lists it."""
    return {
        "slot": spec.link_id,
        "owner": owner_info(spec.owner, node_name, node_tag),
        "name": spec.name,
        "qos": spec.qos.value,
        "format": spec.format.info(),
        "selector": selector,
        "filter": filter.to_json(),
        "members_of": None if members_of is None else {"name": members_of.name, "tag": members_of.tag},
    }


def instance_info(
    descriptor: NodeDescriptor,
    namespace: str,
    core: str,
    instance: str,
    pid: int,
    started_at_ms: int,
    slots: Sequence[SlotPlan],
    consumes: List[Dict[str, Any]],
) -> str:
    """The instance's description, as compact JSON."""
    name, tag = descriptor.name, descriptor.tag

    def owned(owner: Owner, channel: str, entry: str) -> Dict[str, Any]:
        info = owner_info(owner, name, tag) or {}
        segments = f"{info.get('kind')}/{info.get('name')}/{info.get('tag')}"
        return {"owner": info, "name": entry, "key": entry_key(namespace, channel, segments, entry, core, instance)}

    emits = []
    for t in descriptor.emitted_topics:
        o = owned(t.owner, TOPIC, t.name)
        emits.append(
            {
                "owner": o["owner"],
                "name": t.name,
                "qos": t.qos.value,
                "format": t.format.info(),
                "key": o["key"],
            }
        )
    services = []
    for s in descriptor.exposed_services:
        o = owned(s.owner, SERVICE, s.name)
        services.append(
            {
                "owner": o["owner"],
                "name": s.name,
                "request": s.request.info(),
                "response": s.response.info(),
                "key": o["key"],
            }
        )
    actions = []
    for a in descriptor.exposed_actions:
        o = owned(a.owner, ACTION, a.name)
        actions.append(
            {
                "owner": o["owner"],
                "name": a.name,
                "goal": a.goal.info(),
                "feedback": a.feedback.info(),
                "result": a.result.info(),
                "key": o["key"],
            }
        )
    info = {
        "version": DESCRIBE_VERSION,
        "instance_id": instance,
        "core_node": core,
        "namespace": namespace,
        "node": {"name": name, "tag": tag},
        "pid": pid,
        "started_at_ms": started_at_ms,
        "slots": [s.to_json() for s in slots],
        "emits": emits,
        "consumes": consumes,
        "services": services,
        "actions": actions,
    }
    return json.dumps(info, separators=(",", ":"), ensure_ascii=False)
