"""The chassis port: what the loop reads from and commands to a vehicle, simulated or real.

Two implementations share this contract: the PyBullet vehicle driven directly (`testbed.world`)
and `hil`'s CAN bridge. The loop never knows which one it drives.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Literal

from pydantic import Field

from testbed.params import Params
from tracks.pose import Pose


def bicycle_yaw_rate(speed: float, steer: float, wheelbase: float) -> float:
    """The kinematic bicycle's yaw rate ψ̇ = v tan δ / L (rad/s) from speed (m/s), road-wheel angle (rad) and
    wheelbase (m): what a chassis that reports no yaw rate is read as turning at."""
    return speed * math.tan(steer) / wheelbase


class ChassisModel(Params):
    """`[chassis]`: what the simulated car's chassis reports (direct runs; over CAN the emulated chassis is the
    profile's): its own yaw rate, or one derived from its steering angle as a CAN chassis without a yaw-rate
    report is read; and a road-wheel angle sensor that reads `steer_offset_deg` more than the wheels' angle
    (the steering servo, closing its loop on it, sets the wheels that much short of the command)."""

    yaw_rate: Literal["sensed", "steering"] = Field("sensed", description="the yaw rate reported: the body's "
                                                    "(a gyro's), or v tan δ / L from the reported speed and "
                                                    "steering angle (a chassis without a yaw-rate report)")
    steer_offset_deg: float = Field(0.0, ge=-10.0, le=10.0, description="the road-wheel angle sensor reads this "
                                    "much more than the wheels' angle (°): a miscalibration")


@dataclass(frozen=True)
class ChassisCommand:
    """Steering angle at the road wheels (rad, + left) and longitudinal acceleration (m/s², < 0 brakes)."""

    steer: float
    accel: float


@dataclass(frozen=True)
class ChassisState:
    """What the chassis reports: time, speed, steering angle (NaN from a port without the sensor), acceleration;
    simulation adds the true pose, and the body's true yaw rate where the reported one is not it (what a simulated
    IMU measures)."""

    t: float
    speed: float
    steer: float
    accel: float
    true_pose: Pose | None = None
    yaw_rate: float = 0.0
    mode: str = "self-driving"
    faults: tuple[str, ...] = field(default_factory=tuple)
    true_yaw_rate: float | None = None
    mean_yaw_rate: float | None = None
    """The body's yaw rate averaged over the control period that ended at `t` (rad/s), as an integrating gyro's
    delta angle gives it; None where the chassis measures no such thing (only the sampled `yaw_rate`)."""

    @property
    def body_yaw_rate(self) -> float:
        """The yaw rate a simulated IMU measures: the true one where known, else the reported one (rad/s)."""
        return self.yaw_rate if self.true_yaw_rate is None else self.true_yaw_rate

    @property
    def odometry_yaw_rate(self) -> float:
        """The yaw rate odometry integrates over the period ending at `t`: its mean where measured, else the sampled
        one (rad/s). A rate sampled once a period aliases the steering's oscillations near the control rate into a
        yaw drift; the period's mean does not."""
        return self.yaw_rate if self.mean_yaw_rate is None else self.mean_yaw_rate


@dataclass(frozen=True)
class ChassisFault:
    """A fault that ends the run: its kind, the chassis time it was detected (s) and a one-line detail."""

    kind: str
    t: float
    detail: str


class ChassisPort(ABC):
    """A vehicle the loop can drive: read its state, send a command, let time advance by one tick."""

    def latched_faults(self) -> tuple[ChassisFault, ...]:
        """Faults after which the port only brakes to standstill; the run then ends as chassis_fault."""
        return ()

    @abstractmethod
    def read(self) -> ChassisState: ...

    @abstractmethod
    def send(self, cmd: ChassisCommand) -> None: ...

    @abstractmethod
    def advance(self, dt: float) -> None:
        """Let `dt` seconds of vehicle time pass (simulation: step the physics; hardware: wait)."""
