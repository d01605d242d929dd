"""Box bodies as PyBullet's TinyRenderer holds them, drawn by its compiled clone (`testbed.render_kernels`).

A body is one multibody of flat-colour GEOM_BOX visuals: each box becomes PyBullet's 24-vertex box mesh, placed by
its child frame in double precision (Bullet's `btTransform`, `btMatrix3x3::setRotation`) and stored in float, as
`TinyRendererVisualShapeConverter` builds it; the body's pose is its model matrix. Bodies are drawn in the order of
TinyRenderer's instance map: a new body last, a removed body's slot taken by the last one. The same scene drawn by
TinyRenderer and by the clone gives the same RGBA and depth, byte for byte (`tests/test_tiny_boxes.py`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from types import ModuleType

import numpy as np

from tracks.compiled import compiled_module

_CUBE = np.array([  # PyBullet's cube_vertices_textured: the corner's signs, the face normal (uvs unused: no texture)
    (-1, -1, 1, 0, 0, 1), (1, -1, 1, 0, 0, 1), (1, 1, 1, 0, 0, 1), (-1, 1, 1, 0, 0, 1),
    (-1, -1, -1, 0, 0, -1), (1, -1, -1, 0, 0, -1), (1, 1, -1, 0, 0, -1), (-1, 1, -1, 0, 0, -1),
    (-1, -1, -1, -1, 0, 0), (-1, 1, -1, -1, 0, 0), (-1, 1, 1, -1, 0, 0), (-1, -1, 1, -1, 0, 0),
    (1, -1, -1, 1, 0, 0), (1, 1, -1, 1, 0, 0), (1, 1, 1, 1, 0, 0), (1, -1, 1, 1, 0, 0),
    (-1, -1, -1, 0, -1, 0), (-1, -1, 1, 0, -1, 0), (1, -1, 1, 0, -1, 0), (1, -1, -1, 0, -1, 0),
    (-1, 1, -1, 0, 1, 0), (-1, 1, 1, 0, 1, 0), (1, 1, 1, 0, 1, 0), (1, 1, -1, 0, 1, 0)], dtype=np.float64)


def kernel() -> ModuleType | None:
    """The compiled clone, or None (not built, or LD3_COMPILED=0): then TinyRenderer itself draws the bodies."""
    return compiled_module("testbed.render_kernels")


def bullet_rotation(q: Sequence[float]) -> np.ndarray:
    """`btMatrix3x3::setRotation` of the quaternion (x, y, z, w), in double precision, operation for operation."""
    x, y, z, w = (float(v) for v in q)
    d = x * x + y * y + z * z + w * w
    s = 2.0 / d
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return np.array([[1.0 - (yy + zz), xy - wz, xz + wy],
                     [xy + wz, 1.0 - (xx + zz), yz - wx],
                     [xz - wy, yz + wx, 1.0 - (xx + yy)]])


def box_mesh(half_extents: Sequence[float], center: Sequence[float], quaternion: Sequence[float]
             ) -> tuple[np.ndarray, np.ndarray]:
    """PyBullet's mesh of one GEOM_BOX visual (vertices and normals, float32 (24, 3)) in its body's frame."""
    r = bullet_rotation(quaternion)
    local = (np.asarray(half_extents, dtype=np.float64) * _CUBE[:, :3]).astype(np.float32).astype(np.float64)
    normal = _CUBE[:, 3:]
    c = np.asarray(center, dtype=np.float64)
    verts = np.empty((24, 3))
    normals = np.empty((24, 3))
    for k in range(3):  # btVector3::dot, left to right, then the origin
        verts[:, k] = local[:, 0] * r[k, 0] + local[:, 1] * r[k, 1] + local[:, 2] * r[k, 2] + c[k]
        normals[:, k] = r[k, 0] * normal[:, 0] + r[k, 1] * normal[:, 1] + r[k, 2] * normal[:, 2]
    return verts.astype(np.float32), normals.astype(np.float32)


def model_matrix(position: Sequence[float], quaternion: Sequence[float]) -> np.ndarray:
    """A body's pose as TinyRenderer's model matrix: float32 (16,), column-major."""
    m = np.eye(4)
    m[:3, :3] = bullet_rotation(quaternion)
    m[:3, 3] = position
    return np.ascontiguousarray(m.T.ravel().astype(np.float32))


def texel_colour(rgba: Sequence[float]) -> np.ndarray:
    """The body's colour as the shader multiplies it: the white texel's bytes times the float rgba, truncated."""
    return np.trunc(np.float32(255.0) * np.asarray(rgba[:3], dtype=np.float32)).astype(np.float32)


class BoxBody:
    """One body's boxes (vertices, and normals TinyRenderer renormalises in place each frame), pose and colour."""

    def __init__(self, boxes: list[tuple[np.ndarray, np.ndarray]], colour: Sequence[float], model: np.ndarray) -> None:
        self.verts = np.ascontiguousarray(np.stack([v for v, _ in boxes]), dtype=np.float32)
        self.normals = np.ascontiguousarray(np.stack([n for _, n in boxes]), dtype=np.float32)
        self.model = model
        self.colour = texel_colour(colour)

    def as_tuple(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.verts, self.normals, self.model, self.colour


class TinyBoxes:
    """The box bodies of a render scene, in TinyRenderer's drawing order, and their picture by the compiled clone."""

    def __init__(self, module: ModuleType) -> None:
        self._kernel = module
        self._bodies: dict[int, BoxBody] = {}
        self._order: list[int] = []
        self._next = 0

    @property
    def body_count(self) -> int:
        return len(self._order)

    def add(self, boxes: list[tuple[np.ndarray, np.ndarray]], colour: Sequence[float],
            position: Sequence[float] = (0.0, 0.0, 0.0), quaternion: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> int:
        """A new body of `boxes` (from `box_mesh`) at the pose; its key."""
        key = self._next
        self._next += 1
        self._bodies[key] = BoxBody(boxes, colour, model_matrix(position, quaternion))
        self._order.append(key)
        return key

    def remove(self, key: int) -> None:
        """Drop a body: the last one takes its slot (btHashMap::remove)."""
        del self._bodies[key]
        slot = self._order.index(key)
        last = self._order.pop()
        if last != key:
            self._order[slot] = last

    def move(self, key: int, position: Sequence[float], quaternion: Sequence[float]) -> None:
        """`resetBasePositionAndOrientation` of a body."""
        self._bodies[key].model = model_matrix(position, quaternion)

    def clear(self) -> None:
        self._bodies.clear()
        self._order.clear()

    def render(self, view: Sequence[float], projection: Sequence[float], light_dir: Sequence[float],
               light_rgb: Sequence[float], ambient: float, diffuse: float, width: int, height: int
               ) -> tuple[np.ndarray, np.ndarray]:
        """RGBA uint8 (height, width, 4) and depth float32 (height, width), as `getCameraImage` with TinyRenderer,
        `shadow=0` and `lightSpecularCoeff=0` returns them for these bodies."""
        lx, ly, lz = (float(v) for v in np.asarray(light_dir, dtype=np.float32))
        inv = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)  # btVector3::normalize in double
        light = np.array([lx * inv, ly * inv, lz * inv], dtype=np.float32)
        return self._kernel.render_bodies(
            [self._bodies[k].as_tuple() for k in self._order], np.asarray(view, dtype=np.float32),
            np.asarray(projection, dtype=np.float32), light, np.asarray(light_rgb, dtype=np.float32),
            float(np.float32(ambient)), float(np.float32(diffuse)), width, height)
