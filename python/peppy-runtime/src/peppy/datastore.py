"""The datastore: a small key/value store each core node keeps for its
nodes, as PeppyOS's `peppylib.datastore` offers it (docs/WIRE.md, "Core
node functions"). A node leaves bytes under a key, tagged with an
encoding; any node of the same core node reads them later, also after a
restart of the node that wrote them; the store records each key's last
writer. It lives as long as its core node."""

from __future__ import annotations

import builtins
import enum
import struct
from dataclasses import dataclass
from typing import Any, List as _List, Optional, Tuple, Union

from .core_functions import ask

__all__ = ["DatastoreEntry", "Encoding", "StoredValue", "get", "list", "remove", "store"]

MAX_VALUE_BYTES = 16 << 20
"""The largest value the store keeps."""

_U32 = struct.Struct("<I")


class Encoding(str, enum.Enum):
    """Common content-type tags. The set is open: any string is a tag,
    and a tag read back compares equal to its member
    (`stored.encoding == Encoding.APPLICATION_JSON`)."""

    TEXT_PLAIN = "text/plain"
    APPLICATION_JSON = "application/json"
    APPLICATION_OCTET_STREAM = "application/octet-stream"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class StoredValue:
    """A value read from the store: its bytes, their tag, the instance id
    of the node that wrote the key last."""

    value: bytes
    encoding: str
    last_modified_by: str


@dataclass(frozen=True)
class DatastoreEntry:
    """One key of `list`: its tag and last writer, without the value."""

    key: str
    encoding: str
    last_modified_by: str


def _string(s: str, out: bytearray) -> None:
    data = s.encode("utf-8")
    out += _U32.pack(len(data))
    out += data


def _bytes(b: bytes, out: bytearray) -> None:
    out += _U32.pack(len(b))
    out += b


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0

    def take(self, n: int) -> bytes:
        if n > len(self.data) - self.pos:
            raise ValueError(f"the datastore's reply is cut short at byte {self.pos}")
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def u8(self) -> int:
        return self.take(1)[0]

    def count(self) -> int:
        return _U32.unpack(self.take(4))[0]

    def bytes(self) -> bytes:
        return self.take(self.count())

    def string(self) -> str:
        return self.bytes().decode("utf-8")

    def end(self) -> None:
        if self.pos != len(self.data):
            raise ValueError("the datastore's reply has trailing bytes")


def _key(key: str) -> str:
    if not isinstance(key, str) or not key:
        raise ValueError("a datastore key is a non-empty string")
    return key


def _tag(encoding: Union[str, Encoding]) -> str:
    return encoding.value if isinstance(encoding, Encoding) else str(encoding)


def store_request(key: str, value: bytes, encoding: Union[str, Encoding], writer: str) -> bytes:
    """What `store` sends (docs/WIRE.md §12)."""
    out = bytearray([0])
    _string(_key(key), out)
    _bytes(bytes(value), out)
    _string(_tag(encoding), out)
    _string(writer, out)
    return bytes(out)


def key_request(operation: int, key: Optional[str] = None) -> bytes:
    """What `get` (1), `list` (2, no key) and `remove` (3) send."""
    out = bytearray([operation])
    if key is not None:
        _string(_key(key), out)
    return bytes(out)


async def _call(runner: Any, request: bytes, timeout: Optional[float]) -> Tuple[int, _Reader]:
    reader = _Reader(await ask(runner, "datastore", request, timeout))
    return reader.u8(), reader


async def store(
    node_runner: Any,
    key: str,
    value: bytes,
    encoding: Union[str, Encoding] = Encoding.APPLICATION_OCTET_STREAM,
    response_timeout: Optional[float] = None,
) -> None:
    """Stores `value` under `key` on this node's core node, tagged with
    `encoding`; a key already there is overwritten (value, tag, writer).
    `response_timeout` in seconds (None: 10)."""
    value = bytes(value)
    if len(value) > MAX_VALUE_BYTES:
        raise ValueError(f"the datastore keeps values of at most {MAX_VALUE_BYTES} bytes, got {len(value)}")
    kind, reader = await _call(node_runner, store_request(key, value, encoding, node_runner.instance_id), response_timeout)
    if kind != 0:
        raise ValueError(f"the datastore answered a store with a reply of kind {kind}")
    reader.end()


async def get(node_runner: Any, key: str, response_timeout: Optional[float] = None) -> Optional[StoredValue]:
    """The value stored under `key` on this node's core node, None when no
    node stored one."""
    kind, reader = await _call(node_runner, key_request(1, key), response_timeout)
    if kind != 1:
        raise ValueError(f"the datastore answered a get with a reply of kind {kind}")
    present = reader.u8()
    if present == 0:
        reader.end()
        return None
    value, encoding, writer = reader.bytes(), reader.string(), reader.string()
    reader.end()
    return StoredValue(bytes(value), encoding, writer)


async def list(node_runner: Any, response_timeout: Optional[float] = None) -> _List[DatastoreEntry]:  # noqa: A001
    """Every key of this node's core node's store with its tag and last
    writer (not the values), in key order."""
    kind, reader = await _call(node_runner, key_request(2), response_timeout)
    if kind != 2:
        raise ValueError(f"the datastore answered a list with a reply of kind {kind}")
    entries = [DatastoreEntry(reader.string(), reader.string(), reader.string()) for _ in builtins.range(reader.count())]
    reader.end()
    return entries


async def remove(node_runner: Any, key: str, response_timeout: Optional[float] = None) -> bool:
    """Removes `key` from this node's core node's store: True when it was there."""
    kind, reader = await _call(node_runner, key_request(3, key), response_timeout)
    if kind != 3:
        raise ValueError(f"the datastore answered a remove with a reply of kind {kind}")
    removed = reader.u8() == 1
    reader.end()
    return removed
