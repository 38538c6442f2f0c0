"""The payload encoding (WIRE.md §5) and formats (§6): the golden vectors
shared with the Rust runtime (tests/golden/wire.json), round trips of every
type, and every input a decoder must refuse."""

from __future__ import annotations

import math
import struct
import time
import unittest
from dataclasses import dataclass
from typing import Any, List, Optional

import golden

from peppy import Time
from peppy import codec as c


@dataclass
class Numbers:
    u8: int
    u16: int
    u32: int
    u64: int
    i8: int
    i16: int
    i32: int
    i64: int
    f32: float
    f64: float


c.describe(
    Numbers,
    [
        ("u8", c.U8),
        ("u16", c.U16),
        ("u32", c.U32),
        ("u64", c.U64),
        ("i8", c.I8),
        ("i16", c.I16),
        ("i32", c.I32),
        ("i64", c.I64),
        ("f32", c.F32),
        ("f64", c.F64),
    ],
)


@dataclass
class Header:
    stamp: Any
    frame_id: int


@dataclass
class Point:
    x: float
    y: float
    name: Optional[str]


@dataclass
class Frame:
    header: Header
    encoding: str
    points: List[Point]
    corners: List[Point]
    names: List[str]
    flags: List[bool]
    samples: List[int]
    fixed_bytes: bytes
    raw: bytes
    maybe_header: Optional[Header]
    nested: List[List[int]]


c.describe(Header, [("stamp", c.TIME), ("frame_id", c.U32)])
c.describe(Point, [("x", c.F64), ("y", c.F32), ("name", c.Optional(c.STRING))])
c.describe(
    Frame,
    [
        ("header", c.Obj(Header)),
        ("encoding", c.STRING),
        ("points", c.Array(c.Obj(Point))),
        ("corners", c.Array(c.Obj(Point), 2)),
        ("names", c.Array(c.STRING)),
        ("flags", c.Array(c.BOOL)),
        ("samples", c.Array(c.I16)),
        ("fixed_bytes", c.Array(c.U8, 3)),
        ("raw", c.BYTES),
        ("maybe_header", c.Optional(c.Obj(Header))),
        ("nested", c.Array(c.Array(c.U32))),
    ],
)


@dataclass
class Empty:
    pass


c.describe(Empty, [])


@dataclass
class One:
    value: Any


def one(t):
    """A fresh single-field class of type `t` (for refusal tests)."""

    @dataclass
    class Single:
        value: Any

    c.describe(Single, [("value", t)])
    return Single


class GoldenTest(unittest.TestCase):
    """Every message, refused payload and fingerprint of the shared file."""

    def test_every_golden_message_encodes_and_decodes_as_written(self):
        vectors = golden.load()["messages"]
        self.assertTrue(vectors)
        for v in vectors:
            with self.subTest(v["name"]):
                f = golden.format_of(v["format"], v["fingerprint"])
                data = bytes.fromhex(v["hex"])
                shape = golden.shape_of(v["format"])
                if shape is None:
                    self.assertEqual((v["value"], f.encode(None), f.decode(data)), ({}, data, None))
                    continue
                self.assertEqual(f.encode(golden.message(shape, v["value"])), data)
                for received in (data, memoryview(data)):
                    self.assertIsNone(golden.mismatch(shape, v["value"], f.decode(received)))

    def test_every_golden_refusal_is_refused(self):
        for v in golden.load()["rejected"]:
            with self.subTest(v["why"], format=v["format"]):
                shape = golden.shape_of(v["format"])
                f = golden.EMPTY if shape is None else c.Format(shape.cls, v["format"], c.fingerprint_of(v["format"]))
                with self.assertRaises(c.DecodeError):
                    f.decode(bytes.fromhex(v["hex"]))

    def test_every_golden_fingerprint(self):
        for v in golden.load()["fingerprints"]:
            with self.subTest(v["canonical"]):
                fp = golden.fingerprint(v["fingerprint"])
                if v["canonical"] == golden.NO_PAYLOAD:
                    self.assertEqual((golden.EMPTY.canonical, golden.EMPTY.fingerprint), (v["canonical"], fp))
                    continue
                self.assertEqual(c.fingerprint_of(v["canonical"]), fp)
                self.assertEqual(c.Format(None, v["canonical"], fp).fingerprint, fp)

    def test_u8_arrays_accept_any_bytes_like_value(self):
        (v,) = [v for v in golden.load()["messages"] if v["name"] == "wire_md_example"]
        shape = golden.shape_of(v["format"])
        value = golden.message(shape, v["value"])
        for blob in (b"\x01\x02", bytearray(b"\x01\x02"), memoryview(b"\x01\x02"), [1, 2], (1, 2)):
            value.g = blob
            self.assertEqual(c.encode(shape.cls, value), bytes.fromhex(v["hex"]))

    def test_no_payload(self):
        self.assertEqual(c.encode(Empty, Empty()), b"")
        self.assertEqual(c.decode(Empty, b""), Empty())
        f = c.Format(Empty, "(no payload)", 0)
        self.assertEqual(f.encode(Empty()), b"")
        self.assertEqual(f.decode(b""), Empty())
        with self.assertRaises(c.DecodeError):
            f.decode(b"\x00")


