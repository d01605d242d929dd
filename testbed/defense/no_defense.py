"""No defense: the controller always uses MSF and the vehicle never stops on its own."""

from __future__ import annotations

from testbed.defense.base import Defense, DefenseStatus, Mode
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap
from tracks.pose import Pose

_NEVER_DETECTED = DefenseStatus(detected=False)


class NoDefense(Defense):
    """Always normal; MSF passes straight through."""

    name = "none"

    @property
    def mode(self) -> Mode:
        return "normal"

    @property
    def stop_decel(self) -> float | None:
        return None

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        return None

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        return msf.pose

    def status(self) -> DefenseStatus:
        return _NEVER_DETECTED
