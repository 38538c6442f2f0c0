"""What actions say on the wire besides their messages (docs/WIRE.md §4):
goal ids, the goal decision, a result's status byte, a cancel's answer."""

from __future__ import annotations

import enum
import re
import secrets
from typing import Any, NamedTuple, Optional, Tuple

from .codec import BOOL, STRING
from .codec import Optional as _Optional

_GOAL_ID = re.compile(r"[A-Za-z0-9_-]{1,64}\Z")
_DECISION_ACCEPTED = BOOL.decoder()
_DECISION_ERROR = _Optional(STRING).decoder()
_STRING_ENC = STRING.encoder()
_STRING_DEC = STRING.decoder()


class ResultStatus(enum.IntEnum):
    """How a goal ended, as its caller sees it (the result's status byte)."""

    COMPLETED = 0
    CANCELLED = 1
    ABANDONED = 2
    EXPIRED = 3


class ResultOutcome(NamedTuple):
    """A goal's end: its status, and its result for COMPLETED and CANCELLED."""

    status: ResultStatus
    result: Any


class CancelState(enum.IntEnum):
    """The answer to a cancel request."""

    SIGNALLED = 0
    ALREADY_TERMINAL = 1
    UNKNOWN = 2


def new_goal_id() -> str:
    """A fresh goal id: 16 lowercase hex digits."""
    return secrets.token_hex(8)


def is_goal_id(s: str) -> bool:
    """Whether `s` is 1-64 characters of `[A-Za-z0-9_-]`."""
    return bool(_GOAL_ID.match(s))


def encode_string(s: str) -> bytes:
    """`s` encoded as a `string` (u32 length + UTF-8)."""
    out = bytearray()
    _STRING_ENC(s, out)
    return bytes(out)


def split_goal_id(payload: bytes) -> Optional[Tuple[str, bytes]]:
    """`(goal id, rest)` of a goal, cancel or result payload; None if malformed."""
    try:
        goal_id, pos = _STRING_DEC(payload, 0)
    except ValueError:
        return None
    return (goal_id, payload[pos:]) if is_goal_id(goal_id) else None


def goal_id_of(payload: bytes) -> Optional[str]:
    """The goal id a cancel or result query names (its whole payload)."""
    split = split_goal_id(payload)
    return split[0] if split is not None and not split[1] else None


def encode_decision(accepted: bool, error_message: Optional[str], response: bytes = b"") -> bytes:
    """The goal's answer `{ accepted: bool, error_message: optional string }`,
    then the action's declared goal response, encoded, when one is sent."""
    out = bytearray([1 if accepted else 0])
    if error_message is None:
        out.append(0)
    else:
        out.append(1)
        _STRING_ENC(str(error_message), out)
    out += response
    return bytes(out)


def decode_decision(body: bytes) -> Tuple[bool, Optional[str]]:
    """`(accepted, error_message)` of a goal's answer (a declared goal
    response after them is left out: `decode_decision_with_response`)."""
    accepted, error, _ = decode_decision_with_response(body)
    return accepted, error


def decode_decision_with_response(body: bytes) -> Tuple[bool, Optional[str], bytes]:
    """`(accepted, error_message, response)` of a goal's answer: `response`
    is the declared goal response as encoded (empty when none was sent)."""
    accepted, pos = _DECISION_ACCEPTED(body, 0)
    error, pos = _DECISION_ERROR(body, pos)
    return accepted, error, bytes(body[pos:])