class RoundTripTest(unittest.TestCase):
    def round_trip(self, cls, value):
        data = c.encode(cls, value)
        back = c.decode(cls, data)
        self.assertEqual(back, value)
        return data, back

    def test_every_number_at_its_limits(self):
        low = Numbers(0, 0, 0, 0, -128, -32768, -(2**31), -(2**63), -3.4028234663852886e38, -math.inf)
        high = Numbers(255, 65535, 2**32 - 1, 2**64 - 1, 127, 32767, 2**31 - 1, 2**63 - 1, 0.25, 1e308)
        for v in (low, high):
            data, _ = self.round_trip(Numbers, v)
            self.assertEqual(len(data), 1 + 2 + 4 + 8 + 1 + 2 + 4 + 8 + 4 + 8)
        data = c.encode(Numbers, Numbers(1, 2, 3, 4, -1, -2, -3, -4, 0.5, -0.5))
        self.assertEqual(data, struct.pack("<BHIQbhiqfd", 1, 2, 3, 4, -1, -2, -3, -4, 0.5, -0.5))
        nan = c.decode(Numbers, c.encode(Numbers, Numbers(0, 0, 0, 0, 0, 0, 0, 0, math.nan, math.nan)))
        self.assertTrue(math.isnan(nan.f32) and math.isnan(nan.f64))

    def test_nested_objects_arrays_and_optionals(self):
        frame = Frame(
            header=Header(Time(1_700_000_000, 123_456_789), 42),
            encoding="rgb8",
            points=[Point(1.0, 2.0, "a"), Point(-1.5, 0.25, None)],
            corners=[Point(0.0, 0.0, None), Point(1.0, 1.0, "é")],
            names=["", "x", "日本"],
            flags=[True, False, True],
            samples=[-1, 0, 32767],
            fixed_bytes=b"abc",
            raw=b"\x00\xff",
            maybe_header=Header(Time(-2, 999_999_999), 7),
            nested=[[1, 2], [], [3]],
        )
        self.round_trip(Frame, frame)
        empty = Frame(Header(Time(0, 0), 0), "", [], [Point(0, 0, None)] * 2, [], [], [], b"\0\0\0", b"", None, [])
        self.round_trip(Frame, empty)

    def test_time_is_exact_and_interchangeable_with_float(self):
        t = Time(1_700_000_000, 123_456_789)
        self.assertIsInstance(t, float)
        self.assertAlmostEqual(t, 1_700_000_000.123456789, places=5)
        (back,) = [c.decode(Header, c.encode(Header, Header(t, 1))).stamp]
        self.assertEqual((back.seconds, back.nanoseconds), (1_700_000_000, 123_456_789))
        # A float is floored to seconds, nanoseconds rounded.
        h = c.decode(Header, c.encode(Header, Header(2.5, 0)))
        self.assertEqual((h.stamp.seconds, h.stamp.nanoseconds), (2, 500_000_000))
        h = c.decode(Header, c.encode(Header, Header(-1.25, 0)))
        self.assertEqual((h.stamp.seconds, h.stamp.nanoseconds), (-2, 750_000_000))
        h = c.decode(Header, c.encode(Header, Header(7, 0)))
        self.assertEqual((h.stamp.seconds, h.stamp.nanoseconds), (7, 0))
        # Rounding up to a whole second carries.
        carried = Time.from_float(0.9999999999)
        self.assertEqual((carried.seconds, carried.nanoseconds), (1, 0))
        # Times before the epoch: floor seconds, positive nanoseconds (WIRE §5).
        data = c.encode(Header, Header(Time(-1, 500_000_000), 0))
        self.assertEqual(data[:12], struct.pack("<qI", -1, 500_000_000))
        self.assertEqual(Time(-1, 500_000_000), -0.5)
        now = Time.now()
        self.assertLess(abs(now - time.time()), 5)
        self.assertEqual(repr(Time(3, 4)), "Time(seconds=3, nanoseconds=4)")
        with self.assertRaises(ValueError):
            Time(0, 1_000_000_000)
        with self.assertRaises(ValueError):
            Time.from_float(math.inf)

    def test_format_encodes_and_decodes(self):
        f = c.Format(Header, "{stamp:time,frame_id:u32}", c.fingerprint_of("{stamp:time,frame_id:u32}"))
        h = Header(Time(5, 6), 9)
        self.assertEqual(f.decode(f.encode(h)), h)

    def test_a_refine_pin_keeps_the_open_arrays_wire_and_checks_the_length(self):
        # `refine` pins an open array to 7 on one node's side: the bytes are
        # those of the open array (a count, then the items), and only
        # exactly 7 items go out or come in.
        pinned = one(c.Array(c.F64, pinned=7))
        open_ = one(c.Array(c.F64))
        joints = [0.5 * i for i in range(7)]
        data = c.encode(pinned, pinned(joints))
        self.assertEqual(data, c.encode(open_, open_(joints)))
        self.assertEqual(c.decode(pinned, data).value, joints)
        with self.assertRaises(c.EncodeError) as e:
            c.encode(pinned, pinned(joints[:6]))
        self.assertIn("this node's `refine` pins 7", str(e.exception))
        with self.assertRaises(c.DecodeError) as e:
            c.decode(pinned, c.encode(open_, open_(joints + [1.0])))
        self.assertIn("8 items where this node's `refine` pins 7", str(e.exception))


