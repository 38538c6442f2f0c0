"""The codec's scalar types (docs/WIRE.md §5): numbers, `bool`, `string`,
`bytes`, `time`, the errors every codec type raises, and the `u32`
counts arrays and strings start with."""

from __future__ import annotations

import struct
from typing import Any, Callable, Tuple

from .errors import PeppyError
from .timestamps import NANOS_PER_SECOND, Time

_U32 = struct.Struct("<I")
_TIME = struct.Struct("<qI")
_I64_MIN = -(1 << 63)
_I64_MAX = (1 << 63) - 1
_U32_MAX = (1 << 32) - 1

Encoder = Callable[[Any, bytearray], None]
Decoder = Callable[[Any, int], Tuple[Any, int]]


class DecodeError(PeppyError, ValueError):
    """Bytes that are not a valid encoding of the expected message."""

    def __init__(self, offset: int, reason: str) -> None:
        self.offset = offset
        self.reason = reason
        super().__init__(f"invalid payload at byte {offset}: {reason}")


class EncodeError(ValueError):
    """A value that cannot be encoded as its declared type; names the field."""

    def __init__(self, reason: str) -> None:
        self.reason = reason
        self.path = ""
        super().__init__(reason)

    def _within(self, segment: str) -> "EncodeError":
        self.path = segment + self.path
        where = self.path.lstrip(".")
        self.args = (f"field `{where}`: {self.reason}",)
        return self


def too_short(n: int, pos: int, buf: Any) -> DecodeError:
    return DecodeError(pos, f"needs {n} more bytes, {len(buf) - pos} left")


def read_count(buf: Any, pos: int, min_item: int) -> Tuple[int, int]:
    """A `u32` count at `pos`, refused when the rest could not hold it."""
    try:
        (n,) = _U32.unpack_from(buf, pos)
    except struct.error:
        raise too_short(4, pos, buf) from None
    remaining = len(buf) - pos - 4
    if min_item > 0 and n * min_item > remaining:
        raise DecodeError(pos, f"length {n} exceeds the {remaining} bytes that remain")
    return n, pos + 4


def put_count(n: int, out: bytearray) -> None:
    if n > _U32_MAX:
        raise EncodeError(f"{n} items or bytes do not fit a u32 length")
    out += _U32.pack(n)


class WireType:
    """A wire type: how many bytes it takes at least, and how to code it."""

    name = "?"

    @property
    def min_size(self) -> int:
        raise NotImplementedError

    def encoder(self) -> Encoder:
        raise NotImplementedError

    def decoder(self) -> Decoder:
        raise NotImplementedError

    def __repr__(self) -> str:
        return self.name


class Number(WireType):
    """A fixed-size integer or float, coded by `struct`."""

    def __init__(self, name: str, code: str, low: Any = None, high: Any = None) -> None:
        self.name = name
        self.code = code
        self.struct = struct.Struct("<" + code)
        self.low = low
        self.high = high

    @property
    def min_size(self) -> int:
        return self.struct.size

    def refusal(self, value: Any) -> EncodeError:
        if self.low is None:
            return EncodeError(f"{value!r} is not an `{self.name}` (a number within its range)")
        return EncodeError(f"{value!r} is not a `{self.name}` (an integer from {self.low} to {self.high})")

    def encoder(self) -> Encoder:
        pack = self.struct.pack

        def enc(value: Any, out: bytearray) -> None:
            try:
                out += pack(value)
            except (struct.error, OverflowError, TypeError):
                raise self.refusal(value) from None

        return enc

    def decoder(self) -> Decoder:
        unpack = self.struct.unpack_from
        size = self.struct.size

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            try:
                return unpack(buf, pos)[0], pos + size
            except struct.error:
                raise too_short(size, pos, buf) from None

        return dec


class _Bool(WireType):
    name = "bool"

    @property
    def min_size(self) -> int:
        return 1

    def encoder(self) -> Encoder:
        def enc(value: Any, out: bytearray) -> None:
            out.append(bool_byte(value))

        return enc

    def decoder(self) -> Decoder:
        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            if pos >= len(buf):
                raise too_short(1, pos, buf)
            b = buf[pos]
            if b > 1:
                raise DecodeError(pos, f"bool byte is {b}, expected 0 or 1")
            return b == 1, pos + 1

        return dec


