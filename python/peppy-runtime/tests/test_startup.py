"""Start-up inputs (WIRE.md §8): runtime-config files, standalone flags,
bindings and route filters, parameters; and `NodeBuilder.run` as a process."""

from __future__ import annotations

import dataclasses
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
from typing import Any, Dict, List

from peppy import StartupError
from peppy import spec as s
from peppy.node import NodeBuilder
from peppy.params import array, group, leaf
from peppy.routing import RouteFilter, fit_plan, slot_from_json
from peppy.startup import PEPPY_LAUNCH_ENV, SHUTDOWN_GRACE_ENV, grace_from_env, load, peppy_launch
from peppy.target import named_server
import golden
from peppy_testing import model_of

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(os.path.dirname(HERE), "src")


@dataclass
class Video:
    fps: int
    scale: float

    @classmethod
    def from_json(cls, data: Any, where: str = "") -> "Video":
        return cls(fps=leaf(data, "fps", "u16", where), scale=leaf(data, "scale", "f64", where))


@dataclass
class Parameters:
    """As peppy-build's Python generator writes a node's parameters."""

    name: str
    video: Video
    gains: List[float]
    class_: bool
    key: bytes

    @classmethod
    def from_json(cls, data: Any, where: str = "") -> "Parameters":
        return cls(
            name=leaf(data, "name", "string", where),
            video=group(data, "video", Video.from_json, where),
            gains=array(data, "gains", "f64", where),
            class_=leaf(data, "class", "bool", where),
            key=leaf(data, "key", "bytes", where),
        )


def _leaf(name: str, ty: str, default: Any = None) -> Dict[str, Any]:
    return {"name": name, "kind": {"leaf": {"ty": ty, "default": default}}}


PARAMETER_SCHEMA = {
    "fields": [
        _leaf("name", "string"),
        {"name": "video", "kind": {"group": [_leaf("fps", "u16", 30), _leaf("scale", "f64", 1)]}},
        {"name": "gains", "kind": {"array": {"items": {"primitive": "f64"}, "length": 2, "default": [1, 2]}}},
        _leaf("class", "bool", False),
        _leaf("key", "bytes", "k"),
    ]
}


def descriptor(name: str, *slots: s.SlotSpec) -> s.NodeDescriptor:
    """A node as generated code describes it, with the model
    (`peppy_schema::NodeModel` as JSON) its package carries."""
    bare = s.NodeDescriptor(name=name, tag="v1", slots=slots, parameters=Parameters)
    return dataclasses.replace(bare, model=model_of(bare, PARAMETER_SCHEMA))


LEFT = s.SlotSpec("left_cam", "interface", "depth_camera", "v1", False)
BACKUP = s.SlotSpec("backup", "interface", "depth_camera", "v1", True)
ARMS = s.SlotSpec("arms", "node", "robot_arm", "v1", True)

CAMERAS = s.SlotSpec("cameras", "interface", "depth_camera", "v1", False, "one_or_more")
OVERHEAD = s.SlotSpec("overhead", "interface", "depth_camera", "v1", False, "zero_or_one")
VIEWER = descriptor("viewer", CAMERAS, OVERHEAD)
"""`node/v1`'s cardinalities: a list slot and an optional one."""

RECON = descriptor("recon", LEFT, BACKUP)
"""A pinned slot and a from_any slot: a free-form key joins `backup`."""
MIXER = descriptor("mixer", LEFT, BACKUP, ARMS)
"""Two from_any slots wanting different producers: a free-form key is ambiguous."""
SINGLE = descriptor("single", LEFT)
"""No from_any slot: a free-form key is dead."""

FULL = {"name": "n", "video": {"fps": 60, "scale": 1}, "gains": [1, 2], "class": False, "key": "k"}


def slot(link_id, binding, filter_, kind="interface", name="depth_camera"):
    return {
        "link_id": link_id,
        "kind": kind,
        "target": {"name": name, "tag": "v1"},
        "binding": binding,
        "filter": filter_,
    }


