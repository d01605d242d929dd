"""Where a detected lane line's offset at the car is evidence: the lines' model against the map's lane ahead.

A detector reports each line as a polynomial y(x) fitted to what it sees ahead (`LaneDetection`), and Alg. 3
reads its value at x = 0, an extrapolation back from the nearest ground in view. Where the lane turns sharply
within the view (a town corner of radius about 10 m a few metres ahead) the line is no low-order y(x) and that
extrapolation is metres off while the car is centred. `line_model_error` measures it on the map: the ego lane's
line is walked ahead of a pose, taken into the pose's frame, kept while it runs within `VIEW_ANGLE` of the car's
heading, fitted over [`VIEW_NEAR`, the detection's far x] by the polynomial of `MODEL_DEGREE` (samples weighed
1/x², as a camera's image rows thin out with distance), and the fit's value at x = 0 is compared with the line's own
offset there. `followable_lines` withholds a line whose error exceeds a tolerance (a line that leaves the view
before `MIN_SAMPLES` samples counts as unbounded error; one the map ends before is kept: the map shows nothing to
judge it by); it never changes a line it keeps. The pose is the caller's to choose: LD3 passes its dead-reckoned
pose, one no MSF attacker moves.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from testbed.lane_detection import LaneDetection
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle

VIEW_NEAR = 5.0
"""Nearest ground ahead a front camera sees the road at (m; the bonnet hides the rest): the fit starts there."""
VIEW_ANGLE = math.pi / 4
"""A line is followed ahead while its heading is within this of the car's (rad): beyond, it runs more across the
view than along it and is no longer a y(x) a row-by-row detector reads."""
MODEL_DEGREE = 2
"""The lines' model: a quadratic, what the shipped detector's cubic is while its prior holds c3 near 0; a freer
detector follows more, so this test withholds no fewer lines than such a detector needs."""
WALK_STEP = 1.0
"""Lane length between the samples of a line (m)."""
MIN_SAMPLES = MODEL_DEGREE + 2
"""Fewest samples in view for a fit; a line seen over fewer is not followable."""


def _walk(smap: SemanticMap, pose: Pose, lane: int, x_far: float) -> tuple[np.ndarray, bool]:
    """Rows (x, y, heading, width) of the lane centre from the station of `pose` forward every `WALK_STEP`, while
    within `VIEW_ANGLE` of the pose's heading and up to `x_far` plus a lane width ahead, and whether the map ended
    first."""
    rows = []
    point, heading = smap.lane_point(pose, lane)
    width = float(smap.lane_width(pose, lane))
    limit = x_far + width + WALK_STEP
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    while abs(wrap_angle(heading - pose.yaw)) <= VIEW_ANGLE:
        rows.append((float(point[0]), float(point[1]), heading, width))
        if (point[0] - pose.x) * c + (point[1] - pose.y) * s > limit:
            break
        step = Pose(float(point[0]) + WALK_STEP * math.cos(heading), float(point[1]) + WALK_STEP * math.sin(heading),
                    heading)
        try:
            point, heading = smap.lane_point(step, lane)
            width = float(smap.lane_width(step, lane))
        except OffMapError:
            return np.array(rows, dtype=float).reshape(-1, 4), True
    return np.array(rows, dtype=float).reshape(-1, 4), False


def line_model_error(smap: SemanticMap, pose: Pose, lane: int, x_far: float) -> tuple[float, float]:
    """(left, right): how far the lines' model, fitted to the map's line of `lane` as seen from `pose` over
    [VIEW_NEAR, x_far], puts the line at x = 0 from where it is (m); inf for a line in view over too few samples
    (0 where the map ends first). OffMapError when the map cannot place `pose` on `lane`."""
    rows, ended = _walk(smap, pose, lane, x_far)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    errors = []
    for side in (1.0, -1.0):
        half = side * rows[:, 3] / 2.0
        gx = rows[:, 0] - half * np.sin(rows[:, 2]) - pose.x
        gy = rows[:, 1] + half * np.cos(rows[:, 2]) - pose.y
        x, y = c * gx + s * gy, -s * gx + c * gy
        seen = (x >= VIEW_NEAR) & (x <= x_far)
        if int(seen.sum()) < MIN_SAMPLES:
            errors.append(0.0 if ended else math.inf)
            continue
        at_car = y[0] - x[0] * math.tan(wrap_angle(rows[0, 2] - pose.yaw))
        fit = np.polynomial.polynomial.polyfit(x[seen], y[seen], MODEL_DEGREE, w=1.0 / x[seen])
        errors.append(abs(float(fit[0]) - at_car))
    return errors[0], errors[1]


def followable_lines(ld: LaneDetection, smap: SemanticMap, pose: Pose, lane: int,
                     tol: float) -> tuple[LaneDetection, list[str]]:
    """`ld` less each present line whose model error from `pose` exceeds `tol` (m), and the withheld sides with
    their errors ("left 1.42 m"); `ld` itself when none is. OffMapError when the map cannot place `pose`."""
    if ld.left is None and ld.right is None:
        return ld, []
    x_far = ld.x_range[1]
    left, right = line_model_error(smap, pose, lane, x_far)
    withheld, changes = [], {}
    for name, coeffs, error in (("left", ld.left, left), ("right", ld.right, right)):
        if coeffs is not None and not error <= tol:
            withheld.append(f"{name} {error:.2f} m")
            changes |= {name: None, f"{name}_prob": 0.0, f"{name}_var": None}
    return (dataclasses.replace(ld, **changes) if changes else ld), withheld