class RefusalTest(unittest.TestCase):
    def assertRefused(self, cls, data, offset, words):
        with self.assertRaises(c.DecodeError) as caught:
            c.decode(cls, bytes(data))
        self.assertEqual(caught.exception.offset, offset, str(caught.exception))
        self.assertIn(words, str(caught.exception))
        self.assertIsInstance(caught.exception, ValueError)

    def test_decoders_refuse_bad_input(self):
        self.assertRefused(one(c.U8), b"\x01\x02", 1, "1 unexpected trailing bytes")
        self.assertRefused(one(c.BOOL), b"\x02", 0, "bool byte is 2")
        self.assertRefused(one(c.Array(c.BOOL)), b"\x02\0\0\0\x01\x05", 5, "bool byte is 5")
        self.assertRefused(one(c.Optional(c.U8)), b"\x02\x01", 0, "presence byte is 2")
        self.assertRefused(one(c.STRING), b"\x02\0\0\0\xc3\x28", 4, "not valid UTF-8")
        self.assertRefused(one(c.STRING), b"\x02\0\0\0\xed\xa0", 4, "not valid UTF-8")
        self.assertRefused(one(c.TIME), struct.pack("<qI", 1, 1_000_000_000), 0, "nanoseconds out of range")
        self.assertRefused(one(c.TIME), struct.pack("<qI", -(2**63), 0), 0, "out of range")
        self.assertRefused(one(c.U32), b"\x01\x02", 0, "needs 4 more bytes, 2 left")
        self.assertRefused(one(c.Optional(c.U8)), b"", 0, "needs 1 more bytes")

    def test_hostile_lengths_are_refused_before_anything_is_built(self):
        huge = struct.pack("<I", 0xFFFFFFFF)
        self.assertRefused(one(c.STRING), huge + b"ab", 0, "length 4294967295 exceeds the 2 bytes that remain")
        self.assertRefused(one(c.BYTES), huge, 0, "exceeds the 0 bytes")
        self.assertRefused(one(c.Array(c.U64)), struct.pack("<I", 2) + b"\0" * 15, 0, "length 2 exceeds the 15")
        self.assertRefused(one(c.Array(c.STRING)), struct.pack("<I", 3) + b"\0" * 8, 0, "length 3 exceeds the 8")
        self.assertRefused(one(c.Array(c.Obj(Header))), struct.pack("<I", 1) + b"\0" * 15, 0, "exceeds the 15")
        self.assertRefused(one(c.Array(c.U16, 3)), b"\0" * 5, 0, "fixed array of 3 needs more bytes than the 5 left")
        self.assertRefused(one(c.Array(c.Obj(Header), 2)), b"\0" * 31, 0, "fixed array of 2")

    def test_encoding_refuses_values_outside_their_type_naming_the_field(self):
        cases = [
            (Numbers(256, 0, 0, 0, 0, 0, 0, 0, 0, 0), "field `u8`"),
            (Numbers(0, 0, 0, -1, 0, 0, 0, 0, 0, 0), "field `u64`"),
            (Numbers(0, 0, 0, 0, 128, 0, 0, 0, 0, 0), "field `i8`"),
            (Numbers(0, 0, 0, 0, 0, 0, 0, 2**63, 0, 0), "field `i64`"),
            (Numbers(0, 0, 0, 0, 0, 0, 0, 0, 1e39, 0), "field `f32`"),
            (Numbers(0, 0, 1.5, 0, 0, 0, 0, 0, 0, 0), "field `u32`"),
            (Numbers(0, 0, 0, 0, 0, 0, 0, 0, 0, "x"), "field `f64`"),
        ]
        for value, words in cases:
            with self.assertRaises(ValueError) as caught:
                c.encode(Numbers, value)
            self.assertIn(words, str(caught.exception))
        frame = Frame(
            Header(0.0, 0),
            "",
            [Point(0, 0, None), Point(0, 0, 5)],
            [Point(0, 0, None)] * 2,
            [],
            [],
            [],
            b"abc",
            b"",
            None,
            [],
        )
        with self.assertRaises(ValueError) as caught:
            c.encode(Frame, frame)
        self.assertIn("field `points[1].name`", str(caught.exception))
        for field, bad, words in (
            ("corners", [Point(0, 0, None)], "takes exactly 2"),
            ("fixed_bytes", b"ab", "takes exactly 3"),
            ("samples", [1, 40000], "field `samples[1]`"),
            ("flags", [True, 2], "field `flags[1]`"),
            ("nested", [[1], [-1]], "field `nested[1][0]`"),
            ("raw", "text", "field `raw`"),
            ("encoding", b"bytes", "field `encoding`"),
            ("header", Header(Time(0, 0), 2**32), "field `header.frame_id`"),
        ):
            value = Frame(Header(0.0, 0), "", [], [Point(0, 0, None)] * 2, [], [], [], b"abc", b"", None, [])
            setattr(value, field, bad)
            with self.assertRaises(ValueError) as caught:
                c.encode(Frame, value)
            self.assertIn(words, str(caught.exception), field)

    def test_undescribed_classes_are_named(self):
        with self.assertRaises(TypeError):
            c.encode(One, One(1))


class FingerprintTest(unittest.TestCase):
    # docs/WIRE.md §6's example, the first of the file's fingerprints.
    EXAMPLE = golden.load()["fingerprints"][0]["canonical"]

    def test_formats_check_their_fingerprint(self):
        fp = c.fingerprint_of(self.EXAMPLE)
        self.assertEqual(c.Format(None, self.EXAMPLE, fp).fingerprint, fp)
        with self.assertRaises(ValueError):
            c.Format(None, self.EXAMPLE, fp ^ 1)
        self.assertEqual(c.Format(Empty, "(no payload)", 0).fingerprint, 0)
        with self.assertRaises(ValueError):
            c.Format(Empty, "(no payload)", 5)


if __name__ == "__main__":
    unittest.main()
