"""The codec's containers (docs/WIRE.md §5): arrays (counted, or of a
fixed `$length`) and `$optional` values."""

from __future__ import annotations

import struct
from typing import Any, Callable, Sequence, Tuple

from .codec_scalars import (
    BOOL,
    U8,
    DecodeError,
    Decoder,
    EncodeError,
    Encoder,
    Number,
    WireType,
    as_bytes,
    bool_byte,
    put_count,
    read_count,
    too_short,
)


class Array(WireType):
    """An array of `item`: a u32 count then the items, or exactly `length`
    items and no count (`$length`). Arrays of `U8` are `bytes` in Python.

    `pinned` is a length a node fixes with `refine` on an open array: the
    wire keeps the count (every other node reads the open array), and this
    node's values must hold exactly `pinned` items, on the way out and in."""

    def __init__(self, item: WireType, length: "int | None" = None, pinned: "int | None" = None) -> None:
        if not isinstance(item, WireType):
            raise TypeError(f"Array item must be a codec type, got {item!r}")
        if length is not None and (not isinstance(length, int) or length < 0):
            raise ValueError(f"Array length must be a non-negative int, got {length!r}")
        if pinned is not None and (length is not None or not isinstance(pinned, int) or pinned < 0):
            raise ValueError(f"Array pins a length only on an open array, got pinned={pinned!r} length={length!r}")
        self.item = item
        self.length = length
        self.pinned = pinned
        self.name = f"[{item.name}]" if length is None else f"[{item.name};{length}]"

    @property
    def min_size(self) -> int:
        if self.length is None:
            return 4 + self.item.min_size * (self.pinned or 0)
        return self.item.min_size * self.length

    def encoder(self) -> Encoder:
        if self.item is U8:
            return self._bytes_encoder()
        if isinstance(self.item, Number) or self.item is BOOL:
            return self._packed_encoder()
        item_enc = self.item.encoder()

        def enc(value: Any, out: bytearray) -> None:
            items = _as_list(value)
            self._put_length(len(items), out)
            for i, v in enumerate(items):
                try:
                    item_enc(v, out)
                except EncodeError as e:
                    e._within(f"[{i}]")
                    raise

        return enc

    def _put_length(self, n: int, out: bytearray) -> None:
        if self.pinned is not None and n != self.pinned:
            raise EncodeError(f"the array has {n} items, this node's `refine` pins {self.pinned}")
        if self.length is None:
            put_count(n, out)
        elif n != self.length:
            raise EncodeError(f"the array has {n} items, its type `{self.name}` takes exactly {self.length}")

    def _bytes_encoder(self) -> Encoder:
        def enc(value: Any, out: bytearray) -> None:
            data = as_bytes(value)
            self._put_length(len(data), out)
            out += data

        return enc

    def _packed_encoder(self) -> Encoder:
        item = self.item
        if item is BOOL:

            def enc(value: Any, out: bytearray) -> None:
                items = _as_list(value)
                self._put_length(len(items), out)
                for i, v in enumerate(items):
                    try:
                        out.append(bool_byte(v))
                    except EncodeError as e:
                        e._within(f"[{i}]")
                        raise

            return enc
        code = item.code  # type: ignore[attr-defined]

        def enc(value: Any, out: bytearray) -> None:
            items = _as_list(value)
            self._put_length(len(items), out)
            try:
                out += struct.pack(f"<{len(items)}{code}", *items)
                return
            except (struct.error, OverflowError, TypeError):
                pass
            # Find the item to blame, one at a time.
            single = item.encoder()
            for i, v in enumerate(items):
                try:
                    single(v, bytearray())
                except EncodeError as e:
                    e._within(f"[{i}]")
                    raise
            raise EncodeError("the array does not encode")

        return enc

    def decoder(self) -> Decoder:
        if self.item is U8:
            return self._bytes_decoder()
        if self.item is BOOL:
            return self._bools_decoder()
        if isinstance(self.item, Number):
            return self._packed_decoder()
        item_dec = self.item.decoder()
        read_length = self._length_reader()

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_length(buf, pos)
            out = []
            append = out.append
            for _ in range(n):
                v, pos = item_dec(buf, pos)
                append(v)
            return out, pos

        return dec

    def _length_reader(self) -> Callable[[Any, int], Tuple[int, int]]:
        min_item = self.item.min_size
        length = self.length
        pinned = self.pinned
        if length is None and pinned is not None:

            def counted(buf: Any, pos: int) -> Tuple[int, int]:
                n, after = read_count(buf, pos, min_item)
                if n != pinned:
                    raise DecodeError(pos, f"{n} items where this node's `refine` pins {pinned}")
                return n, after

            return counted
        if length is None:
            return lambda buf, pos: read_count(buf, pos, min_item)

        def fixed(buf: Any, pos: int) -> Tuple[int, int]:
            remaining = len(buf) - pos
            if min_item * length > remaining:
                raise DecodeError(pos, f"fixed array of {length} needs more bytes than the {remaining} left")
            return length, pos

        return fixed

    def _bytes_decoder(self) -> Decoder:
        read_length = self._length_reader()

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_length(buf, pos)
            return bytes(buf[pos : pos + n]), pos + n

        return dec

    def _bools_decoder(self) -> Decoder:
        read_length = self._length_reader()

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_length(buf, pos)
            chunk = bytes(buf[pos : pos + n])
            if n and max(chunk) > 1:
                bad = next(i for i, b in enumerate(chunk) if b > 1)
                raise DecodeError(pos + bad, f"bool byte is {chunk[bad]}, expected 0 or 1")
            return [b == 1 for b in chunk], pos + n

        return dec

    def _packed_decoder(self) -> Decoder:
        read_length = self._length_reader()
        code = self.item.code  # type: ignore[attr-defined]
        size = self.item.min_size

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            n, pos = read_length(buf, pos)
            return list(struct.unpack_from(f"<{n}{code}", buf, pos)), pos + n * size

        return dec


def _as_list(value: Any) -> Sequence[Any]:
    if isinstance(value, (list, tuple)):
        return value
    if isinstance(value, (str, bytes, bytearray, dict)) or value is None:
        raise EncodeError(f"{type(value).__name__} is not an array (a list)")
    try:
        return list(value)
    except TypeError:
        raise EncodeError(f"{value!r} is not an array (a list)") from None


class Optional(WireType):
    """`$optional`: a presence byte, then the value when present (None: absent)."""

    def __init__(self, inner: WireType) -> None:
        if not isinstance(inner, WireType):
            raise TypeError(f"Optional takes a codec type, got {inner!r}")
        self.inner = inner
        self.name = f"{inner.name}?"

    @property
    def min_size(self) -> int:
        return 1

    def encoder(self) -> Encoder:
        inner = self.inner.encoder()

        def enc(value: Any, out: bytearray) -> None:
            if value is None:
                out.append(0)
            else:
                out.append(1)
                inner(value, out)

        return enc

    def decoder(self) -> Decoder:
        inner = self.inner.decoder()

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            if pos >= len(buf):
                raise too_short(1, pos, buf)
            b = buf[pos]
            if b == 0:
                return None, pos + 1
            if b == 1:
                return inner(buf, pos + 1)
            raise DecodeError(pos, f"presence byte is {b}, expected 0 or 1")

        return dec
