"""The one detection/response/control loop (docs/architecture.md), shared by simulation and the CAN bridge.

Per control tick: read the chassis and hand its odometry to the defense (the lane tracker and the lateral
controller then read its yaw rate less the bias the defense estimates), step localization (the attacker
may spoof GNSS or the MSF output), on camera ticks run the lane detector and feed the defense, take the pose
the defense wants control to use, plan (lane follow, or the in-lane stop once the defense responds),
control (the acceleration capped behind a car ahead where the run follows cars), command the chassis.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

from testbed.attacks.base import Attack, AttackerView
from testbed.chassis import ChassisCommand, ChassisPort, ChassisState
from testbed.control.lateral import LqrLateralController
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from testbed.defense.base import Defense, DefenseStatus
from testbed.defense.ld_deviation import LdDeviation, LdLines
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.lane_tracker import LaneTracker
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.stack import Localization
from testbed.rates import Rates
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose

log = logging.getLogger(__name__)


@dataclass(slots=True)
class TickRecord:
    """One row of trajectory.csv (docs/outputs.md), the attack's state, and in attack response
    the fusion's internals (None outside it, or for a defense without them)."""

    t: float
    x: float
    y: float
    yaw: float
    speed: float
    phys_dev: float | None
    msf_dev: float | None
    ld_dev: float | None
    cusum: float | None
    mode: str
    steer: float
    accel: float
    ld_fresh: int = 0
    attack_stage: str | None = None
    attack_offset: float | None = None
    fused_dev: float | None = None
    r_msf: float | None = None
    r_ld: float | None = None
    k_msf: float | None = None
    k_ld: float | None = None
    heading_used: float | None = None


_NOT_RESPONDING = DefenseStatus(detected=False)
"""Stands in for the defense's status outside attack response: no fusion internals are recorded there."""


def safe_dev(smap: SemanticMap, pose: Pose, lane: int | None) -> float | None:
    """Signed lane deviation, or None off the map."""
    try:
        return smap.lane_dev(pose, lane)
    except OffMapError:
        return None


@dataclass(frozen=True)
class SensorPorts:
    """Where the loop's pose and images come from: the localization (stepped every tick) and a camera that
    captures a frame at (t, true pose), or None where the detector reads no image."""

    localization: Localization
    camera: Callable[[float, Pose | None], CameraFrame] | None = None


@dataclass(frozen=True)
class PerceptionPorts:
    """The lane detector (None: no lane detections), the existence probability a line needs to count, a hook
    that sees every frame with its detection (video, recording), the tracker of the detected lines (run
    after an LD-side attacker's tamper, predicted with the chassis odometry), and the lines the logged D_LD
    comes from (Alg. 3's `LdLines`)."""

    detector: LaneDetector | None = None
    existence_threshold: float = 0.5
    on_frame: Callable[[CameraFrame, LaneDetection], None] | None = None
    tracker: LaneTracker | None = None
    ld_lines: LdLines = "nearer"


@dataclass(frozen=True)
class DrivingPorts:
    """Planning and control: the map and the lane driven, the planner, the lateral and longitudinal
    controllers, an in-lane stop that is part of the plan ((time, deceleration), not a response), and car
    following: the acceleration cap behind a car ahead at this tick's chassis state (None: no car ahead)."""

    smap: SemanticMap
    lane: int
    planner: LanePlanner
    lateral: LqrLateralController
    longitudinal: SpeedController
    planned_stop: tuple[float, float] | None = None
    follow: Callable[[ChassisState], float | None] | None = None


