"""Coordinated MSF + LD shift: the MSF pose moves `rate` m/s sideways up to `limit` m while the detected
lines move with it, so that D_MSF − D_LD stays near zero. It needs `ld-output` as well as `msf-output`:
outside LD3's threat model, measured to show what LD3 cannot see, never counted as a defeat of its design.
"""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_lines, shift_pose
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate

IDLE, SHIFTING = "idle", "shifting"


class CoordinatedShift(Attack):
    """One lateral offset o(t) = min(limit, rate·(t − start)) on the MSF pose and on the detected lines."""

    name = "coordinated"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT, ThreatCapability.LD_OUTPUT})

    def __init__(self, start: float = 10.0, rate: float = 0.5, limit: float = 3.0, direction: str = "left") -> None:
        super().__init__(start)
        check_finite("coordinated rate", rate, 0.0)
        check_finite("coordinated limit", limit, 0.0)
        self.rate, self.limit = rate, limit
        self.direction, self.sign = direction, side_sign(direction, "coordinated")
        self.stage = IDLE
        self.offset = 0.0

    def _offset(self, t: float) -> float:
        elapsed = t - self.start_time
        self.stage = IDLE if elapsed < 0 else SHIFTING
        self.offset = 0.0 if elapsed < 0 else self.sign * min(self.limit, self.rate * elapsed)
        return self.offset

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        o = self._offset(view.t)
        if o == 0.0:
            return est
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, o), est.cov)

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        """Lines moved by −o, so that the car appears o further left (+) in them, as on the MSF."""
        o = self._offset(view.t)
        return ld if o == 0.0 else shift_lines(ld, o)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "rate": self.rate, "limit": self.limit,
                "direction": self.direction}
