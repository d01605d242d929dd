# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`MultiSensorFusion`'s propagation and gated update compiled.

`Predictor`: the nominal state and F in C, P ← F P Fᵀ + Q dt, the same arithmetic as the pure-Python `predict`
in `testbed/localization/msf.py`, operation for operation (the build turns off multiply-add contraction; the
angle is wrapped as Python's float `%` does), and the two matrix products through numpy's own `dot`, so the
state and covariance are the same to the bit; `tests/localization/test_msf_kernels.py` holds them to it.

`GatedUpdate`: the gate's distance and the Joseph-form update in closed form on P's leading block (H = [I 0]),
equal to the reference (`observed_prefix_update`) to rounding, not to the bit: numpy's LAPACK and BLAS sum in
their own order; `tests/localization/test_msf_kernels.py` bounds the difference and holds the gate's decisions.
"""

from libc.math cimport cos, sin, sqrt

import numpy as np
from numpy.linalg import LinAlgError

from tracks.angles cimport wrap_angle
from tracks.float_order cimport py_max


cdef class Predictor:
    """Propagates a filter's nominal state (x, y, yaw, v, b_g, b_a, u) and its covariance P in place, with F,
    the process noise densities q and a scratch array the filter owns."""

    cdef double[::1] nominal
    cdef double[:, ::1] f
    cdef double[:, ::1] p
    cdef const double[::1] q
    cdef double lever
    cdef object _dot, _f, _ft, _p, _scratch

    def __init__(self, double[::1] nominal, double[:, ::1] f, double[:, ::1] p, const double[::1] q,
                 scratch, double lever):
        self.nominal, self.f, self.p, self.q, self.lever = nominal, f, p, q, lever
        self._dot, self._f, self._ft, self._p, self._scratch = np.dot, f.base, f.base.T, p.base, scratch

    cpdef predict(self, double yaw_rate, double accel_long, double dt):
        """One IMU sample of `dt` s (> 0): yaw rate and longitudinal specific force as measured."""
        cdef double[::1] n = self.nominal
        cdef double[:, ::1] f = self.f
        cdef double x = n[0], y = n[1], yaw = n[2], v = n[3], bg = n[4], ba = n[5], u = n[6]
        cdef double c = cos(yaw), s = sin(yaw)
        cdef double omega = yaw_rate - bg
        cdef double vl = self.lever * omega + u
        cdef double nx = x + (v * c - vl * s) * dt
        cdef double ny = y + (v * s + vl * c) * dt
        cdef double nyaw = wrap_angle(yaw + omega * dt)
        cdef double nv = v + (accel_long - ba) * dt
        n[0], n[1], n[2], n[3] = nx, ny, nyaw, nv
        f[0, 2], f[0, 3], f[0, 4], f[0, 6] = (-v * s - vl * c) * dt, c * dt, self.lever * s * dt, -s * dt
        f[1, 2], f[1, 3], f[1, 4], f[1, 6] = (v * c - vl * s) * dt, s * dt, -self.lever * c * dt, c * dt
        f[2, 4] = -dt
        f[3, 5] = -dt
        self._dot(self._f, self._p, self._scratch)
        self._dot(self._scratch, self._ft, self._p)
        cdef Py_ssize_t i
        for i in range(self.p.shape[0]):
            self.p[i, i] = self.p[i, i] + self.q[i] * dt


cdef class ImuPropagation:
    """`LocalizationStack.step`'s IMU part compiled: the samples `imu.samples` takes up to a tick (its schedule,
    its one call for the tick's draws, the bias random walks and the measured force and yaw rate, each sample's
    arithmetic as `Imu._sample`'s), each handed to `msf.predict` (its first through the Python method, the rest
    to the filter's `Predictor` as `predict` hands them; all to the method where the filter's `predict` was
    replaced on the instance, as instrumentation does). The `Imu`'s and the filter's Python state (biases, last
    sample, schedule, filter time) is read and written back every tick, so either path may take the next one."""

    cdef object imu, schedule, msf, sample
    cdef Predictor predictor
    cdef double accel_bias_walk, gyro_bias_walk, accel_std, gyro_std

    def __init__(self, imu, msf, sample):
        """`sample` builds an `ImuSample` (the filter's first sample goes through its Python `predict`)."""
        m = imu.model
        self.imu, self.schedule, self.msf, self.predictor, self.sample = imu, imu._schedule, msf, msf._predictor, sample
        self.accel_bias_walk, self.gyro_bias_walk = m.accel_bias_walk, m.gyro_bias_walk
        self.accel_std, self.gyro_std = m.accel_std, m.gyro_std

    def step(self, double t, double accel, double yaw_rate):
        """Every IMU sample due up to `t` with the tick's motion (`accel`, `yaw_rate`), propagated."""
        cdef object imu = self.imu, msf = self.msf, schedule = self.schedule, nxt_obj = schedule._next
        cdef double period = schedule.period, nxt = t if nxt_obj is None else <double>nxt_obj
        cdef double ab, gb, ts, dt, sq, a, w, last_t = 0.0, msf_t
        cdef bint has_last, own = "predict" not in msf.__dict__
        cdef Py_ssize_t k, n
        cdef double[::1] draws
        times = []
        while nxt <= t + 1e-9:
            times.append(nxt)
            nxt += period
        schedule._next = nxt
        n = len(times)
        if n:
            times[n - 1] = t
        draws = imu.rng.normal(size=4 * n)
        last_obj = imu._last_t
        has_last = last_obj is not None
        if has_last:
            last_t = last_obj
        ab, gb = imu.accel_bias, imu.gyro_bias
        for k in range(n):
            ts = times[k]
            dt = py_max(0.0, ts - last_t) if has_last else 0.0
            last_t, has_last = ts, True
            sq = sqrt(dt)
            ab += self.accel_bias_walk * sq * draws[4 * k]
            gb += self.gyro_bias_walk * sq * draws[4 * k + 1]
            a = accel + ab + self.accel_std * draws[4 * k + 2]
            w = yaw_rate + gb + self.gyro_std * draws[4 * k + 3]
            msf_t_obj = msf.t
            if msf_t_obj is None or not own:
                msf.predict(self.sample(ts, a, w))
                continue
            msf_t = msf_t_obj
            msf.t = ts
            if not ts - msf_t <= 0.0:
                self.predictor.predict(w, a, ts - msf_t)
        imu.accel_bias, imu.gyro_bias = ab, gb
        if has_last:
            imu._last_t = last_t


cdef enum:
    SIZE = 7  # the error state's dimension


cdef class GatedUpdate:
    """The gated Kalman update of a filter's zero error state whose first n = 2 (GNSS) or 3 (LiDAR) components
    are measured (H = [I 0]), on the filter's 7-element nominal state and 7 × 7 covariance P in place: S = P[:n, :n]
    + R inverted by its adjugate, K = P[:, :n] S⁻¹, P ← (P − K P[:n]) with K's columns taken off again on the
    right (the Joseph form (I − KH) P (I − KH)ᵀ) + K R Kᵀ, and K z added to the nominal state (yaw wrapped)."""

    cdef double[::1] nominal
    cdef double[:, ::1] p
    cdef double s_inv[3][3]
    cdef double z[3]
    cdef double r[3][3]
    cdef int n

    def __init__(self, double[::1] nominal, double[:, ::1] p):
        if nominal.shape[0] != SIZE or p.shape[0] != SIZE or p.shape[1] != SIZE:
            raise ValueError(f"a {SIZE}-element state and a {SIZE} x {SIZE} covariance are needed")
        self.nominal, self.p, self.n = nominal, p, 0

    def distance(self, const double[::1] z, const double[:, :] r) -> float:
        """The innovation z's squared Mahalanobis distance against S = P[:n, :n] + R; S⁻¹, z and R are kept for
        `apply`. A singular S raises numpy's LinAlgError, as `np.linalg.solve` does."""
        cdef int n = z.shape[0], i, j
        cdef double s[3][3]
        cdef double det, d2 = 0.0, row, cof00, cof01, cof02
        if not 2 <= n <= 3 or r.shape[0] != n or r.shape[1] != n:
            raise ValueError(f"2 or 3 measured components with an n x n noise covariance, got {n} and "
                             f"{r.shape[0]} x {r.shape[1]}")
        for i in range(n):
            self.z[i] = z[i]
            for j in range(n):
                self.r[i][j] = r[i, j]
                s[i][j] = self.p[i, j] + r[i, j]
        if n == 2:
            det = s[0][0] * s[1][1] - s[0][1] * s[1][0]
            if det == 0.0:
                raise LinAlgError("Singular matrix")
            self.s_inv[0][0], self.s_inv[0][1] = s[1][1] / det, -s[0][1] / det
            self.s_inv[1][0], self.s_inv[1][1] = -s[1][0] / det, s[0][0] / det
        else:
            cof00 = s[1][1] * s[2][2] - s[1][2] * s[2][1]
            cof01 = s[1][2] * s[2][0] - s[1][0] * s[2][2]
            cof02 = s[1][0] * s[2][1] - s[1][1] * s[2][0]
            det = s[0][0] * cof00 + s[0][1] * cof01 + s[0][2] * cof02
            if det == 0.0:
                raise LinAlgError("Singular matrix")
            self.s_inv[0][0], self.s_inv[1][0], self.s_inv[2][0] = cof00 / det, cof01 / det, cof02 / det
            self.s_inv[0][1] = (s[0][2] * s[2][1] - s[0][1] * s[2][2]) / det
            self.s_inv[1][1] = (s[0][0] * s[2][2] - s[0][2] * s[2][0]) / det
            self.s_inv[2][1] = (s[0][1] * s[2][0] - s[0][0] * s[2][1]) / det
            self.s_inv[0][2] = (s[0][1] * s[1][2] - s[0][2] * s[1][1]) / det
            self.s_inv[1][2] = (s[0][2] * s[1][0] - s[0][0] * s[1][2]) / det
            self.s_inv[2][2] = (s[0][0] * s[1][1] - s[0][1] * s[1][0]) / det
        for i in range(n):
            row = 0.0
            for j in range(n):
                row += self.s_inv[i][j] * self.z[j]
            d2 += self.z[i] * row
        self.n = n
        return d2

    def apply(self) -> None:
        """The update with the fix `distance` measured last: P (Joseph form) and the nominal state in place."""
        cdef int n = self.n, i, j, m
        cdef double[:, ::1] p = self.p
        cdef double[::1] nominal = self.nominal
        cdef double k[SIZE][3]
        cdef double kr[SIZE][3]
        cdef double left[SIZE][SIZE]
        cdef double acc, noise
        if n == 0:
            raise RuntimeError("apply follows a distance")
        self.n = 0
        for i in range(SIZE):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += p[i, m] * self.s_inv[m][j]
                k[i][j] = acc
        for i in range(SIZE):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += k[i][m] * self.r[m][j]
                kr[i][j] = acc
        for i in range(SIZE):  # (I − KH) P
            for j in range(SIZE):
                acc = p[i, j]
                for m in range(n):
                    acc -= k[i][m] * p[m, j]
                left[i][j] = acc
        for i in range(SIZE):  # · (I − KH)ᵀ + K R Kᵀ
            for j in range(SIZE):
                acc = left[i][j]
                for m in range(n):
                    acc -= left[i][m] * k[j][m]
                noise = 0.0
                for m in range(n):
                    noise += kr[i][m] * k[j][m]
                p[i, j] = acc + noise
        for i in range(SIZE):
            acc = 0.0
            for m in range(n):
                acc += k[i][m] * self.z[m]
            nominal[i] = nominal[i] + acc
        nominal[2] = wrap_angle(nominal[2])
