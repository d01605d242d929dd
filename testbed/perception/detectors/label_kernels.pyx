# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""The map's true ego lines (`testbed.perception.detectors.labels._line_truth`: the oracle detector's fit, twice per camera
frame), compiled: the samples of a lane line in the car's frame, its crossing of x = 0 beside the car, the cubic
fitted over the range ahead, and the marking kinds in view.

The same arithmetic as the pure-Python path, operation for operation and in the same order (the build turns off
multiply-add contraction; cos, sin and tan are the C library's, which numpy's float64 cos and sin and Python's
math call on the machines this runs on; `xs ** 3` and the least-squares solve are numpy's own calls, the solve
through the gufunc `np.linalg.lstsq` calls, without its argument handling), so every answer is the same to the
bit; `tests/perception/detectors/test_label_kernels.py` holds them to it. Python's `min`/`max` keep their first argument
on a tie, and so do `_min`/`_max` here.
"""

import numpy as np

try:
    from numpy.linalg._umath_linalg import lstsq as _lstsq
except ImportError:  # a numpy without the module: its public function
    _lstsq = None

from libc.math cimport NAN, cos, fabs, isnan, sin, tan

from tracks.angles cimport wrap_angle
from tracks.reference_kernels cimport LineKernel

cdef double X_MAX = 40.0, X_VIEW_NEAR = 5.0, X_VIEW_FAR = 25.0  # labels.X_MAX, X_VIEW_NEAR, X_VIEW_FAR
cdef double FIT_TOLERANCE = 0.10, FIT_SHRINK = 0.8, X_FIT_MIN = 8.0  # labels.FIT_TOLERANCE, FIT_SHRINK, X_FIT_MIN
cdef double EPS = np.finfo(np.float64).eps


cdef inline double _max(double a, double b) noexcept nogil:
    return b if b > a else a


cdef inline double _min(double a, double b) noexcept nogil:
    return b if b < a else a


cdef inline double _heading_array(const double[:, ::1] segs, double s) noexcept nogil:
    """`ReferenceLine._heading_array` of one element: the segment by `searchsorted(..., 'right') - 1` clipped to
    the segments, no clamping of s (the quadratic runs on beyond the last segment)."""
    cdef Py_ssize_t lo = 0, hi = segs.shape[0], mid
    while lo < hi:
        mid = (lo + hi) // 2
        if s < segs[mid, 0]:
            hi = mid
        else:
            lo = mid + 1
    lo -= 1
    if lo < 0:
        lo = 0
    cdef double u = s - segs[lo, 0]
    return segs[lo, 1] + segs[lo, 2] * u + (0.5 * segs[lo, 3] * u * u)


cdef inline void _point_one(LineKernel line, const double[::1] grid, double s, double t, double* px,
                            double* py) noexcept nogil:
    """`ReferenceLine.points_one`."""
    cdef double sc = _min(_max(s, 0.0), line.length)
    cdef Py_ssize_t i = <Py_ssize_t>(sc / line.ds)
    if i > line.last:
        i = line.last
    cdef double d = sc - grid[i]
    cdef double k = line.samples[i, 4]
    cdef double chord = d * (1.0 - k * k * d * d / 24.0)
    cdef double h_mid = line._heading_at(sc - 0.5 * d)
    cdef double h = line._heading_at(sc)
    px[0] = line.samples[i, 0] + chord * cos(h_mid) - t * sin(h)
    py[0] = line.samples[i, 1] + chord * sin(h_mid) + t * cos(h)


def vehicle_samples(LineKernel line, const double[::1] grid, double t, double px, double py, double c, double sn,
                    const double[::1] s):
    """(x, y) in the frame of the pose at (px, py) with cos/sin of its yaw (c, sn) of the line at offset `t` at arc
    lengths `s`: `ReferenceLine.points` of s clipped to the line, carried on straight beyond either end (grid:
    the line's sample arc lengths, `ReferenceLine.s`)."""
    cdef Py_ssize_t n = s.shape[0], j, i
    x_out, y_out = np.empty(n), np.empty(n)
    cdef double[::1] xv = x_out, yv = y_out
    cdef double length = line.length, h0 = line._heading_at(0.0), h_end = line._heading_at(line.length)
    cdef double sj, sc, d, k, chord, h_mid, h, wx, wy, beyond, he, dx, dy
    for j in range(n):
        sj = s[j]
        sc = _min(_max(sj, 0.0), length)  # np.clip, twice (labels, then points)
        i = <Py_ssize_t>(sc / line.ds)
        if i > line.last:
            i = line.last
        d = sc - grid[i]
        h_mid = _heading_array(line.segs, sc - 0.5 * d)
        k = line.samples[i, 4]
        chord = d * (1.0 - k * k * d * d / 24.0)
        h = _heading_array(line.segs, sc)
        wx = line.samples[i, 0] + chord * cos(h_mid) - t * sin(h)
        wy = line.samples[i, 1] + chord * sin(h_mid) + t * cos(h)
        beyond = sj - sc
        he = h_end if sj > length else h0
        wx = wx + beyond * cos(he)
        wy = wy + beyond * sin(he)
        dx, dy = wx - px, wy - py
        xv[j] = c * dx + sn * dy
        yv[j] = -sn * dx + c * dy
    return x_out, y_out


def at_car(LineKernel line, const double[::1] grid, double t, double px, double py, double yaw, double c, double sn,
           const double[::1] s, const double[::1] x):
    """`labels._at_car`: (offset y, slope dy/dx) at x = 0 of the line, or None."""
    cdef Py_ssize_t n = s.shape[0], i, j, found = -1
    cdef double length = line.length
    for j in range(n - 1):
        if (s[j] >= 0.0 and s[j] <= length and s[j + 1] >= 0.0 and s[j + 1] <= length and x[j] <= 0.0
                and x[j + 1] > 0.0):
            found = j
            break
    if found < 0:
        return None
    i = found
    cdef double si = s[i] + (s[i + 1] - s[i]) * (0.0 - x[i]) / (x[i + 1] - x[i])
    cdef double qx, qy, xi, rel, cr
    cdef int step
    for step in range(3):
        _point_one(line, grid, si, t, &qx, &qy)
        xi = c * (qx - px) + sn * (qy - py)
        rel = wrap_angle(line._heading_at(si) - yaw)
        cr = cos(rel)
        si = _min(_max(si - xi / (0.1 if 0.1 > cr else cr), 0.0), length)
    _point_one(line, grid, si, t, &qx, &qy)
    rel = wrap_angle(line._heading_at(si) - yaw)
    if fabs(rel) >= 0.5 * 3.141592653589793 - 0.05:
        return None
    return -sn * (qx - px) + c * (qy - py), tan(rel)


cdef double _stray(double c0, double c1, double c2, double c3, const double[::1] xs,
                   const double[::1] ys) noexcept nogil:
    """`labels._stray`: max |polyval(xs, c) − ys| (NaN if any is NaN), Horner as numpy's polyval runs it."""
    cdef Py_ssize_t j
    cdef double v, worst = 0.0, xj
    cdef bint nan = False
    for j in range(xs.shape[0]):
        xj = xs[j]
        v = c3 + xj * 0.0
        v = c2 + v * xj
        v = c1 + v * xj
        v = c0 + v * xj
        v = fabs(v - ys[j])
        if isnan(v):
            nan = True
        elif v > worst:
            worst = v
    return NAN if nan else worst


def range_fit(const double[::1] x, const double[::1] y, double y0, double slope):
    """`labels._range_fit` of a line that crosses x = 0 beside the car at (y0, slope): (coefficients, x_far, the
    boolean mask of the samples fitted)."""
    cdef Py_ssize_t n = x.shape[0], j, started = -1, stop = n, m
    for j in range(n):
        if x[j] >= 0.0:
            started = j
            break
    if started >= 0:
        for j in range(started, n - 1):
            if x[j + 1] - x[j] <= 0.0:
                stop = j + 1
                break
    fit = np.empty(n, dtype=bool)
    cdef unsigned char[::1] fv = fit.view(np.uint8)
    cdef double x_far = X_MAX, worst
    cdef double[::1] xsv, ysv, sqv, rhsv
    while True:
        m = 0
        for j in range(n):
            fv[j] = j < stop and x[j] >= 0.0 and x[j] <= x_far
            m += fv[j]
        xs, ys, sq, rhs = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
        xsv, ysv, sqv, rhsv = xs, ys, sq, rhs
        m = 0
        for j in range(n):
            if fv[j]:
                xsv[m], ysv[m] = x[j], y[j]
                sqv[m] = x[j] * x[j]
                rhsv[m] = y[j] - y0 - slope * x[j]
                m += 1
        if m >= 2:
            a = np.empty((m, 2))
            a[:, 0] = sq
            a[:, 1] = xs ** 3
            if _lstsq is None:
                rest = np.linalg.lstsq(a, rhs, rcond=None)[0]
                coeffs = np.array([y0, slope, rest[0], rest[1]])
            else:  # np.linalg.lstsq's call for float64 (rcond=None: machine epsilon times the rows)
                rest = _lstsq(a, rhs[:, None], EPS * m, signature="ddd->ddid")[0]
                coeffs = np.array([y0, slope, rest[0, 0], rest[1, 0]])
        else:
            coeffs = np.array([y0, slope, 0.0, 0.0])
        worst = _stray(coeffs[0], coeffs[1], coeffs[2], coeffs[3], xsv, ysv) if m else 0.0
        if worst <= FIT_TOLERANCE or x_far * FIT_SHRINK < X_FIT_MIN:
            return coeffs, x_far, fit
        x_far *= FIT_SHRINK


def view_kinds(const double[::1] s, const double[::1] x, const double[::1] run_s0, const double[::1] run_s1,
               const Py_ssize_t[::1] run_kind, Py_ssize_t none_kind, Py_ssize_t n_kinds):
    """Over the samples in the camera's view window (x in [X_VIEW_NEAR, X_VIEW_FAR]): (their number, how many are
    painted, the most common marking kind, the first seen among equals), kinds as indices (`none_kind` for
    none; -1 when there are no samples); the kind at s is that of the first run [s0, s1) holding it."""
    cdef Py_ssize_t n = s.shape[0], j, r, kind, seen = 0, painted = 0, best = -1
    counts = np.zeros(n_kinds, dtype=np.intp)
    first = np.full(n_kinds, n, dtype=np.intp)
    cdef Py_ssize_t[::1] cv = counts, fv = first
    for j in range(n):
        if not (x[j] >= X_VIEW_NEAR and x[j] <= X_VIEW_FAR):
            continue
        kind = none_kind
        for r in range(run_s0.shape[0]):
            if run_s0[r] <= s[j] < run_s1[r]:
                kind = run_kind[r]
                break
        seen += 1
        painted += kind != none_kind
        cv[kind] += 1
        if fv[kind] == n:
            fv[kind] = j
    for kind in range(n_kinds):
        if cv[kind] and (best < 0 or cv[kind] > cv[best] or (cv[kind] == cv[best] and fv[kind] < fv[best])):
            best = kind
    return seen, painted, best
