"""Frame integrity of the chassis protocol: XOR checksum of bytes 0-6 in byte 7, and 4-bit life counters.

A life counter advances by exactly one (mod 16) per frame of one ID; the first frame a receiver sees
synchronises it.
"""

from __future__ import annotations

from enum import Enum

FRAME_LENGTH = 8
CHECKSUM_BYTE = 7
LIFE_MODULUS = 16


def xor_checksum(data: bytes | bytearray) -> int:
    """XOR of bytes 0-6."""
    value = 0
    for byte in data[:CHECKSUM_BYTE]:
        value ^= byte
    return value


def checksum_ok(data: bytes | bytearray) -> bool:
    """True when `data` is a full frame whose byte 7 equals the XOR of bytes 0-6."""
    return len(data) == FRAME_LENGTH and data[CHECKSUM_BYTE] == xor_checksum(data)


class LifeCounter:
    """Transmit side of one frame ID: hands out 0, 1, ..., 15, 0, ..."""

    def __init__(self) -> None:
        self._value = -1

    def next(self) -> int:
        self._value = (self._value + 1) % LIFE_MODULUS
        return self._value


class LifeVerdict(Enum):
    """Outcome of checking one received life counter."""

    OK = "ok"
    STALE = "stale"  # the same value again: a repeated or replayed frame
    SKIPPED = "skipped"  # any other jump: lost frames or a second sender


class LifeMonitor:
    """Receive side of one frame ID: accepts only the successor of the last value; a mismatch resyncs."""

    def __init__(self) -> None:
        self._last: int | None = None

    def check(self, value: int) -> LifeVerdict:
        last, self._last = self._last, value
        if last is None or value == (last + 1) % LIFE_MODULUS:
            return LifeVerdict.OK
        return LifeVerdict.STALE if value == last else LifeVerdict.SKIPPED
