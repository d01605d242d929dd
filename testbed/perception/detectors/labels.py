"""Ground-truth ego lane lines from the map: the shared geometry of the oracle detector and dataset labels.

The ego lane is the lane the true pose projects onto (`map.project(pose).lane`); its right line is
boundary `lane`, its left line boundary `lane + 1`. Each line is sampled along the road ahead, taken
into the vehicle frame and fitted with a cubic y(x) pinned to the line's offset and slope at x = 0 (what LD3
reads) over x in [0, X_MAX], or over a range shortened until the cubic stays within FIT_TOLERANCE of the line
(a town corner whose line turns across the car's path within X_MAX; `_range_fit`). A line *exists* when it is
painted (kind other than 'none') on at least half of its samples in the camera's view window
[X_VIEW_NEAR, X_VIEW_FAR]: unmarked edges and intersections give a missing line. Given the rendered frame
(`FrameVisibility`), a line also counts as missing unless its paint stands out against the surfaces on
both sides of it in at least `VISIBLE_FRACTION` of the image rows of that window where paint was laid:
paint worn to the asphalt, or faded to the shade of the kerb beside it, is a line the camera cannot see.
Paint stands out from a surface where their colours differ by `VISIBLE_CONTRAST` of the surface's
brightness (RGB distance over the surface's RGB norm): yellow stands out from a grey kerb by its hue.
"""

from __future__ import annotations

import math
import weakref
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PchipInterpolator

from tracks.compiled import compiled_module
from tracks.map_api import OffMapError
from tracks.paint import marking_coverage
from tracks.pose import Pose, wrap_angle
from tracks.semantic_map import TrackMap
from tracks.texture import tile_frame
from vehicles.camera_rig import CameraRig

X_MAX = 40.0  # m: the fitted range ahead of the reference point
X_VIEW_NEAR, X_VIEW_FAR = 5.0, 25.0  # m: where a line must be painted to count as present
SAMPLE_STEP = 1.0  # m between samples along the line
FIT_TOLERANCE = 0.10  # m: the most a fitted cubic may stray from the line's samples over its range
FIT_SHRINK = 0.8  # factor on the fitted range while the cubic strays more
X_FIT_MIN = 8.0  # m: the shortest fitted range ahead
VISIBLE_CONTRAST = 0.15  # RGB distance of a row's paint from a side's surface over that surface's RGB norm
# (fresh white paint, row mean in a day frame: about 1.4 over asphalt, 0.1-0.3 over a kerb)
VISIBLE_FRACTION = 0.15  # of a line's painted image rows in the view window that must show that contrast
# (noise and asphalt grain alone, paint repaved, in a night frame: about 0.12; worn fragments a viewer follows: 0.15 up)
PAINT_BAND_M = 0.25  # |offset| from the line within which its own paint lies (double yellow included)
PAINT_CORE = 0.9  # marking coverage at a pixel centre for it to show the paint (not its anti-aliased edge)
SIDE_BAND_M = (0.05, 0.25)  # beyond the outermost paint of the row: the surface beside the line, each side
_KERNELS = compiled_module("testbed.perception.detectors.label_kernels")


