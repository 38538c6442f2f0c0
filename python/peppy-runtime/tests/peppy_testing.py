"""Shared by the live tests: message formats and node descriptors written
by hand as generated code would write them, and a way to start nodes on
loopback (explicit endpoints, multicast scouting off, one namespace per test)."""

from __future__ import annotations

import asyncio
import json
import os
import socket
import subprocess
import tempfile
import unittest
import uuid
from dataclasses import dataclass
from typing import Any, Dict, List, Optional

from peppy import NodeBuilder, NodeRunner, QoSProfile
from peppy import codec as c
from peppy import spec as s
from peppy.members import live_instances
from peppy.startup import PEPPY_LAUNCH_ENV, peppy_launch

WAIT = 10.0
"""The bound on every wait of a live test (seconds)."""


def fmt(cls: Any, canonical: str) -> c.Format:
    """A format as generated code writes it (the fingerprint as a literal)."""
    return c.Format(cls, canonical, c.fingerprint_of(canonical))


@dataclass
class Reading:
    """`{seq:u32,label:string}`."""

    seq: int
    label: str


c.describe(Reading, [("seq", c.U32), ("label", c.STRING)])
READING = fmt(Reading, "{seq:u32,label:string}")


@dataclass
class Wide:
    """`{seq:u64}`: another format on the same topic name."""

    seq: int


c.describe(Wide, [("seq", c.U64)])
WIDE = fmt(Wide, "{seq:u64}")


@dataclass
class AddRequest:
    a: int
    b: int


@dataclass
class AddResponse:
    sum: int


c.describe(AddRequest, [("a", c.I32), ("b", c.I32)])
c.describe(AddResponse, [("sum", c.I64)])
ADD_REQUEST = fmt(AddRequest, "{a:i32,b:i32}")
ADD_RESPONSE = fmt(AddResponse, "{sum:i64}")


@dataclass
class MoveGoal:
    distance: float


@dataclass
class MoveFeedback:
    progress: float


@dataclass
class MoveResult:
    travelled: float


c.describe(MoveGoal, [("distance", c.F64)])
c.describe(MoveFeedback, [("progress", c.F32)])
c.describe(MoveResult, [("travelled", c.F64)])
MOVE_GOAL = fmt(MoveGoal, "{distance:f64}")
MOVE_FEEDBACK = fmt(MoveFeedback, "{progress:f32}")
MOVE_RESULT = fmt(MoveResult, "{travelled:f64}")

DEPTH = s.Owner.interface("depth_camera", "v1")
CAMERA = s.Owner.node("camera", "v1")

# camera:v1, conforming to depth_camera:v1.
READINGS_OUT = s.TopicSpec(s.Owner.own(), "readings", QoSProfile.STANDARD, READING)
VIDEO_OUT = s.TopicSpec(DEPTH, "video", QoSProfile.RELIABLE, READING)
MISMATCH_OUT = s.TopicSpec(s.Owner.own(), "mismatch", QoSProfile.STANDARD, WIDE)
ADD_SERVED = s.ServiceSpec(s.Owner.own(), "add", ADD_REQUEST, ADD_RESPONSE)
ADD_SERVED_IFACE = s.ServiceSpec(DEPTH, "add", ADD_REQUEST, ADD_RESPONSE)
MOVE_SERVED = s.ActionSpec(s.Owner.own(), "move", MOVE_GOAL, MOVE_FEEDBACK, MOVE_RESULT)

CAMERA_NODE = s.NodeDescriptor(
    name="camera",
    tag="v1",
    emitted_topics=(READINGS_OUT, VIDEO_OUT, MISMATCH_OUT),
    exposed_services=(ADD_SERVED, ADD_SERVED_IFACE),
    exposed_actions=(MOVE_SERVED,),
)

# lidar:v1, also conforming to depth_camera:v1.
LIDAR_NODE = s.NodeDescriptor(name="lidar", tag="v1", emitted_topics=(VIDEO_OUT,), exposed_services=(ADD_SERVED_IFACE,))

