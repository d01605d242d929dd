"""SAVIOR baseline (paper §5.1, Appendix C): physical-invariant GNSS spoofing detection.

An EKF over (x, y, ψ, v) predicts with a kinematic bicycle model from the control commands (every control tick):
coefficients fitted on benign drives where given (the ROC campaign fits them), else the vanilla model
with the vehicle's wheelbase (closed-loop runs). It corrects with the measured wheel speed; on each GNSS
fix the residual |GNSS - predicted position| feeds a CUSUM(b, τ), and fixes are fused only while no alarm
has been raised. The EKF starts from the first finite MSF estimate it is handed.

Response (the paper compares detection only; this is the testbed's choice): on alarm SAVIOR stops like
LD3, on the ego-lane centreline at `ar_decel`, and the controller uses SAVIOR's own EKF pose, which from
then on is propagated from the commands and wheel speed alone (GNSS is no longer trusted).
"""

from __future__ import annotations

import logging
import math

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from pydantic import Field

from testbed.defense.attack_detection import Cusum
from testbed.defense.base import DefenseStatus, LatchingDefense
from testbed.defense.bicycle import BicycleCoefficients, BicycleModel, fit_bicycle_coefficients
from testbed.defense.faults import FaultLog, FaultRecord
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.params import Params
from tracks.map_api import SemanticMap
from tracks.pose import Pose

logger = logging.getLogger(__name__)

MAX_STEP_S = 0.05
"""Longest single Euler step of the prediction; longer gaps are split."""
_H_POS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_H_SPEED = np.array([[0.0, 0.0, 0.0, 1.0]])
_INITIAL_SPEED_VAR = 1.0


class SaviorConfig(Params):
    """SAVIOR's `[defense]` parameters: its CUSUM on the GNSS residual, its EKF's noise, the response's
    deceleration. SI units."""

    ar_decel: float = Field(4.0, gt=0.0, description="SAVIOR's attack-response deceleration: its in-lane stop (m/s²)")
    savior_b: float = Field(1.0, ge=0.0, description="SAVIOR CUSUM weight on the GNSS residual (m)")
    savior_tau: float = Field(3.0, ge=0.0, description="SAVIOR CUSUM threshold (m)")
    savior_speed_std: float = Field(0.1, gt=0.0, description="SAVIOR EKF: wheel-speed measurement noise (m/s)")
    savior_accel_std: float = Field(0.5, gt=0.0, description="SAVIOR EKF: longitudinal process noise (m/s²)")
    savior_yaw_rate_std: float = Field(0.05, gt=0.0, description="SAVIOR EKF: yaw-rate process noise (rad/s)")


class SaviorDefense(LatchingDefense):
    """Bicycle-model EKF + CUSUM on GNSS residuals."""

    name = "savior"
    fit_bicycle_coefficients = staticmethod(fit_bicycle_coefficients)

    def __init__(self, config: SaviorConfig, coefficients: BicycleCoefficients | None = None) -> None:
        self.config = config
        self.model = BicycleModel(coefficients or BicycleCoefficients())
        self.cusum = Cusum(config.savior_b, config.savior_tau)
        self.faults = FaultLog(logger)
        self.ekf: ExtendedKalmanFilter | None = None
        self.detection_time: float | None = None
        self.last_residual: float | None = None
        self._t: float | None = None
        self._steer = 0.0
        self._accel = 0.0
        self._speed = 0.0

    @property
    def alarm_threshold(self) -> float | None:
        return self.config.savior_tau

    @property
    def response_decel(self) -> float:
        return self.config.ar_decel

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        """SAVIOR ignores the lane lines; the first finite MSF estimate initialises its EKF."""
        if self.ekf is None and msf.pose.is_finite():
            self.start_from(msf)

    def on_command(self, t: float, steer: float, accel: float, speed: float) -> None:
        if not all(math.isfinite(v) for v in (t, steer, accel)):
            self.faults.report("bad-command", t, f"steer={steer}, accel={accel}; command ignored")
            return
        self._propagate(t)
        self._steer, self._accel = steer, accel
        if not math.isfinite(speed):
            self.faults.report("bad-command", t, f"speed={speed}; speed update skipped")
            return
        self._speed = speed
        if self.ekf is not None:
            self.ekf.update(
                np.array([[speed]]),
                lambda _: _H_SPEED,
                lambda x: _H_SPEED @ x,
                R=np.array([[self.config.savior_speed_std**2]]),
            )

    def on_gnss(self, t: float, xy: np.ndarray, cov: np.ndarray) -> None:
        if self.ekf is None or self.detection_time is not None:
            return
        xy = np.asarray(xy, dtype=float).reshape(2, 1)
        cov = np.asarray(cov, dtype=float)
        if not (np.isfinite(xy).all() and np.isfinite(cov).all() and math.isfinite(t)):
            self.faults.report("bad-gnss", t, "non-finite GNSS fix or covariance; fix skipped")
            return
        self._propagate(t)
        residual = float(np.hypot(*(xy - self.ekf.x[:2])[:, 0]))
        self.last_residual = residual
        if self.cusum.update(residual):
            self.detection_time = t
            logger.info("savior: attack detected at t=%.3f (S=%.3f)", t, self.cusum.statistic)
            return
        self.ekf.update(xy, lambda _: _H_POS, lambda x: _H_POS @ x, R=cov)

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        if self.detection_time is None or self.ekf is None:
            return msf.pose
        return self.predicted_pose()

    def predicted_pose(self) -> Pose:
        """The EKF's current (x, y, ψ); requires an initialised EKF."""
        assert self.ekf is not None
        x, y, yaw, _ = self.ekf.x[:, 0]
        return Pose(float(x), float(y), float(yaw))

    def status(self) -> DefenseStatus:
        return DefenseStatus(
            detected=self.detection_time is not None,
            detection_time=self.detection_time,
            cusum=self.cusum.statistic,
        )

    def fault_records(self) -> list[FaultRecord]:
        return self.faults.records()

    def start_from(self, msf: LocalizationEstimate) -> None:
        """Initialise the EKF at a finite MSF estimate, with the last measured speed."""
        ekf = ExtendedKalmanFilter(dim_x=4, dim_z=2)
        p = msf.pose
        ekf.x = np.array([[p.x], [p.y], [p.yaw], [self._speed]])
        cov = np.asarray(msf.cov, dtype=float)
        var = np.diag(cov) if cov.shape == (3, 3) and np.isfinite(cov).all() else np.ones(3)
        ekf.P = np.diag([*np.maximum(var, 1e-4), _INITIAL_SPEED_VAR])
        self.ekf = ekf
        self._t = msf.t

    def _propagate(self, t: float) -> None:
        """Advance the EKF to time t with the held command (no-op before init or for t in the past)."""
        if self.ekf is None or self._t is None:
            self._t = t
            return
        remaining = t - self._t
        cfg = self.config
        while remaining > 1e-9:
            dt = min(remaining, MAX_STEP_S)
            state = self.ekf.x[:, 0]
            f = self.model.jacobian(state, self._steer, self._accel, dt)
            self.ekf.x = self.model.step(state, self._steer, self._accel, dt).reshape(4, 1)
            q = np.diag([0.0, 0.0, (cfg.savior_yaw_rate_std * dt) ** 2, (cfg.savior_accel_std * dt) ** 2])
            self.ekf.P = f @ self.ekf.P @ f.T + q
            remaining -= dt
        self._t = max(self._t, t)
