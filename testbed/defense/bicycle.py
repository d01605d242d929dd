"""Kinematic bicycle model with fitted coefficients, SAVIOR's physical invariant (paper Appendix C).

State (x, y, ψ, v), inputs road-wheel steer δ and commanded acceleration a, wheelbase L (fixed):
  β = atan(c_r tan(c_δ δ)),  ẋ = v cos(ψ + β),  ẏ = v sin(ψ + β),  ψ̇ = v sin β / (c_r L),
  v̇ = c_a a - c_d v  (v held at >= 0).
c_r (rear-axle share of L), c_δ (steer gain), c_a (accel gain), c_d (drag, 1/s) are fitted on benign logs
by scipy's least squares on short open-loop simulations, standing in for Matlab's nlgreyest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

LOG_COLUMNS = ("t", "x", "y", "yaw", "speed", "steer", "accel")
"""Column order of a benign log array, one row per sample (commands held until the next row)."""


@dataclass(frozen=True)
class BicycleCoefficients:
    """Fitted coefficients of the bicycle model; the defaults are the vanilla (uncorrected) model. `lever` is
    geometry, not fitted: the vehicle pose's reference point ahead of the rear axle (m), which LD3's odometry
    carries (0: the rear axle)."""

    wheelbase: float = 2.8
    rear_ratio: float = 0.5
    steer_gain: float = 1.0
    accel_gain: float = 1.0
    drag: float = 0.0
    lever: float = 0.0


class BicycleModel:
    """Euler-discretised kinematic bicycle with its state Jacobian, for the EKF and the fit."""

    def __init__(self, coefficients: BicycleCoefficients) -> None:
        self.c = coefficients

    def step(self, state: np.ndarray, steer: float, accel: float, dt: float) -> np.ndarray:
        """State (4,) or (4, n) advanced by dt with the inputs held."""
        x, y, yaw, v = state
        c = self.c
        beta = np.arctan(c.rear_ratio * np.tan(c.steer_gain * steer))
        heading = yaw + beta
        v_next = np.maximum(v + (c.accel_gain * accel - c.drag * v) * dt, 0.0)
        return np.array(
            [
                x + v * np.cos(heading) * dt,
                y + v * np.sin(heading) * dt,
                yaw + v * np.sin(beta) / (c.rear_ratio * c.wheelbase) * dt,
                v_next,
            ]
        )

    def jacobian(self, state: np.ndarray, steer: float, accel: float, dt: float) -> np.ndarray:
        """∂step/∂state (4×4) at a single state."""
        _, _, yaw, v = (float(s) for s in state)
        c = self.c
        beta = float(np.arctan(c.rear_ratio * np.tan(c.steer_gain * steer)))
        cos_h, sin_h = np.cos(yaw + beta), np.sin(yaw + beta)
        braked_to_rest = v + (c.accel_gain * accel - c.drag * v) * dt <= 0.0
        return np.array(
            [
                [1.0, 0.0, -v * sin_h * dt, cos_h * dt],
                [0.0, 1.0, v * cos_h * dt, sin_h * dt],
                [0.0, 0.0, 1.0, np.sin(beta) / (c.rear_ratio * c.wheelbase) * dt],
                [0.0, 0.0, 0.0, 0.0 if braked_to_rest else 1.0 - c.drag * dt],
            ]
        )


_FIT_X0 = np.array([0.5, 1.0, 1.0, 0.0])
_FIT_BOUNDS = (np.array([0.05, 0.2, 0.2, 0.0]), np.array([1.0, 5.0, 5.0, 2.0]))


def fit_bicycle_coefficients(
    logs: Sequence[np.ndarray], wheelbase: float, horizon_s: float = 1.0
) -> BicycleCoefficients:
    """Fit (c_r, c_δ, c_a, c_d) on benign logs (N×7 arrays, columns `LOG_COLUMNS`).

    Every log is cut into windows of `horizon_s` (starting every half window); each window is simulated
    open loop from its measured first state with the logged commands, and the position and speed errors
    over all windows are minimised.
    """
    segments = [_segments(np.asarray(log, dtype=float), horizon_s) for log in logs]
    segments = [s for s in segments if s is not None]
    if not segments:
        raise ValueError(f"no usable log (N×7, finite, increasing t, longer than the {horizon_s} s horizon)")
    horizon = min(s[0].shape[1] for s in segments)
    cmd = np.concatenate([c[:, :horizon] for c, _ in segments])
    meas = np.concatenate([m[:, : horizon + 1] for _, m in segments])

    def residuals(p: np.ndarray) -> np.ndarray:
        model = BicycleModel(BicycleCoefficients(wheelbase, *p))
        state = meas[:, 0, :4].T
        errors = []
        for k in range(horizon):
            state = model.step(state, cmd[:, k, 0], cmd[:, k, 1], cmd[:, k, 2])
            errors.append(state[[0, 1, 3]] - meas[:, k + 1, [0, 1, 3]].T)
        return np.concatenate(errors).ravel()

    fit = least_squares(residuals, _FIT_X0, bounds=_FIT_BOUNDS)
    return BicycleCoefficients(wheelbase, *(float(p) for p in fit.x))


def _segments(log: np.ndarray, horizon_s: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(commands (n, H, 3) as steer, accel, dt; measured states (n, H + 1, 4) as x, y, yaw, v)."""
    if log.ndim != 2 or log.shape[1] != len(LOG_COLUMNS) or len(log) < 3 or not np.isfinite(log).all():
        return None
    dt = np.diff(log[:, 0])
    if not (dt > 0.0).all():
        return None
    horizon = round(horizon_s / float(np.median(dt)))
    if horizon < 1 or len(log) <= horizon:
        return None
    starts = np.arange(0, len(log) - horizon, max(horizon // 2, 1))
    steps = starts[:, None] + np.arange(horizon)[None, :]
    cmd = np.stack([log[steps, 5], log[steps, 6], dt[steps]], axis=-1)
    rows = starts[:, None] + np.arange(horizon + 1)[None, :]
    meas = log[rows][:, :, 1:5]
    return cmd, meas
