"""Start-up inputs (docs/WIRE.md §8): identity, bindings, parameters,
namespace and Zenoh endpoints, from the launcher's runtime-config file
(`PEPPY_RUNTIME_CONFIG`) or, run by hand, from command-line flags."""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .errors import StartupError
from .routing import FROM_ANY_BOUND, PINNED, SlotBinding, SlotPlan, assign
from .spec import NodeDescriptor

RUNTIME_CONFIG_ENV = "PEPPY_RUNTIME_CONFIG"
DEFAULT_NAMESPACE = "default"
STANDALONE_CORE = "standalone"
STANDALONE_INSTANCE = "standalone"

_NAME = re.compile(r"[A-Za-z0-9_-]+\Z")


def check_name(what: str, value: Any) -> str:
    """`value` if it is a valid instance id / core node / namespace, else StartupError."""
    if not isinstance(value, str) or not _NAME.match(value):
        raise StartupError(
            f"invalid {what} `{value}`: "
            + ("must not be empty" if value == "" else "allowed: ASCII letters, digits, `_` and `-`")
        )
    return value


@dataclass(frozen=True)
class Login:
    """A Zenoh user name and password (user-password authentication)."""

    user: str
    password: str = field(repr=False)


@dataclass(frozen=True)
class Endpoints:
    """How to reach the other nodes."""

    mode: Optional[str] = None
    listen: Tuple[str, ...] = ()
    connect: Tuple[str, ...] = ()
    multicast_scouting: bool = False
    login: Optional[Login] = None

    def zenoh_config(self) -> Any:
        """The Zenoh configuration for these settings."""
        import zenoh

        config = zenoh.Config()

        def put(key: str, value: Any, shown: Any = None) -> None:
            try:
                config.insert_json5(key, json.dumps(value))
            except Exception as e:
                what = shown if shown is not None else json.dumps(value)
                raise StartupError(f"invalid zenoh setting `{key}` = {what}: {e}") from None

        put("mode", self.mode or "peer")
        if self.listen:
            put("listen/endpoints", list(self.listen))
        if self.connect:
            put("connect/endpoints", list(self.connect))
        put("scouting/multicast/enabled", self.multicast_scouting)
        if self.login is not None:
            put("transport/auth/usrpwd/user", self.login.user)
            put("transport/auth/usrpwd/password", self.login.password, shown="<redacted>")
        # A Python node never publishes through shared memory, and mapping a
        # producer's pool needs locked memory it may not have (a message
        # that cannot be mapped is lost inside Zenoh): with it off, a
        # producer on this host sends this node ordinary bytes.
        try:
            config.insert_json5("transport/shared_memory/enabled", "false")
        except Exception:
            pass
        return config


@dataclass
class Startup:
    """Everything the node needs, resolved and checked."""

    instance_id: str
    core_node: str
    namespace: str
    endpoints: Endpoints
    slots: List[SlotPlan]
    parameters: Any
    overrides: Dict[str, str] = field(default_factory=dict)


def _reject_unknown(data: Dict[str, Any], allowed: Sequence[str], where: str) -> None:
    extra = [k for k in data if k not in allowed]
    if extra:
        raise StartupError(f"{where}: unknown field `{extra[0]}` (expected one of {', '.join(allowed)})")


def _strings(value: Any, where: str) -> Tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise StartupError(f"{where} must be a list of strings")
    return tuple(value)


