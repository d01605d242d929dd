/* TinyRenderer's rasterisation of flat-colour box meshes, operation for operation as PyBullet 3.2.7 runs it
 * (bullet3 examples/TinyRenderer: our_gl.cpp triangle/triangleClipped/barycentric, TinyRenderer.cpp renderObject,
 * its Shader and near-plane clipping, geometry.h's loop orders; zlib licence, Erwin Coumans and Dmitry Sokolov).
 * Built with multiply-add contraction off, so every float and double operation rounds where the C++ rounds.
 * Only what the front camera draws is cloned: untextured meshes, no shadow pass, no specular term. */
#ifndef TINY_RASTER_H
#define TINY_RASTER_H

#include <float.h>
#include <limits.h>
#include <math.h>
#include <string.h>

typedef struct {
    float m[4][4];
} tr_mat4;

/* geometry.h's dot product runs from the last component to the first, starting from zero. */
static inline float tr_dot4(const float *a, const float *b) {
    float r = 0.0f;
    r += a[3] * b[3];
    r += a[2] * b[2];
    r += a[1] * b[1];
    r += a[0] * b[0];
    return r;
}

/* The three-component form, for floats and for doubles. */
#define TR_DOT3(name, T)                                  \
    static inline T name(const T *a, const T *b) {        \
        T r = 0;                                          \
        r += a[2] * b[2];                                 \
        r += a[1] * b[1];                                 \
        r += a[0] * b[0];                                 \
        return r;                                         \
    }
TR_DOT3(tr_dot3, float)
TR_DOT3(tr_dot3d, double)

static inline float tr_minf(float a, float b) { return a < b ? a : b; } /* b3Min */
static inline float tr_maxf(float a, float b) { return a > b ? a : b; } /* b3Max */

static inline void tr_mul(const tr_mat4 *a, const tr_mat4 *b, tr_mat4 *out) {
    float col[4];
    for (int j = 0; j < 4; j++) {
        for (int k = 0; k < 4; k++) col[k] = b->m[k][j];
        for (int i = 0; i < 4; i++) out->m[i][j] = tr_dot4(a->m[i], col);
    }
}

static inline void tr_mul_vec(const tr_mat4 *a, const float *v, float *out) {
    for (int i = 0; i < 4; i++) out[i] = tr_dot4(a->m[i], v);
}

/* geometry.h's determinants by cofactor expansion along the first row (dt<N>::det), sign applied as a float
 * product as `cofactor` does. */
static inline float tr_det2(float a00, float a01, float a10, float a11) {
    float r = 0.0f;
    r += a01 * (a10 * -1.0f);
    r += a00 * (a11 * 1.0f);
    return r;
}

static float tr_det3(const float s[3][3]) {
    float r = 0.0f;
    r += s[0][2] * (tr_det2(s[1][0], s[1][1], s[2][0], s[2][1]) * 1.0f);
    r += s[0][1] * (tr_det2(s[1][0], s[1][2], s[2][0], s[2][2]) * -1.0f);
    r += s[0][0] * (tr_det2(s[1][1], s[1][2], s[2][1], s[2][2]) * 1.0f);
    return r;
}

/* mat::invert_transpose: the adjugate over the dot product of its first row with the matrix's. */
static void tr_invert_transpose(const tr_mat4 *a, tr_mat4 *out) {
    tr_mat4 adj;
    float minor[3][3];
    for (int row = 0; row < 4; row++) {
        for (int col = 0; col < 4; col++) {
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) minor[i][j] = a->m[i < row ? i : i + 1][j < col ? j : j + 1];
            adj.m[row][col] = tr_det3(minor) * ((row + col) % 2 ? -1.0f : 1.0f);
        }
    }
    float tmp = tr_dot4(adj.m[0], a->m[0]);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out->m[i][j] = adj.m[i][j] / tmp;
}

/* Vec3f::normalize in place: times one over the norm. */
static inline void tr_normalize3(float *v) {
    float f = 1.0f / sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[2] *= f;
    v[1] *= f;
    v[0] *= f;
}

typedef struct {
    unsigned char *rgba; /* height x width x 4, the picture's row order (TinyRenderer's flipped: row 0 at the top) */
    float *zbuf;         /* height x width, TinyRenderer's row order (row 0 at the bottom) */
    int width, height;
    tr_mat4 viewport;
    float near_plane, far_plane;
} tr_target;

