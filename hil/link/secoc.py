"""SecOC-style frame authentication: each protected frame carries the low bits of a per-ID freshness counter and
a truncated AES-128-CMAC (the layout of AUTOSAR SecOC profile 1: 8-bit freshness, 24-bit MAC).

MAC input = CAN ID (2 bytes, big-endian) || the 8 frame bytes with the freshness and MAC fields cleared || the
full freshness value (8 bytes, big-endian). The MAC field holds the leading `mac_bits` of the CMAC as an
unsigned integer. A sender counts 1, 2, ... per ID. A receiver takes the full value to be the smallest one
above its last accepted value with the received low bits, accepts it only within `window` of that value and
only with a valid MAC, and only then moves its last accepted value (a rejected frame changes nothing).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from cryptography.hazmat.primitives.ciphers import algorithms
from cryptography.hazmat.primitives.cmac import CMAC

from testbed.errors import UserError

FRAME_LENGTH = 8
KEY_BYTES = 16
FRESHNESS_BYTES = 8


def key_from_hex(text: str) -> bytes:
    """A 128-bit AES key from 32 hex digits; raises ValueError."""
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != KEY_BYTES:
        raise UserError(f"expected {2 * KEY_BYTES} hex digits (a 128-bit AES key)")
    return key


def aes_cmac(key: bytes, message: bytes) -> bytes:
    """The full 16-byte AES-CMAC (RFC 4493) of `message` under the 128-bit `key`."""
    mac = CMAC(algorithms.AES(key))
    mac.update(message)
    return mac.finalize()


def mac_input(frame_id: int, cleared: bytes, freshness: int) -> bytes:
    """The authenticated bytes: ID, frame with freshness and MAC fields cleared, full freshness value."""
    return frame_id.to_bytes(2, "big") + bytes(cleared) + freshness.to_bytes(FRESHNESS_BYTES, "big")


@dataclass(frozen=True)
class BitField:
    """An unsigned little-endian (Intel) field of an 8-byte frame: bits start .. start+length-1 of the frame read
    as a little-endian integer (the DBC numbering)."""

    start: int
    length: int

    @property
    def mask(self) -> int:
        return ((1 << self.length) - 1) << self.start

    def read(self, data: bytes | bytearray) -> int:
        return (int.from_bytes(data, "little") & self.mask) >> self.start

    def write(self, data: bytearray, value: int) -> None:
        word = int.from_bytes(data, "little") & ~self.mask | (value << self.start) & self.mask
        data[:] = word.to_bytes(FRAME_LENGTH, "little")


@dataclass(frozen=True)
class SecuredLayout:
    """Where one message carries its truncated freshness value and truncated MAC."""

    freshness: BitField
    mac: BitField

    def cleared(self, data: bytes | bytearray) -> bytes:
        """The frame with both fields set to zero (the authentic payload the MAC covers)."""
        out = bytearray(data)
        self.freshness.write(out, 0)
        self.mac.write(out, 0)
        return bytes(out)


def truncated_mac(key: bytes, frame_id: int, layout: SecuredLayout, data: bytes | bytearray, freshness: int) -> int:
    """The leading `layout.mac.length` bits of the CMAC over the frame's MAC input, as an unsigned integer."""
    full = int.from_bytes(aes_cmac(key, mac_input(frame_id, layout.cleared(data), freshness)), "big")
    return full >> (8 * KEY_BYTES - layout.mac.length)


class SecocVerdict(Enum):
    """Outcome of verifying one received secured frame."""

    OK = "ok"
    STALE = "freshness"  # not newer than the last accepted value within the window: replayed, delayed or foreign
    BAD_MAC = "mac"  # fresh, but the MAC does not match: forged or corrupted


class FreshnessMonitor:
    """Receive side of one ID: the last accepted full freshness value (0 before the first frame)."""

    def __init__(self, bits: int, window: int) -> None:
        self.bits = bits
        self.window = window
        self.last = 0

    def candidate(self, low: int) -> int | None:
        """The full value the received low bits stand for, or None when it lies beyond the window."""
        modulus = 1 << self.bits
        value = self.last - self.last % modulus + low
        if value <= self.last:
            value += modulus
        return value if value - self.last <= self.window else None


class SecocEndpoint:
    """One node's SecOC state: a tx counter and an rx monitor per protected ID, under one key."""

    def __init__(self, key: bytes, layouts: dict[int, SecuredLayout], window: int) -> None:
        if len(key) != KEY_BYTES:
            raise ValueError(f"a SecOC key is {KEY_BYTES} bytes (AES-128), got {len(key)}")
        self._key = key
        self.layouts = layouts
        self._tx = dict.fromkeys(layouts, 0)
        self._rx = {i: FreshnessMonitor(layout.freshness.length, window) for i, layout in layouts.items()}

    def protects(self, frame_id: int) -> bool:
        return frame_id in self.layouts

    def seal(self, frame_id: int, data: bytearray) -> None:
        """Write the next freshness value's low bits and the truncated MAC into `data`."""
        layout = self.layouts[frame_id]
        self._tx[frame_id] += 1
        freshness = self._tx[frame_id]
        layout.freshness.write(data, freshness % (1 << layout.freshness.length))
        layout.mac.write(data, truncated_mac(self._key, frame_id, layout, data, freshness))

    def verify(self, frame_id: int, data: bytes | bytearray) -> SecocVerdict:
        """Check freshness, then the MAC; accept (move the last accepted value) only if both hold."""
        layout, monitor = self.layouts[frame_id], self._rx[frame_id]
        freshness = monitor.candidate(layout.freshness.read(data))
        if freshness is None:
            return SecocVerdict.STALE
        if layout.mac.read(data) != truncated_mac(self._key, frame_id, layout, data, freshness):
            return SecocVerdict.BAD_MAC
        monitor.last = freshness
        return SecocVerdict.OK
