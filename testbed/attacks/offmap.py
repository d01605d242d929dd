"""Off-map MSF attack: the MSF pose is moved `distance` metres sideways (+ left), ramped in over `ramp` s
(one tick for 0), far enough that the map cannot place it; the paper's Alg. 1 skips such updates."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate

IDLE, RAMPING, HELD = "idle", "ramping", "held"


class OffMapAttack(Attack):
    """Moves the MSF pose off the mapped road and keeps it there."""

    name = "offmap"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, distance: float = 20.0, ramp: float = 0.0) -> None:
        super().__init__(start)
        check_finite("offmap distance", distance)
        check_finite("offmap ramp", ramp, 0.0)
        self.distance, self.ramp = distance, ramp
        self.stage = IDLE
        self.offset = 0.0

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        k = ramp_fraction(view.t - self.start_time, self.ramp)
        self.stage = IDLE if view.t < self.start_time else (HELD if k >= 1.0 else RAMPING)
        self.offset = k * self.distance
        if k == 0.0:
            return est
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "distance": self.distance, "ramp": self.ramp}
