"""Off-map MSF attack: the MSF pose is moved `distance` metres sideways (+ left), ramped in over `ramp` s
(one tick for 0), far enough that the map cannot place it; the paper's Alg. 1 skips such updates."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import shift_pose
from testbed.attacks.ramped import RampedMsfAttack
from tracks.pose import Pose


class OffMapAttack(RampedMsfAttack):
    """Moves the MSF pose off the mapped road and keeps it there."""

    name = "offmap"

    def __init__(self, start: float = 10.0, distance: float = 20.0, ramp: float = 0.0) -> None:
        super().__init__(start, distance, ramp)

    def moved(self, pose: Pose, lane_heading: float, value: float) -> Pose:
        return shift_pose(pose, lane_heading, value)

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "distance": self.amount, "ramp": self.ramp}
