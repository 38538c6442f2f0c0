"""Start-up inputs (docs/WIRE.md §8): identity, slots, parameters,
namespace and Zenoh endpoints. They are a plan decided by peppy's one
binding engine and parameter checker (peppy-schema): the launcher's
runtime-config file (`PEPPY_RUNTIME_CONFIG`), or, for a node started by
hand, the plan `peppy-launch plan` gives its command line. This module
reads a plan; it never binds or checks parameters itself."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .errors import StartupError
from .pair_plan import PairPlan, fit_pair_plans, pair_plan_from_json
from .routing import SlotPlan, fit_plan, slot_from_json
from .spec import NodeDescriptor

RUNTIME_CONFIG_ENV = "PEPPY_RUNTIME_CONFIG"
SHUTDOWN_GRACE_ENV = "PEPPY_SHUTDOWN_GRACE_SECS"
"""Overrides the shutdown grace window (seconds) of the plan and of the code."""
DEFAULT_SHUTDOWN_GRACE = 5.0
"""How long shutdown hooks have, together, when nothing says otherwise (seconds)."""
MAX_SHUTDOWN_GRACE = 31_536_000.0
"""The longest window (a year), as `peppy_schema::MAX_SHUTDOWN_GRACE_SECS`:
both runtimes check the vectors of tests/golden/wire.json's `grace`."""
PEPPY_LAUNCH_ENV = "PEPPY_LAUNCH"
"""The `peppy-launch` program a node started by hand asks for its plan
(else `peppy-launch` on `PATH`)."""


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
    use_sim_time: bool = False
    """Whether the node follows the stack's sim time (`peppy.clock`)."""
    shutdown_grace_secs: Optional[float] = None
    """The one window every shutdown hook runs in (seconds, > 0); None when
    the plan does not say (the node's own choice, else 5 s)."""
    pairs: List[PairPlan] = field(default_factory=list)
    """One plan per pairing slot, in the node's order (docs/PAIRINGS.md)."""
    producer_cores: Dict[str, str] = field(default_factory=dict)
    """The core node of each bound producer that runs on another core node
    than this instance, by instance id (what `bound_producer(s)` say)."""


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
    """A launcher's runtime config. Its shape is checked here; what it says
    (names, slots, parameters) the launcher decided and checked already."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise StartupError(f"cannot read the runtime config `{path}` ({RUNTIME_CONFIG_ENV}): {e}") from None
    return plan_from_text(text, f"invalid runtime config `{path}` ({RUNTIME_CONFIG_ENV})", descriptor)


_PLAN_FIELDS = (
    "instance_id",
    "core_node",
    "namespace",
    "slots",
    "pairs",
    "parameters",
    "zenoh",
    "use_sim_time",
    "shutdown_grace_secs",
    # Direct links (same-host Unix sockets beside Zenoh) are the Rust
    # runtime's: a Python node reads and publishes through Zenoh, where a
    # Rust producer also publishes everything it sends over a link.
    "direct_links",
    "producer_cores",
)


def grace_secs(value: Any, where: str) -> float:
    """A shutdown grace window: a number of seconds above 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or value != value:
        raise StartupError(f"{where}: `shutdown_grace_secs` must be a number of seconds above 0, got {value!r}")
    if value == float("inf"):
        raise StartupError(f"{where}: `shutdown_grace_secs` must be finite")
    if value > MAX_SHUTDOWN_GRACE:
        raise StartupError(f"{where}: `shutdown_grace_secs` must be at most a year ({MAX_SHUTDOWN_GRACE:g} s), got {value!r}")
    return float(value)


# A number as Rust's `f64::from_str` reads it: Python's `float` also takes
# `1_000` and digits of other scripts, which the node's launcher refuses.
_RUST_FLOAT = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.ASCII | re.IGNORECASE)


def grace_from_env() -> Optional[float]:
    """`PEPPY_SHUTDOWN_GRACE_SECS`, when set (as `peppy_schema::grace_window_env`
    reads it: blank is unset)."""
    text = os.environ.get(SHUTDOWN_GRACE_ENV)
    if text is None or text.strip() == "":
        return None
    if not _RUST_FLOAT.fullmatch(text.strip()):
        raise StartupError(f"{SHUTDOWN_GRACE_ENV}: `shutdown_grace_secs` must be a number, got {text!r}")
    return grace_secs(float(text), SHUTDOWN_GRACE_ENV)