class PaintLayout:
    """Where lane-line paint was laid on a track: the tiles' marking coverage (`tracks.paint.marking_coverage`)
    at reference arc length s and lateral offset t, nearest texel; 0 off the tiles."""

    def __init__(self, track) -> None:
        self.track = track
        self._coverage: dict[int, np.ndarray] = {}

    def coverage(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        s, t = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(t, dtype=float))
        out = np.zeros(s.shape)
        on_road = (s >= 0.0) & (s < self.track.length)
        tile = np.where(on_road, s // self.track.tile_length, -1).astype(int)
        for i in np.unique(tile[on_road]):
            frame = tile_frame(self.track, int(i))
            if i not in self._coverage:
                self._coverage[i] = marking_coverage(frame)
            here = tile == i
            row, col = (np.floor(v).astype(int) for v in frame.pixel(s[here], t[here]))
            inside = (row >= 0) & (row < frame.height) & (col >= 0) & (col < frame.width)
            values = np.zeros(len(row))
            values[inside] = self._coverage[i][row[inside], col[inside]]
            out[here] = values
        return out


class FrameVisibility:
    """Where a lane line's paint stands out in one rendered frame (RGB, the rig's size), image row by image row.

    The ground is flat and the rig has no roll, so each image row below the horizon looks at one distance x
    ahead; at that x the line lies at a known y and each pixel of the row at a known offset from it. The row's
    paint is the mean colour of its pixels within `PAINT_BAND_M` of the line where `layout` says paint was laid
    (its core, `PAINT_CORE`); each side's surface is the median colour of the pixels `SIDE_BAND_M` beyond that
    paint. A row is judged when it shows paint and both sides."""

    def __init__(self, image: np.ndarray, rig: CameraRig, layout: PaintLayout) -> None:
        if image.shape != (rig.height, rig.width, 3):
            raise ValueError(f"frame of shape {image.shape} is not the rig's {rig.height}x{rig.width} RGB")
        self.layout = layout
        v = np.arange(rig.height, dtype=float)
        row_x = rig.pixel_to_ground(np.column_stack([np.full_like(v, 0.5 * (rig.width - 1)), v]))[:, 0]
        self.rows = np.flatnonzero((row_x >= X_VIEW_NEAR) & (row_x <= X_VIEW_FAR))
        self.row_x = row_x[self.rows]
        u = np.arange(rig.width, dtype=float)
        uv = np.column_stack([np.tile(u, len(self.rows)), np.repeat(self.rows.astype(float), rig.width)])
        self.pixel_y = rig.pixel_to_ground(uv)[:, 1].reshape(len(self.rows), rig.width)
        self.colours = image[self.rows].astype(np.float32)

    def visible_fraction(self, t_line: float, s: np.ndarray, x: np.ndarray, y: np.ndarray) -> float | None:
        """Fraction of the judged rows of the view window in which the paint of the line at lateral offset
        `t_line` stands out from both sides; None where no row is judged. The line is given by samples at arc
        lengths `s` and vehicle-frame points (`x`, `y`) covering the window."""
        order = np.argsort(x)
        x, y, s = x[order], y[order], s[order]
        on_line = (self.row_x >= x[0]) & (self.row_x <= x[-1])
        rx = self.row_x[on_line]
        if len(rx) == 0:
            return None
        heading = np.arctan(np.interp(rx, x, np.gradient(y, x)))
        dy = self.pixel_y[on_line] - np.interp(rx, x, y)[:, None]
        offset = dy * np.cos(heading)[:, None]  # across the line, + left
        along = dy * np.sin(heading)[:, None]
        band = np.abs(offset) < PAINT_BAND_M
        paint = np.zeros(offset.shape, dtype=bool)
        row_s = np.interp(rx, x, s)[:, None] + along
        paint[band] = self.layout.coverage(row_s[band], (t_line + offset)[band]) >= PAINT_CORE
        laid = paint.any(axis=1)
        if not laid.any():
            return None
        colours = self.colours[on_line]
        extent = np.where(paint, np.abs(offset), 0.0).max(axis=1, keepdims=True)
        n_paint = np.maximum(paint.sum(axis=1), 1)[:, None]
        paint_rgb = (colours * paint[..., None]).sum(axis=1) / n_paint
        seen = laid.copy()
        judged = laid.copy()
        for sign in (-1.0, 1.0):
            beyond = sign * offset - extent
            side = (beyond > SIDE_BAND_M[0]) & (beyond < SIDE_BAND_M[1]) & laid[:, None]
            shown = side.any(axis=1)
            judged &= shown
            surface = np.zeros_like(paint_rgb)
            surface[shown] = np.nanmedian(np.where(side[shown][..., None], colours[shown], np.nan), axis=1)
            diff = np.linalg.norm(paint_rgb - surface, axis=1)
            seen &= diff >= VISIBLE_CONTRAST * np.maximum(np.linalg.norm(surface, axis=1), 1.0)
        n = int(judged.sum())
        return int((seen & judged).sum()) / n if n else None


@dataclass(frozen=True)
class LineTruth:
    """One true lane line: cubic y(x) coefficients (ascending powers, vehicle frame), its existence, its
    marking kind (the most common in view, the nearest first among equals), the fraction of its judged
    rows whose paint the frame shows (None where not judged), how far ahead the fit holds (m) and the line's
    samples (x, y) in the vehicle frame, in driving order (`offsets_at`)."""

    coeffs: np.ndarray
    exists: bool
    kind: str
    visible: float | None = None
    x_far: float = X_MAX
    samples: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def offsets_at(self, xs: np.ndarray) -> np.ndarray:
        """The line's offset y (m) at each distance ahead in `xs`, where the line itself lies (interpolated
        between its samples, not the cubic, which holds only up to `x_far`): over the run of samples that leads
        away from the car from x = 0 until the line turns back (shape-preserving cubic interpolation); NaN outside
        that run."""
        xs = np.asarray(xs, dtype=float)
        if self.samples is None:
            return np.full(xs.shape, np.nan)
        x, y = self.samples
        run = _run_ahead(x)
        if run is None:
            return np.full(xs.shape, np.nan)
        first, stop = max(run[0] - 1, 0), run[1]  # from the sample behind x = 0, for the values just ahead of it
        run_x, run_y = x[first:stop], y[first:stop]
        if len(run_x) < 2:
            return np.full(xs.shape, np.nan)
        return PchipInterpolator(run_x, run_y, extrapolate=False)(xs)


@dataclass(frozen=True)
class EgoLines:
    """The true ego lane at a pose: lane index, its width, left and right lines, physical deviation D."""

    lane: int
    width: float
    left: LineTruth
    right: LineTruth
    deviation: float


class _CompiledLines:
    """A track's lane lines for the compiled line fit (testbed/perception/detectors/label_kernels.pyx): the reference
    line's kernel and sample arc lengths, and each line's marking runs as arrays with its kinds by index."""

    def __init__(self, track) -> None:
        ref = track.reference
        self.line, self.grid = ref._kernel, ref.s
        self.runs = []
        for boundary in track.boundaries:
            kinds = list(dict.fromkeys(["none", *(run.kind for run in boundary.runs)]))
            self.runs.append((np.array([run.s0 for run in boundary.runs], dtype=float),
                              np.array([run.s1 for run in boundary.runs], dtype=float),
                              np.array([kinds.index(run.kind) for run in boundary.runs], dtype=np.intp), kinds))


_COMPILED_LINES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""The `_CompiledLines` of each track asked about (kept while the track lives)."""


def _compiled_lines(track) -> _CompiledLines | None:
    """The track's compiled line fit, or None where the kernels are not built (the Python path then answers)."""
    if _KERNELS is None or track.reference._kernel is None:
        return None
    found = _COMPILED_LINES.get(track)
    if found is None:
        found = _COMPILED_LINES[track] = _CompiledLines(track)
    return found


def _line_truth(track, boundary_index: int, pose: Pose, s0: float,
                visibility: FrameVisibility | None = None) -> LineTruth:
    boundary = track.boundaries[boundary_index]
    ref = track.reference
    s = np.arange(s0 - 5.0, s0 + X_MAX * 1.5 + 5.0, SAMPLE_STEP)
    c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
    compiled = _compiled_lines(track)
    if compiled is not None:
        x, y = _KERNELS.vehicle_samples(compiled.line, compiled.grid, boundary.t, pose.x, pose.y, c, sn, s)
        at_car = _KERNELS.at_car(compiled.line, compiled.grid, boundary.t, pose.x, pose.y, pose.yaw, c, sn, s, x)
    else:
        world = ref.points(np.clip(s, 0.0, ref.length), boundary.t)
        beyond = s - np.clip(s, 0.0, ref.length)  # straight extrapolation past either end of the road
        heading_end = np.where(s > ref.length, ref.heading_at(ref.length), ref.heading_at(0.0))
        world = world + beyond[:, None] * np.column_stack([np.cos(heading_end), np.sin(heading_end)])
        dx, dy = world[:, 0] - pose.x, world[:, 1] - pose.y
        x, y = c * dx + sn * dy, -sn * dx + c * dy
        at_car = _at_car(ref, boundary.t, pose, s, x)
    if at_car is None and np.count_nonzero((x >= -2.0) & (x <= X_MAX + 2.0)) < 4:
        # the car faces away from the line (turned across the road): nothing in view to fit
        return LineTruth(coeffs=np.full(4, np.nan), exists=False, kind="none", samples=(x, y))
    if compiled is not None and at_car is not None:
        coeffs, x_far, fit = _KERNELS.range_fit(x, y, at_car[0], at_car[1])
        run_s0, run_s1, run_kind, names = compiled.runs[boundary_index]
        seen_n, painted, best = _KERNELS.view_kinds(s, x, run_s0, run_s1, run_kind, 0, len(names))
        exists = seen_n > 0 and painted >= 0.5 * seen_n
        kind = names[best] if seen_n else "none"
    else:
        coeffs, x_far, fit = _range_fit(x, y, at_car)
        view = (x >= X_VIEW_NEAR) & (x <= X_VIEW_FAR)
        kinds = [boundary.kind_at(float(si)) for si in s[view]]
        painted = sum(k != "none" for k in kinds)
        exists = bool(kinds) and painted >= 0.5 * len(kinds)
        kind = Counter(kinds).most_common(1)[0][0] if kinds else "none"
    seen = None
    if exists and visibility is not None:
        seen = visibility.visible_fraction(boundary.t, s[fit], x[fit], y[fit])
        exists = seen is not None and seen >= VISIBLE_FRACTION
    return LineTruth(coeffs=coeffs, exists=exists, kind=kind, visible=seen, x_far=x_far, samples=(x, y))


def _at_car(ref, t: float, pose: Pose, s: np.ndarray, x: np.ndarray) -> tuple[float, float] | None:
    """(offset y, slope dy/dx) at x = 0 of the line at lateral offset `t` of reference line `ref`, in the frame of
    `pose`, from its samples at arc lengths `s` (vehicle-frame x); None where the line does not cross x = 0 on
    the road beside the car. The crossing is found by Newton's method on x(s); the slope is the line's heading
    there (offset lines run parallel to the reference line)."""
    inside = (s >= 0.0) & (s <= ref.length)
    cross = np.flatnonzero(inside[:-1] & inside[1:] & (x[:-1] <= 0.0) & (x[1:] > 0.0))
    if not len(cross):
        return None
    i = cross[0]
    si = float(s[i] + (s[i + 1] - s[i]) * (0.0 - x[i]) / (x[i + 1] - x[i]))
    c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
    for _ in range(3):
        px, py = ref.points_one(si, t)
        xi = c * (px - pose.x) + sn * (py - pose.y)
        rel = wrap_angle(ref.heading_at(si) - pose.yaw)
        si = min(max(si - xi / max(math.cos(rel), 0.1), 0.0), ref.length)
    px, py = ref.points_one(si, t)
    rel = wrap_angle(ref.heading_at(si) - pose.yaw)
    if abs(rel) >= 0.5 * math.pi - 0.05:
        return None
    return -sn * (px - pose.x) + c * (py - pose.y), math.tan(rel)


def _range_fit(x: np.ndarray, y: np.ndarray, at_car: tuple[float, float] | None
               ) -> tuple[np.ndarray, float, np.ndarray]:
    """(cubic coefficients, range ahead x_far, mask of the samples fitted) of a line sampled in driving order at
    vehicle-frame points (x, y): the cubic through the line's offset and slope at x = 0 (`at_car`) whose x², x³
    terms fit the samples over x in [0, x_far] up to where x stops growing, x_far the largest of
    X_MAX·FIT_SHRINK^k (down to X_FIT_MIN) within FIT_TOLERANCE of them; the least-squares cubic over
    [−2, X_MAX + 2] where the line does not cross x = 0 beside the car."""
    if at_car is None:
        fit = (x >= -2.0) & (x <= X_MAX + 2.0)
        return np.polynomial.polynomial.polyfit(x[fit], y[fit], 3), X_MAX, fit
    ahead = np.ones(len(x), dtype=bool)
    run = _run_ahead(x)
    if run is not None:
        ahead[run[1]:] = False
    y0, slope = at_car
    x_far = X_MAX
    while True:
        fit = ahead & (x >= 0.0) & (x <= x_far)
        xs = x[fit]
        rest = (np.linalg.lstsq(np.column_stack([xs**2, xs**3]), y[fit] - y0 - slope * xs, rcond=None)[0]
                if len(xs) >= 2 else np.zeros(2))
        coeffs = np.array([y0, slope, *rest])
        if _stray(coeffs, xs, y[fit]) <= FIT_TOLERANCE or x_far * FIT_SHRINK < X_FIT_MIN:
            return coeffs, x_far, fit
        x_far *= FIT_SHRINK


def _run_ahead(x: np.ndarray) -> tuple[int, int] | None:
    """(start, stop) of the samples of a line sampled in driving order that lead away from the car: from the first at
    x ≥ 0 up to the last before x stops growing (the line turns back across the car's path); None when none is
    ahead."""
    started = np.flatnonzero(x >= 0.0)
    if not len(started):
        return None
    start = int(started[0])
    turned = np.flatnonzero(np.diff(x[start:]) <= 0.0)
    return start, start + int(turned[0]) + 1 if len(turned) else len(x)


def _stray(coeffs: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    return float(np.max(np.abs(np.polynomial.polynomial.polyval(x, coeffs) - y))) if len(x) else 0.0


def ego_lines(track, pose: Pose, visibility: FrameVisibility | None = None) -> EgoLines:
    """True ego lines at `pose` (existence also by paint visible in the frame rendered there when `visibility`
    is given); raises `OffMapError` when the pose is on no lane of the track."""
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
