# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""TinyRenderer's picture of box bodies, compiled: the arithmetic of `pb.getCameraImage(renderer=ER_TINY_RENDERER)`
for untextured box meshes without shadow or specular light, float for float and double for double
(`testbed/tiny_raster.h`; the build turns off multiply-add contraction), so the RGBA and the depth are PyBullet's to
the byte. `testbed.tiny_boxes` builds the meshes as PyBullet does and keeps them in its drawing order;
`tests/test_tiny_boxes.py` holds the picture to TinyRenderer's.
"""

import numpy as np

cdef extern from "tiny_raster.h":
    ctypedef struct tr_target:
        pass
    void tr_begin(tr_target *t, unsigned char *rgba, float *zbuf, int width, int height, const float *proj)
    void tr_render_boxes(tr_target *t, const float *verts, float *normals, int nboxes, const float *model_cm,
                         const float *view_cm, const float *proj_cm, const float *light, const float *light_rgb,
                         float ambient, float diffuse, const float *colour)
    void tr_finish(const tr_target *t, float *depth)


def render_bodies(list bodies, const float[::1] view, const float[::1] proj, const float[::1] light,
                  const float[::1] light_rgb, float ambient, float diffuse, int width, int height):
    """(RGBA uint8 (height, width, 4), depth float32 (height, width)) of `bodies` drawn in order: each a tuple of
    vertices and normals float32 (boxes, 24, 3) (the normals are renormalised in place, as TinyRenderer's model
    does), its model matrix float32 (16,) column-major and its colour float32 (3,) (the texel 255 times the rgba,
    truncated). `view` and `proj` column-major float32 (16,), `light` the unit light direction float32 (3,)."""
    cdef tr_target t
    cdef float[:, ::1] zbuf = np.empty((height, width), dtype=np.float32)
    rgba = np.empty((height, width, 4), dtype=np.uint8)
    depth = np.empty((height, width), dtype=np.float32)
    cdef unsigned char[:, :, ::1] rgba_v = rgba
    cdef float[:, ::1] depth_v = depth
    cdef const float[:, :, ::1] verts
    cdef float[:, :, ::1] normals
    cdef const float[::1] model, colour
    tr_begin(&t, &rgba_v[0, 0, 0], &zbuf[0, 0], width, height, &proj[0])
    for body in bodies:
        verts, normals, model, colour = body
        if verts.shape[0] == 0:
            continue
        tr_render_boxes(&t, &verts[0, 0, 0], &normals[0, 0, 0], verts.shape[0], &model[0], &view[0], &proj[0],
                        &light[0], &light_rgb[0], ambient, diffuse, &colour[0])
    tr_finish(&t, &depth_v[0, 0])
    return rgba, depth
