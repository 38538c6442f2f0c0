"""Reading parameter values: the helpers generated `Parameters.from_json`
methods call. They check values and fill defaults as peppy-schema's
`ParameterSchema::resolve` does, with the same messages."""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import json
import math
import re
from typing import Any, Callable, Dict, Iterator, List, Optional, Union

MISSING: Any = type("Missing", (), {"__repr__": lambda self: "MISSING"})()
"""The default of a parameter that has none: it must be given."""

_F32_MAX = 3.4028234663852886e38
_INT_RANGES = {
    "u8": (0, 0xFF),
    "u16": (0, 0xFFFF),
    "u32": (0, 0xFFFFFFFF),
    "u64": (0, (1 << 64) - 1),
    "i8": (-0x80, 0x7F),
    "i16": (-0x8000, 0x7FFF),
    "i32": (-(1 << 31), (1 << 31) - 1),
    "i64": (-(1 << 63), (1 << 63) - 1),
}
_INTEGER = re.compile(r"[+-]?[0-9]+\Z")

# Command-line `key=value` texts by dot-path, typed here by the declared
# type (as the Rust runtime types them) rather than guessed from the text.
_overrides: contextvars.ContextVar[Dict[str, str]] = contextvars.ContextVar("peppy_overrides", default={})


@contextlib.contextmanager
def typed_overrides(raw: Dict[str, str]) -> Iterator[None]:
    """While active, a leaf whose path is in `raw` reads that text, typed by its declared type."""
    token = _overrides.set(dict(raw))
    try:
        yield
    finally:
        _overrides.reset(token)


def _path(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _describe(type_name: str) -> str:
    if type_name in _INT_RANGES:
        lo, hi = _INT_RANGES[type_name]
        return f"a `{type_name}` (an integer from {lo} to {hi})"
    return {
        "bool": "a `bool` (true or false)",
        "f32": "an `f32` (a finite number)",
        "f64": "an `f64` (a number)",
        "string": "a `string`",
        "bytes": "`bytes` (a string or an array of 0..=255)",
        "time": "a `time` (seconds since the Unix epoch)",
    }.get(type_name, f"a `{type_name}`")


def _found(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return f"`{'true' if v else 'false'}`"
    if isinstance(v, (int, float)):
        return f"`{v}`"
    if isinstance(v, str):
        return f"the string {json.dumps(v, ensure_ascii=False)}"
    if isinstance(v, (list, tuple)):
        return "an array"
    if isinstance(v, dict):
        return "an object"
    return repr(v)


def _mismatch(path: str, expected: str, v: Any) -> ValueError:
    return ValueError(f"parameter `{path}` expects {expected}, found {_found(v)}")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _typed_text(type_name: str, raw: str) -> Any:
    """A command-line text as the declared type reads it (else the text)."""
    if type_name == "bool":
        return {"true": True, "false": False}.get(raw, raw)
    if type_name in ("string", "bytes"):
        return raw
    if type_name in ("f32", "f64", "time"):
        try:
            f = float(raw)
        except ValueError:
            return raw
        return f if math.isfinite(f) else raw
    return int(raw) if _INTEGER.match(raw) else raw


def check(type_name: str, v: Any, path: str) -> Any:
    """`v` as a value of primitive `type_name`, or ValueError naming `path`."""
    if type_name == "bool":
        ok = isinstance(v, bool)
    elif type_name == "f32":
        ok = _is_number(v) and math.isfinite(v) and abs(v) <= _F32_MAX
    elif type_name == "f64":
        ok = _is_number(v)
    elif type_name == "time":
        ok = _is_number(v) and math.isfinite(v)
    elif type_name == "string":
        ok = isinstance(v, str)
    elif type_name == "bytes":
        if isinstance(v, str):
            return v.encode("utf-8")
        if isinstance(v, (bytes, bytearray)):
            return bytes(v)
        ok = isinstance(v, list) and all(isinstance(b, int) and not isinstance(b, bool) and 0 <= b <= 255 for b in v)
        if ok:
            return bytes(v)
    elif type_name in _INT_RANGES:
        lo, hi = _INT_RANGES[type_name]
        ok = isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi
    else:
        raise ValueError(f"parameter `{path}` has an unknown type `{type_name}`")
    if not ok:
        raise _mismatch(path, _describe(type_name), v)
    if type_name in ("f32", "f64", "time"):
        return float(v)
    return v


def leaf(data: Dict[str, Any], key: str, default: Any, type_name: str, where: str = "") -> Any:
    """The value of leaf parameter `key`: given, else its default; checked."""
    path = _path(where, key)
    raw = _overrides.get().get(path)
    if raw is not None:
        return check(type_name, _typed_text(type_name, raw), path)
    if key in data:
        return check(type_name, data[key], path)
    if default is MISSING:
        raise ValueError(f"missing required parameter `{path}` ({_describe(type_name)})")
    return check(type_name, default, path)


def group(data: Dict[str, Any], key: str, from_json: Callable[[Any, str], Any], where: str = "") -> Any:
    """A parameter group: its own leaves' defaults fill in when it is not given."""
    path = _path(where, key)
    given = data.get(key, MISSING)
    if given is MISSING:
        given = {}
    elif not isinstance(given, dict):
        raise _mismatch(path, "an object (a parameter group)", given)
    value = from_json(given, path)
    refuse_unknown(given, value, path)
    return value


def _describe_array(item: Union[str, Callable[..., Any]], length: Optional[int]) -> str:
    name = item if isinstance(item, str) else "object"
    return f"an array of exactly {length} `{name}`" if length is not None else f"an array of `{name}`"


def array(
    data: Dict[str, Any],
    key: str,
    default: Any,
    item: Union[str, Callable[[Any, str], Any]],
    length: Optional[int],
    where: str = "",
) -> List[Any]:
    """An array parameter; `item` is a primitive type name or an item class's `from_json`."""
    path = _path(where, key)
    if key in data:
        values = data[key]
    elif default is MISSING:
        raise ValueError(f"missing required parameter `{path}` ({_describe_array(item, length)})")
    else:
        values = default
    if not isinstance(values, list) or (length is not None and len(values) != length):
        raise _mismatch(path, _describe_array(item, length), values)
    out = []
    for i, v in enumerate(values):
        ipath = f"{path}[{i}]"
        if isinstance(item, str):
            out.append(check(item, v, ipath))
        elif isinstance(v, dict):
            value = item(v, ipath)
            refuse_unknown(v, value, ipath)
            out.append(value)
        else:
            raise _mismatch(ipath, "an object", v)
    return out


def refuse_unknown(given: Dict[str, Any], value: Any, where: str = "") -> None:
    """ValueError for a key of `given` that the group read into `value`
    (a dataclass) does not declare (keyword names carry a trailing `_`)."""
    if not dataclasses.is_dataclass(value):
        return
    declared = [f.name for f in dataclasses.fields(value)]
    names = {n[:-1] if n.endswith("_") else n for n in declared} | set(declared)
    for key in given:
        if key not in names:
            here = ", ".join(f"`{n}`" for n in declared) or "none"
            raise ValueError(f"unknown parameter `{_path(where, key)}` (parameters here: {here})")
