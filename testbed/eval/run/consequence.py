"""Physical consequence of a run (docs/outputs.md, summary.json): contacts with roadside bodies, leaving the road
surface, and where the car ends relative to its lane.

Precedence: the first contact (curb, barrier/guardrail/tree, lane divider, traffic car) or leaving the paved surface
beyond a drop-off ends the run at once. Otherwise a run stopped by the attack response is
`stop_in_lane` when its final |D| is within the lane straddle deviation, `stop_with_lane_straddle` while
the body still overlaps the lane, `out_of_lane` beyond; a run not stopped is `wrong_way` once a wheel crossed
the centre line into an oncoming lane (D beyond the straddle deviation on that side), `out_of_lane` once |D|
ever exceeded the straddle deviation otherwise, else `reach_destination`.
"""

from __future__ import annotations

import math
from enum import StrEnum


class Consequence(StrEnum):
    """How a run ended for the car; the value is what summary.json holds (docs/outputs.md)."""

    REACH_DESTINATION = "reach_destination"
    STOP_IN_LANE = "stop_in_lane"
    STOP_WITH_LANE_STRADDLE = "stop_with_lane_straddle"
    HIT_CURB = "hit_curb"
    HIT_BARRIER = "hit_barrier"
    HIT_LANE_DIVIDER = "hit_lane_divider"
    FALL_OFF_ROAD = "fall_off_road"
    OUT_OF_LANE = "out_of_lane"
    HIT_VEHICLE = "hit_vehicle"
    WRONG_WAY = "wrong_way"
    CHASSIS_FAULT = "chassis_fault"


CONTACT_CONSEQUENCE = {
    "curb": Consequence.HIT_CURB,
    "barrier": Consequence.HIT_BARRIER,
    "guardrail": Consequence.HIT_BARRIER,
    "tree": Consequence.HIT_BARRIER,
    "divider": Consequence.HIT_LANE_DIVIDER,
    "vehicle": Consequence.HIT_VEHICLE,
}
ATTACK_GOAL_M = {"local": 1.3, "highway": 1.9}
"""FusionRipper's attack goal deviation per road type (paper Table 2)."""
LEFT_ROAD = (Consequence.HIT_CURB, Consequence.HIT_BARRIER, Consequence.FALL_OFF_ROAD)


def attack_succeeded(road: str, max_abs_dev: float | None, consequence: str) -> bool:
    """Paper Table 2's success: the physical deviation went beyond the attack goal of the road type, or
    the car left the road (on `local` the curb stops the car at about 0.8 m, before the 1.3 m goal)."""
    return (max_abs_dev or 0.0) > ATTACK_GOAL_M[road] or consequence in LEFT_ROAD


def footprint_corners(x: float, y: float, yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    c, s = math.cos(yaw), math.sin(yaw)
    out = []
    for fx, fy in ((0.5, 0.5), (0.5, -0.5), (-0.5, -0.5), (-0.5, 0.5)):
        lx, ly = fx * length, fy * width
        out.append((x + c * lx - s * ly, y + s * lx + c * ly))
    return out


class ConsequenceMonitor:
    """Watches a run tick by tick; `terminal` is set on the first run-ending event. `oncoming_left`: the lane left
    of the ego lane carries the other direction (a two-way road's centre line is the ego lane's left line)."""

    def __init__(self, lane_width: float, vehicle_width: float, vehicle_length: float,
                 oncoming_left: bool = False) -> None:
        self.lane_width = lane_width
        self.vehicle_width = vehicle_width
        self.vehicle_length = vehicle_length
        self.straddle_dev = (lane_width - vehicle_width) / 2.0
        self.oncoming_left = oncoming_left
        self.terminal: Consequence | None = None
        self.max_abs_dev = 0.0
        self.max_left_dev = 0.0

    def observe(self, phys_dev: float | None, contacts: set[str], off_surface: bool,
                drop_off: bool) -> Consequence | None:
        if phys_dev is not None and math.isfinite(phys_dev):
            self.max_abs_dev = max(self.max_abs_dev, abs(phys_dev))
            self.max_left_dev = max(self.max_left_dev, phys_dev)
        if self.terminal is None:
            for kind in sorted(contacts):
                if kind in CONTACT_CONSEQUENCE:
                    self.terminal = CONTACT_CONSEQUENCE[kind]
                    break
        if self.terminal is None and off_surface and drop_off:
            self.terminal = Consequence.FALL_OFF_ROAD
        return self.terminal

    def final(self, stopped_by_response: bool, final_dev: float | None) -> Consequence:
        if self.terminal is not None:
            return self.terminal
        if stopped_by_response:
            dev = abs(final_dev) if final_dev is not None and math.isfinite(final_dev) else math.inf
            if dev <= self.straddle_dev:
                return Consequence.STOP_IN_LANE
            if dev < (self.lane_width + self.vehicle_width) / 2.0:
                return Consequence.STOP_WITH_LANE_STRADDLE
            return Consequence.OUT_OF_LANE
        if self.oncoming_left and self.max_left_dev > self.straddle_dev:
            return Consequence.WRONG_WAY
        return Consequence.OUT_OF_LANE if self.max_abs_dev > self.straddle_dev else Consequence.REACH_DESTINATION
