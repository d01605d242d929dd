"""Ground-truth ego lane lines from the map: the shared geometry of the oracle detector and dataset labels.

The ego lane is the lane the true pose projects onto (`map.project(pose).lane`); its right line is
boundary `lane`, its left line boundary `lane + 1`. Each line is sampled along the road ahead, taken
into the vehicle frame and fitted with a cubic y(x) over x in [0, X_MAX]. A line *exists* when it is
painted (kind other than 'none') on at least half of its samples in the camera's view window
[X_VIEW_NEAR, X_VIEW_FAR]: unmarked edges and intersections give a missing line. Given the painted road
textures (`PaintVisibility`), a line also counts as missing when wear has left less than
`VISIBLE_FRACTION` of its paint in that window standing out from the asphalt beside it: the camera cannot
see it either.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracks.map_api import OffMapError
from tracks.paint import marking_coverage
from tracks.pose import Pose
from tracks.semantic_map import TrackMap
from tracks.texture import tile_frame

X_MAX = 40.0  # m: the fitted range ahead of the reference point
X_VIEW_NEAR, X_VIEW_FAR = 5.0, 25.0  # m: where a line must be painted to count as present
SAMPLE_STEP = 1.0  # m between samples along the line
VISIBLE_CONTRAST = 0.2  # a row's mean paint over the asphalt beside it, relative, channel-averaged (fresh ≈ 1.7)
VISIBLE_FRACTION = 0.25  # of a line's painted texture rows in the view window that must keep that contrast
PAINT_BAND_M = 0.25  # |t - line| of the line's own paint (double yellow included)
ASPHALT_BAND_M = (0.3, 0.7)  # |t - line| of the bare surface either side; the darker side is the reference


class PaintVisibility:
    """How much of a lane line's paint still stands out in the painted tile textures (`texture_of(i)`, lit
    or not: the test is a ratio to the asphalt of the same texture row, so shadows and lighting cancel), row
    by row (1/25 m) where the map's marking mask says paint was laid."""

    def __init__(self, track, texture_of: Callable[[int], np.ndarray]) -> None:
        self.track = track
        self.texture_of = texture_of
        self._coverage: dict[int, np.ndarray] = {}

    def visible_fraction(self, t_line: float, s_lo: float, s_hi: float) -> float | None:
        """Fraction of the painted texture rows of the line at lateral offset `t_line` over s ∈ [s_lo, s_hi]
        whose paint is on average `VISIBLE_CONTRAST` brighter than the asphalt of the row; None where no paint
        was laid."""
        track = self.track
        first = max(0, math.floor(s_lo / track.tile_length))
        last = min(track.n_tiles - 1, math.floor(s_hi / track.tile_length))
        laid = seen = 0
        for i in range(first, last + 1):
            frame = tile_frame(track, i)
            if i not in self._coverage:
                self._coverage[i] = marking_coverage(frame)
            rows = frame.rows_between(max(s_lo, frame.s0), min(s_hi, frame.s1))
            off = frame.t_of_cols() - t_line
            band = np.abs(off) < PAINT_BAND_M
            sides = [(d * off > ASPHALT_BAND_M[0]) & (d * off < ASPHALT_BAND_M[1]) for d in (-1.0, 1.0)]
            sides = [m for m in sides if m.any()]
            if not band.any() or not sides:
                continue
            tex = self.texture_of(i)[rows].astype(np.float32)
            # the darker side is the asphalt (beyond an edge line lies a bright shoulder or kerb)
            asphalt = np.maximum(np.min([np.median(tex[:, m], axis=1) for m in sides], axis=0), 1.0)
            paint = self._coverage[i][rows][:, band] > 0.5
            n = paint.sum(axis=1)
            painted_rows = n > 0
            mean_paint = (tex[:, band] * paint[..., None]).sum(axis=1) / np.maximum(n, 1)[:, None]
            contrast = (mean_paint / asphalt).mean(axis=-1) - 1.0
            laid += int(painted_rows.sum())
            seen += int((painted_rows & (contrast >= VISIBLE_CONTRAST)).sum())
        return seen / laid if laid else None


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


def _line_truth(track, boundary_index: int, pose: Pose, s0: float,
                visibility: PaintVisibility | None = None) -> LineTruth:
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
    if exists and visibility is not None:
        seen = visibility.visible_fraction(boundary.t, float(s[view].min()), float(s[view].max()))
        exists = seen is not None and seen >= VISIBLE_FRACTION
    kind = max(set(kinds), key=kinds.count) if kinds else "none"
    return LineTruth(coeffs=coeffs, exists=exists, kind=kind)


def ego_lines(track, pose: Pose, visibility: PaintVisibility | None = None) -> EgoLines:
    """True ego lines at `pose` (existence also by visible paint when `visibility` is given); raises
    `OffMapError` when the pose is on no lane of the track."""
    if not pose.is_finite():
        raise OffMapError(f"pose {pose} is not finite")
    coord = TrackMap(track).project(pose)
    lane = coord.lane
    s0, _ = track.reference.project(pose.x, pose.y)
    return EgoLines(
        lane=lane,
        width=float(track.lanes[lane].width_at(coord.s)),
        left=_line_truth(track, lane + 1, pose, s0, visibility),
        right=_line_truth(track, lane, pose, s0, visibility),
        deviation=float(coord.l),
    )