def endpoints_from_json(data: Any, where: str) -> Endpoints:
    """The `zenoh` section of a runtime config."""
    if not isinstance(data, dict):
        raise StartupError(f"{where}: `zenoh` must be an object")
    _reject_unknown(data, ("mode", "listen", "connect", "multicast_scouting", "login"), where)
    mode = data.get("mode")
    if mode is not None and not isinstance(mode, str):
        raise StartupError(f"{where}: `zenoh.mode` must be a string")
    scouting = data.get("multicast_scouting", False)
    if not isinstance(scouting, bool):
        raise StartupError(f"{where}: `zenoh.multicast_scouting` must be true or false")
    login = data.get("login")
    if login is not None:
        if not isinstance(login, dict):
            raise StartupError(f"{where}: `zenoh.login` must be an object")
        _reject_unknown(login, ("user", "password"), where)
        if not isinstance(login.get("user"), str) or not isinstance(login.get("password"), str):
            raise StartupError(f"{where}: `zenoh.login` needs `user` and `password` strings")
        login = Login(login["user"], login["password"])
    return Endpoints(
        mode=mode,
        listen=_strings(data.get("listen", []), f"{where}: `zenoh.listen`"),
        connect=_strings(data.get("connect", []), f"{where}: `zenoh.connect`"),
        multicast_scouting=scouting,
        login=login,
    )


def read_config_file(path: str, descriptor: NodeDescriptor) -> Startup:
    """A launcher's runtime config: checked as strictly as the Rust runtime reads it."""
    where = f"invalid runtime config `{path}` ({RUNTIME_CONFIG_ENV})"
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise StartupError(f"cannot read the runtime config `{path}` ({RUNTIME_CONFIG_ENV}): {e}") from None
    try:
        data = json.loads(text)
    except ValueError as e:
        raise StartupError(f"{where}: {e}") from None
    if not isinstance(data, dict):
        raise StartupError(f"{where}: expected a JSON object")
    _reject_unknown(data, ("instance_id", "core_node", "namespace", "bindings", "parameters", "zenoh"), where)
    for required in ("instance_id", "core_node", "namespace"):
        if not isinstance(data.get(required), str):
            raise StartupError(f"{where}: missing `{required}` (a string)")
    instance_id = check_name("instance id", data["instance_id"])
    core_node = check_name("core node", data["core_node"])
    namespace = check_name("namespace", data["namespace"])
    bindings = data.get("bindings") or {}
    if not isinstance(bindings, dict):
        raise StartupError(f"{where}: `bindings` must be an object")
    binds: List[Tuple[str, str]] = []
    for link_id, raw in bindings.items():
        if descriptor.slot(link_id) is None:
            raise StartupError(
                f"the runtime config binds `{link_id}`, which is not a slot of `{descriptor.name}:{descriptor.tag}`; "
                f"was this program generated from another {descriptor.document} than the launcher read?"
            )
        binding = SlotBinding.from_json(raw, link_id)
        if binding.kind in (PINNED, FROM_ANY_BOUND):
            binds.extend((link_id, p) for p in binding.producers)
    return Startup(
        instance_id=instance_id,
        core_node=core_node,
        namespace=namespace,
        endpoints=endpoints_from_json(data.get("zenoh", {}), where),
        slots=assign(instance_id, descriptor.slots, binds),
        parameters=data.get("parameters"),
    )


def usage(descriptor: NodeDescriptor) -> str:
    """The help text of a standalone run."""
    lines = [
        f"Node `{descriptor.name}:{descriptor.tag}`. Started by `peppy-launch`, or standalone with these flags.",
        "",
        "Usage: [OPTIONS] [KEY=VALUE]...",
        "",
        "Options:",
        "  --instance-id <ID>      this instance's id (default: standalone)",
        "  --bind <KEY@INSTANCE>   bind a slot, e.g. --bind left_cam@rs_left (repeatable)",
        "  --params <FILE.json>    parameter values from a JSON file",
        "  --namespace <NS>        the namespace to join (default: default)",
        "  --connect <ENDPOINT>    a Zenoh endpoint to connect to (repeatable), e.g. tcp/10.0.0.2:7447",
        "  --listen <ENDPOINT>     a Zenoh endpoint to listen on (repeatable)",
        "  KEY=VALUE               a parameter override, dot-paths for groups (video.fps=30)",
    ]
    if descriptor.slots:
        lines += ["", "Slots:"]
        for s in descriptor.slots:
            many = ", from_any" if s.from_any else ""
            lines.append(f"  {s.link_id}: {s.kind} `{s.name}:{s.tag}`{many}")
    return "\n".join(lines)


