"""Start-up inputs (WIRE.md §8): runtime-config files, standalone flags,
bindings and route filters, parameters; and `NodeBuilder.run` as a process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import unittest
import uuid
from dataclasses import dataclass
from typing import Any, List

from peppy import StartupError
from peppy import spec as s
from peppy.node import NodeBuilder
from peppy.params import MISSING, array, group, leaf
from peppy.routing import RouteFilter, SlotBinding, SlotPlan, compute_filters
from peppy.startup import load

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(os.path.dirname(HERE), "src")


@dataclass
class Video:
    fps: int
    scale: float

    @classmethod
    def from_json(cls, data: Any, where: str = "") -> "Video":
        if not isinstance(data, dict):
            raise ValueError(f"parameter group `{where or 'parameters'}`: expected an object")
        return cls(fps=leaf(data, "fps", 30, "u16", where), scale=leaf(data, "scale", 1, "f64", where))


@dataclass
class Parameters:
    """As peppy-build's Python generator writes a node's parameters."""

    name: str
    video: Video
    gains: List[float]
    class_: bool

    @classmethod
    def from_json(cls, data: Any, where: str = "") -> "Parameters":
        if not isinstance(data, dict):
            raise ValueError(f"parameter group `{where or 'parameters'}`: expected an object")
        return cls(
            name=leaf(data, "name", MISSING, "string", where),
            video=group(data, "video", Video.from_json, where),
            gains=array(data, "gains", [1, 2], "f64", 2, where),
            class_=leaf(data, "class", False, "bool", where),
        )


RECON = s.NodeDescriptor(
    name="recon",
    tag="v1",
    slots=(
        s.SlotSpec("left_cam", "interface", "depth_camera", "v1", False),
        s.SlotSpec("backup", "interface", "depth_camera", "v1", True),
        s.SlotSpec("spare", "interface", "depth_camera", "v1", True),
    ),
    parameters=Parameters,
)


class FilterTest(unittest.TestCase):
    def plan(self, link_id, binding, kind="interface", name="depth_camera"):
        return SlotPlan(link_id, kind, name, "v1", binding, RouteFilter("any"))

    def test_compute_filters_as_peppy_schema(self):
        slots = compute_filters(
            [
                self.plan("left", SlotBinding.pinned("rs_left")),
                self.plan("bound", SlotBinding("from_any_bound", ("rs_left", "zed"))),
                self.plan("rest", SlotBinding("from_any_unbound")),
                self.plan("other", SlotBinding("from_any_unbound"), name="lidar"),
                self.plan("node", SlotBinding("from_any_unbound"), kind="node"),
            ]
        )
        f = {x.link_id: x.filter for x in slots}
        self.assertEqual(f["left"].to_json(), {"kind": "pin", "producers": "rs_left"})
        self.assertEqual(f["bound"].to_json(), {"kind": "only_from", "producers": ["zed"]})
        self.assertEqual(f["rest"].to_json(), {"kind": "any_except", "producers": ["rs_left", "zed"]})
        self.assertEqual(f["other"].to_json(), {"kind": "any"})
        self.assertEqual(f["node"].to_json(), {"kind": "any"}, "a node slot is no sibling of an interface slot")
        self.assertTrue(f["rest"].accepts("rs_right"))
        self.assertFalse(f["rest"].accepts("zed"))
        self.assertTrue(f["bound"].accepts("zed"))
        self.assertFalse(f["bound"].accepts("rs_left"))


class ConfigFileTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def write(self, config):
        path = os.path.join(self.tmp.name, "rt.json")
        with open(path, "w") as f:
            f.write(config if isinstance(config, str) else json.dumps(config))
        return path

    def config(self, **changes):
        base = {
            "instance_id": "recon_1",
            "core_node": "lab-1",
            "namespace": "lab",
            "bindings": {
                "left_cam": {"kind": "pinned", "producer": "rs_left"},
                "backup": {"kind": "from_any_bound", "producers": ["zed_overhead", "rs_left"]},
            },
            "parameters": {"name": "n", "video": {"fps": 60}},
            "zenoh": {
                "mode": "client",
                "listen": [],
                "connect": ["tcp/127.0.0.1:7447"],
                "multicast_scouting": False,
                "login": {"user": "recon_1", "password": "secret"},
            },
        }
        base.update(changes)
        return base

    def test_the_launcher_config_is_read(self):
        st = load(RECON, ["ignored=1"], self.write(self.config()))
        self.assertEqual((st.instance_id, st.core_node, st.namespace), ("recon_1", "lab-1", "lab"))
        filters = {p.link_id: p.filter.to_json() for p in st.slots}
        self.assertEqual(filters["left_cam"], {"kind": "pin", "producers": "rs_left"})
        self.assertEqual(filters["backup"], {"kind": "only_from", "producers": ["zed_overhead"]})
        self.assertEqual(filters["spare"], {"kind": "any_except", "producers": ["rs_left", "zed_overhead"]})
        self.assertEqual(st.endpoints.connect, ("tcp/127.0.0.1:7447",))
        self.assertEqual(st.endpoints.login.user, "recon_1")
        self.assertNotIn("secret", repr(st.endpoints))
        config = st.endpoints.zenoh_config()
        setting = lambda key: json.loads(config.get_json(key))  # noqa: E731
        self.assertEqual(setting("mode"), "client")
        self.assertEqual(setting("transport/auth/usrpwd/user"), "recon_1")
        self.assertEqual(setting("transport/auth/usrpwd/password"), "secret")
        self.assertFalse(setting("scouting/multicast/enabled"))
        self.assertFalse(setting("transport/shared_memory/enabled"))
        self.assertEqual(setting("connect/endpoints"), ["tcp/127.0.0.1:7447"])
        params = NodeBuilder(RECON)._parameters(st)
        self.assertEqual(params, Parameters("n", Video(60, 1.0), [1.0, 2.0], False))
        self.assertIsInstance(params.video.scale, float)

    def test_bad_configs_are_refused(self):
        for config, words in (
            (self.config(extra=1), "unknown field `extra`"),
            (self.config(bindings={"nope": {"kind": "pinned", "producer": "x"}}), "binds `nope`, which is not a slot"),
            (self.config(bindings={}), "pinned slot `left_cam`"),
            (self.config(bindings={"left_cam": {"kind": "from_any_bound", "producers": ["a", "b"]}}), "bound twice"),
            (self.config(bindings={"left_cam": {"kind": "mystery"}}), "kind 'mystery'"),
            (self.config(instance_id="a/b"), "invalid instance id `a/b`"),
            (self.config(namespace=""), "invalid namespace"),
            (self.config(zenoh={"mode": "peer", "port": 1}), "unknown field `port`"),
            ("{not json", "invalid runtime config"),
        ):
            with self.assertRaises(StartupError) as caught:
                load(RECON, [], self.write(config))
            self.assertIn(words, str(caught.exception))
        with self.assertRaises(StartupError):
            load(RECON, [], os.path.join(self.tmp.name, "missing.json"))

    def test_parameters_are_checked(self):
        for parameters, words in (
            ({}, "missing required parameter `name` (a `string`)"),
            ({"name": 5}, "parameter `name` expects a `string`, found `5`"),
            (
                {"name": "n", "video": {"fps": 70000}},
                "parameter `video.fps` expects a `u16` (an integer from 0 to 65535)",
            ),
            ({"name": "n", "video": 3}, "parameter `video` expects an object (a parameter group)"),
            ({"name": "n", "gains": [1]}, "parameter `gains` expects an array of exactly 2 `f64`"),
            ({"name": "n", "gains": [1, "x"]}, "parameter `gains[1]` expects an `f64`"),
            ({"name": "n", "nmae": 1}, "unknown parameter `nmae`"),
            ({"name": "n", "video": {"fsp": 1}}, "unknown parameter `video.fsp`"),
        ):
            st = load(RECON, [], self.write(self.config(parameters=parameters)))
            with self.assertRaises(StartupError) as caught:
                NodeBuilder(RECON)._parameters(st)
            self.assertIn(words, str(caught.exception))


class FlagsTest(unittest.TestCase):
    def test_standalone_flags(self):
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump({"name": "from-file", "video": {"scale": 3}}, f)
        self.addCleanup(os.unlink, f.name)
        st = load(
            RECON,
            [
                "--instance-id",
                "r1",
                "--bind",
                "left_cam@cam_a",
                "--bind=spare@cam_b",
                "--bind",
                "spare@cam_c",
                "--params",
                f.name,
                "--connect",
                "tcp/127.0.0.1:7447",
                "--listen=tcp/127.0.0.1:0",
                "name=123",
                "video.fps=24",
                "class=true",
                "gains=[0.5, 1]",
            ],
            None,
        )
        self.assertEqual((st.instance_id, st.core_node, st.namespace), ("r1", "standalone", "default"))
        plans = {p.link_id: p for p in st.slots}
        self.assertEqual(plans["left_cam"].filter.to_json(), {"kind": "pin", "producers": "cam_a"})
        self.assertEqual(plans["spare"].binding.to_json(), {"kind": "from_any_bound", "producers": ["cam_b", "cam_c"]})
        self.assertEqual(
            plans["backup"].filter.to_json(), {"kind": "any_except", "producers": ["cam_a", "cam_b", "cam_c"]}
        )
        self.assertEqual(st.endpoints.connect, ("tcp/127.0.0.1:7447",))
        self.assertEqual(st.endpoints.listen, ("tcp/127.0.0.1:0",))
        self.assertFalse(st.endpoints.multicast_scouting)
        # `name=123` is a string because `name` is declared one, as the Rust runtime reads it.
        self.assertEqual(NodeBuilder(RECON)._parameters(st), Parameters("123", Video(24, 3.0), [0.5, 1.0], True))

    def test_defaults(self):
        st = load(RECON, ["--bind", "left_cam@x", "name=n"], None)
        self.assertEqual((st.instance_id, st.namespace), ("standalone", "default"))
        self.assertTrue(st.endpoints.multicast_scouting, "no endpoints given: find peers by multicast")
        self.assertEqual(st.parameters, {"name": "n"})

    def test_bad_flags(self):
        for args, words in (
            (["--bind", "nokey"], "expected KEY@INSTANCE"),
            (["--bind", "mystery@x"], "binding `mystery` on instance `standalone` matches no slot"),
            (["--bind", "mystery@x"], "`left_cam` (interface `depth_camera:v1`)"),
            (["--bind", "left_cam@a", "--bind", "left_cam@b"], "bound twice"),
            ([], "pass --bind left_cam@<producer instance id>"),
            (["--bind", "left_cam@a", "--frobnicate"], "unexpected argument `--frobnicate`"),
            (["--bind", "left_cam@a", "--frobnicate"], "Usage:"),
            (["--bind", "left_cam@a", "positional"], "parameter overrides are `key=value`"),
            (["--instance-id"], "needs a value"),
            (["--instance-id", "a b", "--bind", "left_cam@a"], "invalid instance id"),
            (["--help"], "--bind <KEY@INSTANCE>"),
        ):
            with self.assertRaises(StartupError) as caught:
                load(RECON, args, None)
            self.assertIn(words, str(caught.exception), args)


NODE_SCRIPT = textwrap.dedent(
    """
    import asyncio, sys
    sys.path.insert(0, {src!r})
    from peppy import NodeBuilder
    from peppy import spec as s

    async def setup(params, runner):
        if params.get("fail"):
            raise RuntimeError("setup failed on purpose")
        async def tick():
            while True:
                await asyncio.sleep(0.05)
        print("ready", runner.instance_id, runner.core_node, runner.namespace, flush=True)
        return [asyncio.ensure_future(tick())]

    NodeBuilder(s.NodeDescriptor(name="ticker", tag="v1")).run(setup)
    """
)


class ProcessTest(unittest.TestCase):
    def spawn(self, *args):
        env = dict(os.environ)
        env.pop("PEPPY_RUNTIME_CONFIG", None)
        ns = "t" + uuid.uuid4().hex[:12]
        return subprocess.Popen(
            [
                sys.executable,
                "-c",
                NODE_SCRIPT.format(src=SRC),
                "--namespace",
                ns,
                "--listen",
                "tcp/127.0.0.1:0",
                "--instance-id",
                "tick_1",
                *args,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            text=True,
        )

    def test_a_node_runs_until_sigterm_and_exits_zero(self):
        proc = self.spawn()
        try:
            line = proc.stdout.readline()
            self.assertTrue(line.startswith("ready tick_1 standalone t"), line)
            proc.send_signal(signal.SIGTERM)
            self.assertEqual(proc.wait(timeout=10), 0)
        finally:
            proc.kill()
            proc.communicate()

    def test_a_failing_setup_exits_non_zero(self):
        proc = self.spawn("fail=true")
        try:
            _, err = proc.communicate(timeout=20)
        finally:
            proc.kill()
        self.assertNotEqual(proc.returncode, 0)
        self.assertIn("setup failed on purpose", err)

    def test_bad_flags_exit_non_zero_with_usage(self):
        proc = self.spawn("--frobnicate")
        _, err = proc.communicate(timeout=20)
        self.assertNotEqual(proc.returncode, 0)
        self.assertIn("Usage:", err)


if __name__ == "__main__":
    unittest.main()
