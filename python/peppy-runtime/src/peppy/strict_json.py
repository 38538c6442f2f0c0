"""JSON answers read as the Rust runtime reads them: `serde_json` into a
`#[derive(Deserialize)]` struct (no `deny_unknown_fields`, no field
defaults). Every refusal is a `ValueError`.

`loads` parses the text as `serde_json::from_slice` does where plain
`json.loads` is more lenient: `NaN`/`Infinity` and a leading byte order
mark are refused; `-0` and integers of more than 20 characters read as
floats (serde_json makes `-0`, and any integer past u64 or i64, an
`f64`: refused where an integer is read, passed over elsewhere, however
many digits); bytes that are not UTF-8 are kept as lone surrogates
(serde_json passes them over in a value it ignores and refuses them in a
string it reads); an object remembers the keys it repeats. One
difference is left: serde_json passes over a value nested any depth,
`json.loads` refuses one nested about a thousand deep. `struct` then reads a value as serde's derive does: a JSON
object (unknown keys passed over; a known one missing or repeated, or a
key that is not valid Unicode, refused) or a JSON array of exactly one
element per field, in the struct's field order; `string`, `u16`, `u32`
and `u64` read fields of those Rust types (an integer is a JSON integer,
not a boolean, in the type's range)."""

from __future__ import annotations

import json
from typing import Any, Callable, FrozenSet, List, Sequence, Tuple, Union

__all__ = ["Reader", "loads", "string", "struct", "u16", "u32", "u64"]

Reader = Callable[[Any], Any]
"""Reads one JSON value as a Rust type; raises `ValueError`."""


class _Object(dict):
    """A JSON object; `repeated` names the keys it holds more than once
    (`json.loads` keeps the last value of each)."""

    repeated: FrozenSet[str] = frozenset()


def _object(pairs: List[Tuple[str, Any]]) -> _Object:
    obj = _Object(pairs)
    if len(obj) != len(pairs):
        seen: set = set()
        repeated = set()
        for key, _ in pairs:
            (repeated if key in seen else seen).add(key)
        obj.repeated = frozenset(repeated)
    return obj


def _integer(text: str) -> Union[int, float]:
    # serde_json reads `-0`, and an integer beyond u64 (or below i64), as
    # an f64: a float here too, refused where an integer is read. Python
    # reads no more than 4300 digits as an int: float() has no such limit.
    if text == "-0" or len(text) > 20:
        return float(text)
    return int(text)


def _constant(name: str) -> Any:
    raise ValueError(f"`{name}` is not JSON")


def loads(body: Union[bytes, bytearray, memoryview, str]) -> Any:
    """The JSON value of `body` (UTF-8 bytes, or text); `ValueError`
    when serde_json would refuse its syntax."""
    text = body if isinstance(body, str) else bytes(body).decode("utf-8", "surrogateescape")
    try:
        return json.loads(text, object_pairs_hook=_object, parse_int=_integer, parse_constant=_constant)
    except RecursionError:
        # serde_json passes over a value it ignores however deep it is.
        raise ValueError("nested too deeply to read") from None


class _Refused(ValueError):
    """A value refused `at` a path of fields (`a.b`)."""

    def __init__(self, reason: str, at: str = "") -> None:
        self.reason = reason
        self.at = at
        super().__init__(f"`{at}`: {reason}" if at else reason)

    def within(self, field: str) -> "_Refused":
        return _Refused(self.reason, f"{field}.{self.at}" if self.at else field)


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({'true' if value else 'false'})"
    if isinstance(value, int):
        return f"the integer {value}"
    if isinstance(value, float):
        return f"the number {value!r}"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return f"an array of {len(value)}"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _is_unicode(text: str) -> bool:
    """No lone surrogate: what serde_json accepts in a string it reads."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def string(value: Any) -> str:
    """A Rust `String`: a JSON string of valid Unicode."""
    if type(value) is not str:
        raise _Refused(f"{_kind(value)} where a string is expected")
    if not _is_unicode(value):
        raise _Refused("a string that is not valid Unicode (a lone surrogate or a byte that is not UTF-8)")
    return value


def _unsigned(bits: int) -> Reader:
    top = (1 << bits) - 1

    def read(value: Any) -> int:
        if type(value) is not int:  # not a bool, not a float
            raise _Refused(f"{_kind(value)} where an integer (u{bits}) is expected")
        if not 0 <= value <= top:
            raise _Refused(f"the integer {value} is out of u{bits}'s range 0..={top}")
        return value

    return read


u16 = _unsigned(16)
u32 = _unsigned(32)
u64 = _unsigned(64)


def struct(fields: Sequence[Tuple[str, Reader]]) -> Callable[[Any], List[Any]]:
    """A reader of a struct of `fields` (name, reader; in the Rust
    struct's order): the field values, in that order."""
    names = [name for name, _ in fields]

    def read(value: Any) -> List[Any]:
        if isinstance(value, list):
            if len(value) != len(fields):
                raise _Refused(f"an array of {len(value)} where a struct of {len(fields)} fields is expected")
            items = list(zip(names, value))
        elif isinstance(value, dict):
            for key in value:
                if not _is_unicode(key):
                    raise _Refused("a key that is not valid Unicode (a lone surrogate or a byte that is not UTF-8)")
            repeated = sorted(set(names) & getattr(value, "repeated", frozenset()))
            if repeated:
                raise _Refused("given more than once", repeated[0])
            missing = [name for name in names if name not in value]
            if missing:
                raise _Refused("missing", missing[0])
            items = [(name, value[name]) for name in names]
        else:
            raise _Refused(f"{_kind(value)} where a struct (an object or an array) is expected")
        out = []
        for (name, field), (_, item) in zip(fields, items):
            try:
                out.append(field(item))
            except _Refused as e:
                raise e.within(name) from None
        return out

    return read
