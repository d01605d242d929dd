"""Injection on unchecked ticks: a white-box attacker who knows the control and detection rates moves the MSF
pose only on the control ticks that carry no lane detection (`lateral` m sideways, + left, and `yaw` rad),
ramped in over `ramp` s, and leaves it true on the ticks LD3 checks. Against a defense that steers on every
MSF pose both CUSUMs stay at zero while the controller follows the moved pose on the other ticks."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose

IDLE, CHECKED, MOVED = "idle", "checked-tick", "unchecked-tick"


class UncheckedTicks(Attack):
    """Moves the MSF pose on the ticks the attacker predicts carry no detection (module docstring)."""

    name = "unchecked"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, lateral: float = 2.0, yaw: float = 0.0, ramp: float = 1.0) -> None:
        super().__init__(start)
        check_finite("unchecked lateral", lateral)
        check_finite("unchecked yaw", yaw)
        check_finite("unchecked ramp", ramp, 0.0)
        self.lateral, self.yaw, self.ramp = lateral, yaw, ramp
        self.stage = IDLE
        self.offset = 0.0

    def detection_tick(self, t: float) -> bool:
        """Whether the loop runs a lane detection on the control tick at `t` (the white box's rates)."""
        if self.whitebox is None:
            raise RuntimeError("unchecked attack used before know(): it needs the control and detection rates")
        return self.whitebox.detection_tick(t)

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        k = ramp_fraction(view.t - self.start_time, self.ramp)
        if k == 0.0:
            self.stage, self.offset = IDLE, 0.0
            return est
        if self.detection_tick(view.t):
            self.stage, self.offset = CHECKED, 0.0
            return est
        self.stage, self.offset = MOVED, k * self.lateral
        moved = shift_pose(est.pose, view.lane_heading, self.offset)
        return LocalizationEstimate(est.t, Pose(moved.x, moved.y, moved.yaw + k * self.yaw), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "lateral": self.lateral, "yaw": self.yaw,
                "ramp": self.ramp}
