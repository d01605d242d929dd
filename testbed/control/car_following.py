"""Car following for the ego car: the Intelligent Driver Model's braking term caps the longitudinal command behind
a car ahead, as an adaptive cruise control on a range sensor (gap and speed of the nearest car ahead in its lane):

    a_follow = a (1 - (s*(v, v - v_lead) / s)^2),   s* = s0 + max(0, v T + v (v - v_lead) / (2 sqrt(a b)))

The planner's cruise speed stays the free-road target; the loop applies min(command, a_follow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from testbed.control.idm import IdmParams, idm_accel


@dataclass(frozen=True)
class LeadCar:
    """What the range sensor reports: bumper-to-bumper gap (m) to the nearest car ahead and its speed (m/s)."""

    gap: float
    speed: float


class CarFollowing:
    """The acceleration cap (m/s²) behind `lead`, or None with no car ahead."""

    def __init__(self, idm: IdmParams) -> None:
        self.idm = idm

    def cap(self, speed: float, lead: LeadCar | None) -> float | None:
        if lead is None:
            return None
        return idm_accel(self.idm, speed, math.inf, lead.gap, speed - lead.speed)
