"""The report set in SI units and its mapping onto the report frames 0x530-0x537 (and sim truth 0x540/1).

The VCU fills a `VcuReport` and encodes it with `to_signals`; the bridge feeds every verified report
frame to a `ReportFollower`, which turns the latest values into a `ChassisState` (degrees on the wire,
radians in the state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from hil.actuator_map import Gear
from hil.codec import DecodedFrame
from testbed.chassis import ChassisState
from tracks.pose import Pose

DRIVE_STATUS, BRAKE_STATUS, STEER_STATUS = "VCU_DriveStatus", "VCU_BrakeStatus", "VCU_SteerStatus"
WORK_STATUS, FAULT_STATUS = "VCU_WorkStatus", "VCU_FaultStatus"
TRUTH_POSITION, TRUTH_MOTION = "SIM_TruthPosition", "SIM_TruthMotion"
COUNT_SATURATION = 255


class DrivingMode(IntEnum):
    """VCU_WorkStatus.DrivingMode; `label` is the ChassisState.mode string."""

    STANDBY = 0
    SELF_DRIVING = 1
    REMOTE = 2
    MANUAL = 3

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", "-")


class EStopSource(IntEnum):
    """VCU_WorkStatus.EStopSource: why the VCU is braking to standstill on its own."""

    NONE = 0
    COMMAND_TIMEOUT = 1
    BAD_FRAMES = 2
    FOREIGN_NODE = 3
    EMERGENCY_BRAKE_COMMAND = 4


class FaultLevel(IntEnum):
    """Per-subsystem fault level of VCU_FaultStatus."""

    NO_FAULT = 0
    WARNING = 1
    DEGRADED = 2
    FATAL = 3


@dataclass(frozen=True)
class VcuReport:
    """One report set: motion, actuator status, driving mode, faults, rejection counts, simulation truth."""

    speed: float
    accel: float
    steer: float
    gear: Gear
    enabled: bool
    brake_pct: float
    emergency_active: bool
    steer_limited: bool
    mode: DrivingMode
    estop: EStopSource
    command_timeout: bool
    bad_frames: bool
    foreign_node: bool
    bad_checksum_count: int
    bad_counter_count: int
    bad_format_count: int
    true_pose: Pose | None = None
    yaw_rate: float = 0.0

    def to_signals(self) -> dict[str, dict[str, float]]:
        """Signal values per report frame in publication order; truth frames only if a true pose is known."""
        comm = FaultLevel.FATAL if (self.command_timeout or self.bad_frames or self.foreign_node) else 0
        enabled = int(self.enabled)
        frames: dict[str, dict[str, float]] = {
            DRIVE_STATUS: {
                "DriveEnableState": enabled,
                "GearActual": int(self.gear),
                "VehicleSpeed": _clip(self.speed, 65.534),
                "VehicleAccel": _clip(self.accel, 32.767),
            },
            BRAKE_STATUS: {
                "BrakeEnableState": enabled,
                "EmergencyBrakeActive": int(self.emergency_active),
                "BrakePedalActual": min(max(self.brake_pct, 0.0), 100.0),
            },
            STEER_STATUS: {
                "SteerEnableState": enabled,
                "SteerLimitActive": int(self.steer_limited),
                "SteerAngleActual": _clip(math.degrees(self.steer), 65.534),
            },
            WORK_STATUS: {"DrivingMode": int(self.mode), "EStopSource": int(self.estop)},
            FAULT_STATUS: {
                "DriveFaultLevel": 0,
                "BrakeFaultLevel": 0,
                "SteerFaultLevel": 0,
                "CommFaultLevel": int(comm),
                "CommandTimeout": int(self.command_timeout),
                "BadFrameRun": int(self.bad_frames),
                "ForeignNode": int(self.foreign_node),
                "BadChecksumCount": min(self.bad_checksum_count, COUNT_SATURATION),
                "BadCounterCount": min(self.bad_counter_count, COUNT_SATURATION),
                "BadFormatCount": min(self.bad_format_count, COUNT_SATURATION),
            },
        }
        if self.true_pose is not None:
            yaw = math.remainder(self.true_pose.yaw, math.tau)
            frames[TRUTH_POSITION] = {"TruthX": self.true_pose.x, "TruthY": self.true_pose.y}
            frames[TRUTH_MOTION] = {
                "TruthYaw": _clip(yaw, 3.2767),
                "TruthYawRate": _clip(self.yaw_rate, 3.2767),
            }
        return frames


def _clip(value: float, bound: float) -> float:
    return min(max(value, -bound), bound)


_FAULT_FLAGS = (
    ("CommandTimeout", "command_timeout"),
    ("BadFrameRun", "bad_frames"),
    ("ForeignNode", "foreign_node"),
)
_FAULT_LEVELS = (("DriveFaultLevel", "drive"), ("BrakeFaultLevel", "brake"), ("SteerFaultLevel", "steer"))


class ReportFollower:
    """Keeps the latest verified value of every report frame and renders them as a ChassisState."""

    def __init__(self) -> None:
        self._latest: dict[str, dict[str, float]] = {}

    def update(self, frame: DecodedFrame) -> None:
        self._latest[frame.name] = dict(frame.signals)

    def has(self, name: str) -> bool:
        return name in self._latest

    @property
    def mode(self) -> DrivingMode | None:
        work = self._latest.get(WORK_STATUS)
        return DrivingMode(int(work["DrivingMode"])) if work else None

    @property
    def estop(self) -> EStopSource:
        work = self._latest.get(WORK_STATUS)
        return EStopSource(int(work["EStopSource"])) if work else EStopSource.NONE

    def faults(self) -> tuple[str, ...]:
        """VCU fault flags by name, then nonzero subsystem levels as "<subsystem>_fault:<level>"."""
        status = self._latest.get(FAULT_STATUS, {})
        names = [name for signal, name in _FAULT_FLAGS if status.get(signal)]
        for signal, subsystem in _FAULT_LEVELS:
            level = int(status.get(signal, 0))
            if level:
                names.append(f"{subsystem}_fault:{FaultLevel(level).name.lower()}")
        return tuple(names)

    def state(self, t: float, extra_faults: tuple[str, ...] = ()) -> ChassisState:
        drive = self._latest.get(DRIVE_STATUS, {})
        steer = self._latest.get(STEER_STATUS, {})
        position = self._latest.get(TRUTH_POSITION)
        motion = self._latest.get(TRUTH_MOTION)
        pose = None
        if position is not None and motion is not None:
            pose = Pose(position["TruthX"], position["TruthY"], motion["TruthYaw"])
        mode = self.mode
        return ChassisState(
            t=t,
            speed=drive.get("VehicleSpeed", 0.0),
            steer=math.radians(steer.get("SteerAngleActual", 0.0)),
            accel=drive.get("VehicleAccel", 0.0),
            true_pose=pose,
            yaw_rate=motion["TruthYawRate"] if motion else 0.0,
            mode=mode.label if mode is not None else "no-report",
            faults=self.faults() + extra_faults,
        )
