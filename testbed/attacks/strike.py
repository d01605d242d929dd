"""A strike at speed spending both of LD3's CUSUM budgets: a white-box attacker who knows the lateral check's
(b, τ), the heading check's (b_h, τ_h) and the detection rate moves the MSF pose `b + spend·τ/n` sideways and
biases its yaw by `b_h + hspend·τ_h/n` for n detections over `spread` s, both pushing the car the same way, then
holds `sustain·b` and `hsustain·b_h`, which never raise either statistic. At speed the heading budget turns into
lateral metres before either check can alarm."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, WhiteBox, shift_pose
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose

IDLE, STRIKE, SUSTAIN = "idle", "strike", "sustain"


class StrikeAttack(Attack):
    """Spends the lateral and the heading CUSUM budgets together, then holds under both weights."""

    name = "strike"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, spend: float = 0.9, hspend: float = 0.9, spread: float = 0.5,
                 sustain: float = 0.9, hsustain: float = 0.9, direction: str = "left") -> None:
        super().__init__(start)
        for name, value in (("strike spend", spend), ("strike hspend", hspend), ("strike spread", spread),
                            ("strike sustain", sustain), ("strike hsustain", hsustain)):
            check_finite(name, value, 0.0)
        self.spend, self.hspend, self.spread = spend, hspend, spread
        self.sustain, self.hsustain = sustain, hsustain
        self.direction, self.sign = direction, side_sign(direction, "strike")
        self.stage = IDLE
        self.offset = 0.0
        self._plan: tuple[int, float, tuple[float, float], tuple[float, float]] | None = None
        """(detections of the strike, detection period, (offset, yaw) during it, (offset, yaw) held after)."""

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        d = whitebox.defense
        b, tau = float(getattr(d, "b", 0.0)), float(getattr(d, "tau", 0.0))
        hb, htau = float(getattr(d, "heading_b", 0.0)), float(getattr(d, "heading_tau", 0.0))
        n = max(1, round(self.spread * whitebox.detector_hz))
        self._plan = (n, 1.0 / whitebox.detector_hz, (b + self.spend * tau / n, hb + self.hspend * htau / n),
                      (self.sustain * b, self.hsustain * hb))

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            return est
        if self._plan is None:
            raise RuntimeError("strike attack used before know(): it needs the defense's thresholds and rate")
        n, period, during, after = self._plan
        striking = int((view.t - self.start_time) / period + 1e-9) < n
        self.stage = STRIKE if striking else SUSTAIN
        lateral, yaw = during if striking else after
        self.offset = self.sign * lateral
        moved = shift_pose(est.pose, view.lane_heading, self.offset)
        return LocalizationEstimate(est.t, Pose(moved.x, moved.y, moved.yaw + self.sign * yaw), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "spend": self.spend, "hspend": self.hspend,
                "spread": self.spread, "sustain": self.sustain, "hsustain": self.hsustain,
                "direction": self.direction}
