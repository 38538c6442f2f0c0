"""The codec's objects (docs/WIRE.md §5): described classes, their fields
in declaration order, compiled once into an encoder and a decoder."""

from __future__ import annotations

import struct
from typing import Any, Callable, Dict, List, Sequence, Tuple

from .codec_scalars import (
    DecodeError,
    Decoder,
    EncodeError,
    Encoder,
    Number,
    WireType,
    too_short,
)


class _Layout:
    """A described class: its fields, compiled into one encoder and decoder
    on first use (nested classes may be described after their users)."""

    def __init__(self, cls: type, fields: List[Tuple[str, WireType]]) -> None:
        self.cls = cls
        self.fields = fields
        self._enc: "Encoder | None" = None
        self._dec: "Decoder | None" = None

    @property
    def min_size(self) -> int:
        return sum(t.min_size for _, t in self.fields)

    def encoder(self) -> Encoder:
        if self._enc is None:
            self._enc = self._compile_encoder()
        return self._enc

    def decoder(self) -> Decoder:
        if self._dec is None:
            self._dec = self._compile_decoder()
        return self._dec

    def _runs(self) -> List[Tuple[str, Any]]:
        """Consecutive plain numbers share one struct; other fields stand alone."""
        runs: List[Tuple[str, Any]] = []
        for name, t in self.fields:
            if isinstance(t, Number):
                if runs and runs[-1][0] == "numbers":
                    runs[-1][1].append((name, t))
                else:
                    runs.append(("numbers", [(name, t)]))
            else:
                runs.append(("one", (name, t)))
        return runs

    def _compile_encoder(self) -> Encoder:
        steps: List[Encoder] = []
        for kind, what in self._runs():
            steps.append(_numbers_encoder(what) if kind == "numbers" else _field_encoder(*what))

        def enc(value: Any, out: bytearray) -> None:
            for step in steps:
                step(value, out)

        return enc

    def _compile_decoder(self) -> Decoder:
        cls = self.cls
        steps: List[Callable[[Any, int, Dict[str, Any]], int]] = []
        for kind, what in self._runs():
            steps.append(_numbers_decoder(what) if kind == "numbers" else _field_decoder(*what))

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            values: Dict[str, Any] = {}
            for step in steps:
                pos = step(buf, pos, values)
            return cls(**values), pos

        return dec


def _field_encoder(name: str, t: WireType) -> Encoder:
    inner = t.encoder()

    def enc(value: Any, out: bytearray) -> None:
        try:
            inner(getattr(value, name), out)
        except EncodeError as e:
            e._within("." + name)
            raise
        except AttributeError:
            missing = EncodeError(f"{type(value).__name__} has no attribute `{name}`")
            raise missing._within("." + name) from None

    return enc


def _numbers_encoder(run: List[Tuple[str, Number]]) -> Encoder:
    names = [n for n, _ in run]
    pack = struct.Struct("<" + "".join(t.code for _, t in run)).pack

    def enc(value: Any, out: bytearray) -> None:
        try:
            out += pack(*[getattr(value, n) for n in names])
            return
        except (struct.error, OverflowError, TypeError, AttributeError):
            pass
        # Find the field to blame, one at a time.
        for name, t in run:
            _field_encoder(name, t)(value, bytearray())
        raise EncodeError("the message does not encode")

    return enc


def _field_decoder(name: str, t: WireType) -> Callable[[Any, int, Dict[str, Any]], int]:
    inner = t.decoder()

    def dec(buf: Any, pos: int, values: Dict[str, Any]) -> int:
        values[name], pos = inner(buf, pos)
        return pos

    return dec


def _numbers_decoder(run: List[Tuple[str, Number]]) -> Callable[[Any, int, Dict[str, Any]], int]:
    names = [n for n, _ in run]
    s = struct.Struct("<" + "".join(t.code for _, t in run))
    unpack, size = s.unpack_from, s.size

    def dec(buf: Any, pos: int, values: Dict[str, Any]) -> int:
        if pos + size <= len(buf):
            values.update(zip(names, unpack(buf, pos)))
            return pos + size
        # Report where the bytes ran out, as field-by-field decoding would.
        for name, t in run:
            pos = _field_decoder(name, t)(buf, pos, values)
        raise too_short(size, pos, buf)

    return dec


_LAYOUTS: Dict[type, _Layout] = {}


def describe(cls: type, fields: Sequence[Tuple[str, WireType]]) -> type:
    """Registers the wire layout of `cls`: its `(attribute, type)` fields in
    declaration order. Returns `cls`, so it also works as a decorator helper."""
    checked: List[Tuple[str, WireType]] = []
    for entry in fields:
        try:
            name, t = entry
        except (TypeError, ValueError):
            raise TypeError(f"describe({cls.__name__}): each field is (name, type), got {entry!r}") from None
        if not isinstance(name, str) or not isinstance(t, WireType):
            raise TypeError(f"describe({cls.__name__}): field {entry!r} is not (str, codec type)")
        checked.append((name, t))
    _LAYOUTS[cls] = _Layout(cls, checked)
    return cls


def _layout(cls: type) -> _Layout:
    try:
        return _LAYOUTS[cls]
    except KeyError:
        raise TypeError(f"{getattr(cls, '__name__', cls)!r} has no wire layout: call codec.describe on it") from None


class Obj(WireType):
    """A nested object: a class registered with `describe`."""

    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.name = getattr(cls, "__name__", repr(cls))

    @property
    def min_size(self) -> int:
        return _layout(self.cls).min_size

    def encoder(self) -> Encoder:
        cls = self.cls
        cache: List[Encoder] = []

        def enc(value: Any, out: bytearray) -> None:
            if not cache:
                cache.append(_layout(cls).encoder())
            cache[0](value, out)

        return enc

    def decoder(self) -> Decoder:
        cls = self.cls
        cache: List[Decoder] = []

        def dec(buf: Any, pos: int) -> Tuple[Any, int]:
            if not cache:
                cache.append(_layout(cls).decoder())
            return cache[0](buf, pos)

        return dec


def encode(cls: type, value: Any) -> bytes:
    """The bytes of `value`, an instance of the described `cls`."""
    out = bytearray()
    _layout(cls).encoder()(value, out)
    return bytes(out)


def decode(cls: type, data: Any) -> Any:
    """An instance of the described `cls` from exactly `data` (bytes or a
    memoryview); `DecodeError` for anything else, trailing bytes included."""
    value, pos = _layout(cls).decoder()(data, 0)
    if pos != len(data):
        raise DecodeError(pos, f"{len(data) - pos} unexpected trailing bytes")
    return value
