# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`ReferenceLine`'s point queries (`heading_at`, `curvature_at`, `frame`) and `project` with its memo of recent
answers, compiled, over the line's sample arrays.

The same arithmetic as the pure-Python methods in `tracks/geometry.py`, operation for operation and in the
same order (C evaluates left to right like Python, the build turns off multiply-add contraction, and the
trigonometry is the same C library's), so the answers are the same to the bit;
`tests/tracks/test_reference_kernels.py` holds them to it. Python's `min`/`max` keep their first argument on a
tie, and so do `_min`/`_max` here. The arrays: `samples` (n, 5) = x, y, cos heading, sin heading, curvature at
s = i·ds; `segs` (m, 4) = s0, heading, curvature, curvature rate at each segment's start; `coarse` (k, 2) =
every `stride`-th sample's x, y. Coordinates must be finite and within 1e9 m (the caller checks).
"""

from libc.math cimport atan2, cos, fabs, floor, sin, INFINITY

cdef Py_ssize_t MEMO_CAPACITY = 16  # the `memo` array's rows (reference_kernels.pxd)
cdef double REACH = 1e9  # m: coordinates `_project` answers; beyond (and NaN) the caller's Python path does


cdef inline double _max(double a, double b) noexcept nogil:
    return b if b > a else a


cdef inline double _min(double a, double b) noexcept nogil:
    return b if b < a else a


cdef inline Py_ssize_t _clamp(Py_ssize_t i, Py_ssize_t last) noexcept nogil:
    return 0 if i < 0 else (last if i > last else i)


cdef class LineKernel:
    """A reference line's frame and projection queries; `hint` is the sample the last projection settled on
    (-1: none yet), the walk's starting point for the next; the last `memo_size` answers are kept."""

    def __init__(self, const double[:, ::1] samples, const double[:, ::1] segs, const double[:, ::1] coarse,
                 Py_ssize_t stride, double ds, double length, Py_ssize_t memo_size=16):
        if not 0 < memo_size <= MEMO_CAPACITY:
            raise ValueError(f"memo size must be within 1..{MEMO_CAPACITY}, got {memo_size}")
        self.samples, self.segs, self.coarse = samples, segs, coarse
        self.stride, self.ds, self.length = stride, ds, length
        self.last = samples.shape[0] - 1
        self.hint = -1
        self.memo_size, self.memo_count, self.memo_next = memo_size, 0, 0

    def __reduce__(self):
        return LineKernel, (self.samples.base, self.segs.base, self.coarse.base, self.stride, self.ds, self.length,
                            self.memo_size)

    cdef Py_ssize_t _segment(self, double s) noexcept nogil:
        """bisect_right over the segment starts, less one."""
        cdef Py_ssize_t lo = 0, hi = self.segs.shape[0], mid
        while lo < hi:
            mid = (lo + hi) // 2
            if s < self.segs[mid, 0]:
                hi = mid
            else:
                lo = mid + 1
        return lo - 1

    cdef double _heading_at(self, double s) noexcept nogil:
        s = _min(_max(s, 0.0), self.length)
        cdef Py_ssize_t i = self._segment(s)
        if i < 0:
            i = 0
        cdef double u = s - self.segs[i, 0]
        return self.segs[i, 1] + self.segs[i, 2] * u + 0.5 * self.segs[i, 3] * u * u

    cdef double _curvature_at(self, double s) noexcept nogil:
        if s < 0.0 or s > self.length:
            return 0.0
        cdef Py_ssize_t i = self._segment(s)
        if i < 0:
            i = 0
        return self.segs[i, 2] + self.segs[i, 3] * (s - self.segs[i, 0])

    cdef void _frame(self, double s, double* x, double* y, double* h) noexcept nogil:
        cdef double ds = self.ds
        cdef double sc = _min(_max(s, 0.0), self.length)
        cdef Py_ssize_t i = <Py_ssize_t>(sc / ds)
        if i > self.last:
            i = self.last
        cdef double d = sc - i * ds
        cdef Py_ssize_t j = self._segment(sc)
        cdef double s0 = self.segs[j, 0], h0 = self.segs[j, 1], k0 = self.segs[j, 2], dk = self.segs[j, 3]
        cdef double u = sc - s0
        cdef double hh = h0 + k0 * u + 0.5 * dk * u * u
        cdef double um = u - 0.5 * d
        cdef double h_mid
        if um >= 0.0:
            h_mid = h0 + k0 * um + 0.5 * dk * um * um
        else:
            h_mid = self._heading_at(sc - 0.5 * d)
        cdef double k = self.samples[i, 4]
        cdef double chord = d * (1.0 - k * k * d * d / 24.0)
        cdef double px = self.samples[i, 0] + chord * cos(h_mid)
        cdef double py = self.samples[i, 1] + chord * sin(h_mid)
        if s != sc:
            px += (s - sc) * cos(hh)
            py += (s - sc) * sin(hh)
        x[0], y[0], h[0] = px, py, hh

    def heading_at(self, double s):
        """Heading (rad) at arc length s; constant beyond the ends."""
        return self._heading_at(s)

    def curvature_at(self, double s):
        """Signed curvature (1/m) at arc length s; zero beyond the ends."""
        return self._curvature_at(s)

    def frame(self, double s):
        """(x, y, heading) at arc length s; s finite."""
        cdef double x, y, h
        self._frame(s, &x, &y, &h)
        return x, y, h

    cdef Py_ssize_t _walk(self, double x, double y, Py_ssize_t i, bint* settled) noexcept nogil:
        cdef Py_ssize_t previous = -1, j, n
        cdef double a
        for n in range(12):
            a = (x - self.samples[i, 0]) * self.samples[i, 2] + (y - self.samples[i, 1]) * self.samples[i, 3]
            j = _clamp(i + <Py_ssize_t>floor(a / self.ds), self.last)
            if j == i or j == previous:
                settled[0] = True
                return j if j < i else i
            previous, i = i, j
        settled[0] = False
        return i

    cdef void _refine(self, double x, double y, Py_ssize_t i, double* s_out, double* t_out) noexcept nogil:
        cdef double c = self.samples[i, 2], sn = self.samples[i, 3]
        cdef double dx = x - self.samples[i, 0], dy = y - self.samples[i, 1]
        cdef double a = dx * c + dy * sn, t = -dx * sn + dy * c
        cdef double k = self.samples[i, 4]
        cdef double s, px, py, h, denom
        cdef int n
        if fabs(k) > 1e-12:
            s = i * self.ds + atan2(k * a, 1.0 - k * t) / k
        else:
            s = i * self.ds + a
        for n in range(4):
            self._frame(s, &px, &py, &h)
            c, sn = cos(h), sin(h)
            dx, dy = x - px, y - py
            a = dx * c + dy * sn
            t = -dx * sn + dy * c
            if fabs(a) < 1e-6:
                s_out[0], t_out[0] = s + a, t
                return
            k = self._curvature_at(s)
            denom = 1.0 - k * t
            if denom > 0.1:
                s += a / denom
            else:
                s += a
        s_out[0], t_out[0] = s, t

    cdef void _canonical_refine(self, double x, double y, Py_ssize_t i, double* s, double* t) noexcept nogil:
        self._refine(x, y, i, s, t)
        cdef Py_ssize_t k = _clamp(<Py_ssize_t>floor(s[0] / self.ds), self.last)
        if k != i:
            self._refine(x, y, k, s, t)
        self.hint = k

    cdef void _solve(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil:
        """`ReferenceLine._project`, from `hint`."""
        cdef double ex, ey, d2, best_d2 = INFINITY
        cdef Py_ssize_t i, n, best = 0
        cdef bint settled
        if self.hint >= 0:
            i = self._walk(x, y, self.hint, &settled)
            if settled:
                self._canonical_refine(x, y, i, s, t)
                if fabs(t[0]) <= max_offset:
                    return
        for n in range(self.coarse.shape[0]):
            ex, ey = self.coarse[n, 0] - x, self.coarse[n, 1] - y
            d2 = ex * ex + ey * ey
            if d2 < best_d2:
                best, best_d2 = n, d2
        i = self._walk(x, y, best * self.stride, &settled)
        self._canonical_refine(x, y, i, s, t)

    cdef bint _recall(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil:
        """The kept answer for (x, y, max_offset), compared as Python compares the memo's float keys."""
        cdef Py_ssize_t n
        for n in range(self.memo_count):
            if self.memo[n][0] == x and self.memo[n][1] == y and self.memo[n][2] == max_offset:
                s[0], t[0] = self.memo[n][3], self.memo[n][4]
                return True
        return False

    cdef void _keep(self, double x, double y, double max_offset, double s, double t) noexcept nogil:
        """Keep an answer, replacing the oldest beyond `memo_size` (`tracks.recent.RecentAnswers`)."""
        cdef Py_ssize_t n = self.memo_next
        self.memo[n][0], self.memo[n][1], self.memo[n][2], self.memo[n][3], self.memo[n][4] = x, y, max_offset, s, t
        self.memo_next = (n + 1) % self.memo_size
        if self.memo_count < self.memo_size:
            self.memo_count += 1

    cdef bint _project(self, double x, double y, double max_offset, double* s, double* t) noexcept nogil:
        """`ReferenceLine.project`: the kept answer, or the solved one kept; False (nothing kept or changed)
        for a point beyond the kernel's reach, which the Python path answers and `keep`s."""
        if self._recall(x, y, max_offset, s, t):
            return True
        if not (fabs(x) < REACH and fabs(y) < REACH):
            return False
        self._solve(x, y, max_offset, s, t)
        self._keep(x, y, max_offset, s[0], t[0])
        return True

    def project(self, double x, double y, double max_offset):
        """(s, t) of the nearest reference point: `ReferenceLine._project`, from `hint` (no memo)."""
        cdef double s, t
        self._solve(x, y, max_offset, &s, &t)
        return s, t

    def recall_project(self, double x, double y, double max_offset):
        """`ReferenceLine.project` with its memo: (s, t), or None for a point beyond the kernel's reach that was
        not asked before (then the Python path answers it and `keep` keeps it)."""
        cdef double s, t
        if self._project(x, y, max_offset, &s, &t):
            return s, t
        return None

    def keep(self, double x, double y, double max_offset, tuple answer):
        """Keep `answer` = (s, t) for the point and return it."""
        self._keep(x, y, max_offset, answer[0], answer[1])
        return answer

    def forget(self):
        """Drop the kept answers."""
        self.memo_count, self.memo_next = 0, 0
