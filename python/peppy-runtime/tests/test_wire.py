"""Attachments (WIRE.md §2), key expressions (§1), instance descriptions
(§9) and core node answers: the golden bytes, keys and documents shared
with the Rust runtime (tests/golden/wire.json), and what only this
runtime's API does."""

from __future__ import annotations

import dataclasses
import json
import unittest

import golden

from peppy import attachment as a
from peppy import keys as k
from peppy.action_states import (
    decode_decision,
    encode_decision,
    encode_string,
    goal_id_of,
    split_goal_id,
)
from peppy.describe import consumed_topic, instance_info
from peppy.formats import Format
from peppy.info import info_from_body
from peppy.routing import ANY, slot_from_json
from peppy.spec import (
    ActionSpec,
    ConsumedTopicSpec,
    NodeDescriptor,
    Owner,
    QoSProfile,
    ServiceSpec,
    TopicSpec,
)
from peppy.topics import subscription_selector

ATTACHMENTS = golden.load()["attachments"]
KEYS = golden.load()["keys"]


class AttachmentTest(unittest.TestCase):
    def test_golden_topic_attachments(self):
        for v in ATTACHMENTS["topic"]:
            fp, data = golden.fingerprint(v["fingerprint"]), bytes.fromhex(v["hex"])
            self.assertEqual(a.topic(fp), data)
            self.assertEqual(a.parse_topic(data), fp)
        for data in ATTACHMENTS["topic_rejected"]:
            self.assertIsNone(a.parse_topic(bytes.fromhex(data)), data)
        self.assertIsNone(a.parse_topic(None))
        self.assertEqual(a.END_OF_FEEDBACK, bytes.fromhex(ATTACHMENTS["end_of_feedback"]))

    def test_golden_query_headers(self):
        for v in ATTACHMENTS["query"]:
            kind = {"request": a.QueryKind.REQUEST, "probe": a.QueryKind.PROBE}[v["kind"]]
            header = a.QueryHeader(kind, golden.fingerprint(v["fingerprint"]), v["core"], v["instance"])
            data = bytes.fromhex(v["hex"])
            self.assertEqual(header.encode(), data)
            self.assertEqual(a.QueryHeader.decode(data), header)
        for data in ATTACHMENTS["query_rejected"]:
            self.assertIsNone(a.QueryHeader.decode(bytes.fromhex(data)), data)

    def test_long_identities_are_cut_to_255_bytes(self):
        request = a.QueryHeader(a.QueryKind.REQUEST, 2**64 - 1, "", "x" * 300)
        back = a.QueryHeader.decode(request.encode())
        self.assertEqual(
            (back.kind, back.fingerprint, back.core, back.instance), (a.QueryKind.REQUEST, 2**64 - 1, "", "x" * 255)
        )

    def test_golden_replies(self):
        for v in ATTACHMENTS["reply"]:
            status = a.ReplyStatus[v["status"].upper()]
            fp, data = golden.fingerprint(v["fingerprint"]), bytes.fromhex(v["hex"])
            self.assertEqual(a.reply(status, fp), data)
            self.assertEqual(a.parse_reply(data), (status, fp))
        for data in ATTACHMENTS["reply_rejected"]:
            self.assertIsNone(a.parse_reply(bytes.fromhex(data)), data)

    def test_action_payloads(self):
        self.assertEqual(encode_string("g1"), b"\x02\0\0\0g1")
        self.assertEqual(split_goal_id(b"\x02\0\0\0g1rest"), ("g1", b"rest"))
        self.assertIsNone(split_goal_id(b"\x02\0\0\0g/"))
        self.assertIsNone(split_goal_id(b"\x00\0\0\0"))
        self.assertIsNone(split_goal_id(encode_string("x" * 65)))
        self.assertEqual(goal_id_of(encode_string("a-b_C9")), "a-b_C9")
        self.assertIsNone(goal_id_of(encode_string("g1") + b"\0"))
        self.assertEqual(encode_decision(True, None), b"\x01\x00")
        self.assertEqual(encode_decision(False, "no"), b"\x00\x01\x02\0\0\0no")
        self.assertEqual(decode_decision(b"\x00\x01\x02\0\0\0no"), (False, "no"))


def _owner(v):
    return None if v is None else Owner(v["kind"], v["name"], v["tag"]).segments("", "")


