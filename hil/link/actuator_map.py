"""The command cycle in SI units and its mapping onto a profile's drive, brake and steer messages.

Longitudinal: a = throttle/100 * full_throttle_accel (gear D only) - pedal/100 * full_brake_decel, and an
emergency-brake signal (where the profile has one) gives -full_brake_decel. A request's accel >= 0 becomes
throttle, < 0 brake pedal. Steering: road-wheel angle in radians here, `Steering.to_wire` degrees on the wire
(ratio and sign of the profile); the rate likewise. Values beyond the wire's range are clipped to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from hil.link.profile import ChassisProfile, default_profile
from testbed.chassis import ChassisCommand


class Gear(IntEnum):
    """Gear requests and reports by meaning; a profile's [gears] table gives their wire values."""

    NO_REQUEST = 0
    PARK = 1
    REVERSE = 2
    NEUTRAL = 3
    DRIVE = 4

    def wire(self, profile: ChassisProfile) -> int:
        gears = profile.gears
        return gears.get(self.name.lower(), gears.get("no_request", gears["neutral"]))

    @classmethod
    def from_wire(cls, value: int, profile: ChassisProfile) -> Gear | None:
        names = {v: k for k, v in profile.gears.items()}
        return cls[names[value].upper()] if value in names else None


def _clip(value: float, lo: float, hi: float) -> float:
    return min(max(value, lo), hi)


def _signal_range(profile: ChassisProfile, message: str, signal: str) -> tuple[float, float]:
    s = profile.message(message).get_signal_by_name(signal)
    return (s.minimum if s.minimum is not None else -math.inf), (s.maximum if s.maximum is not None else math.inf)


@dataclass(frozen=True)
class ActuatorRequest:
    """One command cycle: enable, gear, acceleration (m/s²), emergency brake, steer (rad) and rate (rad/s)."""

    enable: bool
    gear: Gear
    accel: float
    emergency: bool
    steer: float
    steer_rate: float

    @classmethod
    def from_command(
        cls, cmd: ChassisCommand, *, enable: bool, steer_rate: float, emergency: bool = False
    ) -> ActuatorRequest:
        return cls(enable, Gear.DRIVE, cmd.accel, emergency, cmd.steer, steer_rate)

    def to_signals(self, profile: ChassisProfile | None = None) -> dict[str, dict[str, float]]:
        """Signal values (DBC units) of the three command messages; life counters and checksums come later."""
        p = profile or default_profile()
        c, lon, st = p.commands, p.longitudinal, p.steering
        throttle = _clip(self.accel / lon.full_throttle_accel * 100.0, *_signal_range(p, c.drive, c.throttle))
        pedal_pct = 100.0 if self.emergency and c.emergency is None else -self.accel / lon.full_brake_decel * 100.0
        pedal = _clip(pedal_pct, *_signal_range(p, c.brake, c.pedal))
        angle = _clip(st.to_wire(self.steer), *_signal_range(p, c.steer, c.angle))
        enable = int(self.enable)
        drive = {**c.constants.get(c.drive, {}), c.drive_enable: enable, c.gear: self.gear.wire(p),
                 c.throttle: throttle}
        brake = {**c.constants.get(c.brake, {}), c.brake_enable: enable, c.pedal: pedal}
        if c.emergency is not None:
            brake[c.emergency] = int(self.emergency)
        steer = {**c.constants.get(c.steer, {}), c.steer_enable: enable, c.angle: angle}
        if c.rate is not None:
            steer[c.rate] = _clip(st.ratio * math.degrees(self.steer_rate), *_signal_range(p, c.steer, c.rate))
        return {c.drive: drive, c.brake: brake, c.steer: steer}

    @classmethod
    def from_signals(
        cls,
        drive: dict[str, float],
        brake: dict[str, float],
        steer: dict[str, float],
        profile: ChassisProfile | None = None,
    ) -> ActuatorRequest:
        """The request carried by one verified frame of each command message; enabled only if all three are."""
        p = profile or default_profile()
        c, lon, st = p.commands, p.longitudinal, p.steering
        gear = Gear.from_wire(int(drive[c.gear]), p) or Gear.NO_REQUEST
        emergency = bool(brake[c.emergency]) if c.emergency is not None else False
        throttle = drive[c.throttle] / 100.0 * lon.full_throttle_accel if gear is Gear.DRIVE else 0.0
        brake_decel = brake[c.pedal] / 100.0 * lon.full_brake_decel
        accel = -lon.full_brake_decel if emergency else throttle - brake_decel
        enable = bool(drive[c.drive_enable]) and bool(brake[c.brake_enable]) and bool(steer[c.steer_enable])
        rate = math.radians(steer[c.rate] / st.ratio) if c.rate is not None else st.max_rate
        return cls(enable, gear, accel, emergency, st.from_wire(steer[c.angle]), rate)
