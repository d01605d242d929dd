"""Linear dynamic bicycle model in path-error coordinates (Rajamani, Vehicle Dynamics and Control §2.5, §3.2).

State x = [e_y, ė_y, e_ψ, ė_ψ] (lateral error + left, heading error yaw − path heading), input the
road-wheel steer angle δ; cornering stiffnesses are per axle (N/rad) and linear tyres are assumed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

GRAVITY = 9.81
# Per-axle cornering stiffness per newton of axle load (1/rad): a typical passenger-car tyre value.
DEFAULT_CORNERING_COEFF = 16.0


@dataclass(frozen=True)
class LateralModel:
    """Single-track vehicle: wheelbase, mass, yaw inertia, CG-to-front-axle distance, axle stiffnesses."""

    wheelbase: float
    mass: float
    yaw_inertia: float
    lf: float
    cf: float
    cr: float

    @classmethod
    def from_geometry(
        cls,
        wheelbase: float,
        mass: float,
        lf: float | None = None,
        yaw_inertia: float | None = None,
        cf: float | None = None,
        cr: float | None = None,
    ) -> LateralModel:
        """Fill what is not given: CG at mid-wheelbase, I_z ≈ m·lf·lr, stiffness ∝ static axle load."""
        lf = wheelbase / 2.0 if lf is None else lf
        lr = wheelbase - lf
        yaw_inertia = mass * lf * lr if yaw_inertia is None else yaw_inertia
        cf = DEFAULT_CORNERING_COEFF * mass * GRAVITY * lr / wheelbase if cf is None else cf
        cr = DEFAULT_CORNERING_COEFF * mass * GRAVITY * lf / wheelbase if cr is None else cr
        return cls(wheelbase, mass, yaw_inertia, lf, cf, cr)

    @classmethod
    def from_vehicle(cls, vehicle: Any) -> LateralModel:
        """From any object with `wheelbase`, `mass` and optionally `lf` (CG to front axle), `yaw_inertia`,
        `cornering_stiffness_front`, `cornering_stiffness_rear` (per axle, N/rad)."""
        return cls.from_geometry(
            vehicle.wheelbase,
            vehicle.mass,
            lf=getattr(vehicle, "lf", None),
            yaw_inertia=getattr(vehicle, "yaw_inertia", None),
            cf=getattr(vehicle, "cornering_stiffness_front", None),
            cr=getattr(vehicle, "cornering_stiffness_rear", None),
        )

    @property
    def lr(self) -> float:
        return self.wheelbase - self.lf

    @property
    def understeer_gradient(self) -> float:
        """K_v (rad per m/s² of lateral acceleration): δ_ss = L·κ + K_v·v²·κ."""
        return self.mass / self.wheelbase * (self.lr / self.cf - self.lf / self.cr)

    def error_dynamics(self, speed: float) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time (A, B) of ẋ = A x + B δ at longitudinal speed `speed` (> 0)."""
        m, iz, lf, lr, cf, cr, v = self.mass, self.yaw_inertia, self.lf, self.lr, self.cf, self.cr, speed
        c0, c1, c2 = cf + cr, lr * cr - lf * cf, lf**2 * cf + lr**2 * cr
        a = np.array(
            [
                [0.0, 1.0, 0.0, 0.0],
                [0.0, -c0 / (m * v), c0 / m, c1 / (m * v)],
                [0.0, 0.0, 0.0, 1.0],
                [0.0, c1 / (iz * v), -c1 / iz, -c2 / (iz * v)],
            ]
        )
        b = np.array([[0.0], [cf / m], [0.0], [lf * cf / iz]])
        return a, b

    def steady_state(self, speed: float, curvature: float) -> tuple[float, float]:
        """Steer angle and heading error (sideslip) holding e_y = 0 on a circle of curvature κ."""
        v2k = speed * speed * curvature
        steer = self.wheelbase * curvature + self.understeer_gradient * v2k
        heading_error = -self.lr * curvature + self.lf * self.mass * v2k / (self.cr * self.wheelbase)
        return steer, heading_error
