"""Replay of the bound's worst attack: a white-box attacker who knows the victim's lateral controller (its model,
gains and period), LD3's CUSUMs and the detection rate solves the bound's linear program at the victim's speed when
it starts and replays the program's worst inputs: per detection an MSF offset a_i (m) and yaw bias ψ_i (rad),
held until the next (`testbed.control.attack_bound`). `k_sigma` grants it that much benign residual noise on its
side (0: none, the safe choice), `scale` multiplies the inputs and `direction` mirrors them. With `cancel` the
attacker, who sees the true pose, takes the MSF's own error out of what it sends, so the residual the defense sees
is the program's input and not the input plus the MSF's noise. The program stops at the peak it aims for; the
attack releases there."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from testbed.attacks.base import Attack, AttackerView, WhiteBox, sent_estimate
from testbed.attacks.profile import check_finite, side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.control.attack_bound import Budget, deviation_bound, lateral_loop
from testbed.localization.estimate import LocalizationEstimate

PAPER_YAW_LIMIT = 0.15
"""Yaw bias (rad) the program may use against a defense without a heading check (else it is unbounded)."""
HORIZON_S = 8.0
IDLE, REPLAY, RELEASED = "idle", "replay", "released"


class BoundReplay(Attack):
    """Replays the linear program's worst (offset, yaw bias) sequence (module docstring)."""

    name = "bound-replay"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, scale: float = 1.0, k_sigma: float = 0.0, cancel: bool = True,
                 direction: str = "left") -> None:
        super().__init__(start)
        check_finite("bound-replay scale", scale, 0.0)
        check_finite("bound-replay k_sigma", k_sigma, 0.0)
        self.scale, self.k_sigma, self.cancel = scale, k_sigma, cancel
        self.direction, self.sign = direction, side_sign(direction, "bound-replay")
        self.stage = IDLE
        self.offset = 0.0
        self._plan: tuple[np.ndarray, np.ndarray, float] | None = None  # (a_i, ψ_i, detection period)

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        if whitebox.controller is None:
            raise RuntimeError("bound-replay needs the victim's lateral controller in its white box")

    def _solve(self, speed: float) -> tuple[np.ndarray, np.ndarray, float]:
        wb = self.whitebox
        d = wb.defense
        lateral = Budget(float(d.b), float(d.tau))
        if getattr(d, "fail_closed", False):
            heading = Budget(float(d.heading_b), float(d.heading_tau), clamp=float(d.steer_yaw_tol))
        else:
            heading = Budget(0.0, math.inf, clamp=PAPER_YAW_LIMIT)
        loop = lateral_loop(wb.controller, max(speed, 1.0), wb.ticks_per_detection)
        result = deviation_bound(loop, lateral, heading, k_sigma=self.k_sigma, horizon_s=HORIZON_S)
        return result.offsets_m, result.yaw_biases, 1.0 / wb.detector_hz

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            return est
        if self._plan is None:
            self._plan = self._solve(view.speed)
        offsets, yaws, period = self._plan
        i = int((view.t - self.start_time) / period + 1e-9)
        if i >= len(offsets):
            self.stage, self.offset = RELEASED, 0.0
            return est
        self.stage = REPLAY
        self.offset = self.sign * self.scale * float(offsets[i])
        yaw = self.sign * self.scale * float(yaws[i])
        return sent_estimate(est, view, self.whitebox, self.offset, yaw, self.cancel)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "scale": self.scale, "k_sigma": self.k_sigma,
                "cancel": self.cancel, "direction": self.direction}
