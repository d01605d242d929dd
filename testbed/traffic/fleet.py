"""The traffic cars as a kinematic fleet on a track: each holds its lane's centre line (reference arc length s,
advanced at its speed in its lane's direction of travel: towards decreasing s in an oncoming lane) and sets its
speed by IDM behind the nearest car ahead in its lane, the ego car counted in every lane its footprint overlaps
(coming the other way in an oncoming lane), and the road's end as a standing obstacle.

Oncoming cars run as a stream: one that has fallen `RECYCLE_BEHIND_M` behind the ego (or reached the road's
start) re-enters its lane a drawn gap beyond the farthest car of that lane (if the road reaches that far), so the
ego meets oncoming traffic all along its drive with a fixed number of cars. No physics engine."""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from testbed.control.idm import IdmParams, idm_accel, integrate
from testbed.traffic.config import TrafficConfig
from tracks.pose import Pose
from tracks.road import Track

RECYCLE_BEHIND_M = 60.0
"""How far behind the ego car (m of reference arc length) an oncoming car leaves and re-enters ahead."""


class PlacementError(ValueError):
    """A `[traffic]` table the track cannot hold (a lane it lacks, cars beyond the road's end)."""


@dataclass
class TrafficCar:
    """One car: id (its index in the fleet), lane, reference arc length s of its centre (m), speed and desired
    speed (m/s), its lane's direction of travel (+1 along the reference line, -1 oncoming)."""

    id: int
    lane: int
    s: float
    speed: float
    desired: float
    direction: int = 1


@dataclass(frozen=True)
class EgoOnRoad:
    """The ego car as the fleet sees it: reference arc length and lateral offset of its centre, its speed."""

    s: float
    t: float
    speed: float


@dataclass(frozen=True)
class Gaps:
    """Bumper-to-bumper gaps drawn uniformly within `mean` × (1 ± `spread`) from `rng`."""

    rng: np.random.Generator
    mean: float
    spread: float

    def draw(self) -> float:
        return self.mean * float(self.rng.uniform(1.0 - self.spread, 1.0 + self.spread))


