"""CUSUM-budget burst on the MSF output: a white-box attacker who knows LD3's (b, τ) and detection rate.

Under lane-centring control the residual LD3 sees is about the MSF offset o (paper §6.1), and each detection
adds |o| − b to S. From `start` the attacker spends `spend`·τ of S over `spread` seconds of detections,
shaped by `profile` (`flat`, `rise`: growing, `fall`: shrinking): offset_i = b + w_i with Σ w_i = spend·τ.
Afterwards it holds `sustain`·b, which never raises S.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from testbed.attacks.base import Attack, AttackerView, WhiteBox, shift_pose
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate

PROFILES = ("flat", "rise", "fall")
IDLE, BURST, SUSTAIN = "idle", "burst", "sustain"


def check_profile(profile: str) -> None:
    """UserError unless `profile` is one of `PROFILES`."""
    if profile not in PROFILES:
        raise UserError(f"burst profile must be one of {', '.join(PROFILES)}, got {profile!r}")


def burst_weights(n: int, profile: str, total: float) -> np.ndarray:
    """n non-negative excesses over b summing to `total`, shaped by `profile`."""
    check_profile(profile)
    shape = {"flat": np.ones(n), "rise": np.arange(1.0, n + 1), "fall": np.arange(float(n), 0.0, -1.0)}[profile]
    return total * shape / shape.sum()


class BurstAttack(Attack):
    """Spends the CUSUM budget in a shaped burst, then holds just under b (module docstring)."""

    name = "burst"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, spend: float = 0.9, spread: float = 1.0, profile: str = "flat",
                 sustain: float = 0.9, direction: str = "left") -> None:
        super().__init__(start)
        check_finite("burst spend", spend, 0.0)
        check_finite("burst spread", spread, 0.0)
        check_finite("burst sustain", sustain, 0.0)
        check_profile(profile)
        self.spend, self.spread, self.profile, self.sustain = spend, spread, profile, sustain
        self.direction, self.sign = direction, side_sign(direction, "burst")
        self.stage = IDLE
        self.offset = 0.0
        self._plan: tuple[np.ndarray, float, float] | None = None
        """(offsets per detection of the burst, detection period, sustained offset), from the white box."""

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        b, tau = float(getattr(whitebox.defense, "b", 0.0)), float(getattr(whitebox.defense, "tau", 0.0))
        n = max(1, round(self.spread * whitebox.detector_hz))
        self._plan = (b + burst_weights(n, self.profile, self.spend * tau), 1.0 / whitebox.detector_hz,
                      self.sustain * b)

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            return est
        if self._plan is None:
            raise RuntimeError("burst attack used before know(): it needs the defense's b, τ and rate")
        schedule, period, held = self._plan
        i = int((view.t - self.start_time) / period + 1e-9)
        self.stage = BURST if i < len(schedule) else SUSTAIN
        self.offset = self.sign * (schedule[i] if i < len(schedule) else held)
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "spend": self.spend, "spread": self.spread,
                "profile": self.profile, "sustain": self.sustain, "direction": self.direction}
