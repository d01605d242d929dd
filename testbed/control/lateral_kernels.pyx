# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`LqrLateralController.update` compiled: the steady-state steer and sideslip, the gain interpolated in the
schedule, the error terms, the law (plain or with the steering-rate cost) and the steer limit.

The same arithmetic as the pure-Python methods in `testbed/control/lateral.py`, operation for operation (the
build turns off multiply-add contraction; Python's `min`, `max` and `int` as they treat floats), and the
steering-rate law's gain·state product through numpy's own `matmul` (the function the reference's `@` calls), so
every command is the same to the bit; `tests/control/test_lateral_kernels.py` holds it to it.
"""

from libc.math cimport fabs, isinf, sin
from tracks.float_order cimport py_max, py_min

import numpy as np


cdef class LateralLaw:
    """The steer command of a controller with the bicycle `model`, the gain rows `gains` at the schedule's speeds
    (`lo`..`hi` every `step` m/s), the actuator's `max_steer`, the `hold_speed` below which the last command is
    held, the steering-rate law where `rate` is true, and the lateral-acceleration cap `max_lat_accel`."""

    cdef double wheelbase, kv, lr, lf_mass, cr_wheelbase, max_steer, hold_speed, max_lat_accel, lo, hi, step
    cdef bint rate
    cdef const double[:, ::1] gains
    cdef double[::1] g, z
    cdef object _matmul, _g, _z

    def __init__(self, model, gains, double max_steer, double hold_speed, bint rate, double max_lat_accel,
                 double lo, double hi, double step):
        self.wheelbase, self.kv, self.lr = model.wheelbase, model.understeer_gradient, model.lr
        self.lf_mass, self.cr_wheelbase = model.lf * model.mass, model.cr * model.wheelbase
        self.max_steer, self.hold_speed, self.rate, self.max_lat_accel = max_steer, hold_speed, rate, max_lat_accel
        self.lo, self.hi, self.step = lo, hi, step
        self.gains = np.ascontiguousarray(gains, dtype=float)
        self._g, self._z = np.empty(self.gains.shape[1]), np.empty(self.gains.shape[1])
        self.g, self.z, self._matmul = self._g, self._z, np.matmul

    cdef inline void _steady(self, double speed, double curvature, double* steer, double* heading) noexcept:
        """`LateralModel.steady_state`."""
        cdef double v2k = speed * speed * curvature
        steer[0] = self.wheelbase * curvature + self.kv * v2k
        heading[0] = -self.lr * curvature + self.lf_mass * v2k / self.cr_wheelbase

    cdef Py_ssize_t _schedule_at(self, double speed, double* frac) except -1:
        """`LqrLateralController._schedule_at`."""
        cdef double pos = (py_min(py_max(speed, self.lo), self.hi) - self.lo) / self.step
        cdef Py_ssize_t i
        if pos != pos:
            raise ValueError("cannot convert float NaN to integer")
        i = <Py_ssize_t>pos
        if self.gains.shape[0] - 2 < i:
            i = self.gains.shape[0] - 2
        frac[0] = pos - i
        return i

    def update(self, plan, double speed, yaw_rate, double last):
        """`LqrLateralController.update` from its last command `last`: the steer angle for this tick."""
        cdef double v = speed, rate_v, steer_ss, heading_ss, e_y, e_psi, slip, e_psi_rate, steer, f, limit
        cdef double steer_max, heading_max, heading_error = plan.heading_error, a, b
        cdef Py_ssize_t i, j
        if speed < self.hold_speed:
            return last
        if yaw_rate is None:
            rate_v = v * last / py_max(self.wheelbase + self.kv * v * v, 0.5 * self.wheelbase)
        else:
            rate_v = yaw_rate
        self._steady(v, plan.curvature, &steer_ss, &heading_ss)
        e_y, e_psi = plan.lateral_error, heading_error - heading_ss
        slip = sin(heading_error) - heading_ss
        e_psi_rate = rate_v - v * plan.local_curvature
        i = self._schedule_at(v, &f)
        if self.rate:
            for j in range(self.g.shape[0]):
                a, b = self.gains[i, j], self.gains[i + 1, j]
                self.g[j] = a + f * (b - a)
            self.z[0], self.z[1], self.z[2], self.z[3], self.z[4] = e_y, v * slip, e_psi, e_psi_rate, last - steer_ss
            steer = last - <double>self._matmul(self._g, self._z)
        else:
            steer = (steer_ss - (self.gains[i, 0] + f * (self.gains[i + 1, 0] - self.gains[i, 0])) * e_y
                     - (self.gains[i, 1] + f * (self.gains[i + 1, 1] - self.gains[i, 1])) * v * slip
                     - (self.gains[i, 2] + f * (self.gains[i + 1, 2] - self.gains[i, 2])) * e_psi
                     - (self.gains[i, 3] + f * (self.gains[i + 1, 3] - self.gains[i, 3])) * e_psi_rate)
        if isinf(self.max_lat_accel):
            limit = self.max_steer
        else:
            if v * v == 0.0:
                raise ZeroDivisionError("float division by zero")
            self._steady(v, self.max_lat_accel / (v * v), &steer_max, &heading_max)
            limit = py_min(self.max_steer, fabs(steer_ss) + fabs(steer_max))
        return py_min(py_max(steer, -limit), limit)
