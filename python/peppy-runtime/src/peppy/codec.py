"""The payload encoding of docs/WIRE.md §5: fields in declaration order,
little-endian, no names, no padding.

Generated code declares each message as a dataclass and registers its
layout with `describe(cls, [(attribute, descriptor), ...])`; `encode` and
`decode` then work on instances. Decoding never trusts a length: every
count is checked against the bytes that remain before anything is built.

The types live in `codec_scalars`, `codec_arrays` and `codec_objects`;
this module is the one generated code imports.
"""

from .codec_arrays import Array, Optional
from .codec_objects import Obj, decode, describe, encode
from .codec_scalars import (
    BOOL,
    BYTES,
    F32,
    F64,
    I8,
    I16,
    I32,
    I64,
    STRING,
    TIME,
    U8,
    U16,
    U32,
    U64,
    DecodeError,
    EncodeError,
)
from .formats import Format, fingerprint_of
from .timestamps import Time

__all__ = [
    "BOOL",
    "U8",
    "U16",
    "U32",
    "U64",
    "I8",
    "I16",
    "I32",
    "I64",
    "F32",
    "F64",
    "STRING",
    "BYTES",
    "TIME",
    "Array",
    "Obj",
    "Optional",
    "describe",
    "encode",
    "decode",
    "DecodeError",
    "EncodeError",
    "Format",
    "fingerprint_of",
    "Time",
]
