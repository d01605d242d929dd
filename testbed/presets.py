"""The track-preset and vehicle registries: the `tracks` presets and `vehicles` parameter sets as components,
plus those that installed packages declare under the entry-point groups `ld3.tracks` and `ld3.vehicles`.

A track component's factory is `factory(seed) -> tracks.road.Track`; a vehicle component's factory is
`factory() -> vehicles.params.VehicleParams`. Scenarios name a track as `NAME` or `NAME@SEED`, or an OpenDRIVE
file as `xodr:PATH[#ROAD,ROAD,...]` (the component `xodr`).
"""

from __future__ import annotations

from testbed.errors import UserError
from testbed.registry import Component, Registry
from tracks.opendrive.load import PREFIX as XODR_PREFIX
from tracks.opendrive.load import list_routes
from tracks.opendrive.model import OpenDriveError
from tracks.presets import PRESETS, list_presets, load_track, parse_track_spec
from tracks.road import Track
from vehicles.params import VEHICLES as VEHICLE_PARAMS
from vehicles.params import VehicleParams

TRACKS: Registry[Component] = Registry("track preset", Component, "ld3.tracks")
for _name, _description in list_presets():
    TRACKS.add(Component(_name, PRESETS[_name], _description))


class TrackFileError(UserError):
    """A track file the reader cannot use; the one line names the file, the element and why."""


def _xodr_without_file(seed: int) -> Track:
    raise TrackFileError(f"track 'xodr' needs its file: {XODR_PREFIX}PATH[#ROAD,ROAD,...]")


TRACKS.add(Component("xodr", _xodr_without_file,
                     f"an OpenDRIVE 1.4-1.8 file, {XODR_PREFIX}PATH[#ROAD,ROAD,...] (docs/opendrive.md)"))

VEHICLES: Registry[Component] = Registry("vehicle", Component, "ld3.vehicles")
for _params in VEHICLE_PARAMS.values():
    VEHICLES.add(Component(_params.name, lambda p=_params: p,
                           f"{_params.length:.2f} × {_params.width:.2f} m, wheelbase {_params.wheelbase:.2f} m, "
                           f"up to {_params.max_speed:g} m/s"))


def build_track(spec: str) -> Track:
    """The track `NAME` or `NAME@SEED` of the registry (a UserError naming the known ones), or the route of an
    OpenDRIVE file `xodr:PATH[#ROUTE]` (TrackFileError, one line, where the file cannot be used)."""
    if spec.startswith(XODR_PREFIX):
        try:
            return load_track(spec)
        except OpenDriveError as exc:
            raise TrackFileError(str(exc)) from None
    try:
        name, seed = parse_track_spec(spec)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return TRACKS.get(name).factory(seed)


def xodr_routes(spec: str) -> list[tuple[str, int, float]]:
    """The drivable routes of the OpenDRIVE file `xodr:PATH` as (track spec, roads, length in m); TrackFileError
    where the file cannot be read."""
    if not spec.startswith(XODR_PREFIX):
        raise UserError(f"{spec!r}: name an OpenDRIVE file as {XODR_PREFIX}PATH")
    try:
        return list_routes(spec.removeprefix(XODR_PREFIX).partition("#")[0])
    except OpenDriveError as exc:
        raise TrackFileError(str(exc)) from None


def vehicle(name: str) -> VehicleParams:
    """The vehicle `name` of the registry (ValueError naming the known ones)."""
    return VEHICLES.get(name).factory()