typedef struct {
    float nrm[3][3]; /* varying_nrm: rows x, y, z; a column per vertex */
    float tri[4][3]; /* varying_tri: clip coordinates, a column per vertex */
    float light[3];
    float light_rgb[3];
    float ambient, diffuse;
    float colour[3]; /* the unsigned-char texel 255 times the body's rgba, as floats */
} tr_shader;

static inline void tr_fragment(const tr_shader *sh, const float *bar, unsigned char *out) {
    float bn[3];
    for (int i = 0; i < 3; i++) bn[i] = tr_dot3(sh->nrm[i], bar);
    tr_normalize3(bn);
    float d = tr_dot3(bn, sh->light);
    float diffuse = tr_maxf(0.0f, d);
    float shadow = 1.0f;
    for (int i = 0; i < 3; i++) {
        float c = sh->colour[i];
        float f = (sh->ambient * c + shadow * (sh->diffuse * diffuse + 0.0f) * c * sh->light_rgb[i]);
        int org = 0;
        if (f == f) org = (int)f;
        out[i] = (unsigned char)(org < 255 ? org : 255);
    }
}

/* viewport * clip, transposed, and each point's x, y over its w. */
static inline void tr_screen(const tr_target *t, const float clip[4][3], float pts[3][4], float pts2[3][2]) {
    float col[4], res[4];
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 4; k++) col[k] = clip[k][i];
        tr_mul_vec(&t->viewport, col, res);
        for (int k = 0; k < 4; k++) pts[i][k] = res[k];
    }
    for (int i = 0; i < 3; i++) {
        pts2[i][0] = pts[i][0] / pts[i][3];
        pts2[i][1] = pts[i][1] / pts[i][3];
    }
}

static inline void tr_barycentric(const float a[2], const float b[2], const float c[2], int px, int py, double out[3]) {
    double A[2] = {a[0], a[1]}, B[2] = {b[0], b[1]}, C[2] = {c[0], c[1]};
    double P[2] = {(float)px, (float)py};
    double s[2][3];
    for (int i = 2; i--;) {
        s[i][0] = C[i] - A[i];
        s[i][1] = B[i] - A[i];
        s[i][2] = A[i] - P[i];
    }
    double ux = s[0][1] * s[1][2] - s[0][2] * s[1][1];
    double uy = s[0][2] * s[1][0] - s[0][0] * s[1][2];
    double uz = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    if (fabs(uz) > 1e-2) {
        out[0] = 1. - (ux + uy) / uz;
        out[1] = uy / uz;
        out[2] = ux / uz;
    } else {
        out[0] = -1.;
        out[1] = 1.;
        out[2] = 1.;
    }
}

/* The rows of a column where the triangle's barycentric coordinates may all be non-negative: a pixel outside them
 * lies beyond an edge by far more than any rounding of `tr_barycentric` moves it, so TinyRenderer rejects it; the
 * rows inside are tested as TinyRenderer tests them. Only skips work: the pixels drawn are the same. */
typedef struct {
    int exact;        /* 1: no bound (non-finite points); test every row */
    double ax, ay, s0x, s0y, s1x, s1y, uz, tol;
} tr_span;

static int tr_span_init(tr_span *sp, const float pts2[3][2]) {
    double A[2] = {pts2[0][0], pts2[0][1]}, B[2] = {pts2[1][0], pts2[1][1]}, C[2] = {pts2[2][0], pts2[2][1]};
    sp->exact = 0;
    for (int i = 0; i < 3; i++)
        if (!isfinite(pts2[i][0]) || !isfinite(pts2[i][1])) sp->exact = 1;
    sp->ax = A[0];
    sp->ay = A[1];
    sp->s0x = C[0] - A[0];
    sp->s0y = B[0] - A[0];
    sp->s1x = C[1] - A[1];
    sp->s1y = B[1] - A[1];
    sp->uz = sp->s0x * sp->s1y - sp->s0y * sp->s1x; /* tr_barycentric's u.z: the same for every pixel */
    if (sp->exact) return 1;
    if (!(fabs(sp->uz) > 1e-2)) return 0;
    double m = 0.0;
    for (int i = 0; i < 3; i++) m = fmax(m, fmax(fabs(pts2[i][0]), fabs(pts2[i][1])));
    m += 1e4; /* pixel coordinates are below it */
    sp->tol = 1e-9 * (1.0 + 8.0 * m * m / fabs(sp->uz)); /* rounding of the coordinates is below 1e-12 of this */
    return 1;
}

