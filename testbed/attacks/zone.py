"""Zone-timed MSF attack: a white-box attacker who knows where the map gates or weakens detection.

On the `index`-th time the victim enters a zone after `start` — an intersection (where lane lines are absent
and the paper's Alg. 1 is switched off) or a curve sharper than `kappa` — the MSF pose is moved `lateral`
metres sideways (+ left), ramped in over `ramp` s, and optionally `along` metres along the lane (so that the
believed pose enters a gated zone early). After the zone the offset is held `hold` s, then ramped out.
"""

from __future__ import annotations

import math
from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError
from tracks.pose import Pose

ZONES = ("intersection", "curve")
IDLE, ARMED, IN_ZONE, HOLDING, RELEASING, OVER = "idle", "armed", "in-zone", "holding", "releasing", "over"


class ZoneAttack(Attack):
    """Offsets the MSF pose only around a chosen occurrence of a road feature (module docstring)."""

    name = "zone"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 0.0, zone: str = "intersection", index: int = 0, lateral: float = 2.0,
                 ramp: float = 0.5, hold: float = 0.0, along: float = 0.0, kappa: float = 0.004) -> None:
        super().__init__(start)
        if zone not in ZONES:
            raise UserError(f"zone must be one of {', '.join(ZONES)}, got {zone!r}")
        if index < 0:
            raise UserError(f"zone index must be >= 0, got {index}")
        for name, value, low in (("zone lateral", lateral, None), ("zone ramp", ramp, 0.0), ("zone hold", hold, 0.0),
                                 ("zone along", along, None), ("zone kappa", kappa, 0.0)):
            check_finite(name, value, low)
        self.zone, self.index, self.lateral, self.ramp = zone, index, lateral, ramp
        self.hold, self.along, self.kappa = hold, along, kappa
        self.stage = IDLE
        self.offset = 0.0
        self._entries = 0
        self._inside = False
        self._on: float | None = None
        self._off: float | None = None

    def _in_zone(self, pose: Pose, heading: float) -> bool:
        smap = self.whitebox.smap if self.whitebox is not None else None
        if smap is None:
            raise RuntimeError("zone attack used before know(): it needs the map")
        probe = Pose(pose.x + self.along * math.cos(heading), pose.y + self.along * math.sin(heading), pose.yaw)
        try:
            if self.zone == "intersection":
                return smap.is_intersection(probe)
            return abs(smap.lane_curvature(probe, self.whitebox.lane)) >= self.kappa
        except OffMapError:
            return False

    def _advance(self, view: AttackerView) -> None:
        if view.t < self.start_time:
            return
        inside = self._in_zone(view.true_pose, view.lane_heading)
        entered, left = inside and not self._inside, self._inside and not inside
        self._inside = inside
        if self._on is None:
            self.stage = ARMED
            if entered:
                if self._entries == self.index:
                    self._on = view.t
                    self.stage = IN_ZONE
                self._entries += 1
        elif self._off is None and left:
            self._off = view.t
            self.stage = HOLDING

    def _magnitude(self, t: float) -> float:
        if self._on is None:
            return 0.0
        rise = ramp_fraction(t - self._on, self.ramp)
        if self._off is None:
            return rise
        released = t - self._off - self.hold
        if released >= 0.0:
            self.stage = RELEASING if released < self.ramp else OVER
        return rise * (1.0 - ramp_fraction(released, self.ramp))

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        self._advance(view)
        k = self._magnitude(view.t)
        self.offset = k * self.lateral
        if k == 0.0:
            return est
        moved = shift_pose(est.pose, view.lane_heading, self.offset)
        h = view.lane_heading
        moved = Pose(moved.x + k * self.along * math.cos(h), moved.y + k * self.along * math.sin(h), moved.yaw)
        return LocalizationEstimate(est.t, moved, est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": self._on, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "zone": self.zone, "index": self.index,
                "lateral": self.lateral, "ramp": self.ramp, "hold": self.hold, "along": self.along,
                "kappa": self.kappa}
