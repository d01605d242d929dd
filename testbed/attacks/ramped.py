"""MSF-output attacks of one amount ramped in linearly from `start` over `ramp` seconds and then held."""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

from testbed.attacks.base import Attack, AttackerView
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose

IDLE, RAMPING, HELD = "idle", "ramping", "held"


class RampedMsfAttack(Attack):
    """Applies `amount`·ramp(t − start) to the MSF pose (`moved`); `offset` in the state is that value."""

    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float, amount: float, ramp: float) -> None:
        super().__init__(start)
        check_finite(f"{self.name} amount", amount)
        check_finite(f"{self.name} ramp", ramp, 0.0)
        self.amount, self.ramp = amount, ramp
        self.stage = IDLE
        self.offset = 0.0

    @abstractmethod
    def moved(self, pose: Pose, lane_heading: float, value: float) -> Pose:
        """The MSF pose with the attack's current value applied."""

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        k = ramp_fraction(view.t - self.start_time, self.ramp)
        self.stage = IDLE if view.t < self.start_time else (HELD if k >= 1.0 else RAMPING)
        self.offset = k * self.amount
        if k == 0.0:
            return est
        return LocalizationEstimate(est.t, self.moved(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}
