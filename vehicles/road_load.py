"""Road load: the force resisting forward motion, F = Crr·m·g·s(v) + ½·ρ·CdA·v·|v|.

s(v) = v / max(|v|, 0.1 m/s) softens the rolling-resistance sign change at standstill so a stopped
car is not pushed. The PyBullet vehicle applies this force to the body and feeds it forward in its
drive and brake torques.
"""

from __future__ import annotations

from vehicles.params import VehicleParams

AIR_DENSITY = 1.225
GRAVITY = 9.81
_SOFT_SPEED = 0.1


def road_load(params: VehicleParams, speed: float) -> float:
    """Resisting force (N) along the direction of travel at signed speed `speed` (m/s)."""
    rolling = params.rolling_resistance * params.mass * GRAVITY * speed / max(abs(speed), _SOFT_SPEED)
    drag = 0.5 * AIR_DENSITY * params.drag_area * speed * abs(speed)
    return rolling + drag
