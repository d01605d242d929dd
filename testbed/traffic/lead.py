"""The ego car's range sensor in simulation: the nearest traffic car ahead of the ego in the lane it drives, read
from the fleet (bumper-to-bumper gap and that car's speed), for `testbed.control.car_following`."""

from __future__ import annotations

from testbed.chassis import ChassisState
from testbed.control.car_following import LeadCar
from testbed.traffic.fleet import Fleet
from tracks.map_api import OffMapError, SemanticMap


class LeadSensor:
    """`sensor(state)`: the car ahead of the true pose in lane `lane` (which runs along the road), or None (no car
    ahead, or the ego off the map)."""

    def __init__(self, fleet: Fleet, smap: SemanticMap, lane: int) -> None:
        self.fleet, self.smap, self.lane = fleet, smap, lane
        self._half_lengths = 0.5 * (fleet.ego_length + fleet.length)

    def __call__(self, state: ChassisState) -> LeadCar | None:
        if state.true_pose is None:
            return None
        try:
            s = self.smap.project(state.true_pose, self.lane).s
        except OffMapError:
            return None
        ahead = [car for car in self.fleet.cars if car.lane == self.lane and car.s > s]
        if not ahead:
            return None
        lead = min(ahead, key=lambda car: car.s)
        return LeadCar(lead.s - s - self._half_lengths, lead.speed)
