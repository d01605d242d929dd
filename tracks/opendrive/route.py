"""A route through an OpenDRIVE file: the roads driven in order, each forward (along its s) or backward, and the
ego lane on each of their lane sections.

Consecutive roads must be joined by a road link (either road's predecessor/successor naming the other) or by
a junction connection (a direct junction's too); a connecting road may be left out between two roads its
junction joins. The ego lane starts as the one the route names, else the one the file names, else the outermost
driving lane (keep right; keep left on a left-hand-traffic road), and follows the lane links: a lane's
successor (predecessor when driven backward) from section to section and road to road, a connection's
laneLink into and out of junctions. Without a route the first road outside junctions is driven along its
drivable side and followed through its successors, at a junction along the connection from the ego lane that
turns least, until a road would repeat or none follows.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

from tracks.opendrive.cross_section import DRIVABLE, lane_width, side_lanes
from tracks.opendrive.model import Connection, Junction, LaneSection, Link, OpenDrive, OpenDriveError, Road
from tracks.opendrive.plan_view import PlanView

MIN_WIDTH = 1.0  # m: an ego lane narrower than this where a section begins or ends appears or vanishes there

class Leg(NamedTuple):
    """One road of a route, driven forward (+1, along s) or backward (−1), with the ego lane's id in each of
    its lane sections (in the road's order)."""

    road: Road
    direction: int
    lanes: tuple[int, ...]


def driving_side(road: Road, direction: int) -> int:
    """The road side (−1 right, +1 left of its reference line) of the lanes driven in `direction`."""
    return -direction if road.rule == "RHT" else direction


def _drivable(section: LaneSection, side: int) -> list[int]:
    """Ids of the drivable lanes on `side` of a section, from the centre outward."""
    return [ln.id for ln in side_lanes(section, side) if ln.type in DRIVABLE]


def keep_right(section: LaneSection, side: int) -> list[int]:
    """Candidate ego lanes, best first: the lanes of type driving in the centre's run of drivable lanes from the
    outermost inward, then the run's other drivable lanes (empty where the side has none)."""
    run = []
    for ln in side_lanes(section, side):
        if ln.type in DRIVABLE:
            run.append(ln)
        elif run:
            break
    return [ln.id for ln in run[::-1] if ln.type == "driving"] + [ln.id for ln in run[::-1] if ln.type != "driving"]


def _section_end(road: Road, k: int) -> float:
    """The length of section k of `road`."""
    nxt = road.sections[k + 1].s if k + 1 < len(road.sections) else road.length
    return nxt - road.sections[k].s


def _exit_entry(od: OpenDrive, a: Road, b: Road) -> tuple[str, str] | None:
    """(end of `a` left, end of `b` entered) when the two are joined, from either road's links or a junction."""
    back = _end_towards(b, a.id)
    for end, link in (("end", a.successor), ("start", a.predecessor)):
        if link is None:
            continue
        if link.element_type == "road" and link.element_id == b.id:
            entry = link.contact_point if link.contact_point in ("start", "end") else back
            if entry is not None:
                return end, entry
        if link.element_type == "junction":
            junction = od.junctions.get(link.element_id)
            if junction is not None and (junction.direct or b.junction == link.element_id):
                conn = _connection(junction, a.id, b.id)
                if conn is not None:
                    return end, conn.contact_point
    if back is not None:
        link = b.predecessor if back == "start" else b.successor
        assert link is not None
        exit_end = link.contact_point if link.contact_point in ("start", "end") else _end_towards(a, b.id)
        if exit_end is not None:
            return exit_end, back
    return None


def _end_towards(road: Road, other: str) -> str | None:
    """The end of `road` whose road link names `other`, if one does."""
    for end, link in (("start", road.predecessor), ("end", road.successor)):
        if link is not None and link.element_type == "road" and link.element_id == other:
            return end
    return None


def _connection(junction: Junction | None, incoming: str, connecting: str) -> Connection | None:
    if junction is None:
        return None
    return next((c for c in junction.connections if c.incoming == incoming and c.connecting == connecting), None)


def _joining(od: OpenDrive, a: Road, b: Road) -> Connection | None:
    """The junction connection from `a` into `b` (b a connecting road, or linked by a direct junction)."""
    for link in (a.successor, a.predecessor):
        if link is not None and link.element_type == "junction":
            conn = _connection(od.junctions.get(link.element_id), a.id, b.id)
            if conn is not None:
                return conn
    return None


def _via_junction(od: OpenDrive, a: Road, b: Road) -> Road | None:
    """The connecting road of a junction that joins `a` to `b`, if any."""
    for junction in od.junctions.values():
        for conn in junction.connections:
            c = od.roads.get(conn.connecting)
            if conn.incoming == a.id and c is not None and _exit_entry(od, a, c) and _exit_entry(od, c, b):
                return c
    return None


def _sections(road: Road, direction: int) -> list[int]:
    """Indices of the road's lane sections in driving order."""
    order = list(range(len(road.sections)))
    return order if direction == 1 else order[::-1]


def _lanes_along(od: OpenDrive, road: Road, direction: int, lane: int) -> tuple[int, ...]:
    """The ego lane in each of `road`'s sections (road order) when it enters driving `lane`, by the lanes'
    links (the same id where a lane has none); OpenDriveError where the lane ends or is not drivable."""
    for section in road.sections:
        bad = next((ln for ln in section.lanes if ln.border_only), None)
        if bad is not None:
            raise OpenDriveError(f"{od.source}: road {road.id} <laneSection s={section.s:g}> lane {bad.id}: "
                                 f"<border> is not supported (describe the lane by <width>)")
    side = driving_side(road, direction)
    out = {}
    previous = None
    for k in _sections(road, direction):
        section = road.sections[k]
        if previous is not None:
            rec = road.sections[previous].lane(lane)
            nxt = None if rec is None else (rec.successor if direction == 1 else rec.predecessor)
            lane = lane if nxt is None else nxt
        if lane not in _drivable(section, side):
            raise OpenDriveError(f"{od.source}: road {road.id} <laneSection s={section.s:g}>: the ego lane {lane} "
                                 f"is not a drivable lane of the driving direction there")
        rec = section.lane(lane)
        assert rec is not None
        ends = [0.0, _section_end(road, k)] if direction == 1 else [_section_end(road, k), 0.0]
        for end, what in zip(ends, ("begins", "ends"), strict=True):
            if lane_width(rec, end) < MIN_WIDTH:
                raise OpenDriveError(f"{od.source}: road {road.id} <laneSection s={section.s:g}>: the ego lane "
                                     f"{lane} {what} there (width {lane_width(rec, end):.2f} m)")
        out[k] = lane
        previous = k
    return tuple(out[k] for k in range(len(road.sections)))


def _entry_lane(od: OpenDrive, leg: Leg, road: Road, direction: int) -> int:
    """The lane of `road` (entered driving `direction`) that the ego lane of `leg` leads into: a connection's
    laneLink, the lane's own link, or the drivable lane of the same id (else the outermost) where none says."""
    last = _sections(leg.road, leg.direction)[-1]
    lane = leg.lanes[last]
    entered = road.sections[_sections(road, direction)[0]]
    drivable = _drivable(entered, driving_side(road, direction))
    conn = _joining(od, leg.road, road)
    if conn is not None and conn.lane_links:
        into = [to for frm, to in conn.lane_links if frm == lane]
        if not into:
            raise OpenDriveError(f"{od.source}: junction connection {leg.road.id} → {road.id}: no laneLink from "
                                 f"the ego lane {lane}")
        return into[0]
    rec = leg.road.sections[last].lane(lane)
    nxt = None if rec is None or conn is not None else (rec.successor if leg.direction == 1 else rec.predecessor)
    if nxt is not None:
        return nxt
    same = [d for d in drivable if abs(d) == abs(lane)]
    if same or drivable:
        return same[0] if same else drivable[-1]
    raise OpenDriveError(f"{od.source}: road {road.id}: no drivable lane in the driving direction")


def _first_leg(od: OpenDrive, road: Road, direction: int, lane: int | None) -> Leg:
    """The route's first leg, its ego lane `lane`, else the first of the keep-right candidates that runs through
    the road."""
    section = road.sections[_sections(road, direction)[0]]
    side = driving_side(road, direction)
    if lane is not None and lane not in _drivable(section, side):
        raise OpenDriveError(f"{od.source}: road {road.id} <laneSection s={section.s:g}>: lane {lane} is not a "
                             f"drivable lane of the driving direction (those are: "
                             f"{', '.join(map(str, _drivable(section, side))) or 'none'})")
    candidates = keep_right(section, side) if lane is None else [lane]
    if not candidates:
        raise OpenDriveError(f"{od.source}: road {road.id} <laneSection s={section.s:g}>: no drivable lane in the "
                             f"driving direction")
    failure = None
    for candidate in candidates:
        try:
            return Leg(road, direction, _lanes_along(od, road, direction, candidate))
        except OpenDriveError as exc:
            failure = failure or exc
    assert failure is not None
    raise failure


def _with_lanes(od: OpenDrive, roads: list[tuple[Road, int]], lane: int | None) -> list[Leg]:
    legs: list[Leg] = []
    for road, direction in roads:
        if not legs:
            legs.append(_first_leg(od, road, direction, lane))
        else:
            entry = _entry_lane(od, legs[-1], road, direction)
            legs.append(Leg(road, direction, _lanes_along(od, road, direction, entry)))
    return legs


def resolve_route(od: OpenDrive, ids: list[str], lane: int | None = None) -> list[Leg]:
    """The legs of the route `ids` (road ids in driving order) with the ego lane starting as `lane` (the file's
    ego lane, else keep right, when None); OpenDriveError naming the break otherwise."""
    name = ",".join(ids)
    roads = []
    for road_id in ids:
        if road_id not in od.roads:
            raise OpenDriveError(f"{od.source}: route {name}: road {road_id!r} is not in the file "
                                 f"(roads: {', '.join(list(od.roads)[:12])})")
        road = od.roads[road_id]
        if roads and road is roads[-1]:
            raise OpenDriveError(f"{od.source}: route {name}: road {road_id} is named twice in a row")
        if roads and _exit_entry(od, roads[-1], road) is None:
            via = _via_junction(od, roads[-1], road)
            if via is None:
                raise OpenDriveError(f"{od.source}: route {name}: road {roads[-1].id} does not lead to road "
                                     f"{road_id} (no road link or junction connection joins them)")
            roads.append(via)
        roads.append(road)
    start = lane if lane is not None else od.ego_lane
    if len(roads) == 1:
        side_ok = _drivable(roads[0].sections[0], driving_side(roads[0], 1))
        return _with_lanes(od, [(roads[0], 1 if side_ok or start is not None else -1)], start)
    directed: list[tuple[Road, int]] = []
    entered = None
    for a, b in itertools.pairwise(roads):
        joined = _exit_entry(od, a, b)
        assert joined is not None  # every pair was checked above
        exit_end, entry_end = joined
        direction = 1 if exit_end == "end" else -1
        if entered is not None and (entered == "start") != (direction == 1):
            raise OpenDriveError(f"{od.source}: route {name}: road {a.id} is entered and left at its {exit_end}")
        directed.append((a, direction))
        entered = entry_end
    directed.append((roads[-1], 1 if entered == "start" else -1))
    return _with_lanes(od, directed, start)


def default_route(od: OpenDrive, lane: int | None = None, avoid: frozenset[str] = frozenset()) -> list[Leg]:
    """The first road outside junctions along its drivable side (forward where both are), followed through its
    successors: at a junction the connection from the ego lane that turns least, never one of the roads `avoid`."""
    road = next((r for r in od.roads.values() if r.junction == "-1"), next(iter(od.roads.values())))
    start = lane if lane is not None else od.ego_lane
    forward = _drivable(road.sections[0], driving_side(road, 1))
    direction = 1 if forward or (start is not None and start * driving_side(road, 1) > 0) else -1
    return _followed(od, _first_leg(od, road, direction, start), avoid)


def _followed(od: OpenDrive, first: Leg, avoid: frozenset[str] = frozenset()) -> list[Leg]:
    """`first` and the legs after it along the ego lane until a road would repeat or none follows."""
    legs, seen = [first], {first.road.id}
    while (nxt := _follow(od, legs[-1], avoid)) is not None and nxt.road.id not in seen:
        legs.append(nxt)
        seen.add(nxt.road.id)
    return legs


def _follow(od: OpenDrive, leg: Leg, avoid: frozenset[str]) -> Leg | None:
    """The next leg from `leg`'s exit along the ego lane: the linked road, or the junction connection that
    carries the ego lane and turns least; None where the lane leads nowhere drivable or only onto `avoid`."""
    link: Link | None = leg.road.successor if leg.direction == 1 else leg.road.predecessor
    if link is None:
        return None
    if link.element_type == "road":
        candidates = [(od.roads.get(link.element_id), -1 if link.contact_point == "end" else 1)]
    else:
        junction = od.junctions.get(link.element_id)
        candidates = [(od.roads.get(c.connecting), 1 if c.contact_point == "start" else -1)
                      for c in (junction.connections if junction else ()) if c.incoming == leg.road.id]
    options = []
    for road, direction in candidates:
        if road is None or road.id in avoid:
            continue
        try:
            lane = _entry_lane(od, leg, road, direction)
            options.append(Leg(road, direction, _lanes_along(od, road, direction, lane)))
        except OpenDriveError:
            continue  # a connection the ego lane does not take
    return min(options, key=lambda o: _turn(o.road)) if options else None


def _turn(road: Road) -> float:
    """|heading change| over a road (rad)."""
    _, _, h = PlanView(road.geometries).frame([0.0, road.length])
    return abs(math.remainder(float(h[1] - h[0]), 2.0 * math.pi))


def drivable_routes(od: OpenDrive) -> list[list[Leg]]:
    """From every road outside junctions, along each side that has a drivable lane, the route followed as the
    default one is (keep right, the straightest connection the ego lane takes); routes whose roads one already
    listed covers in the same order and direction are left out."""
    found: list[list[Leg]] = []
    covered: set[tuple[str, int]] = set()
    for road in od.roads.values():
        if road.junction != "-1":
            continue
        for direction in (1, -1):
            if (road.id, direction) in covered or not _drivable(road.sections[_sections(road, direction)[0]],
                                                                driving_side(road, direction)):
                continue
            try:
                legs = _followed(od, _first_leg(od, road, direction, None))
            except OpenDriveError:
                continue
            covered.update((leg.road.id, leg.direction) for leg in legs)
            found.append(legs)
    return found


def route_text(legs: list[Leg]) -> str:
    """`#ROAD,ROAD,...@LANE`: the spec of a route with its first ego lane."""
    first = legs[0]
    lane = first.lanes[_sections(first.road, first.direction)[0]]
    return "#" + ",".join(leg.road.id for leg in legs) + f"@{lane}"
