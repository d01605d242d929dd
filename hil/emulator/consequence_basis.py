"""Which pose a run over CAN is judged on (summary.json's `consequence_basis`): the emulated plant's own where the
run's emulator gives it, else the bridge's odometry, the only pose a run against any other chassis has."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from testbed.chassis import ChassisPort
from tracks.pose import Pose

PosePort = Callable[[], Pose | None]


@dataclass(frozen=True)
class ConsequenceBasis:
    """`name` as summary.json's `consequence_basis`; `pose` reads the plant's pose now (None from it: not known
    yet). No `pose`: the run is judged on the pose its chassis port hands the loop (the bridge's odometry)."""

    name: Literal["plant", "odometry"]
    pose: PosePort | None = None


def consequence_basis(plant: ChassisPort | None, truth: PosePort | None) -> ConsequenceBasis:
    """The plant in this process (its pose as it sensed it at its last step), else `truth`, the truth frames of an
    emulator the run started (None: none, or not publishing them), else odometry."""
    if plant is not None:
        return ConsequenceBasis("plant", lambda: plant.read().true_pose)
    if truth is not None:
        return ConsequenceBasis("plant", truth)
    return ConsequenceBasis("odometry")