def bool_byte(value: Any) -> int:
    if value is True or value is False:
        return int(value)
    try:
        if value == 1:
            return 1
        if value == 0:
            return 0
    except Exception:  # an object whose == is not a truth value (arrays)
        pass
    raise EncodeError(f"{value!r} is not a `bool`")


class _String(WireType):
    name = "string"

    @property
    def min_size(self) -> int:
        return 4

    def encoder(self) -> Encoder:
        def enc(value: Any, out: bytearray) -> None:
            if not isinstance(value, str):
                raise EncodeError(f"{value!r} is not a `string` (a str)")
            try:
                data = value.encode("utf-8")
            except UnicodeEncodeError as e:
                raise EncodeError(f"the string cannot be UTF-8 encoded: {e.reason}") from None
            put_count(len(data), out)
            out += data

        return enc

    def decoder(self) -> Decoder:
        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_count(buf, pos, 1)
            end = pos + n
            try:
                return str(buf[pos:end], "utf-8"), end
            except UnicodeDecodeError as e:
                raise DecodeError(pos + e.start, "string is not valid UTF-8") from None

        return dec


def as_bytes(value: Any) -> bytes:
    """bytes/bytearray/memoryview as is, a sequence of ints as bytes."""
    if isinstance(value, bytes):
        return value
    if isinstance(value, (bytearray, memoryview)):
        return bytes(value)
    if isinstance(value, str):
        raise EncodeError("a str is not bytes (encode it first)")
    try:
        return bytes(value)
    except (TypeError, ValueError) as e:
        raise EncodeError(f"{value!r} is not bytes ({e})") from None


class _Bytes(WireType):
    """`bytes`, and variable arrays of `u8`: a u32 length then the bytes."""

    name = "bytes"

    @property
    def min_size(self) -> int:
        return 4

    def encoder(self) -> Encoder:
        def enc(value: Any, out: bytearray) -> None:
            data = as_bytes(value)
            put_count(len(data), out)
            out += data

        return enc

    def decoder(self) -> Decoder:
        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_count(buf, pos, 1)
            return bytes(buf[pos : pos + n]), pos + n

        return dec


class _Time(WireType):
    name = "time"

    @property
    def min_size(self) -> int:
        return 12

    def encoder(self) -> Encoder:
        pack = _TIME.pack

        def enc(value: Any, out: bytearray) -> None:
            if not isinstance(value, Time):
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise EncodeError(f"{value!r} is not a `time` (a peppy.Time or seconds as a float)")
                try:
                    value = Time.from_float(value)
                except ValueError as e:
                    raise EncodeError(str(e)) from None
            if not _I64_MIN <= value.seconds <= _I64_MAX:
                raise EncodeError(f"{value!r} is out of the range of a `time`")
            out += pack(value.seconds, value.nanoseconds)

        return enc

    def decoder(self) -> Decoder:
        unpack = _TIME.unpack_from

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            try:
                seconds, nanos = unpack(buf, pos)
            except struct.error:
                raise too_short(12, pos, buf) from None
            if nanos >= NANOS_PER_SECOND:
                raise DecodeError(pos, "time nanoseconds out of range")
            if seconds == _I64_MIN:
                raise DecodeError(pos, "time out of range for this platform")
            return Time(seconds, nanos), pos + 12

        return dec


BOOL = _Bool()
U8 = Number("u8", "B", 0, 0xFF)
U16 = Number("u16", "H", 0, 0xFFFF)
U32 = Number("u32", "I", 0, _U32_MAX)
U64 = Number("u64", "Q", 0, (1 << 64) - 1)
I8 = Number("i8", "b", -0x80, 0x7F)
I16 = Number("i16", "h", -0x8000, 0x7FFF)
I32 = Number("i32", "i", -(1 << 31), (1 << 31) - 1)
I64 = Number("i64", "q", _I64_MIN, _I64_MAX)
F32 = Number("f32", "f")
F64 = Number("f64", "d")
STRING = _String()
BYTES = _Bytes()
TIME = _Time()
