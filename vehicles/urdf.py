"""URDF generated from `VehicleParams`: a rigid body with Ackermann-steered front wheels and four wheels.

Link frames: the base link frame is the centre of mass (x forward, y left, z up); each front wheel hangs
from a steering knuckle (revolute about z) and spins on a continuous joint about y; rear wheels spin
directly on the body. Wheels collide as spheres of the wheel radius (a smooth single-point contact
patch) with a friction coefficient of 1, so the road surface's friction sets the tyre grip, through a
compliant contact (spring-damper sagging 3 cm under the static corner load, damping ratio 0.7) that
stands in for tyre and suspension and shares the load over all four wheels; they are drawn as
cylinders. The text is deterministic: the same parameters give byte-identical URDF.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

from vehicles.params import VehicleParams
from vehicles.road_load import GRAVITY
from vehicles.steering import ackermann_angles

KNUCKLE_MASS = 5.0
STATIC_DEFLECTION = 0.03  # m: compliant wheel-ground contact standing in for tyre + suspension
DAMPING_RATIO = 0.7
WHEEL_NAMES = ("front_left", "front_right", "rear_left", "rear_right")
STEER_JOINT_NAMES = ("steer_front_left", "steer_front_right")
_BODY_RGBA = "0.55 0.60 0.68 1"
_CABIN_RGBA = "0.25 0.28 0.33 1"
_WHEEL_RGBA = "0.08 0.08 0.08 1"


def _f(v: float) -> str:
    return f"{v:.6f}"


def _xyz(x: float, y: float, z: float) -> str:
    return f"{_f(x)} {_f(y)} {_f(z)}"


def _box_inertia(mass: float, lx: float, ly: float, lz: float) -> str:
    ixx = mass * (ly * ly + lz * lz) / 12.0
    iyy = mass * (lx * lx + lz * lz) / 12.0
    izz = mass * (lx * lx + ly * ly) / 12.0
    return f'<inertia ixx="{_f(ixx)}" ixy="0" ixz="0" iyy="{_f(iyy)}" iyz="0" izz="{_f(izz)}"/>'


def _box(origin: tuple[float, float, float], size: tuple[float, float, float]) -> str:
    return f'<origin xyz="{_xyz(*origin)}"/><geometry><box size="{_xyz(*size)}"/></geometry>'


def _visual(name: str, geometry: str, rgba: str) -> str:
    return (
        f'<visual name="{name}">{geometry}<material name="{name}"><color rgba="{rgba}"/></material></visual>'
    )


def _body_link(params: VehicleParams) -> str:
    cx, ch = params.cg_x, params.cg_height
    body_mass = params.mass - 4.0 * params.wheel_mass - 2.0 * KNUCKLE_MASS
    lower_h = params.hood_height - params.ground_clearance
    lower = _box(
        (-cx, 0.0, params.ground_clearance + lower_h / 2.0 - ch), (params.length, params.width, lower_h)
    )
    coll_h = params.height - params.ground_clearance
    collision = _box(
        (-cx, 0.0, params.ground_clearance + coll_h / 2.0 - ch), (params.length, params.width, coll_h)
    )
    visuals = [_visual("body", lower, _BODY_RGBA)]
    cabin_h = params.height - params.hood_height
    if cabin_h > 0.0:
        # The greenhouse ends just behind the camera so the camera never sits inside drawn geometry.
        x0 = params.rear_axle_x - 0.2
        x1 = params.camera.mount_x - 0.05
        cabin = _box(
            ((x0 + x1) / 2.0 - cx, 0.0, params.hood_height + cabin_h / 2.0 - ch),
            (x1 - x0, params.width - 0.2, cabin_h),
        )
        visuals.append(_visual("cabin", cabin, _CABIN_RGBA))
    return (
        '<link name="body">'
        f'<inertial><origin xyz="0 0 0"/><mass value="{_f(body_mass)}"/>'
        f"{_box_inertia(body_mass, params.length, params.width, params.height)}</inertial>"
        + "".join(visuals)
        + f"<collision>{collision}</collision></link>"
    )


def _wheel_link(params: VehicleParams, name: str) -> str:
    m, r, w = params.wheel_mass, params.wheel_radius, params.wheel_width
    i_spin = m * r * r / 2.0
    i_other = m * (3.0 * r * r + w * w) / 12.0
    corner_mass = params.mass / 4.0
    stiffness = corner_mass * GRAVITY / STATIC_DEFLECTION
    damping = 2.0 * DAMPING_RATIO * math.sqrt(stiffness * corner_mass)
    return (
        f'<link name="wheel_{name}">'
        f'<contact><lateral_friction value="1.0"/><rolling_friction value="0.0"/>'
        f'<spinning_friction value="0.0"/><stiffness value="{_f(stiffness)}"/>'
        f'<damping value="{_f(damping)}"/></contact>'
        f'<inertial><origin xyz="0 0 0"/><mass value="{_f(m)}"/>'
        f'<inertia ixx="{_f(i_other)}" ixy="0" ixz="0" iyy="{_f(i_spin)}" iyz="0" izz="{_f(i_other)}"/>'
        "</inertial>"
        f'<visual><origin xyz="0 0 0" rpy="{_f(math.pi / 2.0)} 0 0"/>'
        f'<geometry><cylinder radius="{_f(r)}" length="{_f(w)}"/></geometry>'
        f'<material name="tyre"><color rgba="{_WHEEL_RGBA}"/></material></visual>'
        f'<collision><origin xyz="0 0 0"/><geometry><sphere radius="{_f(r)}"/></geometry></collision>'
        "</link>"
    )


def _knuckle_link(name: str) -> str:
    i = 0.02
    return (
        f'<link name="knuckle_{name}"><inertial><origin xyz="0 0 0"/><mass value="{_f(KNUCKLE_MASS)}"/>'
        f'<inertia ixx="{_f(i)}" ixy="0" ixz="0" iyy="{_f(i)}" iyz="0" izz="{_f(i)}"/></inertial></link>'
    )


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str, limit: str = "") -> str:
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>{limit}'
        '<dynamics damping="0" friction="0"/></joint>'
    )


def urdf_text(params: VehicleParams) -> str:
    """The vehicle's URDF document."""
    cx, ch = params.cg_x, params.cg_height
    z = params.wheel_radius - ch
    half_t = params.track_width / 2.0
    inner = ackermann_angles(params.max_steer, params.wheelbase, params.track_width)[0] + 0.05
    limit = f'<limit lower="{_f(-inner)}" upper="{_f(inner)}" effort="1e5" velocity="10"/>'
    parts = [f'<?xml version="1.0"?>\n<robot name="{params.name}">', _body_link(params)]
    for name, side in (("front_left", 1.0), ("front_right", -1.0)):
        parts.append(_knuckle_link(name))
        parts.append(_wheel_link(params, name))
        parts.append(
            _joint(
                f"steer_{name}",
                "revolute",
                "body",
                f"knuckle_{name}",
                _xyz(params.front_axle_x - cx, side * half_t, z),
                "0 0 1",
                limit,
            )
        )
        parts.append(
            _joint(f"spin_{name}", "continuous", f"knuckle_{name}", f"wheel_{name}", "0 0 0", "0 1 0")
        )
    for name, side in (("rear_left", 1.0), ("rear_right", -1.0)):
        parts.append(_wheel_link(params, name))
        parts.append(
            _joint(
                f"spin_{name}",
                "continuous",
                "body",
                f"wheel_{name}",
                _xyz(params.rear_axle_x - cx, side * half_t, z),
                "0 1 0",
            )
        )
    parts.append("</robot>\n")
    return "\n".join(parts)


def write_urdf(params: VehicleParams, directory: str | os.PathLike[str]) -> Path:
    """Write `<directory>/<name>.urdf` atomically (safe with concurrent writers) and return its path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{params.name}.urdf"
    text = urdf_text(params)
    if path.exists() and path.read_text() == text:
        return path
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{params.name}.", suffix=".urdf")
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)
    return path
