"""`PATH[#ROUTE][@LANE]`: a track read from an OpenDRIVE file, along a route of road ids (`#1,5,2`) or the
file's default route (`tracks.opendrive.route.default_route`, around or ending before a road where its lane turns
tighter than a car follows), the ego lane starting on lane id LANE of the route's first road (`@-2`; default keep
right)."""

from __future__ import annotations

from pathlib import Path

from tracks.opendrive.model import OpenDriveError
from tracks.opendrive.parse import read_file
from tracks.opendrive.route import default_route, drivable_routes, resolve_route, route_text
from tracks.opendrive.route_track import TightLaneError, route_track
from tracks.road import Track

PREFIX = "xodr:"


def load_xodr(spec: str) -> Track:
    """The track of `PATH[#ROUTE][@LANE]` (the part after `xodr:`); OpenDriveError, one line, if the file is
    unusable."""
    path_text, _, route_part = spec.partition("#")
    route_text, _, lane_text = route_part.partition("@")
    path = Path(path_text)
    od = read_file(path)
    try:
        lane = int(lane_text) if lane_text else None
    except ValueError:
        raise OpenDriveError(f"{path}: route {route_part}: lane {lane_text!r} is not a lane id (an integer)") from None
    ids = [r.strip() for r in route_text.split(",") if r.strip()]
    legs = resolve_route(od, ids, lane) if ids else default_route(od, lane)
    name = f"{PREFIX}{path.name}" + (f"#{route_part}" if route_part else "")
    avoid: frozenset[str] = frozenset()
    while True:
        try:
            return route_track(legs, name, str(path))
        except TightLaneError as exc:
            if ids or exc.leg == 0:
                raise
            avoid |= {legs[exc.leg].road.id}
            legs = default_route(od, lane, avoid)


def list_routes(path_text: str) -> list[tuple[str, int, float]]:
    """(`xodr:PATH#ROUTE@LANE`, roads, length of its roads in m) of every drivable route of the file at
    `path_text` (`tracks.opendrive.route.drivable_routes`)."""
    od = read_file(Path(path_text))
    return [(f"{PREFIX}{path_text}{route_text(legs)}", len(legs), sum(leg.road.length for leg in legs))
            for legs in drivable_routes(od)]
