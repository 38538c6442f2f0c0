"""Reading parameter values: the helpers generated `Parameters.from_json`
methods call. The values come checked and with every default filled in
(peppy-schema's `ParameterSchema::resolve`, in the launcher or in
`peppy-launch plan`); these helpers only turn JSON into Python values
(`bytes`, `float`), and name a value that is not there, which means the
package was generated from other documents than the plan."""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Union


def _path(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _absent(path: str) -> ValueError:
    return ValueError(
        f"the plan has no value for parameter `{path}`; "
        "was this peppygen generated from another peppy.json5 than the launcher read?"
    )


def _value(type_name: str, v: Any) -> Any:
    """A checked JSON value as the Python type generated code declares."""
    if type_name == "bytes":
        if isinstance(v, str):
            return v.encode("utf-8")
        if isinstance(v, list):
            return bytes(v)
    if type_name in ("f32", "f64", "time") and isinstance(v, int) and not isinstance(v, bool):
        return float(v)
    return v


def leaf(data: Dict[str, Any], key: str, type_name: str, where: str = "") -> Any:
    """The value of leaf parameter `key`."""
    path = _path(where, key)
    if key not in data:
        raise _absent(path)
    return _value(type_name, data[key])


def group(data: Dict[str, Any], key: str, from_json: Callable[[Any, str], Any], where: str = "") -> Any:
    """A parameter group, read by its generated class's `from_json`."""
    path = _path(where, key)
    if not isinstance(data.get(key), dict):
        raise _absent(path)
    return from_json(data[key], path)


def array(
    data: Dict[str, Any],
    key: str,
    item: Union[str, Callable[[Any, str], Any]],
    where: str = "",
) -> List[Any]:
    """An array parameter; `item` is a primitive type name or an item class's `from_json`."""
    path = _path(where, key)
    values = data.get(key)
    if not isinstance(values, list):
        raise _absent(path)
    if isinstance(item, str):
        return [_value(item, v) for v in values]
    return [item(v, f"{path}[{i}]") for i, v in enumerate(values)]
