"""The TuSimple lane benchmark's metric on one frame (as its evaluate/lane.py computes it: a point is right within
20 px at 1280 wide, widened by the labelled lane's angle; a labelled lane is matched at an accuracy of 0.85), and the
ego-lane subset it is applied to here: the two labelled lanes nearest the image's bottom centre on either side.

Lanes are x pixels at the label's rows (`h_samples`), `ABSENT` (-2) where a lane has no point. As in the benchmark, a
row where both the label and the prediction have no point counts as right, and one prediction may match several
labelled lanes. Its rules for over four labelled lanes and for run time never apply to two ego lanes and are left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ABSENT = -2
PIXEL_THRESHOLD = 20.0
"""Benchmark threshold (px) on its 1280-pixel-wide frames; scaled with the width of other frames."""
BENCHMARK_WIDTH = 1280
MATCH_ACCURACY = 0.85
BOTTOM_POINTS = 5
"""Lowest labelled points of a lane fitted to find where it meets the image's bottom row."""


@dataclass(frozen=True)
class FrameScore:
    """The benchmark's accuracy, FP and FN rates of one frame, and each labelled lane's best accuracy."""

    accuracy: float
    fp: float
    fn: float
    lane_accuracy: tuple[float, ...]


def threshold(xs: np.ndarray, ys: np.ndarray, width: int) -> float:
    """Pixel threshold for a labelled lane: `PIXEL_THRESHOLD` scaled to `width`, over the cosine of the lane's angle
    to the image's vertical (a least-squares fit of x on y over its points)."""
    ok = xs >= 0
    angle = 0.0
    if ok.sum() > 1:
        angle = float(np.arctan(np.polyfit(ys[ok].astype(float), xs[ok].astype(float), 1)[0]))
    return PIXEL_THRESHOLD * width / BENCHMARK_WIDTH / np.cos(angle)


def line_accuracy(pred: np.ndarray, gt: np.ndarray, thresh: float) -> float:
    """Share of the rows where the prediction is within `thresh` of the label (both absent counts as right)."""
    p = np.where(pred >= 0, pred, -100.0)
    g = np.where(gt >= 0, gt, -100.0)
    return float(np.mean(np.abs(p - g) < thresh)) if len(g) else 0.0


def bench(pred: list[np.ndarray], gt: list[np.ndarray], ys: np.ndarray, width: int) -> FrameScore:
    """The benchmark's score of predicted lanes against labelled ones, all at rows `ys`."""
    best = []
    for lane in gt:
        thresh = threshold(lane, ys, width)
        best.append(max((line_accuracy(p, lane, thresh) for p in pred), default=0.0))
    matched = sum(a >= MATCH_ACCURACY for a in best)
    return FrameScore(accuracy=sum(best) / max(min(4, len(gt)), 1),
                      fp=(len(pred) - matched) / len(pred) if pred else 0.0,
                      fn=(len(gt) - matched) / max(min(len(gt), 4), 1), lane_accuracy=tuple(best))


def bottom_crossing(xs: np.ndarray, ys: np.ndarray, height: int) -> float | None:
    """Where a labelled lane meets the image's bottom row (px): a straight fit to its lowest `BOTTOM_POINTS`
    points; None for a lane with fewer than two."""
    ok = xs >= 0
    if ok.sum() < 2:
        return None
    order = np.argsort(ys[ok])[-BOTTOM_POINTS:]
    slope, offset = np.polyfit(ys[ok][order].astype(float), xs[ok][order].astype(float), 1)
    return float(slope * (height - 1) + offset)


def ego_lanes(lanes: list[np.ndarray], ys: np.ndarray, width: int, height: int) -> tuple[int | None, int | None]:
    """Indices of the labelled ego lanes (left, right): the lanes meeting the bottom row nearest its centre, left of
    it and right of it; None for a side without one."""
    left: tuple[float, int] | None = None
    right: tuple[float, int] | None = None
    centre = width / 2.0
    for i, lane in enumerate(lanes):
        u = bottom_crossing(lane, ys, height)
        if u is None:
            continue
        if u < centre and (left is None or u > left[0]):
            left = (u, i)
        elif u >= centre and (right is None or u < right[0]):
            right = (u, i)
    return (left[1] if left else None), (right[1] if right else None)
