"""`info`: what this node's core node is, as PeppyOS's `peppylib.info`
answers it."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Optional

from .core_functions import ask


@dataclass(frozen=True)
class ContainerInfo:
    """Container runtimes the core node knows (peppy starts none)."""

    apptainer_version: str
    lima_version: str


@dataclass(frozen=True)
class InfoResponse:
    """A core node's facts."""

    uptime_secs: int
    core_node_name: str
    core_node_instance_id: str
    host_name: str
    node_count: int
    git_version: str
    container_info: ContainerInfo
    messaging_port: int


async def info(node_runner: Any, response_timeout: Optional[float] = None) -> InfoResponse:
    """Asks this node's core node what it is; `response_timeout` in seconds (None: 10)."""
    return info_from_json(json.loads(await ask(node_runner, "info", b"", response_timeout)))


def info_from_json(data: Any) -> InfoResponse:
    """A core node's `info` answer, parsed (`peppy_runtime::info::InfoResponse`)."""
    return InfoResponse(
        uptime_secs=int(data["uptime_secs"]),
        core_node_name=data["core_node_name"],
        core_node_instance_id=data["core_node_instance_id"],
        host_name=data["host_name"],
        node_count=int(data["node_count"]),
        git_version=data["git_version"],
        container_info=ContainerInfo(**data["container_info"]),
        messaging_port=int(data["messaging_port"]),
    )