PINNED_LEFT = slot("left_cam", {"kind": "pinned", "producer": "rs_left"}, {"kind": "pin", "producers": "rs_left"})


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
            "slots": [
                # Out of depends_on order, with a filter the bindings alone
                # would not give: the node takes the plan as it is.
                slot(
                    "backup",
                    {"kind": "from_any_bound", "producers": ["zed_overhead", "rs_left"]},
                    {"kind": "only_from", "producers": ["zed_overhead"]},
                ),
                PINNED_LEFT,
            ],
            "parameters": FULL,
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

    def test_the_launchers_plan_is_applied_as_it_is(self):
        st = load(RECON, ["ignored=1"], self.write(self.config()))
        self.assertEqual((st.instance_id, st.core_node, st.namespace), ("recon_1", "lab-1", "lab"))
        self.assertEqual([p.link_id for p in st.slots], ["left_cam", "backup"], "depends_on order")
        filters = {p.link_id: p.filter.to_json() for p in st.slots}
        self.assertEqual(filters["left_cam"], {"kind": "pin", "producers": "rs_left"})
        self.assertEqual(filters["backup"], {"kind": "only_from", "producers": ["zed_overhead"]})
        self.assertEqual(st.slots[1].binding.producers, ("zed_overhead", "rs_left"))
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
        self.assertEqual(params, Parameters("n", Video(60, 1.0), [1.0, 2.0], False, b"k"))
        self.assertIsInstance(params.video.scale, float)
        self.assertIsInstance(params.gains[0], float)

    def test_a_plan_for_other_slots_is_refused(self):
        unbound = slot("backup", {"kind": "from_any_unbound"}, {"kind": "any"})
        for slots, words in (
            ([PINNED_LEFT], "leaves slot `backup` out"),
            ([PINNED_LEFT, unbound, slot("spare", {"kind": "from_any_unbound"}, {"kind": "any"})], "fills slot `spare`"),
            ([PINNED_LEFT, unbound, unbound], "fills slot `backup` twice"),
            ([slot("left_cam", {"kind": "from_any_unbound"}, {"kind": "any"}), unbound], "binds slot `left_cam` as from_any"),
            ([PINNED_LEFT, slot("backup", {"kind": "from_any_unbound"}, {"kind": "any"}, name="lidar")], "wants interface `lidar:v1`"),
        ):
            with self.assertRaises(StartupError) as caught:
                load(RECON, [], self.write(self.config(slots=slots)))
            self.assertIn(words, str(caught.exception))
            self.assertIn("another peppy.json5", str(caught.exception))

    def test_cardinality_sets_are_applied_as_they_are(self):
        slots = [
            slot(
                "cameras",
                {"kind": "set", "producers": ["rs_b", "rs_a"]},
                {"kind": "only_from", "producers": ["rs_a", "rs_b"]},
            ),
            slot(
                "overhead",
                {"kind": "set", "producers": [], "vacant": "bench run"},
                {"kind": "only_from", "producers": []},
            ),
        ]
        st = load(VIEWER, [], self.write(self.config(slots=slots, parameters={})))
        plans = {p.link_id: p for p in st.slots}
        self.assertEqual(plans["cameras"].binding.producers, ("rs_b", "rs_a"), "link order kept")
        self.assertTrue(plans["cameras"].filter.accepts("rs_a"))
        self.assertFalse(plans["cameras"].filter.accepts("rs_c"))
        self.assertEqual(plans["overhead"].binding.to_json(), {"kind": "set", "producers": [], "vacant": "bench run"})
        self.assertFalse(plans["overhead"].filter.accepts("rs_a"), "an empty slot receives nothing")
        # A set its cardinality does not take: the plan is for other documents.
        for bad, words in (
            ({"kind": "set", "producers": []}, "binds slot `cameras` as a set of producers"),
            ({"kind": "pinned", "producer": "rs_a"}, "binds slot `cameras` as pinned"),
        ):
            wrong = [dict(slots[0], binding=bad), slots[1]]
            with self.assertRaises(StartupError) as caught:
                load(VIEWER, [], self.write(self.config(slots=wrong, parameters={})))
            self.assertIn(words, str(caught.exception))

    def test_bad_configs_are_refused(self):
        for config, words in (
            (self.config(extra=1), "unknown field `extra`"),
            (self.config(bindings={}), "unknown field `bindings`"),
            (self.config(slots=[dict(PINNED_LEFT, binding={"kind": "mystery"})]), "kind 'mystery'"),
            (self.config(slots=[dict(PINNED_LEFT, filter={"kind": "pin"})]), "names one producer"),
            (self.config(slots=[dict(PINNED_LEFT, more=1)]), "expected the fields"),
            (self.config(slots={}), "`slots` must be a list"),
            (self.config(zenoh={"mode": "peer", "port": 1}), "unknown field `port`"),
            (self.config(direct_links=3), "`direct_links` must be a directory's path"),
            ("{not json", "invalid runtime config"),
        ):
            with self.assertRaises(StartupError) as caught:
                load(RECON, [], self.write(config))
            self.assertIn(words, str(caught.exception))
        with self.assertRaises(StartupError):
            load(RECON, [], os.path.join(self.tmp.name, "missing.json"))

    def test_a_launchs_direct_links_directory_is_accepted_and_left_to_rust_nodes(self):
        # A Python node reads and publishes through Zenoh, where a Rust
        # producer on a direct link publishes everything too.
        st = load(RECON, [], self.write(self.config(direct_links="/run/user/1000/peppy-1-2")))
        self.assertEqual((st.instance_id, st.core_node), ("recon_1", "lab-1"))

    def test_parameters_missing_from_the_plan_are_named(self):
        st = load(RECON, [], self.write(self.config(parameters={"name": "n"})))
        with self.assertRaises(StartupError) as caught:
            NodeBuilder(RECON)._parameters(st)
        self.assertIn("the plan has no value for parameter `video`", str(caught.exception))


