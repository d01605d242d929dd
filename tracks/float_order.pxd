"""Python's `max` and `min` of two floats, shared by the compiled kernels, inline so each kernel compiles the same
comparisons as the Python reference makes (the first argument wins a tie or a NaN)."""


cdef inline double py_max(double a, double b) noexcept nogil:
    """Python's `max(a, b)` of two floats: `a` unless `b` is greater."""
    return b if b > a else a


cdef inline double py_min(double a, double b) noexcept nogil:
    """Python's `min(a, b)` of two floats: `a` unless `b` is smaller."""
    return b if b < a else a
