"""The file's own geometry, evaluated independently of the reader (closed forms and scipy quadrature) from the
XML records: reference line points and lane centres at road arc length s."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq, minimize_scalar


def _local(shape: ET.Element, length: float, u: float) -> tuple[float, float, float]:
    a = {k: float(v) for k, v in shape.attrib.items() if k != "pRange"}
    if shape.tag == "line":
        return u, 0.0, 0.0
    if shape.tag == "arc":
        k = a["curvature"]
        return math.sin(k * u) / k, (1 - math.cos(k * u)) / k, k * u
    if shape.tag == "spiral":
        k0, k1 = a["curvStart"], a["curvEnd"]

        def h(v: float) -> float:
            return k0 * v + (k1 - k0) * v * v / (2 * length)

        return (quad(lambda v: math.cos(h(v)), 0, u, epsabs=1e-12)[0],
                quad(lambda v: math.sin(h(v)), 0, u, epsabs=1e-12)[0], h(u))
    if shape.tag == "poly3":
        def dv(w: float) -> float:
            return a["b"] + 2 * a["c"] * w + 3 * a["d"] * w * w

        def arc(w: float) -> float:
            return quad(lambda x: math.hypot(1, dv(x)), 0, w, epsabs=1e-12)[0]

        w = brentq(lambda w: arc(w) - u, 0, u + 1e-9) if u > 0 else 0.0
        return w, a["a"] + a["b"] * w + a["c"] * w * w + a["d"] * w ** 3, math.atan(dv(w))
    p = u / length if shape.get("pRange") == "normalized" else u
    x = a["aU"] + a["bU"] * p + a["cU"] * p * p + a["dU"] * p ** 3
    y = a["aV"] + a["bV"] * p + a["cV"] * p * p + a["dV"] * p ** 3
    return x, y, math.atan2(a["bV"] + 2 * a["cV"] * p + 3 * a["dV"] * p * p,
                            a["bU"] + 2 * a["cU"] * p + 3 * a["dU"] * p * p)


def reference(road: ET.Element, s: float) -> tuple[float, float, float]:
    """(x, y, heading) of the road's reference line at s."""
    geoms = sorted(road.find("planView").findall("geometry"), key=lambda g: float(g.get("s")))
    g = [g for g in geoms if float(g.get("s")) <= s + 1e-9][-1]
    lx, ly, lh = _local(g[0], float(g.get("length")), s - float(g.get("s")))
    h0 = float(g.get("hdg"))
    return (float(g.get("x")) + lx * math.cos(h0) - ly * math.sin(h0),
            float(g.get("y")) + lx * math.sin(h0) + ly * math.cos(h0), h0 + lh)


def _poly(records: list[ET.Element], s_name: str, s: float) -> float:
    rec = [r for r in records if float(r.get(s_name)) <= s + 1e-9][-1]
    ds = s - float(rec.get(s_name))
    return sum(float(rec.get(k)) * ds ** i for i, k in enumerate("abcd"))


def lane_edges(road: ET.Element, lane_id: int, s: float) -> tuple[float, float]:
    """Lateral offsets (+ left) of the inner and outer border of lane `lane_id` at s."""
    lanes = road.find("lanes")
    offsets = lanes.findall("laneOffset")
    t = _poly(offsets, "s", s) if offsets else 0.0
    sec = [x for x in lanes.findall("laneSection") if float(x.get("s")) <= s + 1e-9][-1]
    side = 1 if lane_id > 0 else -1
    for k in range(1, abs(lane_id) + 1):
        lane = next(ln for ln in sec.iter("lane") if int(ln.get("id")) == side * k)
        inner, t = t, t + side * _poly(lane.findall("width"), "sOffset", s - float(sec.get("s")))
    return inner, t


def lane_centre(road: ET.Element, lane_id: int, s: float) -> np.ndarray:
    x, y, h = reference(road, s)
    t = 0.5 * sum(lane_edges(road, lane_id, s))
    return np.array([x - t * math.sin(h), y + t * math.cos(h)])


def closest(road: ET.Element, lane_id: int, xy: np.ndarray, s_guess: float) -> tuple[float, np.ndarray, float, float]:
    """(road s, centre point, signed offset + left of travel along +s, width) of the lane centre point
    nearest xy."""
    length = float(road.get("length"))
    res = minimize_scalar(lambda v: float(np.sum((lane_centre(road, lane_id, v) - xy) ** 2)),
                          bounds=(max(0.0, s_guess - 3), min(length, s_guess + 3)), method="bounded",
                          options={"xatol": 1e-7})
    s = float(res.x)
    c = lane_centre(road, lane_id, s)
    tangent = lane_centre(road, lane_id, min(s + 1e-4, length)) - lane_centre(road, lane_id, max(s - 1e-4, 0))
    d = xy - c
    inner, outer = lane_edges(road, lane_id, s)
    return s, c, float((tangent[0] * d[1] - tangent[1] * d[0]) / np.hypot(*tangent)), abs(outer - inner)
