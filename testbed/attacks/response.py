"""Response-phase attack: a white-box attacker who forces LD3's alarm and then attacks the response.

From `start` the MSF pose is shifted `along` m along the lane (ramped over `lead` s; 0 for none), invisible to
the lateral checks. At start + `lead` it jumps `force` m sideways (+ left) and turns its yaw by `yaw` rad to force
the alarm (the turn also swings the car before the alarm comes). Once the alarm is
observed (the victim brakes: its speed falls `BRAKE_DV` below the speed at the jump; `cue = "observed"`) or
`delay` s after the jump (`"timed"`), the pose follows `policy`: `offmap` (moved `OFFMAP_M` sideways on the side
of the jump, off the map), `centre` (on the lane centre, lane-parallel: D_MSF = 0), `opposite` (the jump mirrored)
or `hold` (the jump kept). The along shift stays throughout.
"""

from __future__ import annotations

import math
from typing import Any

from testbed.attacks.along import along_lane
from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.profile import check_finite, ramp_fraction
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError
from tracks.pose import Pose

CUES = ("observed", "timed")
POLICIES = ("offmap", "centre", "opposite", "hold")
BRAKE_DV = 0.5
"""Speed drop (m/s) below the speed at the jump that tells the attacker the response has begun braking."""
OFFMAP_M = 40.0
"""How far sideways the `offmap` policy moves the pose (m): beyond any lane of the presets."""
IDLE, SHIFTING, FORCING, RESPONDING = "idle", "shifting", "forcing", "responding"


class ResponsePhaseAttack(Attack):
    """Forces the alarm, then steers the response's inputs (module docstring)."""

    name = "response"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, start: float = 10.0, along: float = 0.0, lead: float = 1.0, force: float = 2.5,
                 yaw: float = 0.0, cue: str = "observed", delay: float = 0.5, policy: str = "centre") -> None:
        super().__init__(start)
        for name, value, low in (("response along", along, None), ("response lead", lead, 0.0),
                                 ("response force", force, None), ("response yaw", yaw, None),
                                 ("response delay", delay, 0.0)):
            check_finite(name, value, low)
        if cue not in CUES:
            raise UserError(f"response cue must be one of {', '.join(CUES)}, got {cue!r}")
        if policy not in POLICIES:
            raise UserError(f"response policy must be one of {', '.join(POLICIES)}, got {policy!r}")
        self.along, self.lead, self.force, self.cue = along, lead, force, cue
        self.delay, self.policy, self.yaw = delay, policy, yaw
        self.stage = IDLE
        self.offset = 0.0
        self._forced: tuple[float, float] | None = None  # (time, victim speed) at the jump
        self._switched: float | None = None

    def _switch(self, view: AttackerView) -> bool:
        if self._switched is None and self._forced is not None:
            t0, v0 = self._forced
            seen = view.speed < v0 - BRAKE_DV if self.cue == "observed" else view.t >= t0 + self.delay
            if seen:
                self._switched = view.t
        return self._switched is not None

    def _lateral(self, view: AttackerView) -> float:
        """The sideways offset from the true pose this tick (m, + left)."""
        if not self._switch(view):
            return self.force
        if self.policy == "offmap":
            return math.copysign(OFFMAP_M, self.force)
        if self.policy == "centre":
            return -view.phys_dev if math.isfinite(view.phys_dev) else 0.0
        return -self.force if self.policy == "opposite" else self.force

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        elapsed = view.t - self.start_time
        if elapsed < 0.0:
            return est
        if self.whitebox is None:
            raise RuntimeError("response attack used before know(): it needs the map")
        pose = est.pose
        if self.along:
            pose = along_lane(pose, self.whitebox.smap, self.whitebox.lane,
                              ramp_fraction(elapsed, self.lead) * self.along)
        if elapsed < self.lead:
            self.stage, self.offset = SHIFTING, 0.0
            return LocalizationEstimate(est.t, pose, est.cov)
        if self._forced is None:
            self._forced = (view.t, view.speed)
        self.offset = self._lateral(view)
        self.stage = RESPONDING if self._switched is not None else FORCING
        try:
            heading = self.whitebox.smap.lane_point(pose, self.whitebox.lane)[1]
        except OffMapError:
            heading = view.lane_heading
        moved = shift_pose(pose, heading, self.offset)
        if self._switched is None or self.policy == "hold":
            moved = Pose(moved.x, moved.y, moved.yaw + self.yaw)
        elif self.policy == "centre":
            moved = Pose(moved.x, moved.y, heading)
        return LocalizationEstimate(est.t, moved, est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": self._switched, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "along": self.along, "lead": self.lead,
                "force": self.force, "yaw": self.yaw, "cue": self.cue, "delay": self.delay, "policy": self.policy}
