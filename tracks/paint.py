"""Procedural painters for road tiles (the `tracks.tile_frame.Painter` protocol), applied in order to an RGB image.

Large-scale fields (asphalt tone, wear blotches, shadow placement) are functions of global (s, t) seeded
by the track seed, so they run on seamlessly across tile borders; per-pixel grain comes from the tile rng.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tracks.compiled import compiled_module
from tracks.tile_frame import TileFrame

ASPHALT = (86.0, 86.0, 90.0)
GROUND_COLOURS = {
    "grass": (72.0, 104.0, 52.0),
    "concrete": (158.0, 157.0, 150.0),
    "dirt": (112.0, 92.0, 66.0),
    "drop": (40.0, 34.0, 28.0),
    "asphalt": ASPHALT,
}
BODY_COLOURS = {
    "curb": (185.0, 183.0, 176.0),
    "divider": (176.0, 172.0, 160.0),
    "barrier": (176.0, 172.0, 160.0),
}
WHITE = (236.0, 236.0, 230.0)
YELLOW = (232.0, 182.0, 42.0)
_KERNELS = compiled_module("tracks.paint_kernels")


class NoiseRows(NamedTuple):
    """`value_noise` before its interpolation along s: the noise at each lattice row interpolated across t
    (`along_t`, float32 (lattice rows, W)), and each image row's lattice row below it (`row`) and smoothstep
    weight of the one above (`weight`, float32)."""

    along_t: np.ndarray
    row: np.ndarray
    weight: np.ndarray


def noise_rows(frame: TileFrame, cell: float, salt: int) -> NoiseRows:
    """`value_noise(frame, cell, salt)` up to its last step, the interpolation along s."""
    s, t = frame.s_of_rows() / cell, (frame.t_of_cols() - frame.t_min) / cell
    k0, k1 = math.floor(s.min()), math.floor(s.max()) + 1
    n_cols = math.floor(t.max()) + 2
    lattice = np.stack(
        [np.random.default_rng([frame.track.seed, salt, k]).random(n_cols) for k in range(k0, k1 + 1)]
    )
    ks, ms = np.floor(s).astype(int), np.floor(t).astype(int)
    fs, ft = s - ks, t - ms
    fs, ft = fs * fs * (3 - 2 * fs), ft * ft * (3 - 2 * ft)
    along_t = (lattice[:, ms] * (1 - ft) + lattice[:, ms + 1] * ft).astype(np.float32)  # separable: t first
    return NoiseRows(along_t, ks - k0, fs.astype(np.float32))


def value_noise(frame: TileFrame, cell: float, salt: int) -> np.ndarray:
    """Smooth noise in [0, 1] over global (s, t) on a `cell`-metre lattice, seeded by (track seed, salt)."""
    along_t, r, weight = noise_rows(frame, cell, salt)
    w = weight[:, None]
    return along_t[r] * (1 - w) + along_t[r + 1] * w


def _blend(img: np.ndarray, colour: np.ndarray | tuple[float, ...], alpha: np.ndarray) -> None:
    a = alpha[..., None]
    img[:] = np.clip(img * (1.0 - a) + np.asarray(colour, dtype=float) * a + 0.5, 0, 255).astype(np.uint8)


def _band(x: np.ndarray, lo: float, hi: float, px_per_m: float) -> np.ndarray:
    """Anti-aliased coverage of [lo, hi] sampled at pixel centres x (1 inside, ramps over one pixel)."""
    return np.clip(np.minimum(x - lo, hi - x) * px_per_m + 0.5, 0.0, 1.0)


class AsphaltPainter:
    """Base layer: asphalt with seeded grain and large-scale tone over the paved surface (the whole tile
    width in intersections), roadside ground beyond the edges and the tops of curbs and dividers. Its per-pixel
    layer runs in `tracks.paint_kernels` where that is built (the same bytes), else in numpy (the reference)."""

    def __init__(self, tone: float = 1.0, grain: float = 7.0, tone_variation: float = 0.10) -> None:
        self.tone, self.grain, self.tone_variation = tone, grain, tone_variation

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        track = frame.track
        t = frame.t_of_cols()
        lo, hi = track.paved_range
        ground = np.empty((frame.width, 3))
        ground[:] = np.asarray(ASPHALT) * self.tone
        ground[t < lo] = GROUND_COLOURS[track.right.ground]
        ground[t > hi] = GROUND_COLOURS[track.left.ground]
        for side, edge, outer in (
            (-1, track.right, track.boundaries[0].t),
            (1, track.left, track.boundaries[-1].t),
        ):
            for body in edge.bodies:
                if body.kind in BODY_COLOURS and body.spacing == 0.0:
                    near, far = outer + side * body.gap, outer + side * (body.gap + body.thickness)
                    ground[(t >= min(near, far)) & (t <= max(near, far))] = BODY_COLOURS[body.kind]
        s = frame.s_of_rows()
        crossing = np.array([track.in_intersection(v) for v in s])
        if _KERNELS is not None:
            noise = noise_rows(frame, 2.0, 31)
            normal = rng.standard_normal((frame.height, frame.width), dtype=np.float32)
            _KERNELS.asphalt(ground.astype(np.float32), crossing.view(np.uint8),
                           (np.asarray(ASPHALT) * self.tone).astype(np.float32), np.ascontiguousarray(noise.along_t),
                           noise.row.astype(np.int32), noise.weight, self.tone_variation, normal, self.grain, img)
            return
        layer = np.broadcast_to(ground.astype(np.float32), (frame.height, frame.width, 3)).copy()
        layer[crossing] = np.asarray(ASPHALT) * self.tone
        tone = 1.0 + np.float32(self.tone_variation) * (2.0 * value_noise(frame, 2.0, 31) - 1.0)
        grain = rng.standard_normal((frame.height, frame.width), dtype=np.float32) * np.float32(self.grain)
        layer *= tone[..., None]
        layer += (grain + np.float32(0.5))[..., None]
        img[:] = np.clip(layer, 0, 255, out=layer).astype(np.uint8)


class Stroke(NamedTuple):
    """One painted marking stroke: its coverage `alpha` in [0, 1] over image block [rows, cols]."""

    rows: slice
    cols: slice
    alpha: np.ndarray
    colour: tuple[float, float, float]


def marking_strokes(
    frame: TileFrame, width: float = 0.15, dash: tuple[float, float] = (3.0, 9.0), double_gap: float = 0.10
) -> list[Stroke]:
    """Every lane-line marking stroke in the tile (anti-aliased coverage blocks and paint colours)."""
    s, t = frame.s_of_rows(), frame.t_of_cols()
    out = []
    for boundary in frame.track.boundaries:
        for run in boundary.runs:
            if run.kind == "none" or run.s1 <= frame.s0 or run.s0 >= frame.s1:
                continue
            along = _band(s, run.s0, run.s1, frame.px_per_m_s)
            if run.kind == "dashed_white":
                along = along * _band(np.mod(s, dash[0] + dash[1]), 0.0, dash[0], frame.px_per_m_s)
            if run.kind == "double_yellow":
                w = 0.8 * width
                off = 0.5 * (double_gap + w)
                lines = [(boundary.t - off, w), (boundary.t + off, w)]
            else:
                lines = [(boundary.t, width)]
            colour = YELLOW if "yellow" in run.kind else WHITE
            rows = frame.rows_between(run.s0 - 0.1, run.s1 + 0.1)
            for centre, w in lines:
                cols = frame.cols_between(centre - 0.5 * w - 0.1, centre + 0.5 * w + 0.1)
                across = _band(t[cols], centre - 0.5 * w, centre + 0.5 * w, frame.px_per_m_t)
                if rows.start < rows.stop and cols.start < cols.stop:
                    out.append(Stroke(rows, cols, along[rows, None] * across[None, :], colour))
    return out


def marking_coverage(frame: TileFrame) -> np.ndarray:
    """Union coverage (H×W in [0, 1]) of all lane-line markings in the tile."""
    cover = np.zeros((frame.height, frame.width))
    for stroke in marking_strokes(frame):
        block = cover[stroke.rows, stroke.cols]
        np.maximum(block, stroke.alpha, out=block)
    return cover


class MarkingPainter:
    """Lane-line paint: solid and dashed (3 m on, 9 m off) white, solid and double yellow, ~0.15 m wide,
    with slight per-pixel paint-density noise."""

    def __init__(
        self,
        width: float = 0.15,
        dash: tuple[float, float] = (3.0, 9.0),
        double_gap: float = 0.10,
        paint_noise: float = 0.08,
    ) -> None:
        self.width, self.dash, self.double_gap, self.paint_noise = width, dash, double_gap, paint_noise

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        for stroke in marking_strokes(frame, self.width, self.dash, self.double_gap):
            density = 1.0 - self.paint_noise * rng.random(stroke.alpha.shape)
            block = img[stroke.rows, stroke.cols]
            _blend(block, stroke.colour, stroke.alpha * density)
            img[stroke.rows, stroke.cols] = block


class WearPainter:
    """Worn lane lines: paint faded towards the surrounding asphalt by `amount` in [0, 1], in blotches,
    with fully broken gaps that grow with the amount. Run it after `MarkingPainter`."""

    def __init__(self, amount: float) -> None:
        if not 0.0 <= amount <= 1.0:
            raise ValueError("wear amount must lie in [0, 1]")
        self.amount = amount

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        cover = marking_coverage(frame)
        if self.amount == 0.0 or not cover.any():
            return
        lo, hi = frame.track.paved_range
        t = frame.t_of_cols()
        bare = img[:, (t > lo) & (t < hi)][cover[:, (t > lo) & (t < hi)] == 0.0]
        base = np.median(bare, axis=0) if len(bare) else np.asarray(ASPHALT)
        blotch = value_noise(frame, 0.4, 41)
        fade = np.clip(1.3 * self.amount + 1.2 * (blotch - 0.5), 0.0, 1.0)
        fade[value_noise(frame, 1.5, 43) < 0.6 * self.amount] = 1.0
        asphalt = base[None, None, :] + rng.normal(0.0, 6.0, (frame.height, frame.width))[..., None]
        a = (fade * cover)[..., None]
        img[:] = np.clip(img * (1.0 - a) + asphalt * a + 0.5, 0, 255).astype(np.uint8)


class ShadowPainter:
    """Soft-edged shadow bands (trees, poles, buildings) lying across the road at a skew; about `per_100m`
    shadows per 100 m, each darkening by up to `darkness`. Placement is seeded by (track seed, salt)."""

    _SLOT = 10.0  # m; each slot holds at most one shadow, decided by its own seeded generator

    def __init__(self, darkness: float = 0.55, per_100m: float = 4.0, salt: int = 0) -> None:
        self.darkness, self.per_100m, self.salt = darkness, per_100m, salt

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        s, t = frame.s_of_rows(), frame.t_of_cols()
        shade = np.zeros((frame.height, frame.width))
        for k in range(
            max(0, math.floor((frame.s0 - 20.0) / self._SLOT)), math.floor(frame.s1 / self._SLOT) + 1
        ):
            g = np.random.default_rng([frame.track.seed, 53, self.salt, k])
            if g.random() >= self.per_100m * self._SLOT / 100.0:
                continue
            start, length = (k + g.random()) * self._SLOT, g.uniform(1.5, 6.0)
            t_lo = g.uniform(frame.t_min, frame.t_max - 3.0)
            t_hi = g.uniform(t_lo + 3.0, frame.t_max)
            skew = math.tan(g.uniform(-0.6, 0.6))
            strength = self.darkness * g.uniform(0.7, 1.0)
            along = s[:, None] - (t[None, :] - t_lo) * skew
            a = _band(along, start, start + length, 4.0) * _band(t, t_lo, t_hi, 4.0)[None, :]
            np.maximum(shade, strength * a, out=shade)
        if shade.any():
            img[:] = np.clip(img * (1.0 - shade[..., None]) + 0.5, 0, 255).astype(np.uint8)


class PatchPainter:
    """A dirty road patch: a soft-edged rectangle `length` × `width` m centred at (s_center, t_center), its
    long axis turned `angle` rad from +s towards +t, blended towards dark grime by up to `darkness`."""

    GRIME = (38.0, 33.0, 28.0)
    FEATHER = 0.10  # m

    def __init__(
        self,
        s_center: float,
        t_center: float,
        length: float,
        width: float,
        angle: float = 0.0,
        darkness: float = 0.6,
    ) -> None:
        self.s_center, self.t_center = s_center, t_center
        self.length, self.width, self.angle, self.darkness = length, width, angle, darkness

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        reach = 0.5 * math.hypot(self.length, self.width)
        rows = frame.rows_between(self.s_center - reach, self.s_center + reach)
        cols = frame.cols_between(self.t_center - reach, self.t_center + reach)
        if rows.start >= rows.stop or cols.start >= cols.stop:
            return
        ds = frame.s_of_rows()[rows][:, None] - self.s_center
        dt = frame.t_of_cols()[cols][None, :] - self.t_center
        c, sn = math.cos(self.angle), math.sin(self.angle)
        u, v = ds * c + dt * sn, -ds * sn + dt * c
        inside = np.clip((0.5 * self.length - np.abs(u)) / self.FEATHER, 0.0, 1.0) * np.clip(
            (0.5 * self.width - np.abs(v)) / self.FEATHER, 0.0, 1.0
        )
        grime = self.darkness * (0.8 + 0.2 * rng.random(inside.shape))
        region = img[rows, cols]
        _blend(region, self.GRIME, inside * grime)
        img[rows, cols] = region
