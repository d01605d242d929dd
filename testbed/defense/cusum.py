"""CUSUM anomaly detector: S_i = max(0, S_{i-1} + |r_i| - b), alarm when S_i > τ (Alg. 1, lines 6-10)."""

from __future__ import annotations

from collections.abc import Iterable


class Cusum:
    """One-sided CUSUM over residual magnitudes; latches at the first alarm (Alg. 1 `break`)."""

    def __init__(self, b: float, tau: float) -> None:
        self.b = b
        self.tau = tau
        self.statistic = 0.0
        self.alarmed = False

    def update(self, residual: float) -> bool:
        """Feed one residual; True once S > τ. After the alarm S is frozen at its alarm value."""
        if not self.alarmed:
            self.statistic = max(0.0, self.statistic + abs(residual) - self.b)
            self.alarmed = self.statistic > self.tau
        return self.alarmed

    def reset(self) -> None:
        """S back to 0 and the alarm cleared (after a zone where detection is disabled)."""
        self.statistic = 0.0
        self.alarmed = False


def cusum_alarm_index(residuals: Iterable[float], b: float, tau: float) -> int | None:
    """Index of the first residual at which CUSUM(b, τ) alarms, or None: for offline (b, τ) sweeps."""
    s = 0.0
    for i, r in enumerate(residuals):
        s = max(0.0, s + abs(r) - b)
        if s > tau:
            return i
    return None
