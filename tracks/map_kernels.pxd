# The compiled semantic map's declarations, for the kernels built on it (testbed/control/planner_kernels.pyx).
cimport cython

from tracks.reference_kernels cimport LineKernel


cdef enum Placed:
    PLACED = 0  # on the map: lane, s, l (and t) set
    NON_FINITE = 1  # the pose is not finite
    OFF_MAP = 2  # s beyond the ends or t beyond the lanes' reach (s and t set, for the message)
    NO_LANE = 3  # the lane asked for is not on the road


@cython.final
cdef class MapKernel:
    cdef LineKernel line
    cdef object reference, name
    cdef tuple _args
    cdef Py_ssize_t n_lanes, n_along
    cdef bint two_way
    cdef double length, reach_lo, reach_hi
    cdef double[::1] offsets, lows, highs, directions
    cdef Py_ssize_t memo_size, memo_count, memo_next
    cdef double memo_pose[8][3]  # x, y, yaw of the pose asked about
    cdef Py_ssize_t memo_lane[8][2]  # lane asked for (-1: None), lane answered
    cdef double memo_answer[8][2]  # s, l

    cdef int _place(self, double x, double y, double yaw, Py_ssize_t lane, Py_ssize_t* found, double* s,
                    double* l, double* t) except -1
    cdef Py_ssize_t _lane_at(self, double t, double yaw, double s) noexcept nogil
    cdef void _centre(self, Py_ssize_t lane, double s, double* x, double* y, double* heading) noexcept nogil
    cdef double _curvature(self, Py_ssize_t lane, double s) noexcept nogil
    cdef Py_ssize_t _lane_arg(self, object lane) except? -3
    cdef object _error(self, int placed, object pose, object lane, double x, double y, double s, double t)
    cdef Py_ssize_t _placed(self, object pose, object lane, double* s, double* l) except -1
