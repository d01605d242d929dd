"""`PATH[#ROUTE]`: a track read from an OpenDRIVE file, along a route of road ids (`#1,5,2`) or the file's
default route (`tracks.opendrive.route.default_route`)."""

from __future__ import annotations

from pathlib import Path

from tracks.opendrive.parse import read_file
from tracks.opendrive.route import default_route, resolve_route
from tracks.opendrive.route_track import route_track
from tracks.road import Track

PREFIX = "xodr:"


def load_xodr(spec: str) -> Track:
    """The track of `PATH[#ROUTE]` (the part after `xodr:`); OpenDriveError, one line, if the file is unusable."""
    path_text, _, route_text = spec.partition("#")
    path = Path(path_text)
    od = read_file(path)
    ids = [r.strip() for r in route_text.split(",") if r.strip()]
    legs = resolve_route(od, ids) if ids else default_route(od)
    name = f"{PREFIX}{path.name}" + (f"#{route_text}" if route_text else "")
    return route_track(legs, name, str(path))
