"""Message formats: a described class with its canonical text and
fingerprint (docs/WIRE.md §6)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

NO_PAYLOAD = "(no payload)"


def fingerprint_of(canonical: str) -> int:
    """The first 8 bytes of the SHA-256 of `canonical`, as a big-endian u64."""
    return int.from_bytes(hashlib.sha256(canonical.encode("utf-8")).digest()[:8], "big")


def _codec() -> Any:
    # codec re-exports this module, so it is imported on first use.
    from . import codec

    return codec


@dataclass(frozen=True)
class Format:
    """A message format as compiled into the node.

    `cls` is the described dataclass of its messages; the no-payload format
    (canonical `(no payload)`, fingerprint 0) has a class without fields
    (or None) and encodes to no bytes.
    """

    cls: Any
    canonical: str
    fingerprint: int

    def __post_init__(self) -> None:
        if not isinstance(self.canonical, str):
            raise TypeError("Format canonical text must be a str")
        if not isinstance(self.fingerprint, int) or not 0 <= self.fingerprint < 1 << 64:
            raise ValueError(f"Format fingerprint must be a u64, got {self.fingerprint!r}")
        if self.is_empty:
            if self.fingerprint != 0:
                raise ValueError("the no-payload format has fingerprint 0")
            return
        expected = fingerprint_of(self.canonical)
        if expected != self.fingerprint:
            raise ValueError(
                f"fingerprint {self.fingerprint:016x} is not that of {self.canonical} "
                f"({expected:016x}); regenerate the code"
            )

    @property
    def is_empty(self) -> bool:
        """Whether this is the no-payload format."""
        return self.canonical == NO_PAYLOAD

    def encode(self, message: Any) -> bytes:
        """The bytes of `message` (an instance of `cls`)."""
        if self.cls is None:
            return b""
        return _codec().encode(self.cls, message)

    def decode(self, data: Any) -> Any:
        """A message from exactly `data`; raises `codec.DecodeError`."""
        if self.cls is None:
            if len(data):
                raise _codec().DecodeError(0, f"{len(data)} unexpected trailing bytes")
            return None
        return _codec().decode(self.cls, data)

    def info(self) -> dict:
        """`{canonical, fingerprint}` as instance descriptions show it."""
        return {"canonical": self.canonical, "fingerprint": self.fingerprint}


EMPTY = Format(None, NO_PAYLOAD, 0)
"""The no-payload format without a message class."""
