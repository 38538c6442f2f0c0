"""`stack.list`: the nodes of this node's core node's stack, their
instances and the dependencies between them, as PeppyOS's
`peppylib.stack` answers it. `result.graph` is a plain dict
(`{"nodes": [...], "edges": [...]}`)."""

from __future__ import annotations

import builtins
import json
from dataclasses import dataclass
from typing import Any, Dict, List as _List, Optional

from .core_functions import ask

__all__ = ["StackList", "list"]


@dataclass(frozen=True)
class StackList:
    """The stack and who served it."""

    graph: Dict[str, Any]
    core_node: str
    instance_id: str
    host_name: str

    def running_instance_ids_by_node(self, name: str, tag: str) -> _List[str]:
        """The running instances of node `name:tag` (empty while every one
        is still starting); `KeyError` when the stack has no such node."""
        for node in self.graph.get("nodes", []):
            if node.get("name") == name and node.get("tag") == tag:
                return [i["instance_id"] for i in node.get("instances", []) if i.get("state") == "running"]
        raise KeyError(f"no node matches `{name}:{tag}`")


async def list(node_runner: Any, response_timeout: Optional[float] = None) -> StackList:  # noqa: A001
    """The stack of this node's core node; `response_timeout` in seconds (None: 10)."""
    data = json.loads(await ask(node_runner, "list", b"", response_timeout))
    graph = data["graph"]
    if not isinstance(graph, dict) or not isinstance(graph.get("nodes"), builtins.list):
        raise ValueError("the core node's stack list has no graph")
    return StackList(graph, data["core_node"], data["instance_id"], data["host_name"])
