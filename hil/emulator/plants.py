"""Plants for the ECU emulator: the PyBullet car of a scenario, driven through a DirectChassis without command
hold (the ECU applies commands on its own 50 Hz schedule, so holding them again would delay them)."""

from __future__ import annotations

from testbed.chassis import ChassisModel
from testbed.direct_chassis import DirectChassis
from testbed.errors import UserError
from testbed.eval.run.build import physics_world_for
from testbed.eval.run.scenario import Scenario
from testbed.presets import build_track, vehicle
from testbed.rates import PHYSICS_HZ


def scenario_plant(sc: Scenario) -> DirectChassis:
    """The PyBullet car in the physics world `ld3 run` builds for `sc` (its `world` is the PhysicsWorld), its
    steering sensor as `[chassis]` says; what it reports over CAN is the profile's business."""
    track = build_track(sc.track)
    params = vehicle(sc.vehicle)
    lane = sc.lane if sc.lane is not None else track.ego_lane
    start = track.start_pose(lane, sc.start_s)
    model = ChassisModel(steer_offset_deg=sc.chassis.steer_offset_deg)
    return DirectChassis(physics_world_for(sc, track, params, start), hold_s=0.0, model=model)


def pybullet_plant(
    track: str,
    vehicle: str = "sedan",
    start_s: str | float = 20.0,
    lane: str | int | None = None,
    physics_hz: str | float = PHYSICS_HZ,
    steer_offset_deg: str | float = 0.0,
) -> DirectChassis:
    """Factory for `ld3 ecu --plant pybullet --plant-arg track=parking-lot ...` (values may be strings)."""
    sc = Scenario.build(name="ecu-plant", track=track, vehicle=vehicle, start_s=_number(start_s, "start_s", float),
                        lane=None if lane in (None, "") else _number(lane, "lane", int),
                        rates={"physics_hz": _number(physics_hz, "physics_hz", float)},
                        chassis={"steer_offset_deg": _number(steer_offset_deg, "steer_offset_deg", float)})
    return scenario_plant(sc)


def _number(value: str | float | int, key: str, kind: type[float] | type[int]) -> float | int:
    """A plant argument as a number of `kind`, or a one-line UserError naming it."""
    try:
        return kind(value)
    except ValueError:
        expected = "an integer" if kind is int else "a number"
        raise UserError(f"--plant-arg {key}={value!r}: expected {expected}") from None


def plant_args_for(sc: Scenario) -> dict[str, str]:
    """The `pybullet_plant` keyword strings that rebuild `sc`'s plant in an ECU process."""
    args = {"track": sc.track, "vehicle": sc.vehicle, "start_s": repr(sc.start_s)}
    args["physics_hz"] = repr(sc.rates.physics_hz)
    if sc.chassis.steer_offset_deg:
        args["steer_offset_deg"] = repr(sc.chassis.steer_offset_deg)
    if sc.lane is not None:
        args["lane"] = str(sc.lane)
    return args
