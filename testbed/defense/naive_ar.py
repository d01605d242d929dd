"""LD3-NaiveAR (paper §5.3): LD3's detection; on alarm, brake at the maximum deceleration while still
steering on the MSF output (like Apollo's in-lane-stop emergency planning)."""

from __future__ import annotations

from testbed.defense.alarmed import Ld3AlarmedDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap
from tracks.pose import Pose


class NaiveArDefense(Ld3AlarmedDefense):
    """Same detector as LD3; the response trusts MSF for steering and stops at `max_decel`."""

    name = "ld3-naive-ar"

    @property
    def response_decel(self) -> float:
        return self.config.max_decel

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        self._detect(self.followable(ld, smap), msf, smap)

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        """The checked pose while normal; the MSF pose in the response."""
        return self.checked_pose(msf) if self.detection_time is None else msf.pose
