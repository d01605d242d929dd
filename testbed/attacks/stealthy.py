"""Stealthy attack (paper §6.1): a white-box attacker with instantaneous control of the MSF output who
knows LD3's CUSUM (weight b, threshold τ, evaluated at `rate_hz`) and the LD noise spread.

Under lane-centring control the MSF deviation settles at D_MSF ≈ 0 while the car sits at −o, so the
residual the defense sees is |D_MSF − D_LD| = |o − n_LD|. The attacker cannot see the LD noise sample, so it
bounds it by `margin` (default 3σ_LD) and tracks the worst case of the defender's statistic,
Ŝ ← max(0, Ŝ + |o| + margin − b), choosing at each CUSUM tick the largest offset that keeps
Ŝ + |o| + margin − b ≤ τ − ε. The sustained offset is b − margin after an initial τ-sized burst. With
`spread` > 0 s the burst's τ is spent evenly over that time instead of in one tick (offset b − margin + τ/n
for the n ticks of `spread`): a rate-limited steering cannot follow a one-tick burst's height but can follow
a held one, so with a large τ a spread burst may push the car further.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.profile import side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate

IDLE, STEALTHY = "idle", "stealthy"
_EPS = 1e-3


@dataclass(frozen=True)
class CusumKnowledge:
    """What the white-box attacker knows of the defense: CUSUM b, τ (m) and the LD noise std (m)."""

    b: float = 0.6
    tau: float = 0.1
    ld_noise_std: float = 0.1
    rate_hz: float = 20.0

    def __post_init__(self) -> None:
        for name in ("b", "tau", "ld_noise_std", "rate_hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"stealthy {name} must be a number >= 0, got {v}")
        if self.rate_hz <= 0:
            raise UserError(f"stealthy rate_hz must be > 0, got {self.rate_hz}")


class StealthyAttack(Attack):
    """Pushes the MSF sideways as far as the (worst-case) CUSUM statistic allows without crossing τ."""

    name = "stealthy"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(
        self,
        knowledge: CusumKnowledge,
        start: float = 10.0,
        margin: float | None = None,
        direction: str = "left",
        spread: float = 0.0,
    ) -> None:
        super().__init__(start)
        if not (math.isfinite(spread) and spread >= 0):
            raise UserError(f"stealthy spread must be a duration >= 0 s, got {spread}")
        self.spread = spread
        self._burst_ticks = max(1, round(spread * knowledge.rate_hz))
        self.margin = 3.0 * knowledge.ld_noise_std if margin is None else margin
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise UserError(f"stealthy margin must be a distance >= 0 m, got {margin}")
        self.knowledge, self.direction = knowledge, direction
        self.sign = side_sign(direction, "stealthy")
        self.s_hat = 0.0
        self.offset = 0.0
        self.stage = IDLE
        self._next_tick: float | None = None

    def _cusum_tick(self) -> None:
        k = self.knowledge
        room = k.b + k.tau - _EPS - self.margin - self.s_hat
        magnitude = max(0.0, min(room, k.b - self.margin + k.tau / self._burst_ticks))
        self.s_hat = max(0.0, self.s_hat + magnitude + self.margin - k.b)
        self.offset = self.sign * magnitude

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            return est
        self.stage = STEALTHY
        period = 1.0 / self.knowledge.rate_hz
        if self._next_tick is None:
            self._next_tick = view.t
        while view.t >= self._next_tick - 1e-9:
            self._cusum_tick()
            self._next_tick += period
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        k = self.knowledge
        return {
            "kind": self.name,
            "start": self.start_time,
            "margin": self.margin,
            "direction": self.direction,
            "spread": self.spread,
            "b": k.b,
            "tau": k.tau,
            "ld_std": k.ld_noise_std,
        }