class Fleet:
    """Traffic cars of one footprint (`length` × `width`) on `track`, stepped by `advance`; `gaps` draws where a
    recycled oncoming car re-enters."""

    def __init__(self, track: Track, cars: list[TrafficCar], idm: IdmParams, length: float, width: float,
                 ego_length: float, ego_width: float, end_s: float, gaps: Gaps) -> None:
        self.track = track
        self.cars = cars
        self.idm = idm
        self.length, self.width = length, width
        self.ego_length, self.ego_width = ego_length, ego_width
        self.end_s = end_s
        self.gaps = gaps
        self._leaders: dict[int, TrafficCar] | None = None

    @classmethod
    def place(cls, config: TrafficConfig, track: Track, ego_lane: int, ego_s: float, default_speed: float,
              rng: np.random.Generator, size: tuple[float, float], ego_size: tuple[float, float],
              end_s: float) -> Fleet:
        """The cars of `config` placed (see `TrafficConfig`) at its `start_speed` (default: their desired
        speed), desired speeds and gaps drawn from `rng` car by car, in an oncoming lane from `ahead` m in front
        of the ego car outward like in the ego lane;
        PlacementError naming the fix when a lane is not on the track, a car would start past `end_s`, or an
        `ahead` or `beside` given would place no car."""
        n_lanes = len(track.lanes)
        lanes = config.lanes if config.lanes is not None else list(range(n_lanes))
        for lane in lanes:
            if not 0 <= lane < n_lanes:
                raise PlacementError(f"traffic.lanes names lane {lane}, which {track.name} lacks (lanes 0.."
                                     f"{n_lanes - 1})")
        holding = lanes[:config.vehicles]  # round-robin: the lanes that get a car at all
        from_front = [lane == ego_lane or track.lanes[lane].oncoming for lane in holding]
        for key, used, where in (("ahead", any(from_front), "the ego lane or an oncoming lane"),
                                 ("beside", not all(from_front), "a lane beside the ego lane")):
            if key in config.model_fields_set and not used:
                raise PlacementError(f"traffic.{key} would place no car: no car goes to {where} (cars go to lanes "
                                     f"{holding}): drop traffic.{key} or change traffic.lanes")
        length, width = size
        mean = default_speed if config.speed is None else config.speed
        gaps = Gaps(rng, config.gap, config.gap_spread)
        in_front = 0.5 * ego_size[0] + config.ahead + 0.5 * length
        next_s = {lane: ego_s + (in_front if lane == ego_lane or track.lanes[lane].oncoming else config.beside)
                  for lane in lanes}
        cars = []
        for i in range(config.vehicles):
            lane = lanes[i % len(lanes)]
            desired = max(0.0, float(rng.uniform(mean - config.speed_spread, mean + config.speed_spread)))
            gap = gaps.draw()
            s = next_s[lane]
            if not 0.5 * length <= s <= end_s:
                start_key = "ahead" if lane == ego_lane or track.lanes[lane].oncoming else "beside"
                fix = (f"lower traffic.vehicles, traffic.gap or traffic.{start_key}" if s > end_s
                       else "raise traffic.beside")
                raise PlacementError(f"traffic car {i} would start at s = {s:.0f} m in lane {lane}, off the road "
                                     f"(0..{end_s:.0f} m): {fix}")
            start = desired if config.start_speed is None else config.start_speed
            cars.append(TrafficCar(i, lane, s, start, desired, track.lanes[lane].direction))
            next_s[lane] = s + length + gap
        return cls(track, cars, config.idm(), length, width, ego_size[0], ego_size[1], end_s, gaps)

    def _ego_lanes(self, ego: EgoOnRoad) -> set[int]:
        """Lanes the ego footprint overlaps laterally at its arc length."""
        lanes = set()
        for ln in self.track.lanes:
            c, w = ln.offset_at(ego.s), ln.width_at(ego.s)
            if abs(ego.t - c) < 0.5 * (w + self.ego_width):
                lanes.add(ln.index)
        return lanes

    def advance(self, dt: float, ego: EgoOnRoad | None) -> None:
        """Move every car over dt: IDM acceleration behind its leader (the next car in its lane, the ego, or the
        road's end), evaluated for all cars before any moves, then recycle the oncoming cars left behind; an ego
        off the map (None) leads no car and recycles none."""
        ego_lanes = self._ego_lanes(ego) if ego is not None else set()
        if self._leaders is None:
            self._leaders = self._leader_of()
        leaders, half_pair, length = self._leaders, 0.5 * (self.length + self.ego_length), self.length
        road_end, idm, cars = self.end_s + 0.5 * length, self.idm, self.cars
        steps = []
        for car in cars:
            v, d, s = car.speed, car.direction, car.s
            if car.desired <= 0.0:
                steps.append((0.0, 0.0))
                continue
            gap = road_end - s if d > 0 else math.inf
            lead_speed = 0.0
            ahead = leaders.get(car.id)
            if ahead is not None:
                lead_gap = d * (ahead.s - s) - length
                if lead_gap < -length:
                    self._leaders = None  # the two swapped places: find the leaders again next tick
                if lead_gap < gap:
                    gap, lead_speed = lead_gap, ahead.speed
            if ego is not None and car.lane in ego_lanes and d * (ego.s - s) > 0.0:
                ego_gap = d * (ego.s - s) - half_pair
                if ego_gap < gap:
                    gap, lead_speed = ego_gap, d * ego.speed
            steps.append(integrate(v, idm_accel(idm, v, car.desired, gap, v - lead_speed), dt))
        for car, (ds, v) in zip(cars, steps, strict=True):
            car.s, car.speed = car.s + car.direction * ds, v
        self._recycle(ego)

    def _leader_of(self) -> dict[int, TrafficCar]:
        """The car ahead of each car in its lane (in its direction of travel), by id."""
        leaders: dict[int, TrafficCar] = {}
        by_lane: dict[int, list[TrafficCar]] = {}
        for car in sorted(self.cars, key=lambda c: c.direction * c.s):
            by_lane.setdefault(car.lane, []).append(car)
        for cars in by_lane.values():
            leaders.update((behind.id, ahead) for behind, ahead in pairwise(cars))
        return leaders

    def _recycle(self, ego: EgoOnRoad | None) -> None:
        """Each oncoming car `RECYCLE_BEHIND_M` behind the ego, or at the road's start, re-enters its lane at its
        desired speed, a drawn gap beyond the lane's farthest car; where that lies past the road's end, a car at
        the road's start parks there instead."""
        behind = -math.inf if ego is None else ego.s - RECYCLE_BEHIND_M
        start = 0.5 * self.length
        for car in self.cars:
            if car.direction > 0 or car.desired <= 0.0 or car.s > max(behind, start):
                continue
            s = max(c.s for c in self.cars if c.lane == car.lane) + self.length + self.gaps.draw()
            if s <= self.end_s:
                car.s, car.speed = s, car.desired
                self._leaders = None
            elif car.s <= start:
                car.s, car.speed, car.desired = start, 0.0, 0.0

    def near(self, s: float, radius: float) -> list[TrafficCar]:
        """The cars whose centres lie within `radius` m of reference arc length s."""
        return [car for car in self.cars if abs(car.s - s) <= radius]

    def poses(self, cars: list[TrafficCar] | None = None) -> list[Pose]:
        """Each car's (default: every car's) centre on its lane's centre line, heading in its lane's direction of
        travel."""
        lanes = self.track.lanes
        return [lanes[car.lane].pose_at(car.s) for car in (self.cars if cars is None else cars)]

    def velocity(self, car: TrafficCar) -> tuple[float, float]:
        """The car's world velocity (m/s)."""
        yaw = self.track.lanes[car.lane].heading_at(car.s)
        return car.speed * math.cos(yaw), car.speed * math.sin(yaw)
