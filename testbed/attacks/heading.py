"""Heading bias on the MSF output: the MSF yaw turned by `bias` rad (+ left), ramped in over `ramp` s, with its
position left true. Alg. 1 compares lateral deviations only, so MSF and lines agree while the controller,
steering on the biased heading, settles the car off the centreline."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose

IDLE, RAMPING, HELD = "idle", "ramping", "held"


class HeadingBias(Attack):
    """Adds bias·ramp(t − start) to the MSF yaw; `offset` in the state is the bias (rad), not a distance."""

    name = "heading"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, bias: float = 0.03, ramp: float = 2.0) -> None:
        super().__init__(start)
        check_finite("heading bias", bias)
        check_finite("heading ramp", ramp, 0.0)
        self.bias, self.ramp = bias, ramp
        self.stage = IDLE
        self.offset = 0.0

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        k = ramp_fraction(view.t - self.start_time, self.ramp)
        self.stage = IDLE if view.t < self.start_time else (HELD if k >= 1.0 else RAMPING)
        self.offset = k * self.bias
        if k == 0.0:
            return est
        return LocalizationEstimate(est.t, Pose(est.pose.x, est.pose.y, est.pose.yaw + self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "bias": self.bias, "ramp": self.ramp}
