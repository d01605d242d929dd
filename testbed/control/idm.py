"""The Intelligent Driver Model (Treiber, Hennecke and Helbing 2000): a car's acceleration toward its desired
speed v0, braking for the vehicle ahead of it at bumper-to-bumper gap s closing at dv = v - v_lead:

    a_idm = a (1 - (v / v0)^delta - (s*(v, dv) / s)^2),   s* = s0 + max(0, v T + v dv / (2 sqrt(a b)))

clipped below at -`brake_limit` (what the tyres give); pure arithmetic, no physics engine.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

MIN_GAP_M = 1e-3
"""A gap at or below zero (touching or overlapping) is taken as this, so the model brakes as hard as it may."""


@dataclass(frozen=True)
class IdmParams:
    """IDM's parameters: maximum acceleration a, comfortable deceleration b (m/s²), time headway T (s),
    jam distance s0 (m), the free-road exponent delta and the hardest braking allowed (m/s²)."""

    accel: float = 1.5
    decel: float = 2.0
    headway: float = 1.5
    min_gap: float = 2.0
    delta: float = 4.0
    brake_limit: float = 9.0

    @functools.cached_property
    def braking_scale(self) -> float:
        """2 sqrt(a b), the scale of the closing term of s*."""
        return 2.0 * math.sqrt(self.accel * self.decel)


def desired_gap(p: IdmParams, v: float, dv: float) -> float:
    """s*(v, dv): the gap the driver wants at speed v closing on the leader at dv (m)."""
    return p.min_gap + max(0.0, v * p.headway + v * dv / p.braking_scale)


def idm_accel(p: IdmParams, v: float, v0: float, gap: float | None = None, dv: float = 0.0) -> float:
    """IDM acceleration (m/s²) at speed v toward desired speed v0 > 0, behind a leader `gap` m ahead closing at
    dv m/s (no leader: `gap` None), clipped at -brake_limit."""
    free = 1.0 - (max(v, 0.0) / v0) ** p.delta
    interaction = 0.0 if gap is None else (desired_gap(p, v, dv) / max(gap, MIN_GAP_M)) ** 2
    return max(p.accel * (free - interaction), -p.brake_limit)


def integrate(v: float, a: float, dt: float) -> tuple[float, float]:
    """(distance, new speed) over dt at constant acceleration a, stopping at standstill rather than reversing
    (the ballistic update of traffic simulators)."""
    if v + a * dt >= 0.0:
        return v * dt + 0.5 * a * dt * dt, v + a * dt
    return (-0.5 * v * v / a if a < 0 else 0.0), 0.0
