"""LD3's detection front end as a defense: normal until Alg. 1's CUSUM on the MSF/LD deviations (Alg. 3)
alarms, attack response for good after that. LD3 and NaiveAR share it and differ only in the response.
Chassis odometry reaches the monitor's dead-reckoned pose (fail-closed mode).

Fail-closed mode steers only on checked poses: while normal, the controller gets the MSF pose of the last
detection update (the one Alg. 1 and the heading check just compared with the lines, or with odometry where
lines are absent), carried to the current tick by odometry. An MSF pose between detections never reaches the
controller, whatever the control and camera rates and however late or irregular the frames. An MSF pose the
map cannot place (or not finite) is never taken as the checked pose: the last one is carried on, as a fault.
The checked pose's yaw is kept within `steer_yaw_tol` of the dead-reckoned yaw (the gyro's, which the lines' heading
turns no faster than `line_yaw_rate` and only into the interval spanned by the MSF's, theirs and the lane's; of the
lines' heading before odometry has one): a yaw bias the heading check lets through cannot steer the car by more than
that, nor can lines rotated by a road patch. Its offset from the dead-reckoned pose, along the lane and across it,
moves no faster than `steer_slew`: a jump of the MSF moves the pose steered on by no more than that rate allows in
the detection updates before the CUSUM alarms, while a slow drift of either source (odometry dragged by attacked
lines at `line_rate` at most) passes as it is. Every odometry-carried pose moves on the yaw rate less the bias the
monitor learns where MSF and lines agree (`odometry_bias_span`).
The paper mode steers on every MSF pose.

Fail-closed mode reads no lines where the ego lane turns tighter than `corner_radius` within the lines' near range
ahead of the dead-reckoned pose (`followable`, `testbed.defense.line_model`: a town corner, where a line's offset at
the car is an extrapolation metres off): they are neither compared nor used to anchor, and the MSF is checked
against odometry as where lines are absent."""

from __future__ import annotations

import logging
import math

from testbed.defense import line_model
from testbed.defense.attack_detection import Cusum, LaneConsistencyMonitor
from testbed.defense.base import DefenseStatus, LatchingDefense
from testbed.defense.config import DefenseConfig
from testbed.defense.faults import FaultLog, FaultRecord
from testbed.defense.fused_heading import station_relative_heading
from testbed.defense.odometry import DeadReckoning
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle

logger = logging.getLogger(__name__)


class Ld3AlarmedDefense(LatchingDefense):
    """LD3 detection; once alarmed, mode "ar" and a stop at `response_decel`. `lever` is the pose's reference point
    ahead of the rear axle (m), which the odometry-carried poses move by."""

    def __init__(self, config: DefenseConfig, lever: float = 0.0) -> None:
        self.config = config
        self.faults = FaultLog(logger)
        self.monitor = LaneConsistencyMonitor(config.b, config.tau, config.existence_threshold, self.faults,
                                              fail_closed=config.fail_closed,
                                              heading=Cusum(config.heading_b, config.heading_tau),
                                              along=Cusum(config.along_b, config.along_tau),
                                              along_gain=config.along_gain, line_rate=config.line_rate,
                                              line_yaw_rate=config.line_yaw_rate, yaw_margin=config.yaw_margin,
                                              yaw_agreement=(config.heading_b, config.steer_yaw_tol),
                                              bias_span=config.odometry_bias_span, lever=lever,
                                              lines_gate=(config.lines_gate, config.lines_heading_gate,
                                                          config.lines_heading_gate_in_place),
                                              ld_lines=config.ld_lines)
        self.detection_time: float | None = None
        self.checked = DeadReckoning(lever)
        """The MSF pose of the last detection update, carried by odometry (fail-closed mode)."""
        self._offset: tuple[float, float, float] | None = None
        """(t, along, across): the checked pose's offset from the dead-reckoned pose along and across the lane (m) at
        the last detection update."""

    @property
    def alarm_threshold(self) -> float | None:
        return self.config.tau

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> None:
        self.monitor.on_odometry(t, speed, yaw_rate)
        if self.config.fail_closed:
            self._carry(t, speed, self.odometry_yaw_rate(speed, yaw_rate))

    def odometry_bias(self) -> float | None:
        bias = self.monitor.yaw_bias  # the paper mode carries no odometry, so it never estimates
        return bias.curvature if bias.estimated else None

    def odometry_yaw_rate(self, speed: float, yaw_rate: float) -> float:
        return self.monitor.yaw_bias.corrected(speed, yaw_rate)

    def _carry(self, t: float, speed: float, yaw_rate: float) -> None:
        """Carry the odometry-carried poses the defense keeps besides the monitor's (fail-closed mode) on the
        bias-corrected yaw rate."""
        self.checked.on_odometry(t, speed, yaw_rate)

    def fault_records(self) -> list[FaultRecord]:
        return self.faults.records()

    def followable(self, ld: LaneDetection, smap: SemanticMap) -> LaneDetection:
        """Fail-closed: `ld` without its lines where the lane turns tighter than `corner_radius` near the dead-reckoned
        pose (a fault, logged at debug level: the map's doing, not a bad input); `ld` as given in paper mode, before
        the pose is anchored, or where the map cannot place it."""
        reckoned = self.monitor.reckoned
        if not self.config.fail_closed or reckoned is None:
            return ld
        try:
            lane = self.monitor.ego_lane if self.monitor.ego_lane is not None else smap.project(reckoned).lane
            kept, turn = line_model.followable(ld, smap, reckoned, lane, self.config.corner_radius)
        except OffMapError:
            return ld
        if turn is not None:
            self.faults.report("corner-lines", ld.timestamp, f"the lane turns at a radius of {turn:.1f} m within "
                                                             f"{line_model.NEAR_RANGE:g} m; lines not compared",
                               expected=True)
        return kept

    def _detect(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> bool:
        """One detection update while normal; True on the update that raises the alarm."""
        if self.detection_time is not None:
            return False
        alarm = self.monitor.step(ld, msf, smap)
        if self.config.fail_closed:
            self._take_checked(ld, msf.pose, smap)
        if not alarm:
            return False
        self.detection_time = ld.timestamp
        logger.info("%s: attack detected at t=%.3f by the %s check (S=%.3f)", self.name, ld.timestamp,
                    self.monitor.alarm_check, self.monitor.detector.statistic)
        return True

    def _take_checked(self, ld: LaneDetection, pose: Pose, smap: SemanticMap) -> None:
        """The MSF pose just compared becomes the checked pose, its yaw within tolerance, if the map can place it
        (else a fault)."""
        try:
            lane = smap.project(pose).lane if pose.is_finite() else None
            heading = None if lane is None else smap.lane_point(pose, lane)[1]
        except OffMapError:
            heading = None
        if heading is None:
            self.faults.report("unchecked-msf", ld.timestamp, f"MSF pose {pose} cannot be placed; the last checked "
                                                              f"pose carried on by odometry")
            return
        reckoned = self.monitor.reckoned
        if reckoned is not None:
            ref: float | None = reckoned.yaw
        else:
            psi = station_relative_heading(ld, self.config.existence_threshold, smap, pose, lane)
            ref = heading + psi if psi is not None else None
        if ref is not None:
            tol = self.config.steer_yaw_tol
            pose = Pose(pose.x, pose.y, ref + min(max(wrap_angle(pose.yaw - ref), -tol), tol))
        if reckoned is not None:
            try:
                pose = self._held_near(ld.timestamp, pose, reckoned, smap.lane_point(reckoned, lane)[1])
            except OffMapError as err:
                self.faults.report("unchecked-msf", ld.timestamp, f"the dead-reckoned pose cannot be placed ({err}); "
                                                                  f"the last checked pose carried on by odometry")
                return
        self.checked.anchor(pose)

    def _held_near(self, t: float, pose: Pose, reckoned: Pose, heading: float) -> Pose:
        """`pose` with its offset from the dead-reckoned pose, along and across the lane (of heading `heading` there),
        moved from the last one at `steer_slew` at most, its yaw kept; a fault where it had to be held."""
        c, s = math.cos(heading), math.sin(heading)
        dx, dy = pose.x - reckoned.x, pose.y - reckoned.y
        along, across = dx * c + dy * s, -dx * s + dy * c
        last, self._offset = self._offset, (t, along, across)
        if last is None:
            return pose
        step = self.config.steer_slew * max(0.0, t - last[0])
        held_along = last[1] + min(max(along - last[1], -step), step)
        held_across = last[2] + min(max(across - last[2], -step), step)
        if (held_along, held_across) == (along, across):
            return pose
        self._offset = (t, held_along, held_across)
        self.faults.report("steer-held", t, f"MSF pose {across:.3f} m across and {along:.3f} m along the lane from the "
                                            f"dead-reckoned pose; steered {held_across:.3f} and {held_along:.3f} m",
                           expected=True)
        return Pose(reckoned.x + held_along * c - held_across * s, reckoned.y + held_along * s + held_across * c,
                    pose.yaw)

    def checked_pose(self, msf: LocalizationEstimate) -> Pose:
        """The pose the controller gets while normal: the last checked MSF pose carried by odometry (fail-closed
        mode), the MSF pose itself in paper mode or before any detection update (a fault)."""
        if not self.config.fail_closed:
            return msf.pose
        pose = self.checked.pose
        if pose is None:
            self.faults.report("unchecked-msf", msf.t, "no detection update yet; steering on the MSF pose")
            return msf.pose
        return pose

    def status(self) -> DefenseStatus:
        return DefenseStatus(
            detected=self.detection_time is not None,
            detection_time=self.detection_time,
            cusum=self.monitor.detector.statistic,
            d_msf=self.monitor.d_msf,
            d_ld=self.monitor.d_ld,
            alarm_check=self.monitor.alarm_check,
        )
