"""Multi-sensor fusion in the style of Apollo's MSF: an error-state Kalman filter around IMU dead reckoning.

Nominal state (x, y, yaw, v, gyro bias, accel bias, lateral-velocity residual u) is propagated with each
IMU sample: ω = ω_m − b_g, yaw += ω dt, v += (a − b_a) dt, and the reference point (ahead of the rear axle
by `lever`) moves with body velocity (v, lever·ω + u): the kinematic sideslip of a car's centre plus a
random-walk residual for tyre slip. The 7-D error state δ = (δx, δy, δyaw, δv, δb_g, δb_a, δu) is zero
between updates (each correction is injected into the nominal state at once), so the filter carries only
its covariance P: predicted P ← F P Fᵀ + Q with F the linearisation of the propagation above, and updated
by filterpy's Kalman equations (gain K = P Hᵀ S⁻¹, S = H P Hᵀ + R; Joseph form P ← (I − KH) P (I − KH)ᵀ +
K R Kᵀ) on preallocated arrays. GNSS (x, y) and LiDAR (x, y, yaw) fixes observe the first 2 or 3 error
components (H = [I 0]) with the covariances their sensors report, after a chi-square innovation gate
(Mahalanobis distance of the innovation against S); the accepted correction K z is added to the nominal
state. The LiDAR locator is the filter's anchor: rejected for `lidar_reset_after` seconds in a
row, it is re-admitted by inflating the position covariance (the filter admits it may have drifted).
GNSS fixes that fail the gate are simply dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix, ImuSample, LidarFix
from tracks.compiled import compiled_module
from tracks.pose import Pose, wrap_angle

_N = 7
_IDENTITY = {n: np.eye(n) for n in range(1, _N + 1)}
"""Identity matrices to copy (`np.eye` builds one in Python)."""
_KERNELS = compiled_module("testbed.localization.msf_kernels")
try:  # the gufuncs `np.linalg.solve` (b a vector) and `np.linalg.inv` call for float64
    from numpy.linalg._umath_linalg import inv as _inv
    from numpy.linalg._umath_linalg import solve1 as _solve1
except ImportError:  # a numpy without the module: the public functions (`observed_prefix_update`)
    _inv = _solve1 = None


def propagate_covariance(p: np.ndarray, f: np.ndarray, q_diag: np.ndarray, scratch: np.ndarray) -> None:
    """P ← F P Fᵀ + diag(q) in place (filterpy's `predict` for a zero state), `scratch` an array like P."""
    np.dot(f, p, out=scratch)  # np.dot: the same BLAS product as np.matmul, with less call overhead
    np.dot(scratch, f.T, out=p)
    p.flat[:: len(p) + 1] += q_diag


def observed_prefix_update(p: np.ndarray, z: np.ndarray, r: np.ndarray, s: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update of a zero state whose first len(z) components are measured (H = [I 0]) as z with noise
    covariance R, S = H P Hᵀ + R given: the correction K z and the Joseph-form covariance (filterpy's `update`)."""
    n = len(z)
    k = p[:, :n] @ np.linalg.inv(s)
    i_kh = _IDENTITY[len(p)].copy() if len(p) in _IDENTITY else np.eye(len(p))
    i_kh[:, :n] -= k
    return k @ z, i_kh @ p @ i_kh.T + k @ r @ k.T


class PrefixUpdate:
    """The gated Kalman update of a zero state whose first `n` components are measured (H = [I 0]) on arrays
    allocated once: the operations of `observed_prefix_update` and of the gate's `z @ solve(S, z)` in the same
    order, with numpy's own gufuncs for `solve` and `inv` (called as `np.linalg` calls them for float64, without
    its argument handling) and each product numpy's matmul into its array, so every result is the same to the
    bit (tests/localization/test_msf_equations.py holds it to the reference)."""

    def __init__(self, n: int, size: int = _N) -> None:
        self.n = n
        self.s = np.empty((n, n))
        self.k = np.empty((size, n))
        self.kr = np.empty((size, n))
        self.dx = np.empty(size)
        self.i_kh = np.empty((size, size))
        self.left = np.empty((size, size))
        self.joseph = np.empty((size, size))
        self.noise = np.empty((size, size))
        self._identity = np.eye(size)
        self._i_kh_t, self._k_t = self.i_kh.T, self.k.T

    def distance(self, p: np.ndarray, z: np.ndarray, r: np.ndarray) -> float:
        """The innovation z's squared Mahalanobis distance against S = P[:n, :n] + R (S kept for `apply`)."""
        n = self.n
        np.add(p[:n, :n], r, out=self.s)
        d2 = float(np.matmul(z, _solve1(self.s, z, signature="dd->d")))
        if not math.isfinite(d2):  # a singular S: np.linalg.solve raises its LinAlgError as before
            d2 = float(z @ np.linalg.solve(self.s, z))
        return d2

    def apply(self, p: np.ndarray, z: np.ndarray, r: np.ndarray) -> np.ndarray:
        """P updated in place (Joseph form) after `distance`; returns the correction K z (an array it reuses)."""
        n, k = self.n, self.k
        np.matmul(p[:, :n], _inv(self.s, signature="d->d"), out=k)
        np.copyto(self.i_kh, self._identity)
        self.i_kh[:, :n] -= k
        np.matmul(k, z, out=self.dx)
        np.matmul(self.i_kh, p, out=self.left)
        np.matmul(self.left, self._i_kh_t, out=self.joseph)
        np.matmul(k, r, out=self.kr)
        np.matmul(self.kr, self._k_t, out=self.noise)
        np.add(self.joseph, self.noise, out=p)
        return self.dx


@dataclass(frozen=True)
class MsfParams:
    """Process noise densities, initial uncertainty and gating of the fusion filter."""

    accel_noise: float = 0.1
    gyro_noise: float = 0.005
    accel_bias_walk: float = 0.002
    gyro_bias_walk: float = 0.00005
    init_pos_std: float = 0.05
    init_yaw_std: float = 0.01
    init_speed_std: float = 0.1
    init_accel_bias_std: float = 0.05
    init_gyro_bias_std: float = 0.001
    lat_vel_walk: float = 0.05
    lever: float = 1.4
    gate_prob: float = 0.999
    lidar_reset_after: float = 3.0


class MultiSensorFusion:
    """Error-state KF fusing IMU propagation with gated GNSS and LiDAR-locator updates."""

    def __init__(self, start_pose: Pose, start_speed: float, params: MsfParams | None = None) -> None:
        self.params = p = params or MsfParams()
        self.nominal = np.array([start_pose.x, start_pose.y, start_pose.yaw, start_speed, 0.0, 0.0, 0.0])
        self.P = np.diag(
            [
                p.init_pos_std**2,
                p.init_pos_std**2,
                p.init_yaw_std**2,
                p.init_speed_std**2,
                p.init_gyro_bias_std**2,
                p.init_accel_bias_std**2,
                0.0,
            ]
        )
        self._f = np.eye(_N)
        self._fp = np.empty((_N, _N))
        self._q = np.array([0.0, 0.0, p.gyro_noise**2, p.accel_noise**2, p.gyro_bias_walk**2,
                            p.accel_bias_walk**2, p.lat_vel_walk**2])
        self._q_dt = np.empty(_N)
        self._predictor = None if _KERNELS is None else _KERNELS.Predictor(self.nominal, self._f, self.P, self._q,
                                                                          self._fp, p.lever)
        """`predict`'s propagation compiled (testbed/localization/msf_kernels.pyx), where built; it works on
        `nominal`, F and P in place, so P is only ever updated in place."""
        self._gated = None if _KERNELS is None else _KERNELS.GatedUpdate(self.nominal, self.P)
        """The gated update compiled in closed form (testbed/localization/msf_kernels.pyx), where built: equal to
        the reference to rounding; None: `_updates`."""
        self._updates = None if _solve1 is None else {n: PrefixUpdate(n) for n in (2, 3)}
        """The GNSS (2) and LiDAR (3) updates on preallocated arrays; None: `observed_prefix_update`."""
        self.t: float | None = None
        self._gate = {2: float(chi2.ppf(p.gate_prob, 2)), 3: float(chi2.ppf(p.gate_prob, 3))}
        self._last_accepted = {"gnss": -math.inf, "lidar": -math.inf}
        self.rejected = {"gnss": 0, "lidar": 0}

    def predict(self, imu: ImuSample) -> None:
        """Propagate the nominal state with one IMU sample and the error covariance with it."""
        if self.t is None:
            self.t = imu.t
            for k in self._last_accepted:
                self._last_accepted[k] = imu.t
            return
        dt = imu.t - self.t
        self.t = imu.t
        if dt <= 0.0:
            return
        if self._predictor is not None:
            self._predictor.predict(imu.yaw_rate, imu.accel_long, dt)
            return
        p = self.params
        x, y, yaw, v, bg, ba, u = self.nominal.tolist()
        c, s = math.cos(yaw), math.sin(yaw)
        omega = imu.yaw_rate - bg
        vl = p.lever * omega + u
        self.nominal[:4] = (
            x + (v * c - vl * s) * dt,
            y + (v * s + vl * c) * dt,
            wrap_angle(yaw + omega * dt),
            v + (imu.accel_long - ba) * dt,
        )
        f = self._f
        f[0, 2], f[0, 3], f[0, 4], f[0, 6] = (-v * s - vl * c) * dt, c * dt, p.lever * s * dt, -s * dt
        f[1, 2], f[1, 3], f[1, 4], f[1, 6] = (v * c - vl * s) * dt, s * dt, -p.lever * c * dt, c * dt
        f[2, 4] = -dt
        f[3, 5] = -dt
        np.multiply(self._q, dt, out=self._q_dt)
        propagate_covariance(self.P, f, self._q_dt, self._fp)

    def _gated_update(self, source: str, t: float, z: np.ndarray, r: np.ndarray) -> bool:
        n, gated = len(z), self._gated
        update = None if self._updates is None else self._updates[n]
        if gated is not None:
            d2 = gated.distance(z, r)
        elif update is not None:
            d2 = update.distance(self.P, z, r)
        else:
            s = self.P[:n, :n] + r
            d2 = float(z @ np.linalg.solve(s, z))
        if d2 > self._gate[n]:
            self.rejected[source] += 1
            if source == "lidar" and t - self._last_accepted[source] > self.params.lidar_reset_after:
                self._readmit(source, t, z)
            return False
        if gated is not None:
            gated.apply()
        else:
            if update is not None:
                dx = update.apply(self.P, z, r)
            else:
                dx, self.P[...] = observed_prefix_update(self.P, z, r, s)
            self.nominal += dx
            self.nominal[2] = wrap_angle(self.nominal[2])
        self._last_accepted[source] = t
        return True

    def _readmit(self, source: str, t: float, z: np.ndarray) -> None:
        """Inflate the position covariance to the rejected innovation so the next fix can be accepted."""
        inflation = float(np.max(z[:2] ** 2))
        self.P[0, 0] += inflation
        self.P[1, 1] += inflation
        self._last_accepted[source] = t

    def update_gnss(self, fix: GnssFix) -> bool:
        """Fuse a GNSS fix; returns False when the innovation gate rejects it."""
        z = np.asarray(fix.xy, float) - self.nominal[:2]
        return self._gated_update("gnss", fix.t, z, np.asarray(fix.cov, float))

    def update_lidar(self, fix: LidarFix) -> bool:
        """Fuse a LiDAR-locator pose; returns False when the innovation gate rejects it."""
        z = np.array([fix.xy[0] - self.nominal[0], fix.xy[1] - self.nominal[1], wrap_angle(fix.yaw - self.nominal[2])])
        return self._gated_update("lidar", fix.t, z, np.asarray(fix.cov, float))

    @property
    def pose(self) -> Pose:
        return Pose(*self.nominal[:3].tolist())

    @property
    def speed(self) -> float:
        return float(self.nominal[3])

    def estimate(self, t: float) -> LocalizationEstimate:
        return LocalizationEstimate(t, self.pose, self.P[:3, :3].copy())
