"""LD3 (paper §4): lane-detection-based detection (Alg. 1) and attack response (§4.3).

Response, once alarmed: the planner stops on the ego-lane centreline at `ar_decel` (mode "ar",
`stop_decel`), and the controller steers on the safety-driven fusion pose (Alg. 2, Alg. 4): the fused
deviation placed on the ego lane's centreline point nearest the MSF pose, with the MSF yaw (Alg. 2 does
not say which heading the fused pose carries; the lane's heading instead was measured worse overall:
FusionRipper on `local` hit the curb 9/10 instead of straddling 7/10, see the closing notes). The ego lane
is the one the MSF pose projected onto at the alarm; it stays locked so that a drifting MSF cannot move
the response into a neighbouring lane. When the map cannot answer for the MSF pose, the last fused pose
is carried along by the MSF's motion since then.
"""

from __future__ import annotations

import dataclasses

from testbed.defense.alarmed import Ld3AlarmedDefense
from testbed.defense.base import DefenseStatus
from testbed.defense.config import DefenseConfig
from testbed.defense.fusion import SafetyDrivenFusion, pose_on_lane
from testbed.localization.estimate import LocalizationEstimate
from testbed.perception.detection import LaneDetection
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose


class Ld3Defense(Ld3AlarmedDefense):
    """Detection by MSF/LD deviation consistency; response by in-lane stop on the fused pose."""

    name = "ld3"

    def __init__(self, config: DefenseConfig) -> None:
        super().__init__(config)
        self.fusion = SafetyDrivenFusion(
            config.window, config.lam, config.p_msf, config.p_ld, config.kf_q, config.kf_p0
        )
        self._fused_pose: Pose | None = None
        self._fused_offset: tuple[float, float] | None = None

    @property
    def response_decel(self) -> float:
        return self.config.ar_decel

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        if self.detection_time is None:
            if self._detect(ld, msf, smap):
                self._fuse(self.monitor.d_msf, self.monitor.d_ld)
            return
        pair = self.monitor.deviations(ld, msf.pose, smap, self.monitor.ego_lane)
        if pair is not None:
            self._fuse(*pair)

    def _fuse(self, d_msf: float | None, d_ld: float | None) -> None:
        if d_msf is not None and d_ld is not None:
            self.fusion.update(d_msf, d_ld)

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        step = self.fusion.last
        if self.detection_time is None or step is None:
            return msf.pose
        pose = msf.pose
        if not pose.is_finite():
            self.faults.report("nan-pose", msf.t, "MSF pose not finite; holding the last fused pose")
            return self._fused_pose if self._fused_pose is not None else pose
        try:
            point, heading = smap.lane_point(pose, self.monitor.ego_lane)
        except OffMapError as err:
            self.faults.report("off-map", msf.t, f"lane_point: {err}; fused pose carried by MSF motion")
            if self._fused_offset is None:
                return pose
            self._fused_pose = Pose(pose.x + self._fused_offset[0], pose.y + self._fused_offset[1], pose.yaw)
            return self._fused_pose
        fused = pose_on_lane(point, heading, step.d, pose.yaw)
        self._fused_pose = fused
        self._fused_offset = (fused.x - pose.x, fused.y - pose.y)
        return fused

    def status(self) -> DefenseStatus:
        step = self.fusion.last
        if step is None:
            return super().status()
        return dataclasses.replace(super().status(), fused_dev=step.d, kalman_gain_msf=step.gain_msf,
                                   kalman_gain_ld=step.gain_ld)