# viewer:v1: a pinned node slot, a from_any interface slot, a from_any node slot.
READINGS_IN = s.ConsumedTopicSpec("cam", CAMERA, "readings", QoSProfile.STANDARD, READING)
VIDEO_IN = s.ConsumedTopicSpec("cams", DEPTH, "video", QoSProfile.RELIABLE, READING)
VIDEO_ANY_CAMERA_IN = s.ConsumedTopicSpec("any_cam", DEPTH, "video", QoSProfile.RELIABLE, READING)
EXTERNAL_READINGS_IN = s.ConsumedTopicSpec(None, s.Owner.any(), "readings", QoSProfile.STANDARD, READING)
MISMATCH_IN = s.ConsumedTopicSpec("cam", CAMERA, "mismatch", QoSProfile.STANDARD, READING)
ADD_PINNED = s.ConsumedServiceSpec("cam", CAMERA, "add", ADD_REQUEST, ADD_RESPONSE)
ADD_PROBED = s.ConsumedServiceSpec("cams", DEPTH, "add", ADD_REQUEST, ADD_RESPONSE)
ADD_PROBED_CAMERA = s.ConsumedServiceSpec("any_cam", DEPTH, "add", ADD_REQUEST, ADD_RESPONSE)
MISSING_CALLED = s.ConsumedServiceSpec("cam", CAMERA, "missing", ADD_REQUEST, ADD_RESPONSE)
MOVE_CALLED = s.ConsumedActionSpec("cam", CAMERA, "move", MOVE_GOAL, MOVE_FEEDBACK, MOVE_RESULT)

VIEWER_NODE = s.NodeDescriptor(
    name="viewer",
    tag="v1",
    slots=(
        s.SlotSpec("cam", "node", "camera", "v1", False),
        s.SlotSpec("cams", "interface", "depth_camera", "v1", True),
        s.SlotSpec("any_cam", "node", "camera", "v1", True),
    ),
    consumed_topics=(READINGS_IN, VIDEO_IN, VIDEO_ANY_CAMERA_IN, EXTERNAL_READINGS_IN, MISMATCH_IN),
    consumed_services=(ADD_PINNED, ADD_PROBED, ADD_PROBED_CAMERA, MISSING_CALLED),
    consumed_actions=(MOVE_CALLED,),
)


