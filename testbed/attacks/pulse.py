"""An identification input, not an attack family: from `start` the MSF pose is the true pose (its own error
cancelled, as a white-box attacker who sees the truth can), and on the first lane detection at or after
`pulse_at` with the car within `SPEED_TOL_MPS` of `speed` it is moved by `offset` (m, + left) and its yaw by `yaw`
(rad) for one camera period. Run with zero and
with each input, the difference of the true deviations is the closed loop's response to one checked input: the
linear program of the deviation bound solved on the car (`testbed.eval.search.bound_on_car`)."""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, WhiteBox, sent_estimate
from testbed.attacks.profile import check_finite
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate

IDLE, CANCEL, PULSE = "idle", "cancel", "pulse"
SPEED_TOL_MPS = 0.05


class IdentificationPulse(Attack):
    """The MSF's error cancelled from `start`, one camera period of (`offset`, `yaw`) from the first detection at or
    after `pulse_at` at `speed` (module docstring); `pulse_time` is that detection's time once it came."""

    name = "identification-pulse"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float, pulse_at: float, speed: float = 0.0, offset: float = 0.0,
                 yaw: float = 0.0) -> None:
        super().__init__(start)
        if not pulse_at >= start:
            raise UserError(f"the pulse comes at or after the cancelling starts, got {pulse_at} < {start}")
        check_finite("pulse offset", offset)
        check_finite("pulse yaw", yaw)
        self.pulse_at, self.speed, self.pulse_offset, self.pulse_yaw = pulse_at, speed, offset, yaw
        self.pulse_time: float | None = None
        self.stage = IDLE

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        self._period = whitebox.ticks_per_detection / whitebox.control_hz

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time or not est.pose.is_finite():
            return est
        if (self.pulse_time is None and view.t >= self.pulse_at and abs(view.speed - self.speed) < SPEED_TOL_MPS
                and self.whitebox.detection_tick(view.t)):
            self.pulse_time = view.t
        on = self.pulse_time is not None and view.t < self.pulse_time + self._period - 1e-9
        self.stage = PULSE if on else CANCEL
        offset, yaw = (self.pulse_offset, self.pulse_yaw) if on else (0.0, 0.0)
        return sent_estimate(est, view, self.whitebox, offset, yaw)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": self.pulse_time,
                "offset": self.pulse_offset if self.stage == PULSE else 0.0}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "pulse_at": self.pulse_at, "speed": self.speed,
                "offset": self.pulse_offset, "yaw": self.pulse_yaw}