def launcher_program() -> str:
    program = peppy_launch()
    if program is None:
        raise AssertionError(
            f"these tests start nodes by hand, which ask `peppy-launch plan` for their plan: "
            f"set {PEPPY_LAUNCH_ENV} or put peppy-launch on PATH"
        )
    return program


class GoldenPlansTest(unittest.TestCase):
    def test_golden_plans_fit_as_written(self):
        """Whether a node takes a binding for a slot it declares: the
        vectors peppy_schema::fit_plan is checked against too."""
        cases = golden.load()["plans"]
        self.assertGreaterEqual(len(cases), 20)
        for case in cases:
            declared = s.SlotSpec("s", "interface", "cam", "v1", case["from_any"], case["cardinality"])
            planned = slot_from_json(
                slot("s", case["binding"], {"kind": "any"}, name="cam"),
            )
            with self.subTest(case=case):
                try:
                    fit_plan([planned], [declared])
                    fits = True
                except StartupError:
                    fits = False
                self.assertEqual(fits, case["fits"])

    def test_golden_route_filters_accept_as_written(self):
        """Which producers a slot's filter lets through, as the plan writes
        the filter: the vectors peppy_schema::RouteFilter::accepts is
        checked against too; and the filters neither runtime reads."""
        vectors = golden.load()["route_filters"]
        self.assertGreaterEqual(len(vectors["accepts"]), 12)
        for case in vectors["accepts"]:
            with self.subTest(case=case):
                route_filter = RouteFilter.from_json(case["filter"], "s")
                self.assertEqual(route_filter.accepts(case["instance"]), case["accepts"])
        self.assertGreaterEqual(len(vectors["rejected"]), 5)
        for bad in vectors["rejected"]:
            with self.subTest(bad=bad):
                with self.assertRaises(StartupError):
                    RouteFilter.from_json(bad, "s")

    def test_golden_named_servers(self):
        """The server a request through a slot goes to without probing
        (null: it probes), as peppy_schema::SlotPlan::named_server says."""
        cases = golden.load()["named_servers"]
        self.assertGreaterEqual(len(cases), 10)
        for case in cases:
            with self.subTest(case=case):
                planned = slot_from_json(slot("s", case["binding"], case["filter"], name="cam"))
                self.assertEqual(named_server(planned), case["server"])

    def test_golden_grace_windows(self):
        """PEPPY_SHUTDOWN_GRACE_SECS as peppy_schema::grace_window_text
        reads it: the same vectors, the same windows."""
        cases = golden.load()["grace"]
        self.assertGreaterEqual(len(cases), 8)
        saved = os.environ.get(SHUTDOWN_GRACE_ENV)
        try:
            for case in cases:
                os.environ[SHUTDOWN_GRACE_ENV] = case["text"]
                with self.subTest(case=case):
                    if case["secs"] is None:
                        with self.assertRaises(StartupError):
                            grace_from_env()
                    else:
                        self.assertEqual(grace_from_env(), case["secs"])
        finally:
            if saved is None:
                os.environ.pop(SHUTDOWN_GRACE_ENV, None)
            else:
                os.environ[SHUTDOWN_GRACE_ENV] = saved


