"""`Time`: the `time` wire type as a Python value."""

from __future__ import annotations

import math
import time as _time
from typing import Union

NANOS_PER_SECOND = 1_000_000_000


class Time(float):
    """Seconds since the Unix epoch, usable wherever a float is (`time.time()`).

    A float cannot hold nanoseconds for current dates, so the exact wire
    value travels beside it: `seconds` (floor, also before the epoch) and
    `nanoseconds` (0 <= ns < 1e9). A time received from a Rust node is
    sent on unchanged.
    """

    __slots__ = ("seconds", "nanoseconds")

    seconds: int
    nanoseconds: int

    def __new__(cls, seconds: int, nanoseconds: int = 0) -> "Time":
        if not isinstance(seconds, int) or not isinstance(nanoseconds, int):
            raise TypeError("Time(seconds, nanoseconds) takes integers; use Time.from_float for a float")
        if not 0 <= nanoseconds < NANOS_PER_SECOND:
            raise ValueError(f"nanoseconds must be in 0..1e9, got {nanoseconds}")
        value = super().__new__(cls, seconds + nanoseconds / NANOS_PER_SECOND)
        value.seconds = int(seconds)
        value.nanoseconds = int(nanoseconds)
        return value

    @classmethod
    def from_float(cls, value: Union[float, int]) -> "Time":
        """The time `value` seconds after the epoch, to the nearest nanosecond."""
        if isinstance(value, Time):
            return value
        if isinstance(value, int):
            return cls(value, 0)
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"a time must be finite, got {value}")
        seconds = math.floor(value)
        # value - floor(value) is exact in binary floating point.
        nanos = round((value - seconds) * NANOS_PER_SECOND)
        if nanos >= NANOS_PER_SECOND:
            seconds += 1
            nanos -= NANOS_PER_SECOND
        return cls(int(seconds), int(nanos))

    @classmethod
    def now(cls) -> "Time":
        """The current wall-clock time, exact to the nanosecond the OS gives."""
        seconds, nanos = divmod(_time.time_ns(), NANOS_PER_SECOND)
        return cls(seconds, nanos)

    def __reduce__(self):
        return (Time, (self.seconds, self.nanoseconds))

    def __repr__(self) -> str:
        return f"Time(seconds={self.seconds}, nanoseconds={self.nanoseconds})"

    def __copy__(self) -> "Time":
        return self

    def __deepcopy__(self, memo) -> "Time":
        return self