/* Narrow [*y0, *y1] to the rows of column x where every real barycentric coordinate is at least -tol, one row of
 * margin each side. u.x = s0y (ay - y) - (ax - x) s1y, u.y = (ax - x) s1x - s0x (ay - y); b = (u.y, u.x, u.z - u.x -
 * u.y) / u.z. */
static void tr_span_rows(const tr_span *sp, int x, int *y0, int *y1) {
    if (sp->exact) return;
    double dx = sp->ax - x;
    double cx0 = (sp->s0y * sp->ay - dx * sp->s1y) / sp->uz, cx1 = -sp->s0y / sp->uz; /* u.x / u.z = cx0 + cx1 y */
    double cy0 = (dx * sp->s1x - sp->s0x * sp->ay) / sp->uz, cy1 = sp->s0x / sp->uz; /* u.y / u.z */
    double c[3][2] = {{cy0, cy1}, {cx0, cx1}, {1.0 - cx0 - cy0, -cx1 - cy1}};
    double lo = -1e30, hi = 1e30;
    for (int k = 0; k < 3; k++) {
        double a = c[k][0] + sp->tol, b = c[k][1]; /* a + b y >= 0 */
        if (b > 0) {
            lo = fmax(lo, -a / b);
        } else if (b < 0) {
            hi = fmin(hi, -a / b);
        } else if (a < 0) {
            *y1 = *y0 - 1;
            return;
        }
    }
    if (lo > hi + 2.0) {
        *y1 = *y0 - 1;
        return;
    }
    if (lo > -1e8) *y0 = (int)fmax((double)*y0, floor(lo) - 1.0);
    if (hi < 1e8) *y1 = (int)fmin((double)*y1, ceil(hi) + 1.0);
}

/* our_gl.cpp's coordinates of pixel (x, y) in the screen triangle `p2` (bc), and perspective-correct (bcc): each
 * divided by its vertex's w in `p`, then by their sum. */
static inline void tr_perspective(float p2[3][2], float p[3][4], int x, int y, double bc[3], double bcc[3]) {
    tr_barycentric(p2[0], p2[1], p2[2], x, y, bc);
    bcc[0] = bc[0] / p[0][3];
    bcc[1] = bc[1] / p[1][3];
    bcc[2] = bc[2] / p[2][3];
    double sum = bcc[0] + bcc[1] + bcc[2];
    bcc[2] /= sum;
    bcc[1] /= sum;
    bcc[0] /= sum;
}

/* our_gl.cpp triangle (clipped == 0: the near/far discards) and triangleClipped (the clipped points bound and
 * depth-test the pixels, the original ones shade them). */
static void tr_triangle(tr_target *t, const float clipc[4][3], const float orgc[4][3], int clipped,
                        const tr_shader *sh) {
    float pts[3][4], pts2[3][2], org[3][4], org2[3][2];
    tr_screen(t, clipc, pts, pts2);
    if (clipped) tr_screen(t, orgc, org, org2);
    float bmin[2] = {FLT_MAX, FLT_MAX}, bmax[2] = {-FLT_MAX, -FLT_MAX};
    float clamp[2] = {(float)(t->width - 1), (float)(t->height - 1)};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 2; j++) {
            bmin[j] = tr_maxf(0.0f, tr_minf(bmin[j], pts2[i][j]));
            bmax[j] = tr_minf(clamp[j], tr_maxf(bmax[j], pts2[i][j]));
        }
    }
    double clipz[3] = {clipc[2][0], clipc[2][1], clipc[2][2]};
    unsigned char colour[3];
    tr_span span;
    if (!tr_span_init(&span, pts2)) return; /* degenerate: TinyRenderer rejects every pixel */
    for (int x = (int)bmin[0]; x <= bmax[0]; x++) {
        int y0 = (int)bmin[1], y1 = INT_MAX;
        tr_span_rows(&span, x, &y0, &y1);
        for (int y = y0; y <= bmax[1] && y <= y1; y++) {
            if (x < 0 || y < 0 || x >= t->width || y >= t->height) continue; /* only where TinyRenderer overruns */
            double bc[3], bcc[3];
            tr_perspective(pts2, pts, x, y, bc, bcc);
            double frag_depth = -1. * tr_dot3d(clipz, bcc);
            int idx = x + y * t->width;
            if (bc[0] < 0 || bc[1] < 0 || bc[2] < 0 || t->zbuf[idx] > frag_depth) continue;
            float bar[3];
            if (clipped) {
                double screen2[3], b2[3];
                tr_perspective(org2, org, x, y, screen2, b2);
                bar[0] = (float)b2[0];
                bar[1] = (float)b2[1];
                bar[2] = (float)b2[2];
            } else {
                bar[0] = (float)bcc[0];
                bar[1] = (float)bcc[1];
                bar[2] = (float)bcc[2];
            }
            tr_fragment(sh, bar, colour);
            if (!clipped && (frag_depth < -t->far_plane || frag_depth > t->near_plane)) continue;
            t->zbuf[idx] = (float)frag_depth;
            unsigned char *p = t->rgba + 4 * (x + (t->height - 1 - y) * t->width);
            p[0] = colour[0];
            p[1] = colour[1];
            p[2] = colour[2];
        }
    }
}

