"""The attack contract the loop drives: what an attacker sees each tick and the four places it may act.

An attack may spoof GNSS fixes before the MSF fuses them, tamper with the MSF output, tamper with the
lane detector's output, or paint the road. Every hook defaults to the identity; `state()` reports the
attack's stage, switch time and current lateral offset (signed, + left) for trajectory.csv/summary.json.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from testbed.errors import UserError
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix
from tracks.pose import Pose


@dataclass(frozen=True)
class AttackerView:
    """What a tailgating attacker sees: time, the victim's true pose, signed physical lane deviation."""

    t: float
    true_pose: Pose
    phys_dev: float
    lane_heading: float
    speed: float


def left_normal(heading: float) -> np.ndarray:
    """Unit vector pointing left of a direction of travel `heading` (rad)."""
    return np.array([-math.sin(heading), math.cos(heading)])


def shift_pose(pose: Pose, heading: float, offset: float) -> Pose:
    """`pose` moved `offset` metres to the left (+) or right (−) of a direction of travel `heading`."""
    n = left_normal(heading)
    return Pose(pose.x + offset * float(n[0]), pose.y + offset * float(n[1]), pose.yaw)


class Attack(ABC):
    """One attack: hooks default to the identity; subclasses override the ones their threat model uses."""

    name: str = ""

    def __init__(self, start_time: float) -> None:
        if not (math.isfinite(start_time) and start_time >= 0):
            raise UserError(f"attack start must be a time >= 0 s, got {start_time}")
        self.start_time = start_time

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        return fix

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        return est

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        return ld

    def painters(self) -> list[Any]:
        """Road-texture painters (only the road-patch attack has any)."""
        return []

    @abstractmethod
    def state(self) -> dict[str, Any]:
        """{'stage': str, 'switch_time': float | None, 'offset': float (m, + left)}."""

    @abstractmethod
    def describe(self) -> dict[str, Any]:
        """The attack spec as a JSON-able object: {'kind': ..., parameters...}."""
