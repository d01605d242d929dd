"""A smooth curve given by its heading at known arc lengths, as the curvature-linear segments of
`tracks.geometry` (the form a `ReferenceLine` holds).

Knots go in threes: segment j spans knots 2j..2j+2 and its heading is the quadratic in arc length through
the three headings there, so lines, arcs and clothoids come out exact and headings match at every knot.
"""

from __future__ import annotations

import numpy as np

from tracks.geometry import Arc, Clothoid, Segment, Straight

_FLAT = 1e-9  # 1/m: curvature below this is a straight


def fit_segments(sigma: np.ndarray, heading: np.ndarray) -> list[Segment]:
    """Segments through knots at arc lengths `sigma` (increasing, odd count) with unwrapped `heading`s."""
    if len(sigma) < 3 or len(sigma) % 2 == 0 or len(heading) != len(sigma):
        raise ValueError("need an odd number (>= 3) of knots, one heading each")
    segments: list[Segment] = []
    for j in range(0, len(sigma) - 1, 2):
        um, ub = sigma[j + 1] - sigma[j], sigma[j + 2] - sigma[j]
        dm, db = heading[j + 1] - heading[j], heading[j + 2] - heading[j]
        # h(u) = h_a + k0 u + c u²/2 through (um, dm) and (ub, db)
        c = 2.0 * (db * um - dm * ub) / (ub * ub * um - um * um * ub)
        k0 = (db - 0.5 * c * ub * ub) / ub
        k1 = k0 + c * ub
        if abs(k0) < _FLAT and abs(k1) < _FLAT:
            segments.append(Straight(float(ub)))
        elif abs(k1 - k0) < _FLAT:
            segments.append(Arc(float(1.0 / k0), float(ub)))
        else:
            segments.append(Clothoid(float(k0), float(k1), float(ub)))
    return segments
