"""`info`: what this node's core node is, as PeppyOS's `peppylib.info`
answers it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional, Union

from . import strict_json
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
    """Asks this node's core node what it is; `response_timeout` in seconds
    (None: 10). `ValueError` when its answer is not one the Rust runtime
    reads (Rust's `Error::Deserialization`; `datastore` raises `ValueError`
    for a reply it cannot read too)."""
    return info_from_body(await ask(node_runner, "info", b"", response_timeout))


def info_from_body(body: Union[bytes, bytearray, memoryview, str]) -> InfoResponse:
    """A core node's `info` answer, its JSON text read as the Rust runtime
    reads it (`serde_json::from_slice::<peppy_runtime::info::InfoResponse>`):
    an object of its fields (others passed over) or an array of them in that
    order; integers are JSON integers in their Rust type's range
    (`uptime_secs` u64, `node_count` u32, `messaging_port` u16), text fields
    strings. `ValueError` for any answer Rust refuses."""
    try:
        return _read(strict_json.loads(body))
    except ValueError as e:
        raise ValueError(f"the core node's info: {e}") from None


_container_info = strict_json.struct(
    (
        ("apptainer_version", strict_json.string),
        ("lima_version", strict_json.string),
    )
)

_info = strict_json.struct(
    (
        ("uptime_secs", strict_json.u64),
        ("core_node_name", strict_json.string),
        ("core_node_instance_id", strict_json.string),
        ("host_name", strict_json.string),
        ("node_count", strict_json.u32),
        ("git_version", strict_json.string),
        ("container_info", lambda v: ContainerInfo(*_container_info(v))),
        ("messaging_port", strict_json.u16),
    )
)


def _read(data: Any) -> InfoResponse:
    return InfoResponse(*_info(data))