static inline int tr_inside(const float *v) { return v[3] > 0.f && v[2] > -v[3]; }

/* TinyRenderer.cpp clipEdge: the edge's points, the outside one moved onto the plane z = -w. */
static void tr_clip_edge(const float tri[4][3], int a, int b, float verts[][4], int *n) {
    float v0[4], v1[4];
    for (int k = 0; k < 4; k++) {
        v0[k] = tri[k][a];
        v1[k] = tri[k][b];
    }
    int in0 = tr_inside(v0), in1 = tr_inside(v1);
    if (!in0 && !in1) return;
    if (!(in0 && in1)) {
        float d0 = v0[2] + v0[3];
        float d1 = v1[2] + v1[3];
        float factor = 1.0 / (d1 - d0);
        float nv[4];
        for (int k = 3; k >= 0; k--) nv[k] = (v0[k] * d1 - v1[k] * d0) * factor;
        for (int k = 0; k < 4; k++) {
            if (in0)
                v1[k] = nv[k];
            else
                v0[k] = nv[k];
        }
    }
    for (int k = 0; k < 4; k++) verts[*n][k] = v0[k];
    (*n)++;
    for (int k = 0; k < 4; k++) verts[*n][k] = v1[k];
    (*n)++;
}

static void tr_draw_face(tr_target *t, const tr_shader *sh) {
    const float(*tri)[3] = sh->tri;
    if (tri[3][0] < 0 && tri[3][1] < 0 && tri[3][2] < 0) return;
    if (tri[3][0] >= 0 && tri[3][1] >= 0 && tri[3][2] >= 0) {
        tr_triangle(t, tri, tri, 0, sh);
        return;
    }
    float verts[6][4];
    int n = 0;
    tr_clip_edge(tri, 0, 1, verts, &n);
    tr_clip_edge(tri, 1, 2, verts, &n);
    tr_clip_edge(tri, 2, 0, verts, &n);
    if (n < 3) return;
    for (int i = 1; i < n - 1; i++) {
        float c[4][3];
        for (int k = 0; k < 4; k++) {
            c[k][0] = verts[0][k];
            c[k][1] = verts[i][k];
            c[k][2] = verts[i + 1][k];
        }
        tr_triangle(t, c, tri, 1, sh);
    }
}

/* TinyRenderer::renderObject for one untextured mesh (single-sided): every face's vertex shader (which normalizes
 * the model's normals in place, as Model::normal does), back-face culling in double precision, near-plane
 * clipping, rasterisation. */
static void tr_render_object(tr_target *t, const float *verts, float *normals, const int *indices, int nfaces,
                             const tr_mat4 *model, const tr_mat4 *view, const tr_mat4 *proj, const float light[3],
                             const float light_rgb[3], float ambient, float diffuse, const float colour[3]) {
    tr_mat4 inv_model, model_view, pmv, view_inv_t;
    tr_invert_transpose(model, &inv_model);
    tr_mul(view, model, &model_view);
    tr_mul(proj, &model_view, &pmv);
    tr_invert_transpose(view, &view_inv_t);
    double P[3] = {view_inv_t.m[3][0], view_inv_t.m[3][1], view_inv_t.m[3][2]};
    tr_shader sh;
    for (int k = 0; k < 3; k++) {
        sh.light[k] = light[k];
        sh.light_rgb[k] = light_rgb[k];
        sh.colour[k] = colour[k];
    }
    sh.ambient = ambient;
    sh.diffuse = diffuse;
    for (int f = 0; f < nfaces; f++) {
        double world[3][3];
        for (int j = 0; j < 3; j++) {
            int idx = indices[3 * f + j];
            float *n = normals + 3 * idx;
            tr_normalize3(n);
            float n4[4] = {n[0], n[1], n[2], 0.f}, v4[4], r[4];
            v4[0] = verts[3 * idx];
            v4[1] = verts[3 * idx + 1];
            v4[2] = verts[3 * idx + 2];
            v4[3] = 1.f;
            tr_mul_vec(&inv_model, n4, r);
            for (int k = 0; k < 3; k++) sh.nrm[k][j] = r[k];
            tr_mul_vec(&pmv, v4, r);
            for (int k = 0; k < 4; k++) sh.tri[k][j] = r[k];
            tr_mul_vec(model, v4, r);
            for (int k = 0; k < 3; k++) world[j][k] = r[k];
        }
        double e1[3], e2[3], N[3], d[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = world[1][k] - world[0][k];
            e2[k] = world[2][k] - world[0][k];
            d[k] = world[0][k] - P[k];
        }
        N[0] = e1[1] * e2[2] - e1[2] * e2[1];
        N[1] = e1[2] * e2[0] - e1[0] * e2[2];
        N[2] = e1[0] * e2[1] - e1[1] * e2[0];
        if (d[0] * N[0] + d[1] * N[1] + d[2] * N[2] >= 0) continue;
        tr_draw_face(t, &sh);
    }
}

