"""Ground-truth ego lane lines from the map: the shared geometry of the oracle detector and dataset labels.

The ego lane is the lane the true pose projects onto (`map.project(pose).lane`); its right line is
boundary `lane`, its left line boundary `lane + 1`. Each line is sampled along the road ahead, taken
into the vehicle frame and fitted with a cubic y(x) over x in [0, X_MAX]. A line *exists* when it is
painted (kind other than 'none') on at least half of its samples in the camera's view window
[X_VIEW_NEAR, X_VIEW_FAR]: unmarked edges and intersections give a missing line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracks.map_api import OffMapError
from tracks.pose import Pose

X_MAX = 40.0  # m: the fitted range ahead of the reference point
X_VIEW_NEAR, X_VIEW_FAR = 5.0, 25.0  # m: where a line must be painted to count as present
SAMPLE_STEP = 1.0  # m between samples along the line


@dataclass(frozen=True)
class LineTruth:
    """One true lane line: cubic y(x) coefficients (ascending powers, vehicle frame) and its existence."""

    coeffs: np.ndarray
    exists: bool
    kind: str


@dataclass(frozen=True)
class EgoLines:
    """The true ego lane at a pose: lane index, its width, left and right lines, physical deviation D."""

    lane: int
    width: float
    left: LineTruth
    right: LineTruth
    deviation: float


def _line_truth(track, boundary_index: int, pose: Pose, s0: float) -> LineTruth:
    boundary = track.boundaries[boundary_index]
    ref = track.reference
    s = np.arange(s0 - 5.0, s0 + X_MAX * 1.5 + 5.0, SAMPLE_STEP)
    world = ref.points(np.clip(s, 0.0, ref.length), boundary.t)
    beyond = s - np.clip(s, 0.0, ref.length)  # straight extrapolation past either end of the road
    heading_end = np.where(s > ref.length, ref.heading_at(ref.length), ref.heading_at(0.0))
    world = world + beyond[:, None] * np.column_stack([np.cos(heading_end), np.sin(heading_end)])
    c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
    dx, dy = world[:, 0] - pose.x, world[:, 1] - pose.y
    x, y = c * dx + sn * dy, -sn * dx + c * dy
    fit = (x >= -2.0) & (x <= X_MAX + 2.0)
    coeffs = np.polynomial.polynomial.polyfit(x[fit], y[fit], 3)
    view = (x >= X_VIEW_NEAR) & (x <= X_VIEW_FAR)
    kinds = [boundary.kind_at(float(si)) for si in s[view]]
    painted = sum(k != "none" for k in kinds)
    exists = bool(kinds) and painted >= 0.5 * len(kinds)
    kind = max(set(kinds), key=kinds.count) if kinds else "none"
    return LineTruth(coeffs=coeffs, exists=exists, kind=kind)


def ego_lines(track, pose: Pose) -> EgoLines:
    """True ego lines at `pose`; raises `OffMapError` when the pose is on no lane of the track."""
    if not pose.is_finite():
        raise OffMapError(f"pose {pose} is not finite")
    coord = track.map.project(pose)
    lane = coord.lane
    s0, _ = track.reference.project(pose.x, pose.y)
    return EgoLines(
        lane=lane,
        width=float(track.lanes[lane].width_at(coord.s)),
        left=_line_truth(track, lane + 1, pose, s0),
        right=_line_truth(track, lane, pose, s0),
        deviation=float(coord.l),
    )