class ControlLoop:
    """Wires chassis, sensors, perception, defense and driving at the control rate (docs/architecture.md, "One
    control tick")."""

    def __init__(self, chassis: ChassisPort, sensors: SensorPorts, perception: PerceptionPorts, defense: Defense,
                 driving: DrivingPorts, *, attack: Attack | None = None, rates: Rates | None = None) -> None:
        self.chassis = chassis
        self.sensors = sensors
        self.perception = perception
        self.defense = defense
        self.driving = driving
        self.attack = attack
        self.rates = rates = rates if rates is not None else Rates()
        self.smap = driving.smap
        self.lane = driving.lane
        self.dt = rates.control_dt
        self.ticks = 0
        self.ld_dev = LdDeviation(perception.existence_threshold, perception.ld_lines)
        self.last_ld_dev: float | None = None
        self.stopping = False
        self.last_state: ChassisState | None = None
        self.last_estimate: LocalizationEstimate | None = None
        self.last_control_pose: Pose | None = None
        """The pose the controller tracked on the last tick (the MSF's, or the defense's own in response)."""

    def _attacker_view(self, state: ChassisState) -> AttackerView | None:
        pose = state.true_pose
        if pose is None:
            return None
        phys = safe_dev(self.smap, pose, self.lane)
        try:
            _, heading = self.smap.lane_point(pose, self.lane)
        except OffMapError:
            heading = pose.yaw
        return AttackerView(t=state.t, true_pose=pose, phys_dev=phys if phys is not None else math.nan,
                            lane_heading=heading, speed=state.speed)

    def tick(self) -> TickRecord:
        state = self.chassis.read()
        self.last_state = state
        t = state.t
        self.defense.on_odometry(t, state.speed, state.odometry_yaw_rate)
        yaw_rate = self.defense.odometry_yaw_rate(state.speed, state.yaw_rate)
        view = self._attacker_view(state) if self.attack is not None else None
        spoof = (lambda fix: self.attack.spoof_gnss(fix, view)) if view is not None else None
        localization = self.sensors.localization
        est = localization.step(t, state, spoof)
        if view is not None:
            est = self.attack.tamper_msf(est, view)
        self.last_estimate = est
        gnss = localization.last_gnss
        if gnss is not None:
            self.defense.on_gnss(gnss.t, gnss.xy, gnss.cov)
        fresh = self.perception.detector is not None and self.ticks % self.rates.camera_every == 0
        if fresh:
            self._on_camera_tick(t, state, yaw_rate, est, view)
        pose = self.defense.pose_for_control(est, self.smap)
        self.last_control_pose = pose
        decel = self.defense.stop_decel
        driving = self.driving
        if decel is None and driving.planned_stop is not None and t >= driving.planned_stop[0]:
            decel = driving.planned_stop[1]
        if decel is not None and not self.stopping:
            self.stopping = True
            driving.planner.start_stop(t, state.speed, decel)
        plan = driving.planner.plan(pose, state.speed, t)
        steer = driving.lateral.update(plan, state.speed, yaw_rate=yaw_rate)
        accel = driving.longitudinal.update(plan, state.speed, self.dt)
        cap = driving.follow(state) if driving.follow is not None else None
        if cap is not None and cap < accel:
            accel = cap
        self.chassis.send(ChassisCommand(steer=steer, accel=accel))
        self.defense.on_command(t, steer, accel, state.speed)
        self.chassis.advance(self.dt)
        self.ticks += 1
        return self._record(state, est.pose, steer, accel, fresh)

    def _on_camera_tick(self, t: float, state: ChassisState, yaw_rate: float, est,
                        view: AttackerView | None) -> None:
        camera = self.sensors.camera
        frame = camera(t, state.true_pose) if camera is not None else CameraFrame(t, None, state.true_pose)
        ld = self.perception.detector.detect(frame)
        if view is not None:
            ld = self.attack.tamper_ld(ld, view)
        if self.perception.tracker is not None:
            ld = self.perception.tracker.update(ld, state.speed, yaw_rate)
        width = self._lane_width(est.pose)
        if width is not None:
            self.last_ld_dev = self.ld_dev.update(ld, width)
        self.defense.on_lane_detection(ld, est, self.smap)
        if self.perception.on_frame is not None:
            self.perception.on_frame(frame, ld)

    def _lane_width(self, pose: Pose) -> float | None:
        try:
            return self.smap.lane_width(pose)
        except OffMapError:
            return None

    def _record(self, state: ChassisState, msf_pose: Pose, steer: float, accel: float, fresh: bool) -> TickRecord:
        truth = state.true_pose or msf_pose
        status = self.defense.status()
        mode = self.defense.mode
        attack_state = self.attack.state() if self.attack is not None else {}
        ar = status if mode == "ar" else _NOT_RESPONDING
        return TickRecord(
            t=state.t, x=truth.x, y=truth.y, yaw=truth.yaw, speed=state.speed,
            phys_dev=safe_dev(self.smap, state.true_pose, self.lane) if state.true_pose is not None else None,
            msf_dev=safe_dev(self.smap, msf_pose, self.lane),
            ld_dev=self.last_ld_dev, cusum=status.cusum, mode=mode, steer=steer, accel=accel, ld_fresh=int(fresh),
            attack_stage=attack_state.get("stage"), attack_offset=attack_state.get("offset"),
            fused_dev=ar.fused_dev, r_msf=ar.r_msf, r_ld=ar.r_ld, k_msf=ar.kalman_gain_msf, k_ld=ar.kalman_gain_ld,
            heading_used=ar.heading_rel,
        )
