"""The `[traffic]` of a lane-detection drive in traffic (`ld3 ld closed-loop --traffic`, the `benign-traffic`
campaign): a lead car close ahead in the ego lane, hiding the far part of the ego lines
(`testbed.perception.training.occlusion`), and the other cars ahead of it in every lane (an oncoming lane's from as far
ahead as the lead car, coming towards the ego).

Every car's desired speed is the ego's, without spread, and the IDM time headway and jam distance are 0: at
one speed the IDM then has no interaction term, so no car closes on the one ahead. Started at rest with the
ego (`traffic.start_speed = 0`), the cars accelerate by the IDM with a = `LEAD_ACCEL`, the least at which the lead car
never falls behind the ego's 1 m/s² cruise ramp: its gap opens by at most 3–4 m at 10–12 m/s (22 m at 27 m/s,
back to 3 m after 60 s), and holds until the road's end comes within `END_ZONE` of the front car's IDM desired
gap to a standing obstacle, v² / (2 √(a b)). `traffic_drive` fits this to the track: the gap between
consecutive cars in a lane shrinks (from `GAP_M`, not below `MIN_GAP_M`) until the front car of the ego lane
stays that far from the road's end for the whole drive, and where even the shortest gaps leave too little
road the ego's speed drops (never rises) until it does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from testbed.control.idm import IdmParams
from testbed.errors import UserError
from testbed.eval.run.scenario import END_MARGIN_M
from tracks.road import Track
from vehicles.params import get_vehicle

LEAD_GAP_M = 8.0
"""Ego front to lead car rear (m): on a straight 3.75 m lane the lead car hides the ego lines from about 20 m
ahead on, 40 % of the detector's 5–30 m range (none of it from a gap of 15 m on)."""
GAP_M = 40.0
MIN_GAP_M = 0.5
OTHERS_AHEAD_M = 15.0  # the first car of every other lane starts this far ahead of the lead car's centre
END_ZONE = 6.0  # the front car's IDM braking for the road's end stays under a / 36
MIN_SPEED = 0.1  # m/s: a drive the road leaves less room for is refused
CAR = "sedan"
LEAD_ACCEL = 1.14  # m/s²
ZONE_PER_SPEED2 = END_ZONE / (2.0 * math.sqrt(LEAD_ACCEL * IdmParams.decel))
"""`END_ZONE` IDM desired gaps to a standing obstacle at a speed v, over v² (s²/m)."""


@dataclass(frozen=True)
class TrafficDrive:
    """The `[traffic]` table of a drive and the ego's speed (m/s) it is fitted to."""

    traffic: dict[str, Any]
    speed: float


def _end_room(speed: float, duration: float) -> float:
    """Road the ego lane's front car needs ahead of its start: its drive plus the zone before the road's end."""
    return speed * duration + ZONE_PER_SPEED2 * speed**2


def _speed_for(room: float, duration: float) -> float:
    """The largest speed whose `_end_room` is `room`."""
    c = ZONE_PER_SPEED2
    return max(0.0, (-duration + math.sqrt(duration**2 + 4.0 * c * max(room, 0.0))) / (2.0 * c))


def traffic_drive(track: Track, lane: int, start_s: float, ego_vehicle: str, speed: float, duration: float,
                  vehicles: int, ahead: float = LEAD_GAP_M) -> TrafficDrive:
    """`vehicles` cars for a drive of `duration` s from `start_s` in `lane` of `track` at up to `speed` (see the
    module); a UserError where the cars cannot start on the road even at the shortest gaps."""
    if vehicles < 1:
        raise UserError(f"--traffic must be a number of cars >= 1, got {vehicles}")
    car_length = get_vehicle(CAR).length
    end_s = track.length - END_MARGIN_M
    lead_s = start_s + 0.5 * get_vehicle(ego_vehicle).length + ahead + 0.5 * car_length
    n_lanes = len(track.lanes)
    beside = [ln for ln in range(n_lanes) if ln != lane and not track.lanes[ln].oncoming]
    first = {ln: lead_s + OTHERS_AHEAD_M if ln in beside else lead_s for ln in range(n_lanes)}
    count = {ln: len(range(ln, vehicles, n_lanes)) for ln in range(n_lanes)}
    gap = GAP_M
    for ln in range(n_lanes):
        if count[ln] > 1:
            room = end_s - first[ln] - (_end_room(speed, duration) if ln == lane else 0.0)
            gap = min(gap, room / (count[ln] - 1) - car_length)
    gap = max(gap, MIN_GAP_M)
    last = {ln: first[ln] + (count[ln] - 1) * (car_length + gap) for ln in range(n_lanes)}
    if any(last[ln] > end_s for ln in range(n_lanes) if count[ln]):
        raise UserError(f"{vehicles} traffic cars do not fit on {track.name} ({track.length:.0f} m) even "
                        f"{MIN_GAP_M:g} m apart: lower --traffic")
    fitted = min(speed, math.floor(100.0 * _speed_for(end_s - last[lane], duration)) / 100.0)
    if fitted < MIN_SPEED:
        raise UserError(f"{vehicles} traffic cars leave the ego {end_s - last[lane]:.0f} m of {track.name} for "
                        f"{duration:g} s: lower --traffic or the duration")
    table = {"vehicles": vehicles, "speed": fitted, "speed_spread": 0.0, "ahead": ahead, "gap": gap,
             "gap_spread": 0.0, "start_speed": 0.0, "accel": LEAD_ACCEL, "headway": 0.0, "min_gap": 0.0}
    if beside:
        table["beside"] = lead_s + OTHERS_AHEAD_M - start_s
    return TrafficDrive(table, fitted)

