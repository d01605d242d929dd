"""The command cycle in SI units and its mapping onto the frames 0x130 drive, 0x131 brake, 0x132 steer.

Longitudinal: a = DriveThrottlePct/100 * MAX_DRIVE_ACCEL (gear D only) - BrakePedalPct/100 *
MAX_BRAKE_DECEL, and BrakeEmergency gives -MAX_BRAKE_DECEL. A ChassisCommand's accel >= 0 becomes
throttle, < 0 becomes brake pedal, so the wire resolution is 0.0005 m/s² (drive) and 0.0008 m/s² (brake).
Steering: road-wheel angle in degrees on the wire (0.002° resolution), radians here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from testbed.chassis import ChassisCommand

MAX_DRIVE_ACCEL = 5.0  # m/s² at 100 % throttle
MAX_BRAKE_DECEL = 8.0  # m/s² at 100 % brake pedal, and under BrakeEmergency
MAX_STEER_WIRE_DEG = 65.534
MAX_STEER_RATE_WIRE_DEG = 600.0

DRIVE, BRAKE, STEER = "ACU_DriveCtrl", "ACU_BrakeCtrl", "ACU_SteerCtrl"
COMMAND_FRAMES = (DRIVE, BRAKE, STEER)


class Gear(IntEnum):
    """DriveGearTarget / GearActual values."""

    NO_REQUEST = 0
    PARK = 1
    REVERSE = 2
    NEUTRAL = 3
    DRIVE = 4


def _clip(value: float, lo: float, hi: float) -> float:
    return min(max(value, lo), hi)


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

    def to_signals(self) -> dict[str, dict[str, float]]:
        """Signal values (DBC units) of the three command frames; life counters and checksums come later."""
        throttle = _clip(self.accel / MAX_DRIVE_ACCEL * 100.0, 0.0, 100.0)
        pedal = _clip(-self.accel / MAX_BRAKE_DECEL * 100.0, 0.0, 100.0)
        steer_deg = _clip(math.degrees(self.steer), -MAX_STEER_WIRE_DEG, MAX_STEER_WIRE_DEG)
        rate_deg = _clip(math.degrees(self.steer_rate), 0.0, MAX_STEER_RATE_WIRE_DEG)
        enable = int(self.enable)
        return {
            DRIVE: {"DriveEnable": enable, "DriveGearTarget": int(self.gear), "DriveThrottlePct": throttle},
            BRAKE: {"BrakeEnable": enable, "BrakeEmergency": int(self.emergency), "BrakePedalPct": pedal},
            STEER: {"SteerEnable": enable, "SteerAngleTarget": steer_deg, "SteerAngleSpeed": rate_deg},
        }

    @classmethod
    def from_signals(
        cls, drive: dict[str, float], brake: dict[str, float], steer: dict[str, float]
    ) -> ActuatorRequest:
        """The request carried by one verified frame of each command ID; enabled only if all three are."""
        gear = Gear(int(drive["DriveGearTarget"]))
        emergency = bool(brake["BrakeEmergency"])
        throttle = drive["DriveThrottlePct"] / 100.0 * MAX_DRIVE_ACCEL if gear is Gear.DRIVE else 0.0
        accel = -MAX_BRAKE_DECEL if emergency else throttle - brake["BrakePedalPct"] / 100.0 * MAX_BRAKE_DECEL
        enable = bool(drive["DriveEnable"]) and bool(brake["BrakeEnable"]) and bool(steer["SteerEnable"])
        return cls(
            enable,
            gear,
            accel,
            emergency,
            math.radians(steer["SteerAngleTarget"]),
            math.radians(steer["SteerAngleSpeed"]),
        )
