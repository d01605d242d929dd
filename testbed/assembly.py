"""The one run assembly: typed settings (rates, control, defense, speed, duration) and the ports in, a `LoopRun`
out. The simulator, HIL and the vehicle build their loop here and differ only in the ports they pass and the
per-tick hooks and end conditions they add; the standstill rule and the duration (in time) are the run's own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from testbed.attacks.base import Attack
from testbed.chassis import ChassisPort, ChassisState
from testbed.control.config import ControlConfig
from testbed.control.lateral import LqrLateralController
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from testbed.defense.base import Defense
from testbed.defense.config import DefenseConfig
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.lane_tracker import LaneTracker
from testbed.loop import ControlLoop, DrivingPorts, PerceptionPorts, SensorPorts, TickRecord
from testbed.rates import Rates
from tracks.map_api import SemanticMap
from vehicles.params import VehicleParams

STANDSTILL_MPS = 0.05
"""Below this speed (m/s) the car stands still: the run's end after a stop, and where control may be handed back."""

STANDSTILL_HOLD_S = 0.5
"""A stopped run ends once the car has stood still this long."""

TickHook = Callable[[TickRecord], None]
EndCheck = Callable[[TickRecord], str | None]
"""Sees a tick's record; returns why the run ends there (an `ended_by` value), or None."""


@dataclass(frozen=True)
class LoopSettings:
    """What a run's loop is built from besides its ports: the rates, the lateral controller's design, the
    defense's configuration (its existence threshold also gates the logged D_LD), the cruise speed (m/s) and the
    duration (s of the loop's clock)."""

    speed: float
    duration_s: float
    rates: Rates = field(default_factory=Rates)
    control: ControlConfig = field(default_factory=ControlConfig)
    defense: DefenseConfig = field(default_factory=DefenseConfig)


@dataclass(frozen=True)
class LanePorts:
    """The map, the lane driven on it, the vehicle's parameters (controller design and limits), an in-lane stop
    that is part of the plan ((time, deceleration)) and car following (the acceleration cap behind a car ahead,
    None: no car ahead)."""

    smap: SemanticMap
    lane: int
    vehicle: VehicleParams
    planned_stop: tuple[float, float] | None = None
    follow: Callable[[ChassisState], float | None] | None = None


class LoopRun:
    """Steps a `ControlLoop` to its end. After each tick the hooks see its record, then the end conditions are
    tried in order: the checks added `before` standstill (a consequence), standstill (`STANDSTILL_HOLD_S` below
    `STANDSTILL_MPS` after a stop, a chassis fault's included), the other checks (the end of the road), then the
    duration, measured on the loop's clock from the first tick's start."""

    def __init__(self, loop: ControlLoop, duration_s: float) -> None:
        self.loop = loop
        self.duration_s = duration_s
        self.rows: list[TickRecord] = []
        self.ended_by: str | None = None
        self.stop_t: float | None = None
        """When the car came to the standstill that ended the run (None: it did not end so)."""
        self._hooks: list[TickHook] = []
        self._before: list[EndCheck] = []
        self._after: list[EndCheck] = []
        self._still_since: float | None = None

    @property
    def done(self) -> bool:
        return self.ended_by is not None

    @property
    def elapsed_s(self) -> float:
        """Loop time run so far: from the first tick's start to the end of the last."""
        return self.rows[-1].t - self.rows[0].t + self.loop.dt if self.rows else 0.0

    def add_hook(self, hook: TickHook) -> None:
        self._hooks.append(hook)

    def add_end(self, check: EndCheck, *, before_standstill: bool = False) -> None:
        (self._before if before_standstill else self._after).append(check)

    def step(self) -> TickRecord:
        """One tick, its hooks and the end conditions."""
        if self.done:
            raise RuntimeError("the run is over")
        rec = self.loop.tick()
        self.rows.append(rec)
        for hook in self._hooks:
            hook(rec)
        self.ended_by = self._first_end(rec)
        return rec

    def _first_end(self, rec: TickRecord) -> str | None:
        for check in self._before:
            if (why := check(rec)) is not None:
                return why
        if self._stood_still(rec):
            return "standstill"
        for check in self._after:
            if (why := check(rec)) is not None:
                return why
        if self.elapsed_s >= self.duration_s - 0.5 * self.loop.dt:
            return "duration"
        return None

    def _stood_still(self, rec: TickRecord) -> bool:
        stopping = self.loop.stopping or bool(self.loop.chassis.latched_faults())
        if not (stopping and abs(rec.speed) < STANDSTILL_MPS):
            self._still_since = None
            return False
        self._still_since = rec.t if self._still_since is None else self._still_since
        if rec.t - self._still_since < STANDSTILL_HOLD_S:
            return False
        self.stop_t = self._still_since
        return True


def assemble(settings: LoopSettings, chassis: ChassisPort, sensors: SensorPorts, defense: Defense, lane: LanePorts,
             *, detector: LaneDetector | None = None, tracker: LaneTracker | None = None,
             on_frame: Callable[[CameraFrame, LaneDetection], None] | None = None,
             attack: Attack | None = None) -> LoopRun:
    """The loop of a run: lane-following planner at the settings' speed, the lateral LQR designed for the control
    period with the settings' steering-rate cost, the speed controller within the vehicle's limits."""
    rates, params = settings.rates, lane.vehicle
    driving = DrivingPorts(
        lane.smap, lane.lane, LanePlanner(lane.smap, lane.lane, settings.speed,
                                          lateral_accel=settings.control.lateral_accel),
        LqrLateralController.from_vehicle(params, rates.control_dt,
                                          steer_rate_weight=settings.control.steer_rate_weight,
                                          max_lat_accel=settings.control.steer_lat_accel),
        SpeedController(max_accel=params.max_accel, max_decel=params.max_decel),
        planned_stop=lane.planned_stop, follow=lane.follow)
    perception = PerceptionPorts(detector, settings.defense.existence_threshold, on_frame, tracker,
                                 settings.defense.ld_lines)
    loop = ControlLoop(chassis, sensors, perception, defense, driving, attack=attack, rates=rates)
    return LoopRun(loop, settings.duration_s)