static const int TR_CUBE_INDICES[36] = {0, 1, 2, 0, 2, 3, 6, 5, 4, 7, 6, 4, 10, 9, 8, 11, 10, 8,
                                        12, 13, 14, 12, 14, 15, 18, 17, 16, 19, 18, 16, 20, 21, 22, 20, 22, 23};

/* TinyRendererVisualShapeConverter::render's set-up: the viewport, the near and far planes read off the
 * projection, the colour buffer cleared to white and the depth buffer to minus the far plane. */
static void tr_begin(tr_target *t, unsigned char *rgba, float *zbuf, int width, int height, const float *proj) {
    t->rgba = rgba;
    t->zbuf = zbuf;
    t->width = width;
    t->height = height;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) t->viewport.m[i][j] = (float)(i == j);
    t->viewport.m[0][3] = 0 + width / 2.f;
    t->viewport.m[1][3] = 0 + height / 2.f;
    t->viewport.m[2][3] = .5f;
    t->viewport.m[0][0] = width / 2.f;
    t->viewport.m[1][1] = height / 2.f;
    t->viewport.m[2][2] = .5f;
    t->near_plane = proj[14] / (proj[10] - 1);
    t->far_plane = proj[14] / (proj[10] + 1);
    memset(rgba, 255, (size_t)4 * width * height); /* white, and the alpha copyCameraImageData sets */
    for (int i = 0; i < width * height; i++) zbuf[i] = -t->far_plane;
}

/* The boxes of one body (24 vertices and normals each, as PyBullet's box mesh; the normals are updated in place),
 * drawn with the body's model matrix and colour. Matrices come column-major, as getCameraImage takes them. */
static void tr_render_boxes(tr_target *t, const float *verts, float *normals, int nboxes, const float *model_cm,
                            const float *view_cm, const float *proj_cm, const float light[3], const float light_rgb[3],
                            float ambient, float diffuse, const float colour[3]) {
    tr_mat4 model, view, proj;
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 4; j++) {
            model.m[i][j] = model_cm[i + 4 * j];
            view.m[i][j] = view_cm[i + 4 * j];
            proj.m[i][j] = proj_cm[i + 4 * j];
        }
    }
    for (int b = 0; b < nboxes; b++)
        tr_render_object(t, verts + 72 * b, normals + 72 * b, TR_CUBE_INDICES, 12, &model, &view, &proj, light,
                         light_rgb, ambient, diffuse, colour);
}

/* copyCameraImageData's depth after the vertical flip, mapped to [0, 1] (the RGBA was drawn flipped). */
static inline float tr_depth(float near, float far, float zb) {
    float z_c = -zb;
    return far * (near + z_c) / (2. * far * near + far * z_c - near * z_c);
}

static void tr_finish(const tr_target *t, float *depth) {
    float far = t->far_plane, near = t->near_plane;
    float clear = -far, clear_depth = tr_depth(near, far, clear); /* where nothing was drawn */
    for (int r = 0; r < t->height; r++) {
        int src = (t->height - 1 - r) * t->width, dst = r * t->width;
        for (int x = 0; x < t->width; x++) {
            float zb = t->zbuf[src + x];
            depth[dst + x] = zb == clear ? clear_depth : tr_depth(near, far, zb);
        }
    }
}

#endif
