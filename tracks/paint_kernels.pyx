# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`AsphaltPainter`'s per-pixel layer compiled: the ground colour of each column (or the asphalt of an intersection's
rows) times the large-scale tone, plus the grain, clipped and truncated to bytes, in one pass over the tile.

The same float32 operations as the numpy reference in `tracks/paint.py`, in the same order (`value_noise`'s last
interpolation along s, the tone `1 + v·(2n − 1)`, the grain `normal·g + 0.5`, `layer·tone + grain`), each rounded
to float32 as numpy rounds it; the build turns off multiply-add contraction, so the bytes are the same;
`tests/tracks/test_paint_kernels.py` holds them to it.
"""


def asphalt(const float[:, ::1] ground, const unsigned char[::1] crossing, const float[::1] crossing_colour,
            const float[:, ::1] along_t, const int[::1] row, const float[::1] weight, double tone_variation,
            const float[:, ::1] normal, double grain, unsigned char[:, :, ::1] out):
    """Paint `out` (H, W, 3): `ground` (W, 3) per column, `crossing_colour` (3,) on the rows where `crossing` (H,)
    is set; the tone from `noise_rows`'s `along_t`, `row`, `weight`; the grain from `normal` (H, W) times `grain`."""
    cdef Py_ssize_t h = out.shape[0], w = out.shape[1], i, j, c
    cdef float tv = <float>tone_variation, amp = <float>grain
    cdef float one = 1.0, two = 2.0, half = 0.5  # float operands: every operation below is a float32 one
    cdef float wi, wi1, noise, tone, g, v
    cdef const float* base
    with nogil:
        for i in range(h):
            wi = weight[i]
            wi1 = one - wi
            for j in range(w):
                noise = along_t[row[i], j] * wi1 + along_t[row[i] + 1, j] * wi
                tone = one + tv * (two * noise - one)
                g = normal[i, j] * amp + half
                base = &crossing_colour[0] if crossing[i] else &ground[j, 0]
                for c in range(3):
                    v = base[c] * tone + g
                    out[i, j, c] = 0 if v < 0 else (255 if v > 255 else <unsigned char>v)
