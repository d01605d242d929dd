# The compiled reference line's declarations, for the kernels built on it (tracks/map_kernels.pyx).
cimport cython


@cython.final
cdef class LineKernel:
    cdef const double[:, ::1] samples
    cdef const double[:, ::1] segs
    cdef const double[:, ::1] coarse
    cdef Py_ssize_t stride, last
    cdef double ds, length
    cdef public Py_ssize_t hint
    cdef Py_ssize_t memo_size, memo_count, memo_next
    cdef double memo[16][5]  # x, y, max_offset -> s, t; the oldest replaced first

    cdef Py_ssize_t _segment(self, double s) noexcept nogil
    cdef double _heading_at(self, double s) noexcept nogil
    cdef double _curvature_at(self, double s) noexcept nogil
    cdef void _frame(self, double s, double* x, double* y, double* h) noexcept nogil
    cdef Py_ssize_t _walk(self, double x, double y, Py_ssize_t i, bint* settled) noexcept nogil
    cdef void _refine(self, double x, double y, Py_ssize_t i, double* s_out, double* t_out) noexcept nogil
    cdef void _canonical_refine(self, double x, double y, Py_ssize_t i, double* s, double* t) noexcept nogil
    cdef void _solve(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil
    cdef bint _recall(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil
    cdef void _keep(self, double x, double y, double max_offset, double s, double t) noexcept nogil
    cdef bint _project(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil
