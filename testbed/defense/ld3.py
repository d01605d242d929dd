"""LD3 (paper §4): lane-detection-based detection (Alg. 1) and attack response (§4.3).

Response, once alarmed: the planner stops on the ego-lane centreline at `ar_decel` (mode "ar",
`stop_decel`), and the controller steers on the safety-driven fusion pose (Alg. 2, Alg. 4): the fused
deviation placed on the ego lane's centreline point nearest the MSF pose, with the heading the `heading`
option names (`FusedHeading`; "msf" is the paper mode). Alg. 4's P^MSF / P^LD are the configured
constants or, with `p_source = "reported"`, the MSF's lateral variance across the lane and the
detector's c0 variance of the line Alg. 3 used. The ego lane is the car's lane as the monitor last saw MSF
and lines agree (`LaneConsistencyMonitor.ego_lane`); it stays locked so that a drifting MSF cannot move the
response into a neighbouring lane.

Paper mode (`fail_closed = False`): the fused deviation is placed at the MSF pose's station; when the map
cannot answer for the MSF pose, the last fused pose is carried along by the MSF's motion.
Fail-closed mode (the default): the fused pose is the monitor's dead-reckoned pose, carried by odometry
between detections and, on each detection with a valid line, placed across the ego lane at the fused
deviation (lane point at its own station, its own yaw), Alg. 2's state first moved to where odometry carried it;
the heading option reads that yaw where the paper reads the MSF's. Each source is checked against a reference,
the dead-reckoned pose as of the last detection where MSF and lines agreed within half b (lines that ramp away from a
true MSF pull the dead-reckoned pose up to b before the alarm), carried by odometry to the alarm and from there
moved only towards Alg. 2's fused deviation, on detections whose lines pass the check, no faster than `line_rate`
(the sources as Alg. 2 weighs them, not the lines alone: lines that creep away from a true MSF would otherwise take the
reference with them until the MSF fell outside the gate):
lines farther than `response_gate` are left out of that detection, the MSF out of the rest of the response (as is
an MSF pose the map cannot place); Alg. 2 then runs on D_LD alone. A detection without a valid line leaves the pose to
odometry. The MSF pose is handed to control in response only when there is no pose to carry (never anchored,
the MSF unplaceable at the alarm), as a fault.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from testbed.defense.alarmed import Ld3AlarmedDefense
from testbed.defense.base import DefenseStatus
from testbed.defense.config import DefenseConfig
from testbed.defense.fused_heading import FusedHeading
from testbed.defense.fusion import FusionStep, SafetyDrivenFusion, pose_on_lane
from testbed.defense.odometry import DeadReckoning, drift_allowance, step_toward
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose


def nearest_lane_image(d_ld: float, d_ref: float, width: float) -> float:
    """D_LD moved by at most one lane width towards the deviation odometry predicts: a line crossed in the
    response is a lane change of the car, not a jump of D_LD when Alg. 3 re-references to the next line."""
    shift = max(-1, min(1, round((d_ref - d_ld) / width)))
    return d_ld + shift * width


class Ld3Defense(Ld3AlarmedDefense):
    """Detection by MSF/LD deviation consistency; response by in-lane stop on the fused pose."""

    name = "ld3"

    def __init__(self, config: DefenseConfig, lever: float = 0.0) -> None:
        super().__init__(config, lever)
        self.fusion = SafetyDrivenFusion(config.window, config.lam, config.kf_q, config.kf_p0, config.r_power)
        self.heading = FusedHeading(config.heading, config.heading_clamp, config.existence_threshold,
                                    own_yaw=config.fail_closed,
                                    turn_rate=config.line_yaw_rate if config.fail_closed else math.inf,
                                    yaw_margin=config.yaw_margin if config.fail_closed else math.inf)
        self._p_ld = config.p_ld
        self._fused_pose: Pose | None = None
        self._fused_offset: tuple[float, float] | None = None
        self._msf_disowned = False
        self._reference = DeadReckoning(lever)
        """The response's reference: the monitor's trusted pose at the alarm (`LaneConsistencyMonitor.trusted`), carried
        by odometry and moved towards Alg. 2's fused deviation, on detections whose lines passed the gate, no faster
        than `line_rate`."""
        self._reference_time = -math.inf
        """When the reference was last anchored or moved (s)."""

    @property
    def response_decel(self) -> float:
        return self.config.ar_decel

    def _carry(self, t: float, speed: float, yaw_rate: float) -> None:
        super()._carry(t, speed, yaw_rate)
        self._reference.on_odometry(t, speed, yaw_rate)

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        if self.config.fail_closed:
            ld = self.followable(ld, smap)
            alarm = self.detection_time is None
            if not alarm or self._detect(ld, msf, smap):
                self._respond_fail_closed(ld, msf, smap, alarm)
            return
        if self.detection_time is None:
            if self._detect(ld, msf, smap):
                self._respond(ld, msf, smap, self.monitor.ego_pair(ld.timestamp, msf.pose, smap))
            return
        self._respond(ld, msf, smap, self.monitor.deviations(ld, msf.pose, smap, self.monitor.ego_lane))

    def _respond(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap,
                 pair: tuple[float | None, float | None] | None) -> None:
        """One AR frame: the heading reading, then Alg. 2 when both deviations could be formed."""
        try:
            _, lane_heading = smap.lane_point(msf.pose, self.monitor.ego_lane)
        except OffMapError:
            return
        if pair is not None and pair[0] is not None and pair[1] is not None:
            p_msf, p_ld = self._source_uncertainties(ld, msf, lane_heading)
            self.fusion.update(pair[0], pair[1], p_msf, p_ld)
        step = self.fusion.last
        self.heading.on_detection(ld, msf.pose.yaw, lane_heading, (step.r_msf, step.r_ld) if step else None)

    def _respond_fail_closed(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap,
                             alarm: bool) -> None:
        """One fail-closed AR frame: Alg. 2 on this detection's D_LD (with D_MSF when the map places the MSF
        pose), the fused pose placed across the ego lane at the fused deviation, then the heading reading.
        On the alarm's detection D_LD is the one Alg. 1 just formed, and the status keeps Alg. 1's D_MSF."""
        mon, t, lane = self.monitor, ld.timestamp, self.monitor.ego_lane
        d_msf = mon.msf_deviation(t, msf.pose, smap, lane)
        if d_msf is not None and not alarm:
            mon.d_msf = d_msf
        pose = mon.reckoned
        if pose is None:
            pose = self._unreckoned_pose(t, msf, smap)
        if pose is None:
            return
        try:
            point, heading = smap.lane_point(pose, lane)
            width = float(smap.lane_width(pose, lane))
        except OffMapError as err:
            self.faults.report("odometry-off-map", t, f"fused pose: {err}; carried by odometry alone")
            return
        d_ld = mon.fresh_d_ld if alarm else mon.lines_deviation(ld, width)
        reference, ref_point, ref_heading = self._reference_on_lane(t, pose, smap, lane, alarm)
        d_ref = float(smap.lane_dev(reference, lane))
        d_msf = self._gate_msf(t, d_msf, d_ref)
        if d_ld is not None:
            d_ld = self._gate_ld(t, nearest_lane_image(d_ld, d_ref, width), d_ref)
        if d_ld is not None:
            self.fusion.carry(float(smap.lane_dev(pose, lane)))
            step = self._fuse(ld, msf, d_msf, d_ld, heading)
            limit = drift_allowance(self.config.line_rate, t - self._reference_time)
            self._reference.anchor(pose_on_lane(ref_point, ref_heading, step_toward(d_ref, step.d, limit),
                                                reference.yaw))
            self._reference_time = t
            mon.odometry.anchor(pose_on_lane(point, heading, step.d, pose.yaw))
        step = self.fusion.last
        self.heading.on_detection(ld, pose.yaw, heading, (step.r_msf, step.r_ld) if step else None,
                                  lines_kept=d_ld is not None, msf_heading=msf.pose.yaw)

    def _reference_on_lane(self, t: float, pose: Pose, smap: SemanticMap, lane: int,
                           alarm: bool) -> tuple[Pose, np.ndarray, float]:
        """The gate's reference (at the alarm the monitor's trusted pose, else the dead-reckoned pose, carried since;
        restarted at the fused pose, a fault, when the map cannot place it) with its lane point and lane heading."""
        if alarm or self._reference.pose is None:
            trusted = self.monitor.trusted.pose
            self._reference.anchor(trusted if alarm and trusted is not None else pose)
            self._reference_time = t
        try:
            point, heading = smap.lane_point(self._reference.pose, lane)
        except OffMapError as err:
            self.faults.report("odometry-off-map", t, f"response reference: {err}; restarted at the fused pose")
            self._reference.anchor(pose)
            self._reference_time = t
            point, heading = smap.lane_point(pose, lane)
        return self._reference.pose, point, heading

    def _gate_msf(self, t: float, d_msf: float | None, d_ref: float) -> float | None:
        """D_MSF if the MSF has kept within `response_gate` of the reference deviation throughout the response;
        once it has not (or the map could not place it), the MSF is disowned for the rest of the response (None, a
        fault)."""
        if not self._msf_disowned and (d_msf is None or abs(d_msf - d_ref) > self.config.response_gate):
            self._msf_disowned = True
            seen = "not placed on the ego lane" if d_msf is None else f"D_MSF={d_msf:.3f}"
            self.faults.report("msf-disowned", t, f"{seen}, reference D={d_ref:.3f}; MSF left out of the response")
        return None if self._msf_disowned else d_msf

    def _gate_ld(self, t: float, d_ld: float, d_ref: float) -> float | None:
        """D_LD if within `response_gate` of the reference deviation, else None (a fault)."""
        if abs(d_ld - d_ref) <= self.config.response_gate:
            return d_ld
        self.faults.report("ld-gated", t, f"D_LD={d_ld:.3f} is {abs(d_ld - d_ref):.3f} m from the reference "
                                          f"D={d_ref:.3f}; this detection left out of the response")
        return None

    def _fuse(self, ld: LaneDetection, msf: LocalizationEstimate, d_msf: float | None, d_ld: float,
              lane_heading: float) -> FusionStep:
        """Alg. 2 with both deviations, or on D_LD alone when the MSF is left out."""
        if d_msf is None:
            self.faults.report("msf-left-out", ld.timestamp, f"Alg. 2 on D_LD={d_ld:.3f} alone",
                               expected=self._msf_disowned)
            return self.fusion.update_ld(d_ld, self._ld_uncertainty(ld))
        p_msf, p_ld = self._source_uncertainties(ld, msf, lane_heading)
        return self.fusion.update(d_msf, d_ld, p_msf, p_ld)

    def _unreckoned_pose(self, t: float, msf: LocalizationEstimate, smap: SemanticMap) -> Pose | None:
        """Without a dead-reckoned pose (never anchored, or no odometry): start one at the MSF pose's station
        on the ego lane with its yaw; None (a fault) when the map cannot place the MSF pose either."""
        try:
            point, heading = smap.lane_point(msf.pose, self.monitor.ego_lane)
        except OffMapError as err:
            self.faults.report("no-fused-pose", t, f"no dead-reckoned pose and MSF pose: {err}")
            return None
        self.faults.report("no-fused-pose", t, "no dead-reckoned pose: started at the MSF pose's station")
        self.heading.own_yaw_is_msf()
        step = self.fusion.last
        self.monitor.odometry.anchor(pose_on_lane(point, heading, step.d if step else 0.0, msf.pose.yaw))
        return self.monitor.odometry.pose

    def _source_uncertainties(self, ld: LaneDetection, msf: LocalizationEstimate,
                              lane_heading: float) -> tuple[float, float]:
        """(P^MSF, P^LD): the constants, or what the MSF and the detector report (the last P^LD is kept
        while Alg. 3 reuses an old D)."""
        p_ld = self._ld_uncertainty(ld)
        if self.config.p_source == "constant":
            return self.config.p_msf, p_ld
        return msf.lateral_variance(lane_heading), p_ld

    def _ld_uncertainty(self, ld: LaneDetection) -> float:
        """P^LD: the constant, or the detector's c0 variance of the line Alg. 3 used, of the midpoint where it used
        both (kept while D is reused)."""
        if self.config.p_source == "constant":
            return self.config.p_ld
        side = self.monitor.ld_dev.side
        if side == "both":  # the midpoint of two lines read apart
            var = None if ld.left_var is None or ld.right_var is None else 0.25 * (ld.left_var + ld.right_var)
        else:
            var = ld.left_var if side == "left" else ld.right_var if side == "right" else None
        if var is not None and not self.monitor.ld_dev.reused:
            self._p_ld = var
        return self._p_ld

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        if self.config.fail_closed:
            return self._fail_closed_pose(msf, smap)
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
        fused = pose_on_lane(point, heading, step.d, self.heading.yaw(pose.yaw, heading))
        self._fused_pose = fused
        self._fused_offset = (fused.x - pose.x, fused.y - pose.y)
        return fused

    def _fail_closed_pose(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        """The dead-reckoned fused pose in response, with the heading option's yaw (the checked pose while
        normal)."""
        if self.detection_time is None:
            return self.checked_pose(msf)
        pose = self.monitor.odometry.pose
        if pose is None:
            self.faults.report("no-fused-pose", msf.t, "no fused pose to carry; steering on the MSF pose")
            return msf.pose
        try:
            _, heading = smap.lane_point(pose, self.monitor.ego_lane)
        except OffMapError as err:
            self.faults.report("odometry-off-map", msf.t, f"fused pose: {err}; its own yaw kept")
            return pose
        return Pose(pose.x, pose.y, self.heading.yaw(pose.yaw, heading))

    def status(self) -> DefenseStatus:
        step = self.fusion.last
        if step is None:
            return super().status()
        return dataclasses.replace(super().status(), fused_dev=step.d, r_msf=step.r_msf, r_ld=step.r_ld,
                                   kalman_gain_msf=step.gain_msf, kalman_gain_ld=step.gain_ld,
                                   heading_rel=self.heading.relative)
