"""LD deviation to the lane centreline (paper Alg. 3, Appendix A).

d = |poly(0)| per valid line; the nearer valid line wins: D = lw/2 - d_left (left) or d_right - lw/2
(right), with lw from the map. With neither line valid the last D is reused. A line is valid when
present, all coefficients finite, and its existence probability at least the threshold. On an exact
tie of two valid lines the left one is used (the paper's pseudo-code would reuse the last D there).
"""

from __future__ import annotations

import math

import numpy as np

from testbed.lane_detection import LaneDetection


def line_distance(coeffs: np.ndarray | None, prob: float, existence_threshold: float) -> float:
    """|y(0)| of a valid line, +inf for an invalid one (missing, non-finite, or below the threshold)."""
    if coeffs is None or not prob >= existence_threshold:
        return math.inf
    values = coeffs.tolist() if isinstance(coeffs, np.ndarray) else list(coeffs)
    if not values or not all(map(math.isfinite, values)):
        return math.inf
    return abs(values[0])


class LdDeviation:
    """Alg. 3 with its memory of the last computed D (None until a detection had a valid line)."""

    def __init__(self, existence_threshold: float) -> None:
        self.existence_threshold = existence_threshold
        self.last: float | None = None
        self.reused = False
        """True when the last update found no valid line and returned the previous D."""
        self.side: str | None = None
        """The line the last computed D came from: "left" or "right" (kept while D is reused)."""

    def update(self, ld: LaneDetection, lane_width: float) -> float | None:
        """D_LD for this detection (m, + left); the last D when no line is valid; None if there is none."""
        d_left = line_distance(ld.left, ld.left_prob, self.existence_threshold)
        d_right = line_distance(ld.right, ld.right_prob, self.existence_threshold)
        self.reused = False
        if math.isfinite(d_left) and d_left <= d_right:
            self.last, self.side = lane_width / 2.0 - d_left, "left"
        elif math.isfinite(d_right):
            self.last, self.side = d_right - lane_width / 2.0, "right"
        else:
            self.reused = True
        return self.last

    def reset(self) -> None:
        """Forget the last D (it is stale after a zone without lane markings)."""
        self.last = None
        self.side = None
