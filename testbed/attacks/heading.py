"""Heading bias on the MSF output: the MSF yaw turned by `bias` rad (+ left), ramped in over `ramp` s, with its
position left true. Alg. 1 compares lateral deviations only, so MSF and lines agree while the controller,
steering on the biased heading, settles the car off the centreline."""

from __future__ import annotations

from typing import Any

from testbed.attacks.ramped import RampedMsfAttack
from tracks.pose import Pose


class HeadingBias(RampedMsfAttack):
    """Adds bias·ramp(t − start) to the MSF yaw; `offset` in the state is the bias (rad), not a distance."""

    name = "heading"

    def __init__(self, start: float = 10.0, bias: float = 0.03, ramp: float = 2.0) -> None:
        super().__init__(start, bias, ramp)

    def moved(self, pose: Pose, lane_heading: float, value: float) -> Pose:
        return Pose(pose.x, pose.y, pose.yaw + value)

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "bias": self.amount, "ramp": self.ramp}
