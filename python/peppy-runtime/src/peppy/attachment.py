"""Attachments (docs/WIRE.md §2): the small header beside each payload.
Every one starts with the protocol version byte."""

from __future__ import annotations

import enum
import struct
from typing import NamedTuple, Optional, Tuple

VERSION = 1

END_OF_FEEDBACK = bytes([VERSION, 0xEE])
"""Attachment of the empty publication that ends a goal's feedback stream."""

_FP = struct.Struct(">Q")


def topic(fingerprint: int) -> bytes:
    """A topic publication's attachment: version + fingerprint."""
    return bytes([VERSION]) + _FP.pack(fingerprint)


def parse_topic(data: Optional[bytes]) -> Optional[int]:
    """The fingerprint of a topic attachment; None unless it is exactly one."""
    if data is None or len(data) != 9 or data[0] != VERSION:
        return None
    return _FP.unpack_from(data, 1)[0]


class QueryKind(enum.IntEnum):
    """What a query asks for."""

    REQUEST = 0
    PROBE = 1


class QueryHeader(NamedTuple):
    """A query's header: kind, request fingerprint and the caller's identity."""

    kind: QueryKind
    fingerprint: int
    core: str
    instance: str

    def encode(self) -> bytes:
        """The header's bytes (identities longer than 255 bytes are cut, as the Rust side does)."""
        out = bytearray([VERSION, int(self.kind)])
        out += _FP.pack(self.fingerprint)
        for s in (self.core, self.instance):
            b = s.encode("utf-8")[:255]
            out.append(len(b))
            out += b
        return bytes(out)

    @staticmethod
    def decode(data: Optional[bytes]) -> Optional["QueryHeader"]:
        """A header from its bytes; None for anything malformed."""
        if data is None or len(data) < 10 or data[0] != VERSION or data[1] > 1:
            return None
        kind = QueryKind(data[1])
        (fingerprint,) = _FP.unpack_from(data, 2)
        pos = 10
        texts = []
        for _ in range(2):
            if pos >= len(data):
                return None
            n = data[pos]
            end = pos + 1 + n
            if end > len(data):
                return None
            try:
                texts.append(data[pos + 1 : end].decode("utf-8"))
            except UnicodeDecodeError:
                return None
            pos = end
        if pos != len(data):
            return None
        return QueryHeader(kind, fingerprint, texts[0], texts[1])


class ReplyStatus(enum.IntEnum):
    """What a reply carries."""

    ACK = 0
    OK = 1
    HANDLER_ERROR = 2
    FORMAT_MISMATCH = 3
    PRESENT = 4


def reply(status: ReplyStatus, fingerprint: int) -> bytes:
    """A reply's attachment: version, status, response fingerprint."""
    return bytes([VERSION, int(status)]) + _FP.pack(fingerprint)


def parse_reply(data: Optional[bytes]) -> Optional[Tuple[ReplyStatus, int]]:
    """`(status, fingerprint)` of a reply attachment; None if malformed."""
    if data is None or len(data) != 10 or data[0] != VERSION or data[1] > 4:
        return None
    return ReplyStatus(data[1]), _FP.unpack_from(data, 2)[0]