def plan_from_text(text: str, where: str, descriptor: NodeDescriptor) -> Startup:
    """A plan (`peppy_runtime::StartupConfig` as JSON), applied to this node."""
    try:
        data = json.loads(text)
    except ValueError as e:
        raise StartupError(f"{where}: {e}") from None
    if not isinstance(data, dict):
        raise StartupError(f"{where}: expected a JSON object")
    _reject_unknown(data, _PLAN_FIELDS, where)
    for required in ("instance_id", "core_node", "namespace"):
        if not isinstance(data.get(required), str):
            raise StartupError(f"{where}: missing `{required}` (a string)")
    slots = data.get("slots", [])
    if not isinstance(slots, list):
        raise StartupError(f"{where}: `slots` must be a list")
    pairs = data.get("pairs", [])
    if not isinstance(pairs, list):
        raise StartupError(f"{where}: `pairs` must be a list")
    parameters = data.get("parameters")
    use_sim_time = data.get("use_sim_time", False)
    if not isinstance(use_sim_time, bool):
        raise StartupError(f"{where}: `use_sim_time` must be true or false")
    grace = data.get("shutdown_grace_secs")
    if not isinstance(data.get("direct_links", ""), str):
        raise StartupError(f"{where}: `direct_links` must be a directory's path")
    cores = data.get("producer_cores", {})
    if not isinstance(cores, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in cores.items()):
        raise StartupError(f"{where}: `producer_cores` must map instance ids to core node names")
    return Startup(
        instance_id=data["instance_id"],
        core_node=data["core_node"],
        namespace=data["namespace"],
        endpoints=endpoints_from_json(data.get("zenoh", {}), where),
        slots=fit_plan([slot_from_json(s) for s in slots], descriptor.slots),
        parameters={} if parameters is None else parameters,
        use_sim_time=use_sim_time,
        shutdown_grace_secs=None if grace is None else grace_secs(grace, where),
        pairs=fit_pair_plans([pair_plan_from_json(p) for p in pairs], descriptor.pairings),
        producer_cores=dict(cores),
    )


def peppy_launch(descriptor: Optional[NodeDescriptor] = None) -> Optional[str]:
    """The `peppy-launch` program: `PEPPY_LAUNCH`, else the one that wrote
    the node's generated package (recorded by `sync`, while it is still
    there), else the one on `PATH`."""
    named = os.environ.get(PEPPY_LAUNCH_ENV)
    if named:
        return named
    recorded = descriptor.engine if descriptor is not None else None
    if recorded and os.path.isfile(recorded) and os.access(recorded, os.X_OK):
        return recorded
    return shutil.which("peppy-launch")


def plan_text_from_flags(args: Sequence[str], descriptor: NodeDescriptor) -> str:
    """The plan (JSON text) a standalone command line gives: `peppy-launch
    plan` runs the node's flags (`--instance-id`, `--link`, `--params`,
    `key=value`, ...) through the engine a launch uses, so a Python node
    started by hand (or by the test harness) binds and checks its
    parameters exactly as a Rust one does."""
    if descriptor.model is None:
        raise StartupError(
            f"node `{descriptor.name}:{descriptor.tag}` has no model to plan with; "
            "regenerate its peppygen (`peppy-launch sync`) or give it a runtime config"
        )
    program = peppy_launch(descriptor)
    if program is None:
        recorded = f" (the one that wrote peppygen, {descriptor.engine}, is gone)" if descriptor.engine else ""
        raise StartupError(
            "a node started by hand asks `peppy-launch plan` for its slots and parameters, and "
            f"peppy-launch was not found{recorded}: rerun `peppy-launch sync`, put it on PATH, "
            f"set {PEPPY_LAUNCH_ENV}, or start the node with `peppy-launch run NODE_DIR ...`"
        )
    try:
        done = subprocess.run(
            [program, "plan", "--model", "-", "--", *args],
            input=descriptor.model,
            capture_output=True,
            text=True,
            timeout=60,
        )
    except (OSError, subprocess.SubprocessError) as e:
        raise StartupError(f"cannot run `{program} plan`: {e}") from None
    if done.returncode != 0:
        message = done.stderr.strip()
        raise StartupError(message.removeprefix("peppy-launch: ") or f"`{program} plan` failed")
    return done.stdout


def from_flags(args: Sequence[str], descriptor: NodeDescriptor) -> Startup:
    """The plan a standalone command line gives (`plan_text_from_flags`),
    applied to this node."""
    text = plan_text_from_flags(args, descriptor)
    return plan_from_text(text, "`peppy-launch plan` answered", descriptor)


def load(descriptor: NodeDescriptor, args: Sequence[str], config_file: Optional[str]) -> Startup:
    """The runtime config when the launcher names one, else the plan the flags in `args` give."""
    if config_file:
        return read_config_file(config_file, descriptor)
    return from_flags(args, descriptor)


def config_file_from_env() -> Optional[str]:
    """The runtime-config path the launcher set, if any."""
    return os.environ.get(RUNTIME_CONFIG_ENV) or None
