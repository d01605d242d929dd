"""A road's reference line from its planView records: (x, y, heading) at road arc length s.

line and arc in closed form; spiral (curvature linear in s) by Gauss-Legendre quadrature of its quadratic
heading; poly3 v(u) with u found from the arc length (Newton on the quadrature of √(1 + v'²)); paramPoly3
at its parameter p = s − s0 (pRange arcLength) or (s − s0) / length (normalized), as the standard defines p.
Beyond the last record the line runs on along the last record's shape to the road's length.
"""

from __future__ import annotations

import math

import numpy as np

from tracks.opendrive.model import Geometry

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_CELL = 1.0  # m (or parameter units) per quadrature cell


def _quad(f, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """∫_a^b f elementwise by 8-point Gauss-Legendre (f vectorised over a 2-D array)."""
    half, mid = 0.5 * (b - a), 0.5 * (a + b)
    return half * (f(mid[:, None] + half[:, None] * _GL_NODES[None, :]) @ _GL_WEIGHTS)


def _cumulative(f, x: np.ndarray) -> np.ndarray:
    """∫_0^x f for sorted x >= 0, over cells of at most `_CELL` (f smooth)."""
    top = float(x.max(initial=0.0))
    knots = np.union1d(x, np.linspace(0.0, top, max(2, math.ceil(top / _CELL) + 1)))
    acc = np.concatenate([[0.0], np.cumsum(_quad(f, knots[:-1], knots[1:]))])
    return acc[np.searchsorted(knots, x)]


def _local(g: Geometry, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, heading) in the record's own frame (start at the origin heading +x) at arc length u."""
    p = g.params
    if g.kind == "line":
        return u, np.zeros_like(u), np.zeros_like(u)
    if g.kind == "arc" and abs(p["curvature"]) > 1e-12:
        k = p["curvature"]
        return np.sin(k * u) / k, (1.0 - np.cos(k * u)) / k, k * u
    if g.kind == "arc":
        return u, np.zeros_like(u), np.zeros_like(u)
    if g.kind == "spiral":
        k0, dk = p["curvStart"], (p["curvEnd"] - p["curvStart"]) / g.length

        def heading(v: np.ndarray) -> np.ndarray:
            return k0 * v + 0.5 * dk * v * v

        order = np.argsort(u)
        x, y = np.empty_like(u), np.empty_like(u)
        x[order] = _cumulative(lambda v: np.cos(heading(v)), u[order])
        y[order] = _cumulative(lambda v: np.sin(heading(v)), u[order])
        return x, y, heading(u)
    if g.kind == "poly3":
        a, b, c, d = p["a"], p["b"], p["c"], p["d"]
        w = _poly3_u(b, c, d, u, g.length)
        return w, a + w * (b + w * (c + w * d)), np.arctan(b + w * (2.0 * c + 3.0 * w * d))
    t = u / g.length if p["normalized"] else u
    xu = p["aU"] + t * (p["bU"] + t * (p["cU"] + t * p["dU"]))
    yv = p["aV"] + t * (p["bV"] + t * (p["cV"] + t * p["dV"]))
    du = p["bU"] + t * (2.0 * p["cU"] + 3.0 * t * p["dU"])
    dv = p["bV"] + t * (2.0 * p["cV"] + 3.0 * t * p["dV"])
    return xu, yv, np.arctan2(dv, du)


def _poly3_u(b: float, c: float, d: float, s: np.ndarray, length: float) -> np.ndarray:
    """Local u of the poly3 point at arc length s: a table of arc length over u, then Newton steps."""

    def speed(u: np.ndarray) -> np.ndarray:
        return np.sqrt(1.0 + (b + u * (2.0 * c + 3.0 * u * d)) ** 2)

    grid = np.linspace(0.0, length, max(2, math.ceil(length / _CELL) + 1))  # u <= s, so [0, length] suffices
    arc = np.concatenate([[0.0], np.cumsum(_quad(speed, grid[:-1], grid[1:]))])
    u = np.interp(s, arc, grid)
    for _ in range(4):
        j = np.clip(np.searchsorted(grid, u, side="right") - 1, 0, len(grid) - 2)
        u -= (arc[j] + _quad(speed, grid[j], u) - s) / speed(u)
    return u


class PlanView:
    """The reference line of one road: `frame(s)` gives (x, y, heading) arrays at road arc lengths s."""

    def __init__(self, geometries: tuple[Geometry, ...]) -> None:
        self.geometries = sorted(geometries, key=lambda g: g.s)
        self._starts = np.array([g.s for g in self.geometries])

    def frame(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = np.asarray(s, dtype=float)
        idx = np.clip(np.searchsorted(self._starts, s, side="right") - 1, 0, len(self.geometries) - 1)
        x, y, h = np.empty_like(s), np.empty_like(s), np.empty_like(s)
        for i in np.unique(idx):
            g, sel = self.geometries[i], idx == i
            lx, ly, lh = _local(g, s[sel] - g.s)
            c, sn = math.cos(g.hdg), math.sin(g.hdg)
            x[sel] = g.x + c * lx - sn * ly
            y[sel] = g.y + sn * lx + c * ly
            h[sel] = g.hdg + lh
        return x, y, h
