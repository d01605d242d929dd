"""Cumulative-lateral-deviation uncertainties (paper Alg. 4).

Windows of the last w values of |D_MSF| and |D_LD|; s = window sums, g = sqrt(s_MSF · s_LD),
f = s / g, R = λ f^k + (1 - λ) P with k = 1 in the paper. The side that has deviated more gets the
larger R. Sums are floored at `SUM_FLOOR` so that a source sitting exactly on the centreline cannot make
g zero. P is passed per update, so it may be a constant or what the sources report.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

SUM_FLOOR = 1e-3
"""Smallest window sum used (m): keeps f finite when one source reports D = 0 throughout the window."""


class Uncertainties(NamedTuple):
    r_msf: float
    r_ld: float


class DeviationUncertainty:
    """Alg. 4's two deviation histories and the uncertainties derived from them."""

    def __init__(self, window: int, lam: float, power: float = 1.0) -> None:
        self.lam = lam
        self.power = power
        self._msf: deque[float] = deque(maxlen=window)
        self._ld: deque[float] = deque(maxlen=window)

    def update(self, d_msf: float, d_ld: float, p_msf: float, p_ld: float) -> Uncertainties:
        """Append |D_MSF| and |D_LD| (dropping the oldest beyond w) and return (R_MSF, R_LD)."""
        self._msf.append(abs(d_msf))
        self._ld.append(abs(d_ld))
        s_msf = max(sum(self._msf), SUM_FLOOR)
        s_ld = max(sum(self._ld), SUM_FLOOR)
        geo = math.sqrt(s_msf * s_ld)
        lam, k = self.lam, self.power
        return Uncertainties(
            lam * (s_msf / geo) ** k + (1.0 - lam) * p_msf,
            lam * (s_ld / geo) ** k + (1.0 - lam) * p_ld,
        )
