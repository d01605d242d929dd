"""LD deviation to the lane centreline (paper Alg. 3, Appendix A).

d = |poly(0)| per valid line; the nearer valid line wins: D = lw/2 - d_left (left) or d_right - lw/2
(right), with lw from the map. With neither line valid the last D is reused. A line is valid when
present, all coefficients finite, and its existence probability at least the threshold. On an exact
tie of two valid lines the left one is used (the paper's pseudo-code would reuse the last D there).

`lines = "both"` (not the paper's): where both lines are valid and lie a lane's width apart (within
`MIDPOINT_WIDTH_TOL` of the map's), D is the car's offset from their midpoint, −(y_left(0) + y_right(0))/2, so that
neither the map's lane width nor one line misread alone moves D by more than half of its error; otherwise (one valid
line, or two that are no lane, such as a turn lane's edge where it opens) Alg. 3 as above.
"""

from __future__ import annotations

import math
from typing import Literal

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


MIDPOINT_WIDTH_TOL = 0.5
"""m: how far two valid lines' spacing may be from the map's lane width for D to be their midpoint (`lines = "both"`):
more than public maps' paint and lane widths disagree (0.3 m on CARLA's Town07), less than a lane opening beside."""

LdLines = Literal["nearer", "both"]
"""Which valid lines D comes from: the nearer one with the map's lane width (the paper's Alg. 3), or both lines'
midpoint where both are valid."""


class LdDeviation:
    """Alg. 3 with its memory of the last computed D (None until a detection had a valid line)."""

    def __init__(self, existence_threshold: float, lines: LdLines = "nearer") -> None:
        self.existence_threshold = existence_threshold
        self.lines = lines
        self.last: float | None = None
        self.reused = False
        """True when the last update found no valid line and returned the previous D."""
        self.side: str | None = None
        """The line the last computed D came from: "left", "right" or "both" (kept while D is reused)."""

    def update(self, ld: LaneDetection, lane_width: float) -> float | None:
        """D_LD for this detection (m, + left); the last D when no line is valid; None if there is none."""
        d_left = line_distance(ld.left, ld.left_prob, self.existence_threshold)
        d_right = line_distance(ld.right, ld.right_prob, self.existence_threshold)
        self.reused = False
        if (self.lines == "both" and math.isfinite(d_left) and math.isfinite(d_right)
                and abs(float(ld.left[0]) - float(ld.right[0]) - lane_width) <= MIDPOINT_WIDTH_TOL):
            self.last, self.side = -0.5 * (float(ld.left[0]) + float(ld.right[0])), "both"
        elif math.isfinite(d_left) and d_left <= d_right:
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