# The keys of the shared file this runtime builds, by the name of the Rust
# function that builds them.
BUILD = {
    "entry_key": lambda v: k.entry_key(v["ns"], v["channel"], _owner(v["owner"]), v["entry"], v["core"], v["instance"]),
    "entry_selector": lambda v: k.entry_selector(
        v["ns"], v["channel"], _owner(v["owner"]), v["entry"], v["core"], v["instance"]
    ),
    "action_part_key": lambda v: k.action_part_key(v["action"], v["part"]),
    "feedback_key": lambda v: k.feedback_key(v["action"], v["goal_id"]),
    "format_key": lambda v: k.format_key(v["ns"], golden.fingerprint(v["fingerprint"]), v["instance"]),
    "liveliness_key": lambda v: k.liveliness_key(v["ns"], v["core"], v["instance"], v["node"], v["tag"]),
    "liveliness_selector": lambda v: k.liveliness_selector(v["ns"], v["node"], v["tag"]),
    "describe_key": lambda v: k.describe_key(v["ns"], v["core"], v["instance"]),
    "clock_tick_key": lambda v: k.clock_tick_key(v["ns"], v["source"]),
    "clock_sync_key": lambda v: k.clock_sync_key(v["ns"]),
    "core_function_key": lambda v: k.core_function_key(v["ns"], v["core"], v["function"]),
    "pairing_topic_key": lambda v: k.pairing_topic_key(
        v["ns"], v["pairing"], v["tag"], v["topic"], v["core"], v["instance"], v["link_id"]
    ),
    "pairing_topic_selector": lambda v: k.pairing_topic_selector(
        v["ns"], v["pairing"], v["tag"], v["topic"], v.get("core"), v.get("instance"), v.get("link_id")
    ),
    "claim_key": lambda v: k.pair_claim_key(
        v["ns"],
        v["pairing"],
        v["tag"],
        v["role"],
        v["core"],
        v["instance"],
        v["link_id"],
        None if v.get("peer") is None else v["peer"]["instance"],
        None if v.get("peer") is None else v["peer"]["link_id"],
    ),
    "claim_selector": lambda v: k.claim_selector(v["ns"], v["pairing"], v["tag"]),
}


def _parse_entry_key(key):
    s = k.parse_entry_key(key)
    return None if s is None else s._asdict()


def _parse_liveliness_key(key):
    parsed = k.parse_liveliness_key(key)
    return None if parsed is None else dict(zip(("core", "instance"), parsed))


def _parse_pairing_topic_key(key):
    s = k.parse_pairing_topic_key(key)
    return None if s is None else s._asdict()


def _parse_claim_key(key):
    c = k.parse_pair_claim_key(key)
    if c is None:
        return None
    peer = None if c.peer_instance is None else {"instance": c.peer_instance, "link_id": c.peer_link_id}
    return {
        "pairing": c.pairing,
        "tag": c.tag,
        "role": c.role,
        "core": c.core,
        "instance": c.instance,
        "link_id": c.link_id,
        "peer": peer,
    }


PARSE = {
    "parse_entry_key": _parse_entry_key,
    "parse_liveliness_key": _parse_liveliness_key,
    "parse_pairing_topic_key": _parse_pairing_topic_key,
    "parse_claim_key": _parse_claim_key,
}

# Keys only the launcher and its tools build and read (the security
# policy's selectors, core node tokens, descriptions of every instance).
NOT_IN_THIS_RUNTIME = {
    "describe_selector",
    "all_liveliness_selector",
    "instance_liveliness_selector",
    "core_key",
    "core_selector",
    "parse_core_key",
    "action_parts_selector",
    "feedback_selector",
    "format_selector",
    "namespace_prefix",
    "namespace_selector",
    "space_selector",
    "clock_tick_selector",
}


