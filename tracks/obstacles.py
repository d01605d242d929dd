"""Roadside bodies as static collision boxes, chunked along the (possibly curved) edges within tiles.

Continuous bodies are split so that a straight box deviates at most ~2 cm (sagitta) from the curved edge
and never crosses a tile boundary or an intersection; trees are placed every `spacing` m with seeded
jitter. Boxes stand on z = 0.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from tracks.layout import CollisionBox, RoadsideBody

if TYPE_CHECKING:
    from tracks.road import Track

_SAGITTA = 0.02  # m, the largest gap allowed between a chunk box and the curved edge
_OVERLAP = 0.02  # m added to each chunk's half length so neighbours close up on curves
_BAND_SLACK = 0.1  # m: how far a box may reach inside its body's near face (sagitta and overlap are 0.02 each)


def road_obstacles(track: Track, tile: int | None = None) -> list[CollisionBox]:
    """Static collision boxes (curbs, barriers, guardrails, divider, trees) of the track, chunked within tiles
    (all tiles, or tile `tile`)."""
    tiles = range(track.n_tiles) if tile is None else [tile]
    boxes: list[CollisionBox] = []
    for side, edge, outer in (
        (-1.0, track.right, track.boundaries[0].t),
        (1.0, track.left, track.boundaries[-1].t),
    ):
        for b_index, body in enumerate(edge.bodies):
            t_near = outer + side * body.gap
            t_mid = t_near + side * 0.5 * body.thickness
            for i in tiles:
                s0 = i * track.tile_length
                s1 = min(s0 + track.tile_length, track.length)
                for a, b in _free_pieces(track.intersections, s0, s1):
                    if body.spacing > 0.0:
                        boxes += _discrete(track, body, t_mid, a, b, i, (b_index, int(side > 0)))
                    else:
                        boxes += _continuous(track, body, t_mid, a, b, i)
    return boxes


def clear_band(track: Track) -> tuple[float, float]:
    """The lateral band (t_lo, t_hi, m from the reference line) no roadside box of `road_obstacles` reaches into:
    each side's innermost body's near face, less `_BAND_SLACK` (a chunk's sagitta and overlap, a square's
    corners on a bend); ±inf on a side without bodies."""
    sides = []
    for side, edge, outer in ((-1.0, track.right, track.boundaries[0].t), (1.0, track.left, track.boundaries[-1].t)):
        gaps = [body.gap for body in edge.bodies]
        sides.append(outer + side * (min(gaps) - _BAND_SLACK) if gaps else side * math.inf)
    return sides[0], sides[1]


def _free_pieces(intersections: list[tuple[float, float]], s0: float, s1: float) -> list[tuple[float, float]]:
    pieces, a = [], s0
    for i0, i1 in intersections:
        if i1 <= a or i0 >= s1:
            continue
        if i0 > a:
            pieces.append((a, i0))
        a = max(a, i1)
    if a < s1:
        pieces.append((a, s1))
    return [(p, q) for p, q in pieces if q - p > 0.05]


def _continuous(
    track: Track, body: RoadsideBody, t: float, a: float, b: float, tile: int
) -> list[CollisionBox]:
    ref = track.reference
    ks = np.abs([ref.curvature_at(s) for s in np.linspace(a, b, 9)])
    k = float(np.max(ks / np.maximum(1.0 - ks * abs(t), 0.2)))
    max_len = track.tile_length if k < 1e-6 else min(track.tile_length, math.sqrt(8.0 * _SAGITTA / k))
    n = max(1, math.ceil((b - a) / max_len))
    edges = np.linspace(a, b, n + 1)
    out = []
    for c0, c1 in itertools.pairwise(edges):
        p0, p1 = np.array(ref.point(c0, t)), np.array(ref.point(c1, t))
        d = p1 - p0
        centre = 0.5 * (p0 + p1)
        out.append(
            CollisionBox(
                (float(centre[0]), float(centre[1]), 0.5 * body.height),
                (0.5 * float(np.hypot(*d)) + _OVERLAP, 0.5 * body.thickness, 0.5 * body.height),
                math.atan2(d[1], d[0]),
                body.kind,
                tile,
            )
        )
    return out


def _discrete(
    track: Track, body: RoadsideBody, t: float, a: float, b: float, tile: int, key: tuple[int, int]
) -> list[CollisionBox]:
    """Object j sits near j * spacing, jittered by a generator seeded by (track seed, body, j)."""
    out = []
    for j in range(max(0, math.floor(a / body.spacing) - 1), math.ceil(b / body.spacing) + 2):
        jitter = np.random.default_rng([track.seed, 17, *key, j]).uniform(-0.2, 0.2)
        s = (j + jitter) * body.spacing
        if not (a <= s < b and a + 0.5 * body.thickness <= s <= b - 0.5 * body.thickness):
            continue
        x, y = track.reference.point(s, t)
        half = 0.5 * body.thickness
        out.append(
            CollisionBox(
                (x, y, 0.5 * body.height),
                (half, half, 0.5 * body.height),
                track.reference.heading_at(s),
                body.kind,
                tile,
            )
        )
    return out
