"""Occlusion of the ego lane's lines by traffic cars in the front camera's view, from geometry.

A ground point is hidden from the camera when the segment from the camera's centre to it passes through a
car's box (its footprint, from the ground up to its height). The points looked at are the ego lane's two
lines (`labels.ego_lines`, painted or not) every `STEP_M` from `NEAR_M` to `FAR_M` ahead of the reference
point: the neural detector's anchor range. A frame is *occluded* when any of them is hidden; its occluded
fraction is the share hidden. The camera sits at the rig's mount on the true pose (flat ground, no pitch
or roll of the body), as the simulator renders it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from testbed.perception.detectors.labels import ego_lines
from tracks.map_api import OffMapError
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig

NEAR_M, FAR_M, STEP_M = 5.0, 30.0, 1.0
REACH_M = FAR_M + 10.0  # cars whose centre is farther from the camera than this hide none of the points


def hidden(camera: np.ndarray, points: np.ndarray, car: Pose, size: tuple[float, float, float]) -> np.ndarray:
    """(N,) bools: whether the segment from `camera` (3,) to each of `points` (N, 3) crosses the box of length,
    width, height `size` standing on the ground at `car` (its centre and heading; same frame as the points)."""
    c, s = math.cos(car.yaw), math.sin(car.yaw)
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # frame -> car
    origin = np.array([car.x, car.y, 0.0])
    a = rot @ (np.asarray(camera, float) - origin)
    d = (np.asarray(points, float) - origin) @ rot.T - a
    half = np.array([0.5 * size[0], 0.5 * size[1]])
    lo, hi = np.array([-half[0], -half[1], 0.0]), np.array([half[0], half[1], size[2]])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - a) / d, (hi - a) / d
    parallel = d == 0.0
    inside = (a >= lo) & (a <= hi)
    t_in = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)).max(axis=1)
    t_out = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=1)
    return (t_in <= t_out) & (t_out >= 0.0) & (t_in < 1.0)


def occluded_fraction(track, pose: Pose, rig: CameraRig, cars: Sequence[Pose],
                      size: tuple[float, float, float]) -> float | None:
    """Share of the ego lines' points (see the module) that the cars at `cars` (world poses, one footprint
    `size`) hide from the camera at `pose`; None where the pose is on no lane."""
    try:
        lines = ego_lines(track, pose)
    except OffMapError:
        return None
    x = np.arange(NEAR_M, FAR_M + 1e-9, STEP_M)
    pts = np.concatenate([np.column_stack([x, np.polynomial.polynomial.polyval(x, line.coeffs), np.zeros_like(x)])
                          for line in (lines.left, lines.right)])
    camera = np.array([rig.mount_x, 0.0, rig.mount_height])
    covered = np.zeros(len(pts), dtype=bool)
    for car in cars:
        local = Pose(*pose.to_local(car.x, car.y), car.yaw - pose.yaw)
        if math.hypot(local.x - rig.mount_x, local.y) <= REACH_M:
            covered |= hidden(camera, pts, local, size)
    return float(covered.mean())
