"""LD3's attack detector on deviations alone: CUSUM over r = D_MSF - D_LD (paper Alg. 1, lines 6-10).

Usable standalone on logged (D_MSF, D_LD) traces, e.g. to sweep b and τ for ROC curves.
"""

from __future__ import annotations

from testbed.defense.cusum import Cusum


class Ld3Detector:
    """Consistency check between the MSF and LD lateral deviations; latches at the first alarm."""

    def __init__(self, b: float = 0.6, tau: float = 0.1) -> None:
        self.cusum = Cusum(b, tau)

    def update(self, d_msf: float, d_ld: float) -> bool:
        """Feed one pair of deviations (m); True once under attack."""
        return self.cusum.update(d_msf - d_ld)

    @property
    def statistic(self) -> float:
        return self.cusum.statistic

    @property
    def alarmed(self) -> bool:
        return self.cusum.alarmed

    def reset(self) -> None:
        self.cusum.reset()