class FlagsTest(unittest.TestCase):
    """A node started by hand gets its plan from `peppy-launch plan`: the
    binding engine and parameter checker a launch and a Rust node use."""

    def setUp(self):
        launcher_program()

    def refused(self, node, args):
        with self.assertRaises(StartupError) as caught:
            load(node, args, None)
        return str(caught.exception)

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
                "--bind=backup@cam_b",
                "--bind",
                "backup@cam_c",
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
        self.assertEqual(plans["backup"].binding.to_json(), {"kind": "from_any_bound", "producers": ["cam_b", "cam_c"]})
        self.assertEqual(plans["backup"].filter.to_json(), {"kind": "only_from", "producers": ["cam_b", "cam_c"]})
        self.assertEqual(st.endpoints.connect, ("tcp/127.0.0.1:7447",))
        self.assertEqual(st.endpoints.listen, ("tcp/127.0.0.1:0",))
        self.assertFalse(st.endpoints.multicast_scouting)
        # `name=123` is a string because `name` is declared one.
        self.assertEqual(NodeBuilder(RECON)._parameters(st), Parameters("123", Video(24, 3.0), [0.5, 1.0], True, b"k"))

    def test_link_flags(self):
        st = load(
            VIEWER,
            ["--link", "cameras@rs_b", "--link", "cameras@rs_a", "--vacant-link", "overhead=bench run: none", "name=n"],
            None,
        )
        plans = {p.link_id: p for p in st.slots}
        self.assertEqual(plans["cameras"].binding.to_json(), {"kind": "set", "producers": ["rs_b", "rs_a"]})
        self.assertEqual(
            plans["overhead"].binding.to_json(), {"kind": "set", "producers": [], "vacant": "bench run: none"}
        )
        text = self.refused(VIEWER, ["--link", "cameras@rs_a", "name=n"])
        self.assertIn("slot `overhead`", text)
        self.assertIn("(BindingSlotUnfulfilled)", text)
        self.assertIn("--vacant-link 'overhead=<why>'", text)
        text = self.refused(VIEWER, ["--link", "camras@rs_a", "--vacant-link", "overhead=x", "name=n"])
        self.assertIn("(LinkUnknownSlot)", text)
        self.assertIn("did you mean `cameras`?", text)

    def test_defaults(self):
        st = load(RECON, ["--bind", "left_cam@x", "name=n"], None)
        self.assertRegex(st.instance_id, r"^recon-[0-9a-f]{4}$", "a readable id, as a Rust node's")
        self.assertEqual(st.namespace, "default")
        self.assertTrue(st.endpoints.multicast_scouting, "no endpoints given: find peers by multicast")
        self.assertEqual(st.parameters, dict(FULL, video={"fps": 30, "scale": 1.0}))

    def test_a_free_form_key_joins_the_from_any_slot(self):
        st = load(RECON, ["--instance-id", "r1", "--bind", "left_cam@a", "--bind", "zed_overhead@zed_1", "name=n"], None)
        backup = {p.link_id: p for p in st.slots}["backup"]
        self.assertEqual(backup.binding.to_json(), {"kind": "from_any_bound", "producers": ["zed_1"]})
        self.assertEqual(backup.filter.to_json(), {"kind": "only_from", "producers": ["zed_1"]})

    def test_an_ambiguous_key_is_refused(self):
        text = self.refused(MIXER, ["--instance-id", "m1", "--bind", "left_cam@a", "--bind", "front@rs_a", "name=n"])
        self.assertIn("binding `front` on instance `m1`", text)
        self.assertIn("(DeadBindingKey)", text)
        self.assertIn("--bind arms@rs_a or --bind backup@rs_a", text)

    def test_a_dead_key_is_refused(self):
        text = self.refused(SINGLE, ["--instance-id", "s1", "--bind", "left_cam@a", "--bind", "front@rs_a", "name=n"])
        self.assertIn("binding `front` on instance `s1` matches no slot", text)
        self.assertIn("(DeadBindingKey)", text)

    def test_bad_flags(self):
        for args, words in (
            (["--bind", "nokey"], "expected KEY@INSTANCE"),
            (["--bind", "left_cam@a", "--bind", "left_cam@b", "name=n"], "(DuplicateBindingKey)"),
            (["name=n"], "pass --bind left_cam@<producer instance id>"),
            (["--bind", "left_cam@a", "--frobnicate"], "unexpected argument '--frobnicate'"),
            (["--bind", "left_cam@a", "positional"], "parameter overrides are `key=value`"),
            (["--bind", "left_cam@a"], "missing required parameter `name`"),
            (["--bind", "left_cam@a", "name=n", "video.fps=70000"], "`video.fps`"),
            (["--instance-id", "a b", "--bind", "left_cam@a", "name=n"], "invalid instance id"),
            (["--help"], "--bind <KEY@INSTANCE>"),
        ):
            self.assertIn(words, self.refused(RECON, args), args)

    def test_a_descriptor_without_model_cannot_plan(self):
        bare = s.NodeDescriptor(name="old", tag="v1")
        self.assertIn("has no model to plan with", self.refused(bare, []))


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

    NodeBuilder(s.NodeDescriptor(name="ticker", tag="v1", model={model!r})).run(setup)
    """
)


TICKER_MODEL = model_of(s.NodeDescriptor(name="ticker", tag="v1"), {"fields": [_leaf("fail", "bool", False)]})


class ProcessTest(unittest.TestCase):
    def setUp(self):
        launcher_program()

    def spawn(self, *args):
        env = dict(os.environ)
        env.pop("PEPPY_RUNTIME_CONFIG", None)
        ns = "t" + uuid.uuid4().hex[:12]
        return subprocess.Popen(
            [
                sys.executable,
                "-c",
                NODE_SCRIPT.format(src=SRC, model=TICKER_MODEL),
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
        self.assertIn("unexpected argument '--frobnicate'", err)


if __name__ == "__main__":
    unittest.main()
