"""A route through an OpenDRIVE file: the roads driven in order, each forward (along its s) or backward.

Consecutive roads must be joined by a road link (either road's predecessor/successor naming the other) or by
a junction connection; a connecting road may be left out between two roads its junction joins. Without a
route the first road outside junctions is driven forward and followed through its successors, at a junction
along the connection that turns least, until a road would repeat or none follows.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

from tracks.opendrive.model import Junction, Link, OpenDrive, OpenDriveError, Road
from tracks.opendrive.plan_view import PlanView


class Leg(NamedTuple):
    """One road of a route, driven forward (+1, along s) or backward (−1)."""

    road: Road
    direction: int


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
        if link.element_type == "junction" and b.junction == link.element_id:
            conn = _connection(od.junctions.get(link.element_id), a.id, b.id)
            if conn is not None:
                return end, conn
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


def _connection(junction: Junction | None, incoming: str, connecting: str) -> str | None:
    if junction is None:
        return None
    for conn in junction.connections:
        if conn.incoming == incoming and conn.connecting == connecting:
            return conn.contact_point
    return None


def _via_junction(od: OpenDrive, a: Road, b: Road) -> Road | None:
    """The connecting road of a junction that joins `a` to `b`, if any."""
    for junction in od.junctions.values():
        for conn in junction.connections:
            c = od.roads.get(conn.connecting)
            if conn.incoming == a.id and c is not None and _exit_entry(od, a, c) and _exit_entry(od, c, b):
                return c
    return None


def resolve_route(od: OpenDrive, ids: list[str]) -> list[Leg]:
    """The legs of the route `ids` (road ids in driving order); OpenDriveError naming the break otherwise."""
    name = ",".join(ids)
    roads = []
    for road_id in ids:
        if road_id not in od.roads:
            raise OpenDriveError(f"{od.source}: route {name}: road {road_id!r} is not in the file "
                                 f"(roads: {', '.join(list(od.roads)[:12])})")
        road = od.roads[road_id]
        if roads and _exit_entry(od, roads[-1], road) is None:
            via = _via_junction(od, roads[-1], road)
            if via is None:
                raise OpenDriveError(f"{od.source}: route {name}: road {roads[-1].id} does not lead to road "
                                     f"{road_id} (no road link or junction connection joins them)")
            roads.append(via)
        roads.append(road)
    if len(roads) == 1:
        return [Leg(roads[0], 1)]
    legs: list[Leg] = []
    entered = None
    for a, b in itertools.pairwise(roads):
        joined = _exit_entry(od, a, b)
        assert joined is not None  # every pair was checked above
        exit_end, entry_end = joined
        direction = 1 if exit_end == "end" else -1
        if entered is not None and (entered == "start") != (direction == 1):
            raise OpenDriveError(f"{od.source}: route {name}: road {a.id} is entered and left at its {exit_end}")
        legs.append(Leg(a, direction))
        entered = entry_end
    legs.append(Leg(roads[-1], 1 if entered == "start" else -1))
    return legs


def default_route(od: OpenDrive) -> list[Leg]:
    """The first road outside junctions, forward, followed through successors (the straightest connection)."""
    road = next((r for r in od.roads.values() if r.junction == "-1"), next(iter(od.roads.values())))
    legs, seen, direction = [], set(), 1
    while road is not None and road.id not in seen:
        legs.append(Leg(road, direction))
        seen.add(road.id)
        link = road.successor if direction == 1 else road.predecessor
        road, direction = _follow(od, road, direction, link)
    return legs


def _follow(od: OpenDrive, road: Road, direction: int, link: Link | None) -> tuple[Road | None, int]:
    if link is None:
        return None, 1
    if link.element_type == "road":
        nxt = od.roads.get(link.element_id)
        return nxt, -1 if link.contact_point == "end" else 1
    junction = od.junctions.get(link.element_id)
    options = [(conn, od.roads[conn.connecting]) for conn in (junction.connections if junction else ())
               if conn.incoming == road.id and conn.connecting in od.roads]
    if not options:
        return None, 1
    conn, nxt = min(options, key=lambda o: _turn(o[1]))
    return nxt, 1 if conn.contact_point == "start" else -1


def _turn(road: Road) -> float:
    """|heading change| over a road (rad)."""
    _, _, h = PlanView(road.geometries).frame([0.0, road.length])
    return abs(math.remainder(float(h[1] - h[0]), 2.0 * math.pi))
