# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`MultiSensorFusion.predict`'s propagation compiled: the nominal state and F in C, P ← F P Fᵀ + Q dt.

The same arithmetic as the pure-Python method in `testbed/localization/msf.py`, operation for operation (the
build turns off multiply-add contraction; the angle is wrapped as Python's float `%` does), and the two
matrix products through numpy's own `dot`, so the state and covariance are the same to the bit;
`tests/localization/test_msf_kernels.py` holds them to it.
"""

from libc.math cimport cos, sin

import numpy as np

from tracks.angles cimport wrap_angle


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

    def predict(self, double yaw_rate, double accel_long, double dt):
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
