"""Angle arithmetic shared by the compiled kernels, inline so each kernel compiles the same operations."""

from libc.math cimport copysign, fmod


cdef inline double wrap_angle(double a) noexcept nogil:
    """`tracks.pose.wrap_angle`: (a + π) % 2π − π with Python's float remainder (the divisor's sign)."""
    cdef double pi = 3.141592653589793
    cdef double w = 2.0 * pi
    cdef double mod = fmod(a + pi, w)
    if mod != 0.0:
        if (w < 0.0) != (mod < 0.0):
            mod += w
    else:
        mod = copysign(0.0, w)
    return mod - pi
