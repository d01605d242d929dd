"""The one detection/response/control loop (DESIGN.md), shared by simulation and the CAN bridge.

Per control tick: read the chassis, step localization (the attacker may spoof GNSS or the MSF output),
on camera ticks run the lane detector and feed the defense, take the pose the defense wants control to
use, plan (lane follow, or the in-lane stop once the defense responds), control, command the chassis.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

from testbed.attacks.base import Attack, AttackerView
from testbed.chassis import ChassisCommand, ChassisPort, ChassisState
from testbed.control.planner import LanePlanner
from testbed.defense.base import Defense, DefenseStatus
from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LoopRates:
    control_hz: float = 100.0
    camera_hz: float = 20.0

    @property
    def camera_every(self) -> int:
        return max(1, round(self.control_hz / self.camera_hz))


@dataclass(slots=True)
class TickRecord:
    """One row of trajectory.csv (DESIGN.md output contract), the attack's state, and in attack response
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


class ControlLoop:
    """Wires chassis, localization, detector, defense, planner and controllers at the control rate."""

    def __init__(self, *, chassis: ChassisPort, localization, smap: SemanticMap, lane: int, planner: LanePlanner,
                 lateral, longitudinal, defense: Defense, detector: LaneDetector | None,
                 camera: Callable[[float, Pose], CameraFrame] | None, attack: Attack | None = None,
                 rates: LoopRates = LoopRates(), on_frame: Callable[[CameraFrame, LaneDetection], None] | None = None,
                 existence_threshold: float = 0.5, planned_stop: tuple[float, float] | None = None) -> None:
        """`planned_stop` = (time, deceleration) of an in-lane stop that is part of the plan, not a response."""
        self.chassis = chassis
        self.localization = localization
        self.smap = smap
        self.lane = lane
        self.planner = planner
        self.lateral = lateral
        self.longitudinal = longitudinal
        self.defense = defense
        self.detector = detector
        self.camera = camera
        self.attack = attack
        self.rates = rates
        self.on_frame = on_frame
        self.dt = 1.0 / rates.control_hz
        self.ticks = 0
        self.ld_dev = LdDeviation(existence_threshold)
        self.last_ld_dev: float | None = None
        self.stopping = False
        self.planned_stop = planned_stop
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
        view = self._attacker_view(state) if self.attack is not None else None
        spoof = (lambda fix: self.attack.spoof_gnss(fix, view)) if view is not None else None
        est = self.localization.step(t, state, spoof)
        if view is not None:
            est = self.attack.tamper_msf(est, view)
        self.last_estimate = est
        gnss = getattr(self.localization, "last_gnss", None)
        if gnss is not None:
            self.defense.on_gnss(gnss.t, gnss.xy, gnss.cov)
        fresh = self.detector is not None and self.ticks % self.rates.camera_every == 0
        if fresh:
            self._on_camera_tick(t, state, est, view)
        pose = self.defense.pose_for_control(est, self.smap)
        self.last_control_pose = pose
        decel = self.defense.stop_decel
        if decel is None and self.planned_stop is not None and t >= self.planned_stop[0]:
            decel = self.planned_stop[1]
        if decel is not None and not self.stopping:
            self.stopping = True
            self.planner.start_stop(t, state.speed, decel)
        plan = self.planner.plan(pose, state.speed, t)
        steer = self.lateral.update(plan, state.speed, yaw_rate=state.yaw_rate)
        accel = self.longitudinal.update(plan, state.speed, self.dt)
        self.chassis.send(ChassisCommand(steer=steer, accel=accel))
        self.defense.on_command(t, steer, accel, state.speed)
        self.chassis.advance(self.dt)
        self.ticks += 1
        return self._record(state, est.pose, steer, accel, fresh)

    def _on_camera_tick(self, t: float, state: ChassisState, est, view: AttackerView | None) -> None:
        frame = self.camera(t, state.true_pose) if self.camera is not None else CameraFrame(t, None, state.true_pose)
        ld = self.detector.detect(frame)
        if view is not None:
            ld = self.attack.tamper_ld(ld, view)
        width = self._lane_width(est.pose)
        if width is not None:
            self.last_ld_dev = self.ld_dev.update(ld, width)
        self.defense.on_lane_detection(ld, est, self.smap)
        if self.on_frame is not None:
            self.on_frame(frame, ld)

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
