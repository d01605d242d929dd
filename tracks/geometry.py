"""Planar reference lines built from curvature-linear segments: straights, circular arcs and clothoids.

Every segment has curvature linear in its own arc length u, k(u) = k0 + (k1 - k0) u / L, so heading is
quadratic in u and joining a clothoid between a straight and an arc keeps curvature continuous. The
reference line is sampled densely (exact s, x, y, heading, curvature arrays, positions integrated by
Gauss-Legendre quadrature) and answers point, frame and projection queries by interpolation plus an
exact Newton refinement on the segment formulas.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from tracks.compiled import compiled_module
from tracks.pose import Pose
from tracks.recent import RecentAnswers

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(6)
_COARSE_SPACING = 5.0  # m between the samples of the global (cold) nearest-point search
_MEMO_SIZE = 16  # recent projections kept: a control tick asks about the same few points several times
_KERNEL_REACH = 1e9  # m: coordinates the compiled kernel takes (beyond, and for NaN, the pure-Python path answers)
_KERNELS = compiled_module("tracks.reference_kernels")
try:
    from numpy._core.umath import clip as _clip
except ImportError:  # numpy 1.x
    from numpy.core.umath import clip as _clip
"""The ufunc `np.clip` ends in, without its per-call argument handling: the same values, called thousands of
times a second by the vectorised point queries."""


def _cos_sin_one(h: float) -> tuple[float, float]:
    """numpy's cos and sin of `h` as a one-element array, as `ReferenceLine.points` computes them."""
    a = np.array([h])
    return float(np.cos(a)[0]), float(np.sin(a)[0])


@dataclass(frozen=True)
class Straight:
    """A straight segment of `length` metres."""

    length: float

    @property
    def k0(self) -> float:
        return 0.0

    @property
    def k1(self) -> float:
        return 0.0


@dataclass(frozen=True)
class Arc:
    """A circular arc; `radius` is signed, + turning left (counter-clockwise), - turning right."""

    radius: float
    length: float

    @property
    def k0(self) -> float:
        return 1.0 / self.radius

    @property
    def k1(self) -> float:
        return 1.0 / self.radius


@dataclass(frozen=True)
class Clothoid:
    """A clothoid (Euler spiral): curvature varies linearly from `k0` to `k1` over `length`."""

    k0: float
    k1: float
    length: float


Segment = Straight | Arc | Clothoid


def bend(radius: float, angle: float, transition: float) -> list[Segment]:
    """A curvature-continuous bend: clothoid in, arc of `radius` (signed), clothoid out; turns |angle| rad."""
    k = 1.0 / radius
    arc_angle = abs(angle) - abs(k) * transition
    if arc_angle < 0.0:
        raise ValueError(
            f"transition {transition} m too long for a {angle:.3f} rad bend of radius {radius} m"
        )
    return [Clothoid(0.0, k, transition), Arc(radius, arc_angle * abs(radius)), Clothoid(k, 0.0, transition)]


