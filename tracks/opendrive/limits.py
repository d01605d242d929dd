"""What a parsed OpenDRIVE road may hold before the reader samples it: lengths, coordinates and widths under
stated limits, plan-view records that follow each other without overlap, arcs and spirals that turn less than a
full circle, and polynomials whose reference line is a curve of about the length the record claims. A file
cannot make the reader allocate more than `MAX_ROAD_LENGTH` of samples per road or `MAX_ROUTE_LENGTH` per route.
"""

from __future__ import annotations

import math

import numpy as np

from tracks.opendrive.model import Geometry, OpenDriveError, Road

MAX_ROAD_LENGTH = 100_000.0  # m: one road
MAX_ROUTE_LENGTH = 500_000.0  # m: the roads of one route together
MAX_COORDINATE = 1e7  # m: |x|, |y| of a plan-view record (10 000 km from the origin)
MAX_WIDTH = 50.0  # m: one lane
MAX_TURN = 2.0 * math.pi  # rad: heading change along one record
LENGTH_TOLERANCE = 1e-3  # m: gap or overlap allowed between records
CURVE_RATIO = (0.5, 2.0)  # a polynomial record's sampled length over the length it states
SAMPLES_PER_RECORD = 64


def check_road(road: Road, source: str) -> None:
    """OpenDriveError (one line naming `source`, the road and the record) when `road` breaks a limit above."""
    name = f"{source}: road {road.id}"
    if not 0.0 < road.length <= MAX_ROAD_LENGTH:
        raise OpenDriveError(f"{name}: length {road.length:g} m is not within (0, {MAX_ROAD_LENGTH:g}] m; a road "
                             f"longer than that is split into roads")
    end = 0.0
    for g in sorted(road.geometries, key=lambda g: g.s):
        where = f"{name} <geometry s={g.s:g}>"
        if g.s < end - LENGTH_TOLERANCE:
            raise OpenDriveError(f"{where}: starts at s={g.s:g}, before the record before it ends (s={end:g}): the "
                                 f"records overlap")
        if g.s > road.length + LENGTH_TOLERANCE:
            raise OpenDriveError(f"{where}: starts beyond the road's length {road.length:g} m")
        if max(abs(g.x), abs(g.y)) > MAX_COORDINATE:
            raise OpenDriveError(f"{where}: coordinate ({g.x:g}, {g.y:g}) is more than {MAX_COORDINATE:g} m from "
                                 f"the origin")
        if g.length > MAX_ROAD_LENGTH:
            raise OpenDriveError(f"{where}: length {g.length:g} m is longer than {MAX_ROAD_LENGTH:g} m")
        _check_shape(g, where)
        end = g.s + g.length
    for section in road.sections:
        _check_widths(road, section.s, section.lanes, f"{name} <laneSection s={section.s:g}>")


def _check_shape(g: Geometry, where: str) -> None:
    p = g.params
    turn = {"arc": lambda: abs(p["curvature"]) * g.length,
            "spiral": lambda: 0.5 * (abs(p["curvStart"]) + abs(p["curvEnd"])) * g.length}.get(g.kind)
    if turn is not None and turn() > MAX_TURN:
        raise OpenDriveError(f"{where}: the <{g.kind}> turns {turn() / (2 * math.pi):.2g} turns along its "
                             f"{g.length:g} m; one record turns less than a full circle")
    if g.kind in ("poly3", "paramPoly3"):
        from tracks.opendrive.plan_view import PlanView

        s = np.linspace(g.s, g.s + g.length, SAMPLES_PER_RECORD)
        with np.errstate(all="ignore"):
            x, y, _ = PlanView((g,)).frame(s)
            walked = float(np.sum(np.hypot(np.diff(x), np.diff(y))))
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and math.isfinite(walked)):
            raise OpenDriveError(f"{where}: the <{g.kind}> leaves the range of numbers")
        low, high = CURVE_RATIO
        if not low * g.length <= walked <= high * g.length:
            raise OpenDriveError(f"{where}: the <{g.kind}> is {walked:.3g} m long where the record says "
                                 f"{g.length:g} m (a degenerate or runaway polynomial)")


def _check_widths(road: Road, start: float, lanes, where: str) -> None:
    later = [sec.s for sec in road.sections if sec.s > start]
    end = min(later, default=road.length)
    for lane in lanes:
        for k, w in enumerate(lane.widths):
            w_end = lane.widths[k + 1].s if k + 1 < len(lane.widths) else end - start
            ds = np.linspace(0.0, max(w_end - w.s, 0.0), 33)
            with np.errstate(all="ignore"):
                width = w.a + ds * (w.b + ds * (w.c + ds * w.d))
            low, high = float(np.min(width)), float(np.max(width))
            if not (math.isfinite(low) and math.isfinite(high)) or low < -LENGTH_TOLERANCE or high > MAX_WIDTH:
                raise OpenDriveError(f"{where} lane {lane.id} <width sOffset={w.s:g}>: the width runs from "
                                     f"{low:.3g} to {high:.3g} m; a lane is 0 to {MAX_WIDTH:g} m wide")
