"""A white-box shadow of LD3's detection: the attacker runs the defense's own CUSUMs (`Cusum`, with the white
box's `b`, `τ`, `heading_b`, `heading_τ`) on the residuals it predicts the defense will see, and on each
detection tick chooses the largest MSF offset and yaw bias that keep its shadow statistics within their budgets.

It predicts the residual from what it sees: the true pose (the lines' deviation and heading, as an oracle
detector reports them) and the MSF's own output before it tampers with it, so the MSF's benign error is
cancelled, not spent. While a shadow statistic is below `spend`·τ the residual is the weight plus an even share
of the room left (`spend`·τ over `spread` s); at the budget it is `sustain`·b, which lets the statistic decay, and
the attacker tops it up again. The lateral offset and the yaw bias push the car the same way; an optional
`along` shift (m, + ahead; the along check's weight is its budget) hands the controller another station's
curvature beside them. The pose the controller reads between detections carries the last choice."""

from __future__ import annotations

from typing import Any

from testbed.attacks.along import along_lane
from testbed.attacks.base import Attack, AttackerView, WhiteBox, msf_error, shift_pose
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.defense.attack_detection import Cusum
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError
from tracks.pose import Pose

IDLE, SPENDING, SUSTAINING = "idle", "spending", "sustaining"


def budgeted_residual(cusum: Cusum, spend: float, sustain: float, share: int) -> float:
    """The residual magnitude the attacker feeds a shadow `cusum`: its weight plus an even `share`-th of the room
    up to `spend`·τ while there is room, else `sustain`·b; the shadow statistic takes it."""
    room = spend * cusum.tau - cusum.statistic
    residual = cusum.b + min(room, spend * cusum.tau / share) if room > 1e-12 else sustain * cusum.b
    cusum.update(residual)
    return residual


class ShadowAttack(Attack):
    """Spends LD3's lateral and heading CUSUM budgets on a shadow of the defense's detection (module docstring)."""

    name = "shadow"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, spend: float = 0.9, sustain: float = 0.95, hspend: float = 0.9,
                 hsustain: float = 0.95, spread: float = 0.5, along: float = 0.0, direction: str = "left") -> None:
        super().__init__(start)
        for name, value in (("shadow spend", spend), ("shadow sustain", sustain), ("shadow hspend", hspend),
                            ("shadow hsustain", hsustain), ("shadow spread", spread)):
            check_finite(name, value, 0.0)
        check_finite("shadow along", along)
        self.spend, self.sustain, self.hspend, self.hsustain = spend, sustain, hspend, hsustain
        self.spread, self.along = spread, along
        self.direction, self.sign = direction, side_sign(direction, "shadow")
        self.stage = IDLE
        self.offset = 0.0
        self._shadows: tuple[Cusum, Cusum] | None = None
        self._share = 1
        self._choice = (0.0, 0.0)
        """(MSF offset from its own pose, m + left; yaw bias, rad + left) chosen at the last detection tick."""

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        d = whitebox.defense
        self._shadows = (Cusum(float(d.b), float(d.tau)), Cusum(float(d.heading_b), float(d.heading_tau)))
        self._share = max(1, round(self.spread * whitebox.detector_hz))

    def _choose(self, est: LocalizationEstimate, view: AttackerView, wb: WhiteBox) -> None:
        """On a detection tick: the residuals the shadow allows, less the MSF's own error the attacker sees."""
        assert self._shadows is not None
        lateral, heading = self._shadows
        r = budgeted_residual(lateral, self.spend, self.sustain, self._share)
        rh = budgeted_residual(heading, self.hspend, self.hsustain, self._share)
        self.stage = SPENDING if lateral.statistic < self.spend * lateral.tau - 1e-12 else SUSTAINING
        error, yaw_error = msf_error(est, view, wb)
        self._choice = (self.sign * r - error, self.sign * rh - yaw_error)

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            return est
        wb = self.whitebox
        if wb is None or self._shadows is None:
            raise RuntimeError("shadow attack used before know(): it needs the defense's thresholds and rates")
        if not est.pose.is_finite():
            return est
        try:
            if wb.detection_tick(view.t):
                self._choose(est, view, wb)
        except OffMapError:
            return est
        self.offset, yaw = self._choice
        pose = shift_pose(est.pose, view.lane_heading, self.offset)
        if self.along:
            pose = along_lane(pose, wb.smap, wb.lane, self.along)
        return LocalizationEstimate(est.t, Pose(pose.x, pose.y, pose.yaw + yaw), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "spend": self.spend, "sustain": self.sustain,
                "hspend": self.hspend, "hsustain": self.hsustain, "spread": self.spread, "along": self.along,
                "direction": self.direction}
