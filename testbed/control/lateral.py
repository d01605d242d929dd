"""Gain-scheduled discrete LQR lateral controller on the path-error bicycle model, curvature feed-forward.

δ = δ_ss(v, κ) − K(v)·[e_y, v·sin e_ψ − v·e_ψss, e_ψ − e_ψss, r − v·κ_local], clamped to ±max_steer.
δ_ss and e_ψss are the steady-state cornering steer (kinematic + understeer) and sideslip heading error,
so the loop regulates around the cornering equilibrium and holds e_y → 0 on arcs. K(v) comes from
python-control's discrete LQR (`dlqr`) on the model discretised by its `c2d` (zero-order hold) at speeds
1..40 m/s and is linearly interpolated per tick.

With a steering-rate weight w > 0 the cost is ∫ xᵀQx + r·δ² + w·δ̇² dt: the LQR runs on the model augmented with
the last command, z = [x, δ_prev − δ_ss], input the step Δδ (weighted w/dt² per tick, so w means the same at any
rate), and δ = δ_prev − K_z(v)·z. As w → 0 this is the law above.

python-control is imported where the gains are designed, not with this module: it imports matplotlib's pyplot,
which importing the vehicle side or starting `ld3 --help` should not (tests/test_vehicle_install.py,
tests/test_figure_backend.py).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from testbed.control.lateral_model import LateralModel
from testbed.control.plan import Plan
from tracks.compiled import compiled_module

SCHEDULE_MIN_SPEED = 1.0
SCHEDULE_MAX_SPEED = 40.0
SCHEDULE_STEP = 1.0
_KERNELS = compiled_module("testbed.control.lateral_kernels")
GAIN_SCHEDULES_KEPT = 16
"""Gain schedules `gain_schedule` keeps (one per vehicle, control rate and tuning met in a process)."""


def discretise(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation of (A, B) over `dt` (python-control's `c2d`)."""
    import control

    n, m = a.shape[0], b.shape[1]
    sampled = control.c2d(control.ss(a, b, np.zeros((1, n)), np.zeros((1, m))), dt, method="zoh")
    return sampled.A, sampled.B


def dlqr(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, cross: np.ndarray | None = None
         ) -> np.ndarray:
    """Gain K of u = −K·x minimising Σ xᵀQx + uᵀRu + 2xᵀNu for x⁺ = A·x + B·u (N = `cross`, default 0; the
    stabilising solution of the DARE, by python-control's `dlqr` on scipy's solver whether or not slycot is
    installed, so the gains do not depend on it)."""
    import control

    if cross is None:
        cross = np.zeros((a.shape[0], b.shape[1]))
    gain, _, _ = control.dlqr(a, b, q, r, cross, method="scipy")
    return gain


def rate_lqr(ad: np.ndarray, bd: np.ndarray, q: np.ndarray, r: float, step_weight: float) -> np.ndarray:
    """Gain K_z of Δu = −K_z·[x, u_prev] minimising Σ xᵀQx + r·u² + s·Δu² with u = u_prev + Δu, for the
    discrete model x⁺ = Ad·x + Bd·u (s = `step_weight` per tick): the DARE of the model augmented with u_prev."""
    n = ad.shape[0]
    a_aug = np.block([[ad, bd], [np.zeros((1, n)), np.ones((1, 1))]])
    b_aug = np.vstack([bd, np.ones((1, 1))])
    q_aug = np.zeros((n + 1, n + 1))
    q_aug[:n, :n], q_aug[n, n] = q, r
    cross = np.zeros((n + 1, 1))
    cross[n, 0] = r
    return dlqr(a_aug, b_aug, q_aug, np.array([[r + step_weight]]), cross).ravel()


@functools.lru_cache(maxsize=GAIN_SCHEDULES_KEPT)
def gain_schedule(model: LateralModel, dt: float, q: tuple[float, ...], r: float, steer_rate_weight: float
                  ) -> np.ndarray:
    """The LQR gain rows at the schedule's speeds (`LqrLateralController`'s law), kept per design: every run of
    a campaign worker with the same vehicle, rate and tuning reuses the 40 Riccati solutions (seconds to
    compute) instead of solving them again. Read-only; the same bits as a fresh computation."""
    q_mat, r_mat = np.diag(q), np.array([[r]])
    gains = []
    for v in np.arange(SCHEDULE_MIN_SPEED, SCHEDULE_MAX_SPEED + 1e-9, SCHEDULE_STEP):
        ad, bd = discretise(*model.error_dynamics(float(v)), dt)
        if steer_rate_weight > 0.0:
            gains.append(rate_lqr(ad, bd, q_mat, r, steer_rate_weight / (dt * dt)))
        else:
            gains.append(dlqr(ad, bd, q_mat, r_mat).ravel())
    table = np.array(gains)
    table.setflags(write=False)
    return table


