# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`LanePlanner.plan`'s path terms compiled over the semantic map's kernel: the pose's lane coordinates, the lane
heading and curvature at its projection, and the curvature at the preview point walked along the centreline; and
the curves ahead of its curve speed limit, walked along the centreline in fixed steps.

The same map questions as the pure-Python planner in `testbed/control/planner.py`, asked in the same order
(so the map's memo and the reference line's walk see the same history), and the same arithmetic operation for
operation (the build turns off multiply-add contraction; the heading error is wrapped as Python's float `%`
does), so the plans are the same to the bit; `tests/control/test_planner_kernels.py` holds them to it.
"""

from libc.math cimport INFINITY, cos, fabs, pow, sin, sqrt

import numpy as np

from tracks.angles cimport wrap_angle
from tracks.float_order cimport py_max
from tracks.map_kernels cimport NO_LANE, PLACED, MapKernel


cdef class PathKernel:
    """The path terms of lane `lane` on the map kernel `smap`, the preview walked in steps of at most `step` m."""

    cdef MapKernel smap
    cdef object lane
    cdef Py_ssize_t lane_key
    cdef double step

    def __init__(self, MapKernel smap, lane, double step):
        self.smap, self.lane, self.step = smap, lane, step
        self.lane_key = smap._lane_arg(lane)

    def __reduce__(self):
        return PathKernel, (self.smap, self.lane, self.step)

    def terms(self, pose, double distance):
        """(lateral error, heading error, curvature `distance` ahead, curvature at the projection) of `pose`, or
        None where the map cannot place it (or the preview's last point)."""
        cdef MapKernel smap = self.smap
        cdef Py_ssize_t lane = self.lane_key, on
        cdef double x, y, yaw, s = 0.0, l, t = 0.0, lateral, px, py, heading, local, remaining, step, h, ahead_x
        cdef double ahead_y
        cdef int placed
        x, y, yaw = pose
        placed = smap._place(x, y, yaw, lane, &on, &s, &lateral, &t)
        if placed != PLACED:
            if placed == NO_LANE:
                raise smap._error(placed, pose, self.lane, x, y, s, t)
            return None
        smap._centre(on, s, &px, &py, &heading)  # lane_point and lane_curvature: the same question, kept
        local = smap._curvature(on, s)
        remaining, h = distance, heading
        while remaining > 1e-9:
            step = remaining if not (self.step < remaining) else self.step
            remaining -= step
            ahead_x, ahead_y = px + step * cos(h), py + step * sin(h)
            if smap._place(ahead_x, ahead_y, h, lane, &on, &s, &l, &t) != PLACED:
                break
            smap._centre(on, s, &px, &py, &h)
        if smap._place(px, py, h, lane, &on, &s, &l, &t) != PLACED:
            return None
        return lateral, wrap_angle(yaw - heading), smap._curvature(on, s), local

    def curves_ahead(self, pose, double horizon, double step, double lateral_accel):
        """`LanePlanner._curves_ahead` with the same map questions in the same order: (distances ahead,
        a_lat/|κ| there) as lists, every `step` m along the centreline up to `horizon`, where the lane curves; the
        walk stops where the map cannot place it (as the Python method stops at its OffMapError)."""
        cdef MapKernel smap = self.smap
        cdef Py_ssize_t lane = self.lane_key, on
        cdef double x, y, yaw, s = 0.0, l, t = 0.0, heading, d = 0.0, kappa
        cdef int placed
        ds, v2 = [], []
        x, y, yaw = pose
        placed = smap._place(x, y, yaw, lane, &on, &s, &l, &t)
        if placed == PLACED:
            smap._centre(on, s, &x, &y, &heading)
        while placed == PLACED:
            placed = smap._place(x, y, heading, lane, &on, &s, &l, &t)
            if placed != PLACED:
                break
            kappa = fabs(smap._curvature(on, s))
            if kappa > 1e-9:
                ds.append(d)
                v2.append(lateral_accel / kappa)
            if d >= horizon:
                return ds, v2
            placed = smap._place(x + step * cos(heading), y + step * sin(heading), heading, lane, &on, &s, &l, &t)
            if placed == PLACED:
                smap._centre(on, s, &x, &y, &heading)
                d = d + step
        if placed == NO_LANE:
            raise smap._error(placed, pose, self.lane, x, y, s, t)
        return ds, v2


cdef class CurveLimit:
    """`LanePlanner._curve_limit` compiled: the curves ahead (`PathKernel.curves_ahead`, up to `horizon` every
    `step` m at `lateral_accel`, `horizon` the distance to slow from the cruise speed at `decel` and a step) sampled
    every `period` s, brought nearer in between by the distance driven at the
    measured speed, and the highest speed from which each is reached braking at `decel`: the same operations as
    the method's numpy expression, element for element, and the same minimum."""

    cdef PathKernel path
    cdef double step, lateral_accel, decel, period
    cdef double sampled_t, travel
    cdef bint sampled
    cdef double[::1] d, v2

    def __init__(self, PathKernel path, double step, double lateral_accel, double decel, double period):
        self.path, self.step, self.lateral_accel = path, step, lateral_accel
        self.decel, self.period, self.sampled, self.travel = decel, period, False, 0.0

    def limit(self, pose, double speed, double t, t_last, double cruise_speed):
        """The curve speed limit at `t` for a car at `pose` moving at `speed`, `t_last` the planner's last plan
        time (None before its first), at the planner's cruise speed (`LanePlanner._horizon`'s arithmetic, its
        `**` libm's `pow` as Python's is)."""
        cdef Py_ssize_t i, n
        cdef double m, value, near, scale, horizon
        if not self.sampled or t - self.sampled_t >= self.period - 1e-9:
            horizon = pow(cruise_speed, 2.0) / (2.0 * self.decel) + self.step
            ds, v2 = self.path.curves_ahead(pose, horizon, self.step, self.lateral_accel)
            self.d, self.v2 = np.array(ds, dtype=float), np.array(v2, dtype=float)
            self.sampled, self.sampled_t, self.travel = True, t, 0.0
        elif t_last is not None:
            self.travel += py_max(speed, 0.0) * py_max(t - <double>t_last, 0.0)
        n = self.d.shape[0]
        if n == 0:
            return INFINITY
        scale = 2.0 * self.decel
        m = INFINITY
        for i in range(n):
            near = self.d[i] - self.travel - self.step
            if not (near >= 0.0 or near != near):  # np.maximum(near, 0.0)
                near = 0.0
            value = self.v2[i] + scale * near
            if value != value:  # np.min propagates a NaN
                return value
            if value < m:
                m = value
        return sqrt(m)