class KeyTest(unittest.TestCase):
    def test_every_golden_key_is_built_as_written(self):
        built = 0
        for v in KEYS["build"]:
            with self.subTest(v["fn"], key=v["key"]):
                if v["fn"] in NOT_IN_THIS_RUNTIME:
                    continue
                self.assertIn(v["fn"], BUILD, "a key this runtime does not build: add it, or say why not")
                self.assertEqual(BUILD[v["fn"]](v["args"]), v["key"])
                built += 1
        self.assertGreater(built, 0)

    def test_every_golden_key_is_parsed_as_written(self):
        for v in KEYS["parse"]:
            with self.subTest(v["fn"], key=v["key"]):
                if v["fn"] in NOT_IN_THIS_RUNTIME:
                    continue
                self.assertIn(v["fn"], PARSE, "a key this runtime does not read: add it, or say why not")
                self.assertEqual(PARSE[v["fn"]](v["key"]), v["parts"])

    def test_pairing_keys_in_the_shared_files_shape(self):
        # The shapes the shared file gives pairing keys in (docs/PAIRINGS.md
        # §3), checked here until the file carries them.
        claim = {"ns": "lab", "pairing": "arm_link", "tag": "v1", "role": "arm", "core": "c1"}
        claim.update(instance="arm_1", link_id="commander")
        key = "peppy/lab/pair/arm_link/v1/arm/c1/arm_1/commander/cmd_1/arm"
        self.assertEqual(BUILD["claim_key"](dict(claim, peer={"instance": "cmd_1", "link_id": "arm"})), key)
        self.assertEqual(PARSE["parse_claim_key"](key)["peer"], {"instance": "cmd_1", "link_id": "arm"})
        nobody = BUILD["claim_key"](dict(claim, peer=None))
        self.assertEqual(nobody, "peppy/lab/pair/arm_link/v1/arm/c1/arm_1/commander/~/~")
        self.assertIsNone(PARSE["parse_claim_key"](nobody)["peer"])
        self.assertIsNone(PARSE["parse_claim_key"]("peppy/lab/pair/arm_link/v1/arm/c1/arm_1/commander/~/arm"))
        topic = {"ns": "lab", "pairing": "arm_link", "tag": "v1", "topic": "state"}
        self.assertEqual(
            BUILD["pairing_topic_selector"](dict(topic, core=None, instance="arm_1", link_id="commander")),
            "peppy/lab/topic/pairing/arm_link/v1/state/*/arm_1/commander",
        )
        key = BUILD["pairing_topic_key"](dict(topic, core="c1", instance="arm_1", link_id="commander"))
        self.assertEqual(PARSE["parse_pairing_topic_key"](key)["link_id"], "commander")
        self.assertIsNone(PARSE["parse_pairing_topic_key"]("peppy/lab/topic/pairing/arm_link/v1/state/*/arm_1/x"))
        self.assertEqual(BUILD["claim_selector"](claim), "peppy/lab/pair/arm_link/v1/*/*/*/*/*/*")

    def test_golden_segments(self):
        for s in KEYS["segments"]["valid"]:
            self.assertTrue(k.is_segment(s), repr(s))
        for s in KEYS["segments"]["invalid"]:
            self.assertFalse(k.is_segment(s), repr(s))


class DatastoreGoldenTest(unittest.TestCase):
    """The datastore's requests encode, and a store answers them, as the
    golden steps say (the Rust runtime's tests check the same steps)."""

    def test_the_datastore_speaks_the_golden_steps(self):
        from peppy.core_functions import Store
        from peppy.datastore import key_request, store_request

        steps = golden.load()["datastore"]
        key = "calibration/wrist"
        ours = [
            store_request(key, b'{"x":1}', "application/json", "arm_left"),
            key_request(1, key),
            key_request(2),
            key_request(3, key),
            key_request(1, key),
            key_request(3, key),
        ]
        self.assertEqual([bytes.fromhex(s["request"]) for s in steps], ours)
        store = Store()
        for step in steps:
            with self.subTest(step["about"]):
                self.assertEqual(store.answer(bytes.fromhex(step["request"])).hex(), step["reply"])


def _spec_owner(v):
    """An entry's owner as a vector writes it: `own`, `any`, or a node or interface."""
    return Owner(v["kind"], v.get("name"), v.get("tag"))


def _format(v):
    return Format(None, v["canonical"], golden.fingerprint(v["fingerprint"]))


