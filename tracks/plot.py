"""Bird's-eye drawing of a track with matplotlib: surface, lane lines by marking kind, edges and bodies,
intersections. `draw_track` draws on a given Axes so run plots can add paths on top."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from tracks.obstacles import road_obstacles
from tracks.road import Track

BODY_STYLE = {
    "curb": ("#b9b7b0", 1.2),
    "barrier": ("#8a6d3b", 2.0),
    "guardrail": ("#5f7f9f", 1.6),
    "divider": ("#d08a2a", 2.4),
}
LINE_COLOUR = {
    "solid_white": "#ffffff",
    "dashed_white": "#ffffff",
    "solid_yellow": "#f0b400",
    "double_yellow": "#f0b400",
}
GROUND_COLOUR = {
    "grass": "#9bb98a",
    "concrete": "#d4d2cc",
    "dirt": "#b59f7f",
    "drop": "#3b2f24",
    "asphalt": "#6b6b70",
}


def _strip(track: Track, s: np.ndarray, t_a: float, t_b: float) -> np.ndarray:
    """Closed polygon of the band between lateral offsets t_a and t_b over arc lengths s."""
    return np.vstack([track.reference.points(s, t_a), track.reference.points(s[::-1], t_b)])


def _masked_line(ax: Axes, pts: np.ndarray, on: np.ndarray, **style: object) -> None:
    xy = pts.astype(float).copy()
    xy[~on] = np.nan
    ax.plot(xy[:, 0], xy[:, 1], **style)


def draw_track(ax: Axes, track: Track, s_range: tuple[float, float] | None = None, step: float = 0.5) -> None:
    """Draw `track` (or its arc-length window `s_range`) on `ax` in world coordinates (m)."""
    s0, s1 = s_range if s_range is not None else (0.0, track.length)
    s0, s1 = max(0.0, s0), min(track.length, s1)
    s = np.linspace(s0, s1, max(2, int((s1 - s0) / step) + 1))
    lo, hi = track.paved_range
    t_min, t_max = track.lateral_range
    s_fill = np.linspace(s0, s1, min(len(s), 800))
    surfaces = PolyCollection([_strip(track, s_fill, t_min, lo), _strip(track, s_fill, hi, t_max),
                               _strip(track, s_fill, lo, hi)], linewidths=0, zorder=1,
                              facecolors=[GROUND_COLOUR[track.right.ground], GROUND_COLOUR[track.left.ground],
                                          GROUND_COLOUR["asphalt"]])
    ax.add_collection(surfaces)  # one collection: a patch per polygon updates the limits segment by segment
    labelled = False
    for a, b in track.intersections:
        if b > s0 and a < s1:
            band = np.linspace(max(a, s0), min(b, s1), 20)
            ax.fill(*_strip(track, band, t_min, t_max).T, color="#6b6b70", lw=0, zorder=1)
            ax.fill(
                *_strip(track, band, t_min, t_max).T,
                facecolor="none",
                edgecolor="#c0392b",
                hatch="//",
                lw=0.8,
                zorder=4,
                label=None if labelled else "intersection",  # one legend entry for every zone
            )
            labelled = True
    for boundary in track.boundaries:
        for run in boundary.runs:
            if run.kind == "none" or run.s1 <= s0 or run.s0 >= s1:
                continue
            on = (s >= run.s0) & (s <= run.s1)
            if run.kind == "dashed_white":
                on &= np.mod(s, 12.0) < 3.0
            offsets = (-0.11, 0.11) if run.kind == "double_yellow" else (0.0,)
            for off in offsets:
                _masked_line(
                    ax,
                    track.reference.points(s, boundary.t + off),
                    on,
                    color=LINE_COLOUR[run.kind],
                    lw=0.8,
                    zorder=3,
                )
    free = np.array([not track.in_intersection(v) for v in s])
    for side, edge, outer in (
        (-1, track.right, track.boundaries[0].t),
        (1, track.left, track.boundaries[-1].t),
    ):
        if edge.kind == "drop_off":
            edge_t = lo if side < 0 else hi
            _masked_line(
                ax, track.reference.points(s, edge_t), free, color="#3b2f24", lw=2.0, ls="--", zorder=3
            )
        for body in edge.bodies:
            t_mid = outer + side * (body.gap + 0.5 * body.thickness)
            if body.spacing > 0.0:
                tiles = range(
                    int(s0 // track.tile_length), min(track.n_tiles, math.ceil(s1 / track.tile_length))
                )
                trees = [box for i in tiles for box in road_obstacles(track, i) if box.kind == body.kind]
                ax.scatter(
                    [b.center[0] for b in trees], [b.center[1] for b in trees], s=6, color="#2e7d32", zorder=4
                )
            else:
                colour, lw = BODY_STYLE[body.kind]
                _masked_line(ax, track.reference.points(s, t_mid), free, color=colour, lw=lw, zorder=3)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")


def save_track_png(track: Track, path: str | Path, s_range: tuple[float, float] | None = None) -> Path:
    """Bird's-eye PNG of the track (or a window of it)."""
    fig = Figure(figsize=(12, 9), dpi=150)
    ax = fig.subplots()
    ax.set_facecolor("#e9efe4")
    draw_track(ax, track, s_range)
    ax.set_title(f"{track.name}@{track.seed}: {track.description}", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path
