"""Vehicle and front-camera parameter sets, and the registry of the vehicles the testbed can drive.

Geometry is given in the vehicle frame (x forward, y left, z up) whose origin, the reference point,
is the centre of the footprint on the ground. The rear axle sits `rear_overhang` ahead of the rear
bumper; the centre of mass sits at the middle of the wheelbase, `cg_height` above the ground.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class CameraParams:
    """A forward camera: image size (px), vertical field of view and downward pitch (deg), mount (m)."""

    width: int = 320
    height: int = 160
    fov_deg: float = 30.0
    mount_x: float = 0.5
    mount_height: float = 1.4
    pitch_deg: float = 5.0

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera image size must be positive, got {self.width}x{self.height}")
        if not 0.0 < self.fov_deg < 180.0:
            raise ValueError(f"camera vertical field of view must be in (0, 180) deg, got {self.fov_deg}")
        if self.mount_height <= 0.0:
            raise ValueError(f"camera mount height must be above the ground, got {self.mount_height}")


@dataclass(frozen=True)
class VehicleParams:
    """Dimensions (m), mass (kg), actuator limits (rad, rad/s, m/s, m/s²) and road load of one vehicle."""

    name: str
    length: float
    width: float
    height: float
    hood_height: float
    ground_clearance: float
    wheelbase: float
    track_width: float
    rear_overhang: float
    wheel_radius: float
    wheel_width: float
    wheel_mass: float
    mass: float
    cg_height: float
    max_steer: float
    max_steer_rate: float
    max_speed: float
    max_accel: float
    max_decel: float
    front_brake_share: float
    drag_area: float
    rolling_resistance: float
    camera: CameraParams

    def __post_init__(self) -> None:
        if self.rear_overhang + self.wheelbase > self.length:
            raise ValueError(f"{self.name}: rear overhang + wheelbase exceed the length")
        if self.track_width + self.wheel_width > self.width + 1e-9:
            raise ValueError(f"{self.name}: wheels stick out of the body width")
        if not 0.0 <= self.front_brake_share <= 1.0:
            raise ValueError(f"{self.name}: front brake share must be in [0, 1]")

    @property
    def rear_axle_x(self) -> float:
        """Rear axle position along the vehicle x axis, relative to the footprint centre."""
        return -self.length / 2.0 + self.rear_overhang

    @property
    def front_axle_x(self) -> float:
        return self.rear_axle_x + self.wheelbase

    @property
    def cg_x(self) -> float:
        """Centre of mass x (middle of the wheelbase)."""
        return self.rear_axle_x + self.wheelbase / 2.0


SEDAN = VehicleParams(
    name="sedan",
    length=4.90,
    width=1.90,
    height=1.45,
    hood_height=0.75,
    ground_clearance=0.15,
    wheelbase=2.85,
    track_width=1.60,
    rear_overhang=1.05,
    wheel_radius=0.33,
    wheel_width=0.225,
    wheel_mass=22.0,
    mass=1800.0,
    cg_height=0.55,
    max_steer=math.radians(35.0),
    max_steer_rate=math.radians(35.0),
    max_speed=45.0,
    max_accel=3.5,
    max_decel=8.0,
    front_brake_share=0.6,
    drag_area=0.65,
    rolling_resistance=0.012,
    camera=CameraParams(mount_x=0.45, mount_height=1.4, pitch_deg=5.0),
)

# Modelled on a PIXKIT-class drive-by-wire development chassis (the paper's parking-lot vehicle):
# real car size, slow, with a camera on a sensor mast near the front.
DEV_CHASSIS = VehicleParams(
    name="dev-chassis",
    length=3.50,
    width=1.60,
    height=1.20,
    hood_height=1.20,
    ground_clearance=0.15,
    wheelbase=2.40,
    track_width=1.36,
    rear_overhang=0.55,
    wheel_radius=0.30,
    wheel_width=0.20,
    wheel_mass=15.0,
    mass=900.0,
    cg_height=0.50,
    max_steer=math.radians(30.0),
    max_steer_rate=0.55,
    max_speed=5.0,
    max_accel=1.5,
    max_decel=3.5,
    front_brake_share=0.6,
    drag_area=1.2,
    rolling_resistance=0.015,
    camera=CameraParams(mount_x=1.2, mount_height=1.4, pitch_deg=5.0),
)

VEHICLES: dict[str, VehicleParams] = {v.name: v for v in (SEDAN, DEV_CHASSIS)}


def vehicle_names() -> list[str]:
    """Names accepted by `get_vehicle`, sorted."""
    return sorted(VEHICLES)


def get_vehicle(name: str) -> VehicleParams:
    """The parameter set registered under `name`; ValueError naming the known vehicles otherwise."""
    try:
        return VEHICLES[name]
    except KeyError:
        raise ValueError(f"unknown vehicle {name!r}; known vehicles: {', '.join(vehicle_names())}") from None