_FLAGS = ("--instance-id", "--bind", "--params", "--namespace", "--connect", "--listen")


def _parse_flags(args: Sequence[str], descriptor: NodeDescriptor) -> Tuple[Dict[str, List[str]], List[str]]:
    flags: Dict[str, List[str]] = {f: [] for f in _FLAGS}
    positional: List[str] = []
    i = 0
    only_positional = False
    while i < len(args):
        arg = args[i]
        i += 1
        if only_positional or not arg.startswith("-"):
            positional.append(arg)
            continue
        if arg == "--":
            only_positional = True
            continue
        if arg in ("-h", "--help"):
            raise StartupError(usage(descriptor))
        name, eq, value = arg.partition("=")
        if name not in flags:
            raise StartupError(f"unexpected argument `{arg}`\n\n{usage(descriptor)}")
        if not eq:
            if i >= len(args):
                raise StartupError(f"`{name}` needs a value\n\n{usage(descriptor)}")
            value = args[i]
            i += 1
        flags[name].append(value)
    for single in ("--instance-id", "--params", "--namespace"):
        if len(flags[single]) > 1:
            raise StartupError(f"`{single}` given more than once\n\n{usage(descriptor)}")
    return flags, positional


def _merge(base: Any, patch: Any) -> Any:
    """Deep merge: objects merge key by key, anything else replaces."""
    if isinstance(base, dict) and isinstance(patch, dict):
        out = dict(base)
        for k, v in patch.items():
            out[k] = _merge(out.get(k), v)
        return out
    return patch


def from_flags(args: Sequence[str], descriptor: NodeDescriptor) -> Startup:
    """The start-up inputs a standalone command line gives."""
    flags, positional = _parse_flags(args, descriptor)
    binds: List[Tuple[str, str]] = []
    for b in flags["--bind"]:
        key, at, instance = b.partition("@")
        if not at or not key or not instance:
            raise StartupError(f"invalid --bind `{b}`: expected KEY@INSTANCE, e.g. --bind left_cam@rs_left")
        binds.append((key, instance))
    parameters: Any = None
    if flags["--params"]:
        file = flags["--params"][0]
        try:
            with open(file, encoding="utf-8") as f:
                parameters = json.load(f)
        except OSError as e:
            raise StartupError(f"cannot read --params `{file}`: {e}") from None
        except ValueError as e:
            raise StartupError(f"--params `{file}` is not valid JSON: {e}") from None
    overrides: Dict[str, str] = {}
    for o in positional:
        path, eq, raw = o.partition("=")
        if not eq or not path:
            raise StartupError(f"unexpected argument `{o}`: parameter overrides are `key=value` (dot-paths for groups)")
        try:
            value: Any = json.loads(raw)
        except ValueError:
            value = raw
        for key in reversed(path.split(".")):
            value = {key: value}
        parameters = _merge(parameters, value)
        overrides[path] = raw
    if flags["--connect"] or flags["--listen"]:
        endpoints = Endpoints(listen=tuple(flags["--listen"]), connect=tuple(flags["--connect"]))
    else:
        endpoints = Endpoints(multicast_scouting=True)
    instance_id = check_name("instance id", (flags["--instance-id"] or [STANDALONE_INSTANCE])[0])
    namespace = check_name("namespace", (flags["--namespace"] or [DEFAULT_NAMESPACE])[0])
    return Startup(
        instance_id=instance_id,
        core_node=STANDALONE_CORE,
        namespace=namespace,
        endpoints=endpoints,
        slots=assign(instance_id, descriptor.slots, binds),
        parameters=parameters,
        overrides=overrides,
    )


def load(descriptor: NodeDescriptor, args: Sequence[str], config_file: Optional[str]) -> Startup:
    """The runtime config when the launcher names one, else the flags in `args`."""
    if config_file:
        return read_config_file(config_file, descriptor)
    return from_flags(args, descriptor)


def config_file_from_env() -> Optional[str]:
    """The runtime-config path the launcher set, if any."""
    return os.environ.get(RUNTIME_CONFIG_ENV) or None
