# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`TrackMap`'s queries compiled for a map whose lanes have constant offsets and widths: `project` with its memo,
`lane_point` (`Lane.centre_at`) and `lane_curvature` (`Lane.curvature_at`), over the reference line's kernel.

The same arithmetic as the pure-Python methods in `tracks/semantic_map.py` and `tracks/lane.py`, operation for
operation and in the same order (the build turns off multiply-add contraction), the same checks in the same
order, the same errors with the same messages, and the same memo (the last `memo_size` distinct (pose, lane)
questions, the oldest replaced first, errors not kept), so the answers and the reference line's state after
them are the same to the bit; `tests/tracks/test_map_kernels.py` holds them to it.
"""

from libc.math cimport cos, isfinite, sin

from operator import index

import numpy as np

from tracks.map_api import LaneCoord, OffMapError

from tracks.reference_kernels cimport LineKernel

cdef Py_ssize_t MEMO_CAPACITY = 8  # the memo arrays' rows (map_kernels.pxd)
cdef double PI = 3.141592653589793
cdef Py_ssize_t NONE = -1  # the lane key of a question about the lane containing the pose
cdef Py_ssize_t INVALID = -2  # a lane not on the road (an error once the pose is placed)


cdef class MapKernel:
    """The semantic map of a road over its reference line's kernel `line` (`reference` answers points beyond the
    kernel's reach); lanes by `offsets`, `bounds` (lateral, on the reference line) and `directions` (+1 along the
    reference line, −1 against),
    the first `n_along` travelled along it on a two-way road (`two_way`), `reach` the lateral span that still
    counts as on the map, `name` the track's for messages."""

    def __init__(self, LineKernel line, object reference, str name, double length, tuple reach, offsets, bounds,
                 directions, bint two_way, Py_ssize_t n_along, Py_ssize_t memo_size=8):
        if not 0 < memo_size <= MEMO_CAPACITY:
            raise ValueError(f"memo size must be within 1..{MEMO_CAPACITY}, got {memo_size}")
        self.line, self.reference, self.name, self.length = line, reference, name, length
        self.reach_lo, self.reach_hi = reach
        self.n_lanes = len(offsets)
        self.offsets = np.array(offsets, dtype=float)
        self.lows = np.array([lo for lo, _ in bounds], dtype=float)
        self.highs = np.array([hi for _, hi in bounds], dtype=float)
        self.directions = np.array(directions, dtype=float)
        self.two_way, self.n_along = two_way, n_along
        self.memo_size, self.memo_count, self.memo_next = memo_size, 0, 0
        self._args = (line, reference, name, length, reach, list(offsets), list(bounds), list(directions), two_way,
                      n_along, memo_size)

    def __reduce__(self):
        return MapKernel, self._args

    cdef Py_ssize_t _lane_arg(self, object lane) except? -3:
        if lane is None:
            return NONE
        cdef Py_ssize_t i = index(lane)
        return i if 0 <= i < self.n_lanes else INVALID

    cdef int _place(self, double x, double y, double yaw, Py_ssize_t lane, Py_ssize_t* found, double* s, double* l,
                    double* t) except -1:
        """`TrackMap.project`: PLACED with the lane, s and l (the kept answer, or the new one kept), or why not."""
        cdef Py_ssize_t n
        for n in range(self.memo_count):
            if (self.memo_pose[n][0] == x and self.memo_pose[n][1] == y and self.memo_pose[n][2] == yaw
                    and self.memo_lane[n][0] == lane):
                found[0], s[0], l[0] = self.memo_lane[n][1], self.memo_answer[n][0], self.memo_answer[n][1]
                return PLACED
        if not (isfinite(x) and isfinite(y) and isfinite(yaw)):
            return NON_FINITE
        if not self.line._project(x, y, 20.0, s, t):
            s[0], t[0] = self.reference.project(x, y)
        if not (0.0 <= s[0] <= self.length and self.reach_lo <= t[0] <= self.reach_hi):
            return OFF_MAP
        if lane == INVALID:
            return NO_LANE
        cdef Py_ssize_t on = lane if lane != NONE else self._lane_at(t[0], yaw, s[0])
        found[0], l[0] = on, self.directions[on] * (t[0] - self.offsets[on])
        n = self.memo_next
        self.memo_pose[n][0], self.memo_pose[n][1], self.memo_pose[n][2] = x, y, yaw
        self.memo_lane[n][0], self.memo_lane[n][1] = lane, on
        self.memo_answer[n][0], self.memo_answer[n][1] = s[0], l[0]
        self.memo_next = (n + 1) % self.memo_size
        if self.memo_count < self.memo_size:
            self.memo_count += 1
        return PLACED

    cdef Py_ssize_t _lane_at(self, double t, double yaw, double s) noexcept nogil:
        """`TrackMap._lane_at` over `TrackMap._candidates`: the lane whose bounds hold t, else the nearer end."""
        cdef Py_ssize_t first = 0, end = self.n_lanes, i
        if self.two_way:
            if cos(yaw - self.line._heading_at(s)) >= 0.0:
                end = self.n_along
            else:
                first = self.n_along
        for i in range(first, end):
            if self.lows[i] <= t < self.highs[i]:
                return i
        return first if t < self.lows[first] else end - 1

    cdef void _centre(self, Py_ssize_t lane, double s, double* x, double* y, double* heading) noexcept nogil:
        """`Lane.centre_at`."""
        cdef double px, py, h
        self.line._frame(s, &px, &py, &h)
        cdef double t = self.offsets[lane] + self.directions[lane] * 0.0
        x[0], y[0] = px - t * sin(h), py + t * cos(h)
        heading[0] = h if self.directions[lane] > 0 else h + PI

    cdef double _curvature(self, Py_ssize_t lane, double s) noexcept nogil:
        """`Lane.curvature_at`."""
        cdef double k = self.line._curvature_at(s)
        return self.directions[lane] * k / (1.0 - k * self.offsets[lane])

    cdef object _error(self, int placed, object pose, object lane, double x, double y, double s, double t):
        if placed == NON_FINITE:
            return OffMapError(f"non-finite pose {pose}")
        if placed == OFF_MAP:
            return OffMapError(f"pose ({x:.2f}, {y:.2f}) is off the map of {self.name} (s={s:.1f}, t={t:.2f})")
        return ValueError(f"lane {lane} not on {self.name} (lanes 0..{self.n_lanes - 1})")

    cdef Py_ssize_t _placed(self, object pose, object lane, double* s, double* l) except -1:
        """The lane a (x, y, yaw) pose is placed on and its (s, l) there; raises as `TrackMap.project` does."""
        cdef double x, y, yaw, t = 0.0
        cdef Py_ssize_t found
        x, y, yaw = pose
        s[0] = 0.0
        cdef int placed = self._place(x, y, yaw, self._lane_arg(lane), &found, s, l, &t)
        if placed != PLACED:
            raise self._error(placed, pose, lane, x, y, s[0], t)
        return found

    def project(self, pose, lane=None):
        """`TrackMap.project`: the pose's `LaneCoord` on `lane` (None: the lane containing it)."""
        cdef double s, l
        cdef Py_ssize_t found = self._placed(pose, lane, &s, &l)
        return LaneCoord(found, s, l)

    def lane_point(self, pose, lane=None):
        """`TrackMap.lane_point` as (x, y, heading) of the lane centre at the pose's projection."""
        cdef double s, l, cx, cy, heading
        self._centre(self._placed(pose, lane, &s, &l), s, &cx, &cy, &heading)
        return cx, cy, heading

    def lane_curvature(self, pose, lane=None):
        """`TrackMap.lane_curvature`."""
        cdef double s, l
        return self._curvature(self._placed(pose, lane, &s, &l), s)

    def forget(self):
        """Drop the kept answers."""
        self.memo_count, self.memo_next = 0, 0

