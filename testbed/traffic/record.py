"""The traffic cars' trajectories as the run writes them (`traffic.csv`: t, id, lane, x, y, yaw, speed) and
draws them (`birdseye.png`), and the ego's collision with one of them (`HitVehicle`, a field of summary.json)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict

from testbed.traffic.fleet import Fleet
from tracks.pose import Pose


class HitVehicle(BaseModel):
    """The ego's first contact with a traffic car: its id and lane, when, and the ego's speed relative to it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: int
    lane: int
    time_s: float
    relative_speed_mps: float


REENTRY_JUMP_M = 20.0
"""A step between two rows of one car longer than this is a re-entry (a recycled oncoming car), not a drive."""
RECORD_HZ = 10.0
"""Rate of the traffic trajectory rows (at most the control rate)."""
COLUMNS = ("t", "id", "lane", "x", "y", "yaw", "speed")


class TrafficLog:
    """Rows of every car's pose and speed, one set per `add`."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, int, int, float, float, float, float]] = []

    def add(self, t: float, fleet: Fleet, poses: list[Pose]) -> None:
        """One row per car at time t, at `poses` (the fleet's `poses()`)."""
        for car, p in zip(fleet.cars, poses, strict=True):
            self.rows.append((t, car.id, car.lane, p.x, p.y, p.yaw, car.speed))

    def paths(self) -> dict[int, np.ndarray]:
        """Each car's (x, y, yaw) path (N × 3), by id; a row of NaN separates the drives of a car that re-entered
        the road, so a drawn path does not jump."""
        out: dict[int, list[tuple[float, float, float]]] = {}
        for _, i, _, x, y, yaw, _ in self.rows:
            path = out.setdefault(i, [])
            if path and math.hypot(x - path[-1][0], y - path[-1][1]) > REENTRY_JUMP_M:
                path.append((math.nan, math.nan, math.nan))
            path.append((x, y, yaw))
        return {i: np.array(xy) for i, xy in out.items()}

    def write(self, path: Path) -> None:
        """traffic.csv: times to the microsecond, positions to the millimetre, angles and speeds to 1e-4."""
        with path.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(COLUMNS)
            for t, i, lane, x, y, yaw, v in self.rows:
                w.writerow((f"{t:.6f}", i, lane, f"{x:.3f}", f"{y:.3f}", f"{yaw:.4f}", f"{v:.4f}"))


def vehicle_hit(fleet: Fleet, index: int, t: float, ego_speed: float, ego_yaw: float) -> HitVehicle:
    """The hit of traffic car `index` by the ego moving at `ego_speed` along `ego_yaw` at time t: the relative
    speed is the norm of the velocity difference."""
    car = fleet.cars[index]
    vx, vy = fleet.velocity(car)
    rel = math.hypot(ego_speed * math.cos(ego_yaw) - vx, ego_speed * math.sin(ego_yaw) - vy)
    return HitVehicle(id=car.id, lane=car.lane, time_s=t, relative_speed_mps=rel)