def free_port() -> int:
    """A TCP port nobody listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def model_of(descriptor: s.NodeDescriptor, parameters: Optional[Dict[str, Any]] = None) -> str:
    """The model (`peppy_schema::NodeModel` as JSON) generated code would
    carry for a hand-written descriptor; `parameters`: its parameter
    schema as the model writes it (none by default)."""
    return json.dumps(
        {
            "identity": {"name": descriptor.name, "tag": descriptor.tag},
            "dependencies": [
                {
                    "kind": x.kind,
                    "target": {"name": x.name, "tag": x.tag},
                    "link_id": x.link_id,
                    "from_any": x.from_any,
                    "cardinality": "zero_or_more" if x.from_any else x.cardinality,
                    "sha256": None,
                }
                for x in descriptor.slots
            ],
            "parameters": parameters or {"fields": []},
            "pairings": [
                {
                    "link_id": x.link_id,
                    "pairing": {"name": x.pairing, "tag": x.tag},
                    "role": x.role,
                    "counterpart": x.counterpart,
                    "observer": x.observer,
                    "optional": x.optional,
                    "cardinality": x.cardinality,
                }
                for x in descriptor.pairings
            ],
        }
    )


def plan(descriptor: s.NodeDescriptor, args: List[str]) -> Dict[str, Any]:
    """The plan `peppy-launch plan` gives `descriptor` for the command line `args`."""
    program = peppy_launch()
    if program is None:
        raise AssertionError(f"the live tests plan their nodes with peppy-launch: set {PEPPY_LAUNCH_ENV}")
    done = subprocess.run(
        [program, "plan", "--model", "-", "--", *args],
        input=descriptor.model or model_of(descriptor),
        capture_output=True,
        text=True,
        timeout=60,
    )
    if done.returncode != 0:
        raise AssertionError(f"peppy-launch plan {args}: {done.stderr}")
    return json.loads(done.stdout)


class LiveTest(unittest.IsolatedAsyncioTestCase):
    """Starts nodes in one namespace of its own; every node listens on its
    own port and connects to every node started before it (peers do not
    route for each other)."""

    async def asyncSetUp(self) -> None:
        self.namespace = "t" + uuid.uuid4().hex[:12]
        self.endpoints: List[str] = []
        self.runners: List[NodeRunner] = []
        self.endpoint_of: Dict[str, str] = {}
        self.tmp = tempfile.TemporaryDirectory()

    async def asyncTearDown(self) -> None:
        for r in reversed(self.runners):
            await asyncio.wait_for(r.shutdown(), WAIT)
        self.tmp.cleanup()

    def write_config(
        self,
        descriptor: s.NodeDescriptor,
        instance: str,
        core: str,
        bindings: Dict[str, Any],
        links: Optional[List[str]] = None,
    ) -> str:
        """A runtime-config file as the launcher writes it: the slots are
        planned by `peppy-launch plan` (the launcher's binding engine) from
        `bindings` (link_id -> a binding as the runtime config writes one),
        the identity and endpoints are this test's."""
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        args = ["--instance-id", instance]
        for link_id, binding in bindings.items():
            producers = [binding["producer"]] if binding["kind"] == "pinned" else binding.get("producers", [])
            for producer in producers:
                args += ["--bind", f"{link_id}@{producer}"]
        for link in links or ():
            args += ["--link", link]
        config = plan(descriptor, args)
        config.update(
            core_node=core,
            namespace=self.namespace,
            zenoh={
                "mode": "peer",
                "listen": [endpoint],
                "connect": list(self.endpoints),
                "multicast_scouting": False,
            },
        )
        self.endpoints.append(endpoint)
        self.endpoint_of[instance] = endpoint
        path = os.path.join(self.tmp.name, f"{instance}.json")
        with open(path, "w") as f:
            json.dump(config, f)
        return path

    async def node(
        self,
        descriptor: s.NodeDescriptor,
        instance: str,
        core: str = "lab",
        bindings: Optional[Dict[str, Any]] = None,
        retention: Optional[float] = None,
        links: Optional[List[str]] = None,
    ) -> NodeRunner:
        """Starts a node from a runtime config; shut down at the end of the
        test. `links`: `--link` flags (pairing slots) for its plan."""
        path = self.write_config(descriptor, instance, core, bindings or {}, links)
        builder = NodeBuilder(descriptor).with_runtime_config(path)
        if retention is not None:
            builder.action_result_retention(retention)
        runner = await asyncio.wait_for(builder.start(), WAIT)
        self.runners.append(runner)
        return runner

    async def stop(self, runner: NodeRunner) -> None:
        """Shuts `runner` down now; nodes started later no longer connect to it."""
        await asyncio.wait_for(runner.shutdown(), WAIT)
        self.runners.remove(runner)
        endpoint = self.endpoint_of.pop(runner.instance_id, None)
        if endpoint in self.endpoints:
            self.endpoints.remove(endpoint)

    async def sees(self, runner: NodeRunner, node: str, instance: str) -> None:
        """Waits until `runner` sees `instance` (of `node:v1`) up. Its
        declarations precede its token on the same link, so they are known too."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + WAIT
        while loop.time() < deadline:
            live = await live_instances(runner, node, "v1", 0.5)
            if any(live.contains(core, instance) for core in ("lab", "other", "standalone")):
                return
            await asyncio.sleep(0.05)
        self.fail(f"{runner.instance_id} never saw {instance}")


async def keep_emitting(runner: NodeRunner, spec: s.TopicSpec, label: str, make: Any = None) -> None:
    """Emits a numbered message every 20 ms until cancelled."""
    from peppy import topics

    seq = 0
    while True:
        message = make(seq) if make else Reading(seq, label)
        await topics.emit(runner, spec, message)
        seq += 1
        await asyncio.sleep(0.02)
