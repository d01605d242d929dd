"""A road tile's texture-space frame and the painters that paint it: what a painter reads of the road
(`PaintedRoad`, which `tracks.road.Track` provides) and the pixel grid of one tile (`TileFrame`).

Image convention (RGB, H×W×3 uint8): row 0 is the tile's far end (s1) and rows run backwards to s0; column 0 is
its left edge (t_max) and columns run rightwards to t_min (`tracks.texture` builds the frames and the meshes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from tracks.layout import Boundary, Edge


class PaintedRoad(Protocol):
    """What a painter reads of the road it paints: the seed of its large-scale fields, the lane lines, the two
    edges, the paved cross section and where intersections are."""

    seed: int
    boundaries: list[Boundary]
    right: Edge
    left: Edge

    @property
    def paved_range(self) -> tuple[float, float]: ...

    def in_intersection(self, s: float) -> bool: ...


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
    track: PaintedRoad

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