class LqrLateralController:
    """Steer command (rad, + left) from a `Plan`; LQR gains scheduled on speed, feed-forward on curvature."""

    def __init__(
        self,
        model: LateralModel,
        max_steer: float,
        dt: float,
        q: tuple[float, float, float, float] = (0.5, 0.0, 1.0, 0.0),
        r: float = 25.0,
        hold_speed: float = 0.1,
        steer_rate_weight: float = 0.0,
        max_lat_accel: float = math.inf,
    ) -> None:
        self.model = model
        self.max_steer = max_steer
        self.dt = dt
        self.hold_speed = hold_speed
        self.speeds = np.arange(SCHEDULE_MIN_SPEED, SCHEDULE_MAX_SPEED + 1e-9, SCHEDULE_STEP)
        self.steer_rate_weight = steer_rate_weight
        self.max_lat_accel = max_lat_accel
        self.gains = gain_schedule(model, dt, tuple(q), r, steer_rate_weight).copy()
        self._gain_rows = [tuple(float(g) for g in row) for row in self.gains]
        self._kv = model.understeer_gradient
        self._last = 0.0
        self._law = None if _KERNELS is None else _KERNELS.LateralLaw(
            model, self.gains, max_steer, hold_speed, steer_rate_weight > 0.0, max_lat_accel, SCHEDULE_MIN_SPEED,
            SCHEDULE_MAX_SPEED, SCHEDULE_STEP)
        """`update` compiled (testbed/control/lateral_kernels.pyx), where built; None: the methods below, the
        reference it is tested equal to."""

    @classmethod
    def from_vehicle(cls, vehicle: Any, dt: float, **tuning: Any) -> LqrLateralController:
        """Build from any object with `max_steer` and the attributes `LateralModel.from_vehicle` reads."""
        return cls(LateralModel.from_vehicle(vehicle), vehicle.max_steer, dt, **tuning)

    def gain(self, speed: float) -> tuple[float, ...]:
        """K(v) = [k_ey, k_ėy, k_eψ, k_ėψ] linearly interpolated in the schedule (clamped to its range)."""
        i, f = self._schedule_at(speed)
        (a1, a2, a3, a4), (b1, b2, b3, b4) = self._gain_rows[i], self._gain_rows[i + 1]
        return a1 + f * (b1 - a1), a2 + f * (b2 - a2), a3 + f * (b3 - a3), a4 + f * (b4 - a4)

    def rate_gain(self, speed: float) -> np.ndarray:
        """K_z(v) = [k_ey, k_ėy, k_eψ, k_ėψ, k_δ] of the steering-rate design, interpolated like `gain`."""
        i, f = self._schedule_at(speed)
        return self.gains[i] + f * (self.gains[i + 1] - self.gains[i])

    def _schedule_at(self, speed: float) -> tuple[int, float]:
        """The schedule row below `speed` (clamped to the schedule's range) and the fraction of the way to the next."""
        pos = (min(max(speed, SCHEDULE_MIN_SPEED), SCHEDULE_MAX_SPEED) - SCHEDULE_MIN_SPEED) / SCHEDULE_STEP
        i = min(int(pos), len(self.gains) - 2)
        return i, pos - i

    def reset(self) -> None:
        self._last = 0.0

    def update(self, plan: Plan, speed: float, yaw_rate: float | None = None) -> float:
        """Steer angle for this tick. `yaw_rate` (rad/s, gyro) is optional: without it the yaw rate is
        estimated from the last command through the steady-state yaw-rate gain. Holds the last command
        below `hold_speed` (no steering at standstill)."""
        if self._law is not None:
            self._last = self._law.update(plan, speed, yaw_rate, self._last)
            return self._last
        if speed < self.hold_speed:
            return self._last
        v = speed
        if yaw_rate is None:
            wheelbase = self.model.wheelbase
            yaw_rate = v * self._last / max(wheelbase + self._kv * v * v, 0.5 * wheelbase)
        steer_ss, heading_ss = self.model.steady_state(v, plan.curvature)
        e_y, e_psi = plan.lateral_error, plan.heading_error - heading_ss
        slip = math.sin(plan.heading_error) - heading_ss  # ė_y / v
        e_psi_rate = yaw_rate - v * plan.local_curvature
        if self.steer_rate_weight > 0.0:
            z = np.array([e_y, v * slip, e_psi, e_psi_rate, self._last - steer_ss])
            steer = self._last - float(self.rate_gain(v) @ z)
        else:
            k1, k2, k3, k4 = self.gain(v)
            steer = steer_ss - k1 * e_y - k2 * v * slip - k3 * e_psi - k4 * e_psi_rate
        limit = self.steer_limit(v, steer_ss)
        self._last = min(max(steer, -limit), limit)
        return self._last

    def steer_limit(self, speed: float, steer_ss: float) -> float:
        """The largest |steer|: the actuator's, and at speed the steady-state steer of the curvature that gives
        `max_lat_accel` (never below the road's own steady-state steer plus that)."""
        if math.isinf(self.max_lat_accel):
            return self.max_steer
        steer_max, _ = self.model.steady_state(speed, self.max_lat_accel / (speed * speed))
        return min(self.max_steer, abs(steer_ss) + abs(steer_max))
