"""Lane planner: follow the ego-lane centreline at a cruise speed, or stop in lane at a set deceleration.

Cruise: the speed reference ramps from the current speed to `cruise_speed` at ±max_accel.
Stop (LD3 attack response, paper §4.3): same centreline, v(t) = max(0, v0 − decel·(t − t0)) with
target_accel −decel until standstill, then 0 held (the speed controller holds the brake).
"""

from __future__ import annotations

import math

import numpy as np

from testbed.control.plan import Plan
from tracks.compiled import compiled_module
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle

AR_DECEL = 4.0  # paper §4.3: Apollo's maximum allowed safe deceleration (m/s²)
PREVIEW_STEP = 5.0  # m per step when walking the centreline to the preview point
_KERNELS = compiled_module("testbed.control.planner_kernels")


class LanePlanner:
    """Path errors to the centreline of lane `lane` and a speed profile, one `Plan` per control tick."""

    def __init__(
        self,
        smap: SemanticMap,
        lane: int,
        cruise_speed: float,
        max_accel: float = 1.0,
        preview_time: float = 0.3,
        min_preview: float = 1.0,
    ) -> None:
        self.map = smap
        self.lane = lane
        self.cruise_speed = cruise_speed
        self.max_accel = max_accel
        self.preview_time = preview_time
        self.min_preview = min_preview
        self._speed_ref: float | None = None
        self._t_last: float | None = None
        self._stop: tuple[float, float, float] | None = None  # (t0, v0, decel)
        self._last: Plan | None = None
        compiled = getattr(smap, "compiled", None)
        self._kernel = None if _KERNELS is None or compiled is None else _KERNELS.PathKernel(compiled, lane,
                                                                                               PREVIEW_STEP)
        """The path terms compiled over the map's compiled queries (testbed/control/planner_kernels.pyx), where
        both are built; None: the pure-Python `_path_terms` answers, the reference the kernel is tested equal to."""

    @property
    def stopping(self) -> bool:
        return self._stop is not None

    def start_stop(self, t: float, speed: float, decel: float = AR_DECEL) -> None:
        """Switch to an in-lane stop from `speed` at time `t` with constant deceleration `decel` (> 0)."""
        if decel <= 0.0:
            raise ValueError(f"stop deceleration must be positive, got {decel}")
        self._stop = (t, max(speed, 0.0), decel)

    def plan(self, pose: Pose, speed: float, t: float) -> Plan:
        """The plan for a vehicle at `pose` (the pose control steers on) moving at `speed`, at time `t`."""
        target_speed, target_accel = self._speed_profile(speed, t)
        distance = max(self.min_preview, self.preview_time * speed)
        terms = self._path_terms(pose, distance) if self._kernel is None else self._kernel.terms(pose, distance)
        if terms is None:
            held = self._last
            return Plan(
                lateral_error=held.lateral_error if held else 0.0,
                heading_error=held.heading_error if held else 0.0,
                curvature=held.curvature if held else 0.0,
                target_speed=target_speed,
                target_accel=target_accel,
                local_curvature=held.local_curvature if held else 0.0,
                off_map=True,
            )
        lateral_error, heading_error, preview, local_curvature = terms
        self._last = Plan(lateral_error, heading_error, preview, target_speed, target_accel, local_curvature)
        return self._last

    def _path_terms(self, pose: Pose, distance: float) -> tuple[float, float, float, float] | None:
        """(lateral error, heading error, curvature `distance` ahead, curvature at the projection), or None
        where the map cannot place the pose."""
        try:
            coord = self.map.project(pose, self.lane)
            point, heading = self.map.lane_point(pose, self.lane)
            local_curvature = self.map.lane_curvature(pose, self.lane)
            preview = self._preview_curvature(point, heading, distance)
        except OffMapError:
            return None
        return coord.l, wrap_angle(pose.yaw - heading), preview, local_curvature

    def _preview_curvature(self, point: np.ndarray, heading: float, distance: float) -> float:
        """Curvature at `distance` ahead along the centreline, walked in steps of at most PREVIEW_STEP
        (or at the last point reached where the lane ends within the preview)."""
        x, y = float(point[0]), float(point[1])
        remaining = distance
        while remaining > 1e-9:
            step = min(remaining, PREVIEW_STEP)
            remaining -= step
            ahead = Pose(x + step * math.cos(heading), y + step * math.sin(heading), heading)
            try:
                nxt, heading = self.map.lane_point(ahead, self.lane)
            except OffMapError:
                break
            x, y = float(nxt[0]), float(nxt[1])
        return self.map.lane_curvature(Pose(x, y, heading), self.lane)

    def _speed_profile(self, speed: float, t: float) -> tuple[float, float]:
        dt = 0.0 if self._t_last is None else max(t - self._t_last, 0.0)
        self._t_last = t
        if self._stop is not None:
            t0, v0, decel = self._stop
            v = v0 - decel * (t - t0)
            return (v, -decel) if v > 0.0 else (0.0, 0.0)
        if self._speed_ref is None:
            self._speed_ref = max(speed, 0.0)
        gap = self.cruise_speed - self._speed_ref
        step = self.max_accel * dt
        if abs(gap) <= step:
            self._speed_ref = self.cruise_speed
            return self._speed_ref, 0.0
        self._speed_ref += math.copysign(step, gap)
        return self._speed_ref, math.copysign(self.max_accel, gap)
