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

CONTACT_CONSEQUENCE = {
    "curb": "hit_curb",
    "barrier": "hit_barrier",
    "guardrail": "hit_barrier",
    "tree": "hit_barrier",
    "divider": "hit_lane_divider",
    "vehicle": "hit_vehicle",
}
ATTACK_GOAL_M = {"local": 1.3, "highway": 1.9}
"""FusionRipper's attack goal deviation per road type (paper Table 2)."""
LEFT_ROAD = ("hit_curb", "hit_barrier", "fall_off_road")


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
        self.terminal: str | None = None
        self.max_abs_dev = 0.0
        self.max_left_dev = 0.0

    def observe(self, phys_dev: float | None, contacts: set[str], off_surface: bool, drop_off: bool) -> str | None:
        if phys_dev is not None and math.isfinite(phys_dev):
            self.max_abs_dev = max(self.max_abs_dev, abs(phys_dev))
            self.max_left_dev = max(self.max_left_dev, phys_dev)
        if self.terminal is None:
            for kind in sorted(contacts):
                if kind in CONTACT_CONSEQUENCE:
                    self.terminal = CONTACT_CONSEQUENCE[kind]
                    break
        if self.terminal is None and off_surface and drop_off:
            self.terminal = "fall_off_road"
        return self.terminal

    def final(self, stopped_by_response: bool, final_dev: float | None) -> str:
        if self.terminal is not None:
            return self.terminal
        if stopped_by_response:
            dev = abs(final_dev) if final_dev is not None and math.isfinite(final_dev) else math.inf
            if dev <= self.straddle_dev:
                return "stop_in_lane"
            if dev < (self.lane_width + self.vehicle_width) / 2.0:
                return "stop_with_lane_straddle"
            return "out_of_lane"
        if self.oncoming_left and self.max_left_dev > self.straddle_dev:
            return "wrong_way"
        return "out_of_lane" if self.max_abs_dev > self.straddle_dev else "reach_destination"
