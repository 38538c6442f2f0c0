"""The golden vectors the Python and Rust runtimes share
(`tests/golden/wire.json` at the repository's root, docs/WIRE.md), and
what the tests need to read them: a format's canonical text as a described
class (generated `peppygen` code describes its classes the same way), a
vector's JSON value as a message, and a decoded message compared with it."""

from __future__ import annotations

import json
import math
import struct
from dataclasses import make_dataclass
from pathlib import Path
from typing import Any, List, Optional, Tuple

from peppy import Time
from peppy import codec as c
from peppy.formats import EMPTY, NO_PAYLOAD

PATH = Path(__file__).resolve().parents[3] / "tests" / "golden" / "wire.json"


def load() -> dict:
    """The whole file."""
    return json.loads(PATH.read_text(encoding="utf-8"))


def fingerprint(text: str) -> int:
    """A fingerprint as the file writes it: 16 hex digits."""
    if len(text) != 16:
        raise ValueError(f"fingerprint `{text}` is not 16 hex digits")
    return int(text, 16)


_PRIMITIVES = {
    "bool": c.BOOL,
    "u8": c.U8,
    "u16": c.U16,
    "u32": c.U32,
    "u64": c.U64,
    "i8": c.I8,
    "i16": c.I16,
    "i32": c.I32,
    "i64": c.I64,
    "f32": c.F32,
    "f64": c.F64,
    "string": c.STRING,
    "bytes": c.BYTES,
    "time": c.TIME,
}


class Shape:
    """One type of a format: `kind` is a primitive's name, `object` (with
    `cls` and `fields`: name, shape, optional) or `array` (with `item` and
    `length`); `wire` is the codec type."""

    def __init__(self, kind: str, wire: Any, **parts: Any) -> None:
        self.kind = kind
        self.wire = wire
        self.cls = parts.get("cls")
        self.fields: List[Tuple[str, "Shape", bool]] = parts.get("fields", [])
        self.item: Optional["Shape"] = parts.get("item")
        self.length: Optional[int] = parts.get("length")


class _Reader:
    """docs/WIRE.md §6's grammar, read into described classes."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0
        self.classes = 0

    def eat(self, char: str) -> bool:
        if self.text.startswith(char, self.pos):
            self.pos += 1
            return True
        return False

    def expect(self, char: str) -> None:
        if not self.eat(char):
            raise ValueError(f"expected `{char}` at {self.pos} of {self.text}")

    def word(self) -> str:
        start = self.pos
        while self.pos < len(self.text) and (self.text[self.pos].isalnum() or self.text[self.pos] == "_"):
            self.pos += 1
        return self.text[start : self.pos]

    def obj(self) -> Shape:
        self.expect("{")
        fields = []
        while True:
            name = self.word()
            self.expect(":")
            shape = self.type()
            fields.append((name, shape, self.eat("?")))
            if self.eat("}"):
                break
            self.expect(",")
        self.classes += 1
        cls = make_dataclass(f"Golden{self.classes}", [name for name, _, _ in fields])
        wire = [(name, c.Optional(s.wire) if optional else s.wire) for name, s, optional in fields]
        c.describe(cls, wire)
        return Shape("object", c.Obj(cls), cls=cls, fields=fields)

    def type(self) -> Shape:
        if self.text.startswith("{", self.pos):
            return self.obj()
        if self.eat("["):
            item = self.type()
            length = int(self.word()) if self.eat(";") else None
            self.expect("]")
            return Shape("array", c.Array(item.wire, length), item=item, length=length)
        name = self.word()
        return Shape(name, _PRIMITIVES[name])


def shape_of(canonical: str) -> Optional[Shape]:
    """The message shape of a canonical text; None for no payload."""
    if canonical == NO_PAYLOAD:
        return None
    reader = _Reader(canonical)
    shape = reader.obj()
    if reader.pos != len(canonical):
        raise ValueError(f"trailing text in {canonical}")
    return shape


def format_of(canonical: str, written: str) -> c.Format:
    """The runtime's `Format` of a vector (which checks the fingerprint)."""
    shape = shape_of(canonical)
    if shape is None:
        return EMPTY
    return c.Format(shape.cls, canonical, fingerprint(written))


_FLOAT_WORDS = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def message(shape: Shape, value: Any) -> Any:
    """The Python value of a vector's JSON value."""
    if shape.kind == "object":
        values = {}
        for name, field, optional in shape.fields:
            v = value[name]
            values[name] = None if optional and v is None else message(field, v)
        return shape.cls(**values)
    if shape.kind == "array":
        if shape.item.kind == "u8":
            return bytes(value)
        return [message(shape.item, v) for v in value]
    if shape.kind == "bytes":
        return bytes(value)
    if shape.kind == "time":
        return Time(value["secs"], value["nanos"])
    if shape.kind in ("f32", "f64"):
        return _FLOAT_WORDS.get(value, value) if isinstance(value, str) else float(value)
    return value


def mismatch(shape: Shape, expected: Any, actual: Any, path: str = "") -> Optional[str]:
    """Where a decoded `actual` differs from a vector's JSON value, or None.
    An `f32` is compared with the `f32` nearest the value written."""
    if shape.kind == "object":
        for name, field, optional in shape.fields:
            want, got = expected[name], getattr(actual, name)
            if optional and (want is None or got is None):
                if want is not got:
                    return f"{path}.{name}: {got!r}, expected {want!r}"
                continue
            found = mismatch(field, want, got, f"{path}.{name}")
            if found:
                return found
        return None
    if shape.kind == "array" and shape.item.kind != "u8":
        if len(actual) != len(expected):
            return f"{path}: {len(actual)} items, expected {len(expected)}"
        for i, (want, got) in enumerate(zip(expected, actual)):
            found = mismatch(shape.item, want, got, f"{path}[{i}]")
            if found:
                return found
        return None
    if shape.kind in ("bytes", "array"):
        return None if actual == bytes(expected) else f"{path}: {actual!r}, expected {expected!r}"
    if shape.kind == "time":
        got = {"secs": actual.seconds, "nanos": actual.nanoseconds}
        return None if got == expected else f"{path}: {got}, expected {expected}"
    if shape.kind in ("f32", "f64"):
        want = message(shape, expected)
        if shape.kind == "f32" and math.isfinite(want):
            want = struct.unpack("<f", struct.pack("<f", want))[0]
        same = (math.isnan(want) and math.isnan(actual)) or (want == actual and type(actual) is float)
        return None if same else f"{path}: {actual!r}, expected {want!r}"
    same = actual == expected and type(actual) is type(expected)
    return None if same else f"{path}: {actual!r}, expected {expected!r}"
