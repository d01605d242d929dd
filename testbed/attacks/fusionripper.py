"""FusionRipper (Shen et al., USENIX Security'20): opportunistic lateral GNSS spoofing of MSF.

The attacker tailgates the victim and watches its physical lateral deviation. From `start` it spoofs the
GNSS position sideways by a constant `d` (vulnerability profiling). As soon as the victim's physical
deviation, in the direction the spoofing pushes it (opposite to the spoofed offset under lane-centring
control), exceeds `trigger`, it switches to aggressive spoofing: the offset is multiplied by `f` every
second, d·f^k with k the whole seconds since the switch. The attacker's view of the deviation (from its own
sensors, tailgating) carries Gaussian noise `obs_std`, drawn from the scenario's attack stream.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from testbed.attacks.base import Attack, AttackerView, left_normal
from testbed.attacks.profile import side_sign
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.sensors import GnssFix

IDLE, PROFILING, AGGRESSIVE = "idle", "profiling", "aggressive"


class FusionRipper(Attack):
    """Two-stage lateral GNSS spoofing; `direction` is the side the spoofed position goes (left|right)."""

    name = "fusionripper"
    capabilities = frozenset({ThreatCapability.GNSS})

    def __init__(
        self,
        d: float = 0.5,
        f: float = 1.2,
        direction: str = "left",
        start: float = 10.0,
        trigger: float = 0.3,
        obs_std: float = 0.02,
        rng: np.random.Generator | None = None,
    ) -> None:
        super().__init__(start)
        if not (math.isfinite(d) and d > 0):
            raise UserError(f"fusionripper d must be a distance > 0 m, got {d}")
        if not (math.isfinite(f) and f >= 1.0):
            raise UserError(f"fusionripper f must be a factor >= 1, got {f}")
        if not (math.isfinite(trigger) and trigger > 0):
            raise UserError(f"fusionripper trigger must be a deviation > 0 m, got {trigger}")
        if not (math.isfinite(obs_std) and obs_std >= 0):
            raise UserError(f"fusionripper obs_std must be a deviation >= 0 m, got {obs_std}")
        self.d, self.f, self.direction, self.trigger = d, f, direction, trigger
        self.obs_std, self.rng = obs_std, rng
        self.sign = side_sign(direction, "fusionripper")
        self.stage = IDLE
        self.switch_time: float | None = None
        self.offset = 0.0

    def _observe(self, view: AttackerView) -> None:
        t = view.t
        if t < self.start_time:
            self.stage, self.offset = IDLE, 0.0
            return
        if self.stage == IDLE:
            self.stage = PROFILING
        observed = view.phys_dev
        if self.rng is not None and self.obs_std > 0:
            observed += self.obs_std * float(self.rng.normal())
        pushed = -self.sign * observed
        if self.stage == PROFILING and math.isfinite(pushed) and pushed > self.trigger:
            self.stage, self.switch_time = AGGRESSIVE, t
        if self.switch_time is None:
            self.offset = self.sign * self.d
        else:
            k = math.floor(t - self.switch_time + 1e-9)
            self.offset = self.sign * self.d * self.f**k

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        self._observe(view)
        if self.offset == 0.0:
            return fix
        return dataclasses.replace(fix, xy=fix.xy + self.offset * left_normal(view.lane_heading))

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": self.switch_time, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {
            "kind": self.name,
            "d": self.d,
            "f": self.f,
            "direction": self.direction,
            "start": self.start_time,
            "trigger": self.trigger,
            "obs_std": self.obs_std,
        }
