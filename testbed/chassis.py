"""The chassis port: what the loop reads from and commands to a vehicle, simulated or real.

Two implementations share this contract: the PyBullet vehicle driven directly (`testbed.world`)
and `hil`'s CAN bridge. The loop never knows which one it drives.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

from tracks.pose import Pose


@dataclass(frozen=True)
class ChassisCommand:
    """Steering angle at the road wheels (rad, + left) and longitudinal acceleration (m/s², < 0 brakes)."""

    steer: float
    accel: float


@dataclass(frozen=True)
class ChassisState:
    """What the chassis reports: time, speed, steering angle, acceleration; simulation adds the true pose."""

    t: float
    speed: float
    steer: float
    accel: float
    true_pose: Pose | None = None
    yaw_rate: float = 0.0
    mode: str = "self-driving"
    faults: tuple[str, ...] = field(default_factory=tuple)


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
