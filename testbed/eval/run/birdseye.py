"""birdseye.png of a run: the road seen from above with the true and believed paths, the traffic cars' paths
and the attack start, detection and stop points; the deviations against time; and the detector's statistic
against its threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from testbed.eval.run.consequence import footprint_corners
from testbed.loop import TickRecord
from tracks.plot import draw_track

_MARGINS = {"left": 0.08, "right": 0.98, "bottom": 0.05, "top": 0.96, "hspace": 0.22}
"""Fixed margins (fractions of the figure) that fit the axis labels: a campaign writes one figure per run, and
an automatic layout draws the figure twice."""


def _col(rows: Sequence[TickRecord], name: str) -> np.ndarray:
    return np.array([np.nan if getattr(r, name) is None else getattr(r, name) for r in rows], dtype=float)


def _frame_equal(ax, x: np.ndarray, y: np.ndarray, pad: float) -> None:
    """Limits around the path (plus `pad` m) widened on one axis to the axes' shape: 1 m is 1 m both ways."""
    fig_w, fig_h = ax.figure.get_size_inches()
    box = ax.get_position()
    shape = (box.width * fig_w) / (box.height * fig_h)
    cx, cy = (np.nanmin(x) + np.nanmax(x)) / 2.0, (np.nanmin(y) + np.nanmax(y)) / 2.0
    half_w, half_h = (np.nanmax(x) - np.nanmin(x)) / 2.0 + pad, (np.nanmax(y) - np.nanmin(y)) / 2.0 + pad
    half_w, half_h = max(half_w, half_h * shape), max(half_h, half_w / shape)
    ax.set_xlim(cx - half_w, cx + half_w)
    ax.set_ylim(cy - half_h, cy + half_h)
    ax.set_aspect("equal", adjustable="box")


def save_birdseye(path: Path, track, rows: Sequence[TickRecord], *, lane_width: float, straddle_dev: float,
                  believed_xy: np.ndarray, detection_t: float | None, stop_t: float | None, title: str,
                  attack_t: float | None = None, threshold: float | None = None,
                  traffic: dict[int, np.ndarray] | None = None, traffic_size: tuple[float, float] = (0.0, 0.0)
                  ) -> None:
    """`attack_t` is when the attack starts, `threshold` the level the CUSUM column alarms above, `traffic` each
    traffic car's (x, y, yaw) path by id (drawn grey, its last footprint, `traffic_size` = length × width, with
    its id)."""
    t = _col(rows, "t")
    x, y = _col(rows, "x"), _col(rows, "y")
    phys, msf, ld = _col(rows, "phys_dev"), _col(rows, "msf_dev"), _col(rows, "ld_dev")
    cusum = _col(rows, "cusum")
    fig = Figure(figsize=(10, 11))
    ax_map, ax_dev, ax_cusum = fig.subplots(3, 1, gridspec_kw={"height_ratios": [3, 2, 1]})
    fig.subplots_adjust(**_MARGINS)
    draw_track(ax_map, track)
    _frame_equal(ax_map, x, y, pad=25.0)
    ax_map.plot(x, y, color="tab:blue", lw=1.6, label="true path")
    ax_map.plot(believed_xy[:, 0], believed_xy[:, 1], color="tab:red", lw=1.0, ls="--", label="believed (MSF)")
    for n, (car, xy) in enumerate(sorted((traffic or {}).items())):
        ax_map.plot(xy[:, 0], xy[:, 1], color="0.45", lw=0.8, label="traffic" if n == 0 else None,
                    zorder=1.9)  # under the ego's paths, which share the lane centre
        x_end, y_end, yaw_end = xy[-1]
        ax_map.add_patch(Polygon(footprint_corners(x_end, y_end, yaw_end, *traffic_size), closed=True,
                                 facecolor="0.55", edgecolor="0.25", lw=0.6, zorder=3))
        ax_map.annotate(str(car), (x_end, y_end), fontsize=6, color="0.15", ha="center", va="center",
                        clip_on=True, zorder=4)
    for when, marker, label in ((attack_t, "v", "attack start"), (detection_t, "*", "detection"),
                                (stop_t, "s", "stop")):
        if when is not None:
            i = int(np.searchsorted(t, when).clip(0, len(t) - 1))
            ax_map.plot(x[i], y[i], marker=marker, color="k", ms=12, ls="", label=label)
    ax_map.legend(loc="best", fontsize=8)
    ax_map.set_title(title)

    half = lane_width / 2.0
    ax_dev.axhspan(-straddle_dev, straddle_dev, color="0.92", label="no lane straddle")
    for edge in (-half, half):
        ax_dev.axhline(edge, color="0.3", lw=1.5)
    ax_dev.plot(t, phys, color="tab:blue", label="physical D")
    ax_dev.plot(t, msf, color="tab:red", ls="--", label="MSF D")
    if np.isfinite(ld).any():
        ax_dev.plot(t, ld, color="tab:green", lw=0.8, label="LD D")
    events = ((attack_t, "r--", "attack start"), (detection_t, "k:", "detection"), (stop_t, "k-.", "stop"))
    for when, style, label in events:
        if when is not None:
            ax_dev.axvline(when, color=style[0], ls=style[1:], label=label)
    ax_dev.set_xlabel("time (s)")
    ax_dev.set_ylabel("lateral deviation D (m, + left)")
    lim = max(half + 0.5, float(np.nanmax(np.abs(np.concatenate([phys, msf])))) + 0.3 if len(t) else half + 0.5)
    ax_dev.set_ylim(-lim, lim)
    ax_dev.legend(loc="best", fontsize=8, ncols=3)
    ax_dev.grid(alpha=0.3)

    if np.isfinite(cusum).any():
        ax_cusum.plot(t, cusum, color="tab:purple", label="CUSUM S")
    else:
        ax_cusum.text(0.5, 0.5, "no detector statistic (defense none)", ha="center", va="center",
                      transform=ax_cusum.transAxes, color="0.4")
    if threshold is not None:
        ax_cusum.axhline(threshold, color="tab:purple", ls="--", lw=1.0, label=f"threshold τ = {threshold:g}")
    for when, style, _ in events:
        if when is not None:
            ax_cusum.axvline(when, color=style[0], ls=style[1:])
    ax_cusum.set_xlim(ax_dev.get_xlim())
    ax_cusum.set_xlabel("time (s)")
    ax_cusum.set_ylabel("CUSUM S (m)")
    if ax_cusum.get_legend_handles_labels()[0]:
        ax_cusum.legend(loc="upper left", fontsize=8)
    ax_cusum.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
