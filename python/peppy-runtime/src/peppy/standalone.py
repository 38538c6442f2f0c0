"""`StandaloneConfig`: what a node started by hand (no launcher, no
`PEPPY_RUNTIME_CONFIG`) uses when its command line does not say otherwise.
A launcher's runtime config always wins."""

from __future__ import annotations

import dataclasses
import json
import tempfile
from typing import Any, Dict, List, Optional, Sequence, Tuple


class StandaloneConfig:
    """Defaults for a standalone start, each replaced by the matching
    command-line flag when one is given:
    `NodeBuilder().standalone(StandaloneConfig().with_instance_id("cam_1")).run(setup)`."""

    def __init__(self) -> None:
        self.parameters: Any = None
        self.instance_id: Optional[str] = None
        self.messaging: Optional[Tuple[str, int]] = None
        self.use_sim_time: Optional[bool] = None
        self.links: List[Tuple[str, str]] = []
        self.vacant: List[str] = []
        self.cores: Dict[str, str] = {}
        self.written: List[str] = []

    def with_parameters(self, parameters: Any) -> "StandaloneConfig":
        """Parameter values: the generated `Parameters` dataclass, or a dict."""
        self.parameters = parameters
        return self

    def with_instance_id(self, instance_id: str) -> "StandaloneConfig":
        """This instance's id."""
        self.instance_id = instance_id
        return self

    def with_messaging(self, host: str, port: int) -> "StandaloneConfig":
        """Connects to the Zenoh endpoint `tcp/<host>:<port>`."""
        self.messaging = (host, int(port))
        return self

    def with_use_sim_time(self, use_sim_time: bool = True) -> "StandaloneConfig":
        """Follows the stack's sim time (`peppy.clock`) instead of the wall clock."""
        self.use_sim_time = bool(use_sim_time)
        return self

    def with_messaging_host(self, host: str) -> "StandaloneConfig":
        """The host of the Zenoh endpoint (port 7447 until `with_messaging_port`)."""
        _, port = self.messaging or ("127.0.0.1", 7447)
        self.messaging = (host, port)
        return self

    def with_messaging_port(self, port: int) -> "StandaloneConfig":
        """The port of the Zenoh endpoint (on 127.0.0.1 until `with_messaging_host`)."""
        host, _ = self.messaging or ("127.0.0.1", 7447)
        self.messaging = (host, int(port))
        return self

    def with_bound_producer(self, link_id: str, core_node: str, instance_id: str) -> "StandaloneConfig":
        """Links slot `link_id` to producer `instance_id` of core node
        `core_node` (repeat for a list slot). Instance ids name producers in
        a stack; `core_node` is where the producer runs, as the slot's
        `bound_producer(s)` tell it."""
        self.links.append((link_id, instance_id))
        self.cores[instance_id] = core_node
        return self

    def with_peer_pin(self, link_id: str, core_node: str, instance_id: str, peer_link_id: str) -> "StandaloneConfig":
        """Pins pairing slot `link_id` to slot `peer_link_id` of instance
        `instance_id` (as `--link link_id@instance_id/peer_link_id`)."""
        del core_node
        self.links.append((link_id, f"{instance_id}/{peer_link_id}"))
        return self

    def with_observed_source(
        self, link_id: str, core_node: str, instance_id: str, source_link_id: str
    ) -> "StandaloneConfig":
        """Adds slot `source_link_id` of instance `instance_id` to observer
        slot `link_id`'s sources (repeat for several)."""
        del core_node
        self.links.append((link_id, f"{instance_id}/{source_link_id}"))
        return self

    def with_vacant_producer_slot(self, link_id: str) -> "StandaloneConfig":
        """Leaves the `zero_or_one` slot `link_id` empty on purpose."""
        self.vacant.append(link_id)
        return self

    def flags(self, given: Sequence[str]) -> List[str]:
        """The flags these defaults add to a command line `given`."""

        def has(flag: str) -> bool:
            return any(a == flag or a.startswith(flag + "=") for a in given)

        out: List[str] = []
        if self.instance_id is not None and not has("--instance-id"):
            out += ["--instance-id", self.instance_id]
        if self.messaging is not None and not has("--connect"):
            host, port = self.messaging
            out += ["--connect", f"tcp/{host}:{port}"]
        if not has("--link") and not has("--vacant-link") and not has("--bind"):
            for link_id, instance in self.links:
                out += ["--link", f"{link_id}@{instance}"]
            for link_id in self.vacant:
                out += ["--vacant-link", f"{link_id}=left vacant by the node's StandaloneConfig"]
        if self.parameters is not None and not has("--params"):
            path = _parameters_file(self.parameters)
            self.written.append(path)
            out += ["--params", path]
        return out


def _parameters_file(parameters: Any) -> str:
    """A JSON file holding `parameters`, for `peppy-launch plan --params`."""
    if dataclasses.is_dataclass(parameters) and not isinstance(parameters, type):
        data = dataclasses.asdict(parameters)
    else:
        data = parameters
    with tempfile.NamedTemporaryFile("w", suffix=".json", prefix="peppy-params-", delete=False) as f:
        json.dump(data, f)
        return f.name
