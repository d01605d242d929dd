"""The track-preset and vehicle registries: the `tracks` presets and `vehicles` parameter sets as components,
plus those that installed packages declare under the entry-point groups `ld3.tracks` and `ld3.vehicles`.

A track component's factory is `factory(seed) -> tracks.road.Track`; a vehicle component's factory is
`factory() -> vehicles.params.VehicleParams`. Scenarios name a track as `NAME` or `NAME@SEED`.
"""

from __future__ import annotations

from testbed.errors import UserError
from testbed.registry import Component, Registry
from tracks.presets import PRESETS, list_presets, parse_track_spec
from tracks.road import Track
from vehicles.params import VEHICLES as VEHICLE_PARAMS
from vehicles.params import VehicleParams

TRACKS: Registry[Component] = Registry("track preset", Component, "ld3.tracks")
for _name, _description in list_presets():
    TRACKS.add(Component(_name, PRESETS[_name], _description))

VEHICLES: Registry[Component] = Registry("vehicle", Component, "ld3.vehicles")
for _params in VEHICLE_PARAMS.values():
    VEHICLES.add(Component(_params.name, lambda p=_params: p,
                           f"{_params.length:.2f} × {_params.width:.2f} m, wheelbase {_params.wheelbase:.2f} m, "
                           f"up to {_params.max_speed:g} m/s"))


def build_track(spec: str) -> Track:
    """The track `NAME` or `NAME@SEED` of the registry (a UserError naming the known ones)."""
    try:
        name, seed = parse_track_spec(spec)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return TRACKS.get(name).factory(seed)


def vehicle(name: str) -> VehicleParams:
    """The vehicle `name` of the registry (ValueError naming the known ones)."""
    return VEHICLES.get(name).factory()
