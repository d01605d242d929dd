"""A quantity tabulated along a road's arc length s: linear between knots, held constant beyond the ends."""

from __future__ import annotations

import bisect

import numpy as np


class Profile:
    """Values `v` at increasing arc lengths `s` (m)."""

    def __init__(self, s: np.ndarray, v: np.ndarray) -> None:
        if len(s) != len(v) or len(s) < 2 or np.any(np.diff(s) <= 0.0):
            raise ValueError("a profile needs at least two knots at increasing s, one value each")
        self.s, self.v = np.asarray(s, dtype=float), np.asarray(v, dtype=float)
        self._s, self._v = self.s.tolist(), self.v.tolist()

    def at(self, s: float) -> float:
        i = min(max(bisect.bisect_right(self._s, s) - 1, 0), len(self._s) - 2)
        s0, s1 = self._s[i], self._s[i + 1]
        f = min(max((s - s0) / (s1 - s0), 0.0), 1.0)
        return self._v[i] + f * (self._v[i + 1] - self._v[i])
