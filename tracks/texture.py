"""Road tiles: tile i covers reference arc length [i·L, (i+1)·L) and the whole cross section plus roadside.

Painting happens in straight (s, t) texture space; the curvature lives in the mesh. Image convention
(RGB, H×W×3 uint8): row 0 is the tile's far end (s1) and rows run backwards to s0; column 0 is its left
edge (t_max) and columns run rightwards to t_min, so the image reads like a bird's-eye view with the
direction of travel up. The mesh uv is image-relative: u = column / W, v = row / H (v = 0 at row 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from tracks.road import Track

MAX_TEXTURE_SIDE = 1024


@dataclass(frozen=True)
class TileFrame:
    """Texture-space frame of one tile: its (s, t) rectangle, pixel grid and the track it belongs to."""

    index: int
    s0: float
    s1: float
    t_min: float
    t_max: float
    height: int
    width: int
    track: Track

    @property
    def px_per_m_s(self) -> float:
        return self.height / (self.s1 - self.s0)

    @property
    def px_per_m_t(self) -> float:
        return self.width / (self.t_max - self.t_min)

    def s_of_rows(self) -> np.ndarray:
        """Arc length at each row centre, shape (H,)."""
        return self.s1 - (np.arange(self.height) + 0.5) / self.px_per_m_s

    def t_of_cols(self) -> np.ndarray:
        """Lateral offset at each column centre, shape (W,)."""
        return self.t_max - (np.arange(self.width) + 0.5) / self.px_per_m_t

    def pixel(self, s: float, t: float) -> tuple[float, float]:
        """Fractional (row, col) of the point (s, t); pixel centres sit at integer + 0.5."""
        return (self.s1 - s) * self.px_per_m_s, (self.t_max - t) * self.px_per_m_t

    def rows_between(self, s_a: float, s_b: float) -> slice:
        """Rows whose centres lie in s ∈ [s_a, s_b] (clipped to the tile)."""
        r0 = math.ceil((self.s1 - max(s_a, s_b)) * self.px_per_m_s - 0.5)
        r1 = math.floor((self.s1 - min(s_a, s_b)) * self.px_per_m_s - 0.5) + 1
        return slice(min(max(r0, 0), self.height), min(max(r1, 0), self.height))

    def cols_between(self, t_a: float, t_b: float) -> slice:
        """Columns whose centres lie in t ∈ [t_a, t_b] (clipped to the tile)."""
        c0 = math.ceil((self.t_max - max(t_a, t_b)) * self.px_per_m_t - 0.5)
        c1 = math.floor((self.t_max - min(t_a, t_b)) * self.px_per_m_t - 0.5) + 1
        return slice(min(max(c0, 0), self.width), min(max(c1, 0), self.width))


class Painter(Protocol):
    """Paints into a tile image in place; all randomness comes from `rng` (or from the track seed)."""

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None: ...


def tile_frame(track: Track, i: int) -> TileFrame:
    if not 0 <= i < track.n_tiles:
        raise IndexError(f"tile {i} out of range 0..{track.n_tiles - 1}")
    s0 = i * track.tile_length
    s1 = min(s0 + track.tile_length, track.length)
    t_min, t_max = track.lateral_range
    height = min(MAX_TEXTURE_SIDE, max(1, round((s1 - s0) * track.px_per_m)))
    width = min(MAX_TEXTURE_SIDE, max(1, round((t_max - t_min) * track.px_per_m)))
    return TileFrame(i, s0, s1, t_min, t_max, height, width, track)


def tile_texture(track: Track, i: int, rng: np.random.Generator | None = None) -> np.ndarray:
    """Paint tile i (H×W×3 uint8 RGB) with the track's painters; the default rng is seeded by (track seed, i):
    repeatable."""
    rng = np.random.default_rng([track.seed, i]) if rng is None else rng
    frame = tile_frame(track, i)
    img = np.zeros((frame.height, frame.width, 3), dtype=np.uint8)
    for painter in track.painters:
        painter.paint(img, frame, rng)
    return img


def tile_mesh(track: Track, i: int, spacing: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strip mesh of tile i at z = 0 (rows about `spacing` m apart along the road; a cross-section is a
    straight line, so each row has just its two ends), uvs per the module convention, triangle-list
    indices wound counter-clockwise seen from above (normals +z). Few triangles keep TinyRenderer fast."""
    f = tile_frame(track, i)
    s = np.linspace(f.s0, f.s1, max(2, math.ceil((f.s1 - f.s0) / spacing) + 1))
    t = np.array([f.t_min, f.t_max])
    ss, tt = np.meshgrid(s, t, indexing="ij")
    xy = track.reference.points(ss.ravel(), tt.ravel())
    vertices = np.column_stack([xy, np.zeros(len(xy))])
    uvs = np.column_stack([(f.t_max - tt.ravel()) / (f.t_max - f.t_min), (f.s1 - ss.ravel()) / (f.s1 - f.s0)])
    n_t = len(t)
    a = (np.arange(len(s) - 1)[:, None] * n_t + np.arange(n_t - 1)[None, :]).ravel()
    b, c, d = a + n_t, a + n_t + 1, a + 1  # (s+1, t), (s+1, t+1), (s, t+1)
    indices = np.column_stack([a, b, c, a, c, d]).ravel()
    return vertices, uvs, indices.astype(np.int32)