class ReferenceLine:
    """A continuous road reference line: start pose plus segments, sampled every ~`step` metres.

    Offsets t are lateral (+ left of the direction of travel); (s, t) are its Frenet coordinates.
    Beyond either end the line continues straight along the end tangent.
    """

    def __init__(self, start: Pose, segments: list[Segment], step: float = 0.5) -> None:
        if not segments:
            raise ValueError("a reference line needs at least one segment")
        self.start = start
        self.segments = list(segments)
        lengths = [float(seg.length) for seg in self.segments]
        if min(lengths) <= 0.0:
            raise ValueError("segment lengths must be positive")
        self._seg_s0 = [0.0, *np.cumsum(lengths)[:-1].tolist()]
        self._seg_k0 = [float(seg.k0) for seg in self.segments]
        self._seg_dk = [(float(seg.k1) - float(seg.k0)) / seg.length for seg in self.segments]
        self.length = float(sum(lengths))
        heading0 = [start.yaw]
        for seg, ln in zip(self.segments, lengths, strict=True):
            heading0.append(heading0[-1] + 0.5 * (seg.k0 + seg.k1) * ln)
        self._seg_h0 = heading0[:-1]
        self._seg_arrays = tuple(np.array(v, dtype=float) for v in (self._seg_s0, self._seg_h0, self._seg_k0,
                                                                      self._seg_dk))
        """The segment lists as arrays, for the vectorised formulas (converted once, not per call)."""

        n = max(1, math.ceil(self.length / step))
        self.ds = self.length / n
        self.s = np.linspace(0.0, self.length, n + 1)
        self.heading = self._heading_array(self.s)
        self.curvature = self._curvature_array(self.s)
        self.x, self.y = self._integrate_positions(self.s)
        self._xs, self._ys, self._curv = self.x.tolist(), self.y.tolist(), self.curvature.tolist()
        self._cos, self._sin = np.cos(self.heading).tolist(), np.sin(self.heading).tolist()
        self._last_sample = len(self._xs) - 1
        self._s_list = self.s.tolist()
        self._seg_coeffs = list(zip(self._seg_s0, self._seg_h0, self._seg_k0, self._seg_dk, strict=True))
        """(s0, heading, curvature, curvature rate) at the start of each segment."""
        self._coarse_stride = max(1, round(_COARSE_SPACING / self.ds))
        self._coarse_xy = np.column_stack([self.x, self.y])[:: self._coarse_stride].copy()
        self._kernel = None if _KERNELS is None else _KERNELS.LineKernel(
            np.column_stack([self.x, self.y, self._cos, self._sin, self.curvature]),
            np.array(self._seg_coeffs, dtype=float), self._coarse_xy, self._coarse_stride, self.ds, self.length,
            _MEMO_SIZE)
        """The compiled point queries and `project` with its memo (tracks/reference_kernels.pyx), where built;
        None: the pure-Python methods below answer, the reference the kernel is tested equal to."""
        self._hint: int | None = None
        self._memo: RecentAnswers[tuple[float, float, float], tuple[float, float]] = RecentAnswers(_MEMO_SIZE)

    # ---- exact segment formulas -------------------------------------------------------------
    def _seg_index(self, s: float) -> int:
        return max(0, bisect.bisect_right(self._seg_s0, s) - 1)

    def heading_at(self, s: float) -> float:
        """Heading (rad) at arc length s; constant beyond the ends."""
        if self._kernel is not None:
            return self._kernel.heading_at(s)
        return self._heading_at(s)

    def _heading_at(self, s: float) -> float:
        s = min(max(s, 0.0), self.length)
        i = self._seg_index(s)
        u = s - self._seg_s0[i]
        return self._seg_h0[i] + self._seg_k0[i] * u + 0.5 * self._seg_dk[i] * u * u

    def curvature_at(self, s: float) -> float:
        """Signed curvature (1/m, + left) at arc length s; zero beyond the ends."""
        if self._kernel is not None:
            return self._kernel.curvature_at(s)
        return self._curvature_at(s)

    def _curvature_at(self, s: float) -> float:
        if s < 0.0 or s > self.length:
            return 0.0
        i = self._seg_index(s)
        return self._seg_k0[i] + self._seg_dk[i] * (s - self._seg_s0[i])

    def _heading_array(self, s: np.ndarray) -> np.ndarray:
        s0, h0, k0, dk = self._seg_arrays
        idx = _clip(s0.searchsorted(s, side="right") - 1, 0, len(self.segments) - 1)
        u = s - s0[idx]
        return h0[idx] + k0[idx] * u + (0.5 * dk[idx] * u * u)

    def _curvature_array(self, s: np.ndarray) -> np.ndarray:
        s0, _, k0, dk = self._seg_arrays
        idx = _clip(s0.searchsorted(s, side="right") - 1, 0, len(self.segments) - 1)
        return k0[idx] + dk[idx] * (s - s0[idx])

    def _integrate_positions(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integrate cos/sin(heading) over sub-intervals split at segment joins (heading is smooth inside)."""
        knots = np.union1d(s, np.asarray([*self._seg_s0, self.length]))
        a, b = knots[:-1], knots[1:]
        half, mid = 0.5 * (b - a), 0.5 * (a + b)
        # evaluate inside each sub-interval using the segment that holds its midpoint
        nodes = mid[:, None] + half[:, None] * _GL_NODES[None, :]
        idx = np.clip(np.searchsorted(self._seg_s0, mid, side="right") - 1, 0, len(self.segments) - 1)
        u = nodes - np.asarray(self._seg_s0)[idx][:, None]
        h = (
            np.asarray(self._seg_h0)[idx][:, None]
            + np.asarray(self._seg_k0)[idx][:, None] * u
            + 0.5 * np.asarray(self._seg_dk)[idx][:, None] * u * u
        )
        dx = half * (np.cos(h) @ _GL_WEIGHTS)
        dy = half * (np.sin(h) @ _GL_WEIGHTS)
        xk = self.start.x + np.concatenate([[0.0], np.cumsum(dx)])
        yk = self.start.y + np.concatenate([[0.0], np.cumsum(dy)])
        pick = np.searchsorted(knots, s)
        return xk[pick], yk[pick]

    # ---- point queries ----------------------------------------------------------------------
    def frame(self, s: float) -> tuple[float, float, float]:
        """(x, y, heading) of the reference point at arc length s (extrapolated straight beyond the ends)."""
        if self._kernel is not None and -_KERNEL_REACH < s < _KERNEL_REACH:
            return self._kernel.frame(s)
        return self._frame(s)

    def _frame(self, s: float) -> tuple[float, float, float]:
        ds = self.ds
        sc = min(max(s, 0.0), self.length)
        i = min(int(sc / ds), self._last_sample)
        d = sc - i * ds
        s0, h0, k0, dk = self._seg_coeffs[bisect.bisect_right(self._seg_s0, sc) - 1]
        u = sc - s0
        h = h0 + k0 * u + 0.5 * dk * u * u
        um = u - 0.5 * d
        h_mid = h0 + k0 * um + 0.5 * dk * um * um if um >= 0.0 else self._heading_at(sc - 0.5 * d)
        k = self._curv[i]
        chord = d * (1.0 - k * k * d * d / 24.0)
        x = self._xs[i] + chord * math.cos(h_mid)
        y = self._ys[i] + chord * math.sin(h_mid)
        if s != sc:
            x += (s - sc) * math.cos(h)
            y += (s - sc) * math.sin(h)
        return x, y, h

    def point(self, s: float, t: float = 0.0) -> tuple[float, float]:
        """World point at arc length s and lateral offset t (+ left)."""
        x, y, h = self.frame(s)
        return x - t * math.sin(h), y + t * math.cos(h)

    def points(self, s: np.ndarray, t: float | np.ndarray = 0.0) -> np.ndarray:
        """Vectorised `point` for s in [0, length]: (N, 2) world points."""
        s = _clip(np.asarray(s, dtype=float), 0.0, self.length)
        i = np.minimum((s / self.ds).astype(int), len(self.s) - 1)
        d = s - self.s[i]
        h_mid = self._heading_array(s - 0.5 * d)
        chord = d * (1.0 - self.curvature[i] ** 2 * d * d / 24.0)
        h = self._heading_array(s)
        x = self.x[i] + chord * np.cos(h_mid) - t * np.sin(h)
        y = self.y[i] + chord * np.sin(h_mid) + t * np.cos(h)
        return np.column_stack([x, y])

    def points_one(self, s: float, t: float = 0.0) -> tuple[float, float]:
        """`points` of the one-element array [s] to the bit, for a finite s, without its array overhead: the
        same operations in the same order on Python floats, and numpy's cos and sin on one-element arrays as
        `points` calls them (the only steps whose last bit could depend on how they are computed)."""
        sc = min(max(s, 0.0), self.length)
        i = min(int(sc / self.ds), self._last_sample)
        d = sc - self._s_list[i]
        k = self._curv[i]
        chord = d * (1.0 - k * k * d * d / 24.0)
        cos_mid, sin_mid = _cos_sin_one(self._heading_at(sc - 0.5 * d))
        cos_h, sin_h = _cos_sin_one(self._heading_at(sc))
        return self._xs[i] + chord * cos_mid - t * sin_h, self._ys[i] + chord * sin_mid + t * cos_h

    # ---- projection -------------------------------------------------------------------------
    def project(self, x: float, y: float, max_offset: float = 20.0) -> tuple[float, float]:
        """Nearest-point Frenet coordinates (s, t) of a world point.

        Walks from the previous answer first (consecutive queries of a moving vehicle); when that walk does
        not settle or lands farther than `max_offset` laterally, restarts from the nearest of coarse samples
        (every ~5 m). s is then refined exactly by Newton steps on the segment formulas. s < 0 or
        s > length means the point lies beyond an end. The answers to the last few queries are kept and
        returned again for the same point.
        """
        kernel = self._kernel
        if kernel is not None:  # the memo is the kernel's; beyond its reach the Python path answers
            found = kernel.recall_project(x, y, max_offset)
            return found if found is not None else kernel.keep(x, y, max_offset, self._project(x, y, max_offset))
        found = self._memo.get((x, y, max_offset))
        return found if found is not None else self._memo.keep((x, y, max_offset), self._project(x, y, max_offset))

    def project_aside(self, x: float, y: float, max_offset: float = 20.0) -> tuple[float, float]:
        """`project` for a point off the road (one ahead of a car in a turn): the next query still walks from the
        answer before, and this one is not kept. Such a point may lie nearest another part of a route that comes
        back beside itself; walking the next query of the car from there can settle on that part."""
        kernel = self._kernel
        if kernel is not None:
            hint = kernel.hint
            found = kernel.project(x, y, max_offset)
            kernel.hint = hint
            return found
        hint = self._hint
        found = self._project(x, y, max_offset)
        self._hint = hint
        return found

    def forget(self) -> None:
        """Drop the memo of recent projections (the next one walks from the last answer)."""
        self._memo.clear()
        if self._kernel is not None:
            self._kernel.forget()

    def _project(self, x: float, y: float, max_offset: float) -> tuple[float, float]:
        if self._hint is not None:
            i, settled = self._walk(x, y, self._hint)
            if settled:
                s, t = self._canonical_refine(x, y, i)
                if abs(t) <= max_offset:
                    return s, t
        d2 = (self._coarse_xy[:, 0] - x) ** 2 + (self._coarse_xy[:, 1] - y) ** 2
        i, _ = self._walk(x, y, int(np.argmin(d2)) * self._coarse_stride)
        return self._canonical_refine(x, y, i)

    def _canonical_refine(self, x: float, y: float, i: int) -> tuple[float, float]:
        """Refine from the sample just behind the answer, so the result (to the bit) does not depend on
        the query history that produced the starting index."""
        s, t = self._refine(x, y, i)
        k = min(max(math.floor(s / self.ds), 0), self._last_sample)
        if k != i:
            s, t = self._refine(x, y, k)
        self._hint = k
        return s, t

    def _walk(self, x: float, y: float, i: int) -> tuple[int, bool]:
        """Step along the samples by the along-track distance until it stays (or bounces between two
        neighbours, which happens just outside a curve); returns (index, settled)."""
        last, previous = self._last_sample, -1
        xs, ys, cos, sin, ds = self._xs, self._ys, self._cos, self._sin, self.ds
        for _ in range(12):
            a = (x - xs[i]) * cos[i] + (y - ys[i]) * sin[i]
            j = min(max(i + math.floor(a / ds), 0), last)
            if j in (i, previous):
                return min(i, j), True
            previous, i = i, j
        return i, False

    def _refine(self, x: float, y: float, i: int) -> tuple[float, float]:
        """Exact projection near sample i: osculating-circle guess, then Newton steps on the segments."""
        c, sn = self._cos[i], self._sin[i]
        dx, dy = x - self._xs[i], y - self._ys[i]
        a, t = dx * c + dy * sn, -dx * sn + dy * c
        k = self._curv[i]
        s = i * self.ds + (math.atan2(k * a, 1.0 - k * t) / k if abs(k) > 1e-12 else a)
        for _ in range(4):
            px, py, h = self._frame(s)
            c, sn = math.cos(h), math.sin(h)
            dx, dy = x - px, y - py
            a = dx * c + dy * sn
            t = -dx * sn + dy * c
            if abs(a) < 1e-6:
                return s + a, t
            k = self._curvature_at(s)
            denom = 1.0 - k * t
            s += a / denom if denom > 0.1 else a
        return s, t
