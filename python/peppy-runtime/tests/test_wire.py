"""Attachments (WIRE.md §2) and key expressions (§1): golden bytes and keys,
the same ones the Rust runtime's tests pin."""

from __future__ import annotations

import unittest

from peppy import attachment as a
from peppy import keys as k
from peppy.action_states import (
    decode_decision,
    encode_decision,
    encode_string,
    goal_id_of,
    split_goal_id,
)


class AttachmentTest(unittest.TestCase):
    def test_topic_attachment(self):
        self.assertEqual(a.topic(0x0102030405060708), bytes([1, 1, 2, 3, 4, 5, 6, 7, 8]))
        self.assertEqual(a.parse_topic(bytes([1, 1, 2, 3, 4, 5, 6, 7, 8])), 0x0102030405060708)
        self.assertIsNone(a.parse_topic(bytes([2, 1, 2, 3, 4, 5, 6, 7, 8])))
        self.assertIsNone(a.parse_topic(bytes([1, 1])))
        self.assertIsNone(a.parse_topic(None))
        self.assertIsNone(a.parse_topic(a.END_OF_FEEDBACK))
        self.assertEqual(a.END_OF_FEEDBACK, bytes([0x01, 0xEE]))

    def test_probe_golden(self):
        header = a.QueryHeader(a.QueryKind.PROBE, 7, "c", "me")
        data = header.encode()
        self.assertEqual(data, bytes.fromhex("01 01 00 00 00 00 00 00 00 07 01 63 02 6d 65"))
        self.assertEqual(a.QueryHeader.decode(data), header)
        self.assertIsNone(a.QueryHeader.decode(data[:-1]))
        self.assertIsNone(a.QueryHeader.decode(data + b"\0"))
        self.assertIsNone(a.QueryHeader.decode(bytes([1, 2]) + data[2:]))
        self.assertIsNone(a.QueryHeader.decode(bytes([2]) + data[1:]))
        self.assertIsNone(a.QueryHeader.decode(data[:10] + bytes([1, 0xFF, 0])))
        request = a.QueryHeader(a.QueryKind.REQUEST, 2**64 - 1, "", "x" * 300)
        back = a.QueryHeader.decode(request.encode())
        self.assertEqual(
            (back.kind, back.fingerprint, back.core, back.instance), (a.QueryKind.REQUEST, 2**64 - 1, "", "x" * 255)
        )

    def test_reply_attachment(self):
        self.assertEqual(a.reply(a.ReplyStatus.OK, 9), bytes([1, 1, 0, 0, 0, 0, 0, 0, 0, 9]))
        self.assertEqual(a.parse_reply(a.reply(a.ReplyStatus.HANDLER_ERROR, 9)), (a.ReplyStatus.HANDLER_ERROR, 9))
        self.assertEqual(a.parse_reply(a.reply(a.ReplyStatus.PRESENT, 0)), (a.ReplyStatus.PRESENT, 0))
        self.assertIsNone(a.parse_reply(bytes([1, 9, 0, 0, 0, 0, 0, 0, 0, 0])))
        self.assertIsNone(a.parse_reply(bytes([1, 1, 0])))

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


class KeyTest(unittest.TestCase):
    def test_golden_keys(self):
        cam = "interface/depth_camera/v1"
        self.assertEqual(
            k.entry_key("lab", k.TOPIC, cam, "video_stream", "launch-1", "rs_left"),
            "peppy/lab/topic/interface/depth_camera/v1/video_stream/launch-1/rs_left",
        )
        self.assertEqual(
            k.entry_selector("lab", k.TOPIC, cam, "video_stream", None, "rs_left"),
            "peppy/lab/topic/interface/depth_camera/v1/video_stream/*/rs_left",
        )
        self.assertEqual(
            k.entry_selector("lab", k.TOPIC, None, "joint_commands"), "peppy/lab/topic/*/*/*/joint_commands/*/*"
        )
        self.assertEqual(
            k.entry_key("lab", k.SERVICE, "node/robot_arm/v1", "home", "c", "arm"),
            "peppy/lab/service/node/robot_arm/v1/home/c/arm",
        )
        base = "peppy/lab/action/node/robot_arm/v1/move_arm/c/arm"
        self.assertEqual(k.action_part_key(base, "goal"), base + "/goal")
        self.assertEqual(k.feedback_key(base, "g1"), base + "/feedback/g1")
        self.assertEqual(k.format_key("lab", 0x1111, "rs_left"), "peppy/lab/format/0000000000001111/rs_left")
        self.assertEqual(k.describe_key("lab", "c", "arm"), "peppy/lab/describe/c/arm")

    def test_liveliness_keys(self):
        key = k.liveliness_key("lab", "launch-1", "rs_left", "realsense_d405", "v1")
        self.assertEqual(key, "peppy/lab/live/launch-1/rs_left/realsense_d405/v1")
        self.assertEqual(k.parse_liveliness_key(key), ("launch-1", "rs_left"))
        self.assertEqual(k.liveliness_selector("lab", "realsense_d405", "v1"), "peppy/lab/live/*/*/realsense_d405/v1")
        self.assertIsNone(k.parse_liveliness_key("peppy/lab/live/c"))
        self.assertIsNone(k.parse_liveliness_key("peppy/lab/topic/c/i/n/t"))

    def test_sender_identity(self):
        s = k.parse_entry_key("peppy/lab/topic/node/robot_arm/v1/joint_states/c1/arm/extra")
        self.assertEqual((s.kind, s.name, s.instance, s.core), ("node", "robot_arm", "arm", "c1"))
        self.assertIsNone(k.parse_entry_key("peppy/lab/topic/other/x/v1/t/c/i"))
        self.assertIsNone(k.parse_entry_key("peppy/lab/topic/node/x/v1/t/c"))
        self.assertIsNone(k.parse_entry_key("elsewhere/lab/topic/node/x/v1/t/c/i"))
        self.assertTrue(k.is_segment("rs_left-1.0"))
        for bad in ("", "a/b", "a*", "a b", "a$", "a#", "a?", "a@"):
            self.assertFalse(k.is_segment(bad), bad)


if __name__ == "__main__":
    unittest.main()
