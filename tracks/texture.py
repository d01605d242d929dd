"""Road tiles: tile i covers reference arc length [i·L, (i+1)·L) and the whole cross section plus roadside.

Painting happens in straight (s, t) texture space; the curvature lives in the mesh. Image convention
(RGB, H×W×3 uint8): row 0 is the tile's far end (s1) and rows run backwards to s0; column 0 is its left
edge (t_max) and columns run rightwards to t_min, so the image reads like a bird's-eye view with the
direction of travel up. The mesh uv is image-relative: u = column / W, v = row / H (v = 0 at row 0).
"""

from __future__ import annotations

import math

import numpy as np

from tracks.road import Track
from tracks.tile_frame import TileFrame

MAX_TEXTURE_SIDE = 1024


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