def described(v) -> str:
    """The description an instance answers, built from a `describe` vector's
    inputs as the runtime builds it (`declare`: consumed routes, then
    `instance_info`)."""
    name, tag = v["node"]["name"], v["node"]["tag"]
    slots = [slot_from_json(s) for s in v["slots"]]
    by_id = {s.link_id: s for s in slots}
    descriptor = NodeDescriptor(
        name,
        tag,
        emitted_topics=tuple(
            TopicSpec(_spec_owner(t["owner"]), t["name"], QoSProfile(t["qos"]), _format(t["format"]))
            for t in v["emits"]
        ),
        consumed_topics=tuple(
            ConsumedTopicSpec(c["slot"], _spec_owner(c["owner"]), c["name"], QoSProfile(c["qos"]), _format(c["format"]))
            for c in v["consumes"]
        ),
        exposed_services=tuple(
            ServiceSpec(_spec_owner(s["owner"]), s["name"], _format(s["request"]), _format(s["response"]))
            for s in v["services"]
        ),
        exposed_actions=tuple(
            ActionSpec(
                _spec_owner(a["owner"]), a["name"], _format(a["goal"]), _format(a["feedback"]), _format(a["result"])
            )
            for a in v["actions"]
        ),
    )
    consumes = []
    for spec in descriptor.consumed_topics:
        slot = by_id[spec.link_id] if spec.link_id is not None else None
        route_filter = slot.filter if slot is not None else ANY
        members_of = slot if slot is not None and slot.kind == "node" and spec.owner.kind == "interface" else None
        selector = subscription_selector(v["namespace"], spec.owner.segments(name, tag), spec, route_filter)
        consumes.append(consumed_topic(spec, name, tag, selector, route_filter, members_of))
    return instance_info(
        descriptor, v["namespace"], v["core"], v["instance"], v["pid"], v["started_at_ms"], slots, consumes
    )


class DescribeGoldenTest(unittest.TestCase):
    """The description an instance answers (WIRE §9), byte for byte as the
    Rust runtime's `InstanceInfo` writes it from the same inputs."""

    def test_golden_descriptions_are_built_as_written(self):
        vectors = golden.load()["describe"]
        self.assertGreaterEqual(len(vectors), 2)
        for v in vectors:
            with self.subTest(v["about"]):
                self.assertEqual(described(v), v["json"])


class InfoGoldenTest(unittest.TestCase):
    """A core node's `info` answer, read as the Rust runtime's
    `InfoResponse` reads it (null: refused, with a `ValueError`)."""

    def test_golden_info_answers_are_read_as_written(self):
        vectors = golden.load()["info"]
        self.assertGreaterEqual(len(vectors), 30)
        for v in vectors:
            with self.subTest(v["about"]):
                for body in (v["json"], v["json"].encode("utf-8")):
                    if v["reads"] is None:
                        with self.assertRaises(ValueError) as refused:
                            info_from_body(body)
                        self.assertTrue(str(refused.exception).startswith("the core node's info: "))
                    else:
                        self.assertEqual(dataclasses.asdict(info_from_body(body)), v["reads"])

    def test_a_refusal_is_a_value_error_never_a_key_or_type_error(self):
        for data in (None, 12, "x", [], {}, {"uptime_secs": 12}, [None] * 8, {"container_info": None}):
            with self.subTest(data):
                with self.assertRaises(ValueError) as refused:
                    info_from_body(json.dumps(data))
                self.assertIs(type(refused.exception), ValueError)

    def test_a_body_that_is_not_utf8_json_is_refused_as_rust_refuses_it(self):
        good = golden.load()["info"][0]["json"].encode()
        for body in (
            b"",
            b"\xef\xbb\xbf" + good,  # a byte order mark
            good.decode().encode("utf-16"),
            good.replace(b'"host_name":"lab-pc"', b'"host_name":"lab-\xff"'),
            good.replace(b'"host_name":"lab-pc"', b'"host_n\xffame":"lab-pc","host_name":"lab-pc"'),
            good + b"x",
        ):
            with self.subTest(body):
                with self.assertRaises(ValueError):
                    info_from_body(body)
        # Not UTF-8 in a field Rust passes over: serde_json does not look.
        read = info_from_body(good.replace(b'"messaging_port"', b'"shm":"\xff","messaging_port"'))
        self.assertEqual(read.messaging_port, 7447)
        # Nor at the digits of a number it passes over.
        read = info_from_body(good.replace(b'"messaging_port"', b'"big":' + b"9" * 5000 + b',"messaging_port"'))
        self.assertEqual(read.messaging_port, 7447)


if __name__ == "__main__":
    unittest.main()
