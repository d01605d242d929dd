"""Lane planner: follow the ego-lane centreline at a cruise speed, or stop in lane at a set deceleration.

Cruise: the speed reference ramps from the current speed to `cruise_speed` at ±max_accel, and never exceeds the
curve limit: at every point d ahead on the centreline (up to the distance needed to slow from the cruise speed)
v ≤ √(a_lat/|κ(d)| + 2·CURVE_DECEL·(d − CURVE_STEP)) (a curve may start a sample step nearer), so the car
reaches each curve at a speed that keeps its lateral acceleration within `lateral_accel`.
Stop (LD3 attack response, paper §4.3): same centreline, v(t) = max(0, v0 − decel·(t − t0)) with
target_accel −decel until the car stands (its measured speed no longer above 0: a car that lags the profile when
it reaches 0 keeps braking at decel rather than on the speed error alone), then 0 held (the speed controller holds
the brake); the curve limit holds there too.
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
CURVE_DECEL = 2.0  # m/s²: the deceleration the curve limit allows for slowing into a curve ahead
CRUISE_ACCEL = 1.0  # m/s²: the speed reference's ramp towards the cruise speed (from rest at a run's start)
CURVE_STEP = 2.0  # m between the curvature samples of the curve limit
CURVE_PERIOD = 0.25  # s between samplings of the curvature ahead
_KERNELS = compiled_module("testbed.control.planner_kernels")


class LanePlanner:
    """Path errors to the centreline of lane `lane` and a speed profile, one `Plan` per control tick."""

    def __init__(
        self,
        smap: SemanticMap,
        lane: int,
        cruise_speed: float,
        max_accel: float = CRUISE_ACCEL,
        preview_time: float = 0.3,
        min_preview: float = 1.0,
        lateral_accel: float = 3.0,
    ) -> None:
        if lateral_accel <= 0.0:
            raise ValueError(f"lateral acceleration bound must be positive, got {lateral_accel}")
        self.map = smap
        self.lane = lane
        self.cruise_speed = cruise_speed
        self.max_accel = max_accel
        self.preview_time = preview_time
        self.min_preview = min_preview
        self.lateral_accel = lateral_accel
        self._ahead: tuple[float, np.ndarray, np.ndarray] | None = None  # (time sampled, distances, a_lat/|κ|)
        self._travel = 0.0  # m driven since the curvature ahead was sampled
        self._speed_ref: float | None = None
        self._t_last: float | None = None
        self._stop: tuple[float, float, float] | None = None  # (t0, v0, decel)
        self._last: Plan | None = None
        compiled = getattr(smap, "compiled", None)
        self._kernel = None if _KERNELS is None or compiled is None else _KERNELS.PathKernel(compiled, lane,
                                                                                               PREVIEW_STEP)
        """The path terms and the curves ahead compiled over the map's compiled queries
        (testbed/control/planner_kernels.pyx), where both are built; None: the pure-Python `_path_terms` and
        `_curves_ahead` answer, the references the kernel is tested equal to."""
        self._limit = None if self._kernel is None else _KERNELS.CurveLimit(self._kernel, CURVE_STEP, lateral_accel,
                                                                             CURVE_DECEL, CURVE_PERIOD)
        """`_curve_limit` compiled with its samples of the curves ahead, where the kernel is built."""

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
        target_speed, target_accel = self._speed_profile(speed, t, self._curve_limit(pose, speed, t))
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

    def _curve_limit(self, pose: Pose, speed: float, t: float) -> float:
        """The highest speed from which every curve ahead can be reached at `lateral_accel` by braking at
        CURVE_DECEL (inf where none binds). The curvature ahead is sampled every CURVE_PERIOD; in between the
        distance travelled since (at the measured speed) brings each sampled curve nearer."""
        if self._limit is not None:
            return self._limit.limit(pose, speed, t, self._t_last, self.cruise_speed)
        if self._ahead is None or t - self._ahead[0] >= CURVE_PERIOD - 1e-9:
            self._ahead = (t, *self._curves_ahead(pose))
            self._travel = 0.0
        elif self._t_last is not None:
            self._travel += max(speed, 0.0) * max(t - self._t_last, 0.0)
        _, d, v2 = self._ahead
        if not len(d):
            return math.inf
        return float(np.sqrt(np.min(v2 + 2.0 * CURVE_DECEL * np.maximum(d - self._travel - CURVE_STEP, 0.0))))

    def _curves_ahead(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """(distance ahead along the centreline, a_lat/|κ| there) every CURVE_STEP up to the distance needed to
        slow from the cruise speed (or to where the lane ends), where the lane curves."""
        horizon = self._horizon()
        if self._kernel is not None:
            ds, v2 = self._kernel.curves_ahead(pose, horizon, CURVE_STEP, self.lateral_accel)
            return np.array(ds), np.array(v2)
        ds, v2 = [], []
        try:
            point, heading = self.map.lane_point(pose, self.lane)
            x, y, d = float(point[0]), float(point[1]), 0.0
            while True:
                kappa = abs(self.map.lane_curvature(Pose(x, y, heading), self.lane))
                if kappa > 1e-9:
                    ds.append(d)
                    v2.append(self.lateral_accel / kappa)
                if d >= horizon:
                    break
                ahead = Pose(x + CURVE_STEP * math.cos(heading), y + CURVE_STEP * math.sin(heading), heading)
                nxt, heading = self.map.lane_point(ahead, self.lane)
                x, y, d = float(nxt[0]), float(nxt[1]), d + CURVE_STEP
        except OffMapError:
            pass  # the lane ends (or the pose is off it) within the horizon: the curves up to there
        return np.array(ds), np.array(v2)

    def _horizon(self) -> float:
        """How far ahead the curve limit looks: the distance to slow from the cruise speed, and a sample step."""
        return self.cruise_speed**2 / (2.0 * CURVE_DECEL) + CURVE_STEP

    def _speed_profile(self, speed: float, t: float, limit: float) -> tuple[float, float]:
        dt = 0.0 if self._t_last is None else max(t - self._t_last, 0.0)
        self._t_last = t
        if self._stop is not None:
            t0, v0, decel = self._stop
            v = v0 - decel * (t - t0)
            if v > limit:
                return limit, -decel
            if v > 0.0:
                return v, -decel
            return (0.0, -decel) if speed > 0.0 else (0.0, 0.0)
        if self._speed_ref is None:
            self._speed_ref = max(speed, 0.0)
        gap = self.cruise_speed - self._speed_ref
        step = self.max_accel * dt
        if abs(gap) <= step:
            ref, accel = self.cruise_speed, 0.0
        else:
            ref, accel = self._speed_ref + math.copysign(step, gap), math.copysign(self.max_accel, gap)
        if ref > limit:
            ref, accel = limit, -CURVE_DECEL if limit < self._speed_ref else 0.0
        self._speed_ref = ref
        return ref, accel
