"""Chassis frame codec: cantools coding of a chassis profile's DBC plus the life counters, checksums and SecOC
fields the profile declares.

One codec instance is one endpoint: `encode` fills the next life counter of that frame ID (for IDs that
carry one) and seals byte 7 with the XOR checksum (for IDs that carry one), or, for IDs the profile's [secoc]
table secures, writes the next freshness value and the truncated MAC (`hil.link.secoc`); `decode` rejects a frame
unless it is a standard, non-remote 8-byte frame of a known ID with a correct checksum where one is declared,
fresh and with a valid MAC where secured, every signal within its DBC range, and (for IDs with a life counter)
the successor of the previous counter on that ID. Physical units are those of the DBC (degrees for angles);
the SI conversions live in `hil.link.actuator_map` and `hil.link.report_map`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import can

from hil.link.integrity import (
    CHECKSUM_BYTE,
    FRAME_LENGTH,
    LifeCounter,
    LifeMonitor,
    LifeVerdict,
    checksum_ok,
    xor_checksum,
)
from hil.link.profile import PROFILES_DIR, ChassisProfile, Integrity, default_profile
from hil.link.secoc import BitField, SecocEndpoint, SecocVerdict, SecuredLayout
from testbed.errors import UserError

DBC_PATH = PROFILES_DIR / "ld3-dev" / "chassis.dbc"
REJECT_REASONS = ("format", "checksum", "range", "counter", "freshness", "mac")


class FrameRejected(Exception):
    """A received frame failed verification; `reason` is one of REJECT_REASONS."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True)
class DecodedFrame:
    """A verified frame: DBC message name, ID and physical signal values (checksum and life included)."""

    name: str
    frame_id: int
    signals: Mapping[str, float]


def _idle(lo: float | None, hi: float | None) -> float:
    return min(max(0.0, lo if lo is not None else 0.0), hi if hi is not None else 0.0)


def _secoc_endpoint(profile: ChassisProfile, key: bytes | None) -> SecocEndpoint | None:
    spec = profile.secoc
    if spec is None:
        return None
    if key is None:
        raise UserError(f"profile {profile.name} authenticates frames: the codec needs its key "
                         "(hil.link.secoc_key.link_key)")
    layouts = {}
    for name, signals in spec.messages.items():
        message = profile.message(name)
        fields = (message.get_signal_by_name(s) for s in (signals.freshness, signals.mac))
        layouts[message.frame_id] = SecuredLayout(*(BitField(f.start, f.length) for f in fields))
    return SecocEndpoint(key, layouts, spec.freshness_window)


class ChassisCodec:
    """Encodes and decodes chassis frames for one endpoint; owns its tx counters and rx monitors. A profile with
    a [secoc] table needs the 128-bit `key`."""

    def __init__(self, profile: ChassisProfile | None = None, key: bytes | None = None) -> None:
        self.profile = profile or default_profile()
        self._secoc = _secoc_endpoint(self.profile, key)
        self.db = self.profile.db
        self._messages = {m.frame_id: m for m in self.db.messages}
        integrity = {m.frame_id: self.profile.integrity.get(m.name, Integrity()) for m in self.db.messages}
        self._life = {i: spec.counter for i, spec in integrity.items()}
        self._checksum = {i: spec.checksum for i, spec in integrity.items()}
        self._tx_life: dict[int, LifeCounter] = {i: LifeCounter() for i, n in self._life.items() if n}
        self._rx_life: dict[int, LifeMonitor] = {i: LifeMonitor() for i, n in self._life.items() if n}

    def frame_id(self, name: str) -> int:
        return self.db.get_message_by_name(name).frame_id

    def knows(self, frame_id: int) -> bool:
        return frame_id in self._messages

    def encode(self, name: str, signals: Mapping[str, float]) -> can.Message:
        """A sealed frame of message `name`; signals left out of `signals` (life counter, checksum, SecOC fields,
        fields this side does not use) are filled: counter, checksum, freshness and MAC as declared, the others at
        0 clipped to their range."""
        message = self.db.get_message_by_name(name)
        payload = {s.name: _idle(s.minimum, s.maximum) for s in message.signals}
        payload.update(signals)
        checksum_name = self._checksum[message.frame_id]
        if checksum_name:
            payload[checksum_name] = 0
        life_name = self._life[message.frame_id]
        if life_name:
            payload[life_name] = self._tx_life[message.frame_id].next()
        data = bytearray(message.encode(payload, strict=True))
        if checksum_name:
            data[CHECKSUM_BYTE] = xor_checksum(data)
        if self._secoc is not None and self._secoc.protects(message.frame_id):
            self._secoc.seal(message.frame_id, data)
        return can.Message(arbitration_id=message.frame_id, is_extended_id=False, dlc=FRAME_LENGTH, data=data)

    def decode(self, frame: can.Message) -> DecodedFrame:
        """Verify and decode a received frame; raises FrameRejected."""
        message = self._messages.get(frame.arbitration_id)
        odd_kind = frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame or frame.is_fd
        if message is None or odd_kind:
            raise FrameRejected("format", f"not a chassis frame: {frame}")
        data = bytes(frame.data)
        if frame.dlc != FRAME_LENGTH or len(data) != FRAME_LENGTH:
            raise FrameRejected("format", f"{message.name}: DLC {frame.dlc}, {len(data)} bytes")
        if self._checksum[message.frame_id] and not checksum_ok(data):
            raise FrameRejected("checksum", f"{message.name}: {data.hex()}")
        if self._secoc is not None and self._secoc.protects(message.frame_id):
            verdict = self._secoc.verify(message.frame_id, data)
            if verdict is not SecocVerdict.OK:
                raise FrameRejected(verdict.value, f"{message.name}: {data.hex()}")
        signals = message.decode(data, decode_choices=False, scaling=False)
        physical = {}
        for signal in message.signals:
            raw = signals[signal.name]
            value = signal.conversion.raw_to_scaled(raw, decode_choices=False)
            lo, hi = signal.minimum, signal.maximum
            tolerance = abs(signal.scale) / 2
            if (lo is not None and value < lo - tolerance) or (hi is not None and value > hi + tolerance):
                raise FrameRejected("range", f"{message.name}.{signal.name} = {value}")
            physical[signal.name] = value
        life_name = self._life[message.frame_id]
        if life_name:
            verdict = self._rx_life[message.frame_id].check(int(physical[life_name]))
            if verdict is not LifeVerdict.OK:
                raise FrameRejected("counter", f"{message.name}: life {physical[life_name]} {verdict.value}")
        return DecodedFrame(message.name, message.frame_id, physical)
