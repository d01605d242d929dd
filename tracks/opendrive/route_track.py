"""A route of OpenDRIVE roads as one `Track`: the driving direction's lanes along a reference line on the ego
lane's centre.

The driving direction's lanes are those right of the centre lane when a right-hand-traffic road is driven
forward (left when backward, mirrored for LHT). The ego lane is the route's (`Leg.lanes`); the track keeps the
drivable lanes beside it, without a gap, that every road outside junctions has; inside junctions lanes a
connecting road lacks are interpolated. The ego lane's centre is sampled every half metre of road (and at every
geometry, section and width record start) and fitted by curvature-linear segments; lane widths become tabulated
profiles when they vary; each lane line keeps the road-mark kind it has over most of the route outside
junctions; connecting roads are intersections. A route whose ego lane turns tighter than `MIN_RADIUS` is refused
naming the road (`TightLaneError`). The other direction's drivable lanes next to the centre lane
become the track's oncoming lanes on a right-hand-traffic route (the track's oncoming lanes are its leftmost);
where something else (a median, a left-hand-traffic route) comes first, that side is paved surface beyond the
centre line."""

from __future__ import annotations

import itertools
import math
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import numpy as np

from tracks.geometry import ReferenceLine
from tracks.layout import Edge, RoadsideBody
from tracks.opendrive.centreline import fit_segments
from tracks.opendrive.cross_section import CrossSection, cross_section
from tracks.opendrive.limits import MAX_ROUTE_LENGTH
from tracks.opendrive.model import OpenDriveError, Road
from tracks.opendrive.plan_view import PlanView
from tracks.opendrive.route import Leg, driving_side
from tracks.pose import Pose
from tracks.road import Track

PIECE = 1.0  # m of road per fitted segment (three knots)
DELTA = 1e-3  # m: central-difference step for the ego centre's heading
JOIN_GAP, JOIN_TURN = 0.05, 0.02  # m, rad: the most the ego lane may jump where two roads meet
FIT_TOLERANCE = 0.005  # m: the most the fitted reference line may stray from the sampled ego centre
CURB = RoadsideBody("curb", gap=0.0, thickness=0.30, height=0.15)
MIN_RADIUS = 3.0
"""m: the tightest ego-lane centre a route may have (over a metre of lane). A car's turning circle at full lock is
4-6 m in radius; the sedan has driven a metre of 3.8 m (Town04) within its lane, not a 1.7 m lane (Town05's
junction 924, where it leaves the lane by 1.66 m)."""


class TightLaneError(OpenDriveError):
    """A route whose ego lane turns tighter than `MIN_RADIUS`; `leg` is the index of the route's leg where."""

    def __init__(self, message: str, leg: int) -> None:
        super().__init__(message)
        self.leg = leg


class _Knot(NamedTuple):
    """A sample of one leg at road arc length p; lane queries are taken inside [lo, hi]."""

    leg: int
    p: float
    lo: float
    hi: float


class _Sample(NamedTuple):
    """The ego lane's centre and heading, both sides' cross sections and the ego lane's index `ego` in `near`."""

    x: float
    y: float
    heading: float
    near: CrossSection
    far: CrossSection
    ego: int

    def rank(self) -> tuple[int, int]:
        """(drivable lanes between the ego lane and the centre side of its run, drivable lanes from the ego lane
        outward, itself included)."""
        first, count = self.near.group(self.ego)
        return self.ego - first, first + count - self.ego

    def lane(self, j: int, e: int) -> int:
        """The index in `near` of track lane j counted from the centre side, the ego lane being lane e."""
        return self.ego - e + j


def _breaks(road: Road) -> list[float]:
    marks = {0.0, road.length, *(g.s for g in road.geometries), *(o.s for o in road.lane_offsets)}
    for sec in road.sections:
        marks.add(sec.s)
        marks.update(sec.s + w.s for ln in sec.lanes for w in ln.widths)
    return sorted(m for m in marks if 0.0 <= m <= road.length)


def _knots(legs: list[Leg]) -> list[list[_Knot]]:
    """Per leg, knots in driving order: every interval between breaks split into pieces of <= PIECE, three
    knots a piece sharing their ends (a leg's first knot repeats the previous leg's last)."""
    out = []
    for i, leg in enumerate(legs):
        knots: list[_Knot] = []
        edges = _breaks(leg.road)
        spans = [(a, b) for a, b in itertools.pairwise(edges) if b - a > 1e-6]
        for a, b in spans if leg.direction == 1 else [(b, a) for a, b in reversed(spans)]:
            n = max(1, math.ceil(abs(b - a) / PIECE))
            lo, hi = min(a, b), max(a, b)
            ps = np.linspace(a, b, 2 * n + 1)
            knots += [_Knot(i, float(p), lo, hi) for p in (ps if not knots else ps[1:])]
        out.append(knots)
    return out


def _side(leg: Leg) -> int:
    """The road side (−1 right, +1 left of its reference line) of the lanes driven in the leg's direction."""
    return driving_side(leg.road, leg.direction)


class _Sampler:
    """The ego lane's centre and both sides' cross sections at the knots of a route."""

    def __init__(self, legs: list[Leg], source: str) -> None:
        self.legs, self.source = legs, source
        self.views = [PlanView(leg.road.geometries) for leg in legs]

    def ego_lane(self, k: _Knot, p: float) -> int:
        """The ego lane's id at road arc length p of knot k's leg."""
        road = self.legs[k.leg].road
        return self.legs[k.leg].lanes[road.sections.index(road.section_at(p))]

    def sections(self, k: _Knot) -> tuple[CrossSection, CrossSection]:
        leg = self.legs[k.leg]
        p = min(max(k.p, k.lo + 1e-7), k.hi - 1e-7)
        side = _side(leg)
        return cross_section(leg.road, p, side), cross_section(leg.road, p, -side)

    def centre(self, k: _Knot, ps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) of the ego lane centre at road arc lengths ps of knot k's leg."""
        leg = self.legs[k.leg]
        side = _side(leg)
        x, y, h = self.views[k.leg].frame(ps)
        t = np.empty_like(ps)
        for j, p in enumerate(ps):
            q = min(max(float(p), k.lo + 1e-7), k.hi - 1e-7)
            cs = cross_section(leg.road, q, side)
            i = cs.ids.index(self.ego_lane(k, q))
            t[j] = 0.5 * (cs.borders[i] + cs.borders[i + 1])
        return x - t * np.sin(h), y + t * np.cos(h)

    def sample(self, k: _Knot) -> _Sample:
        near, far = self.sections(k)
        ego = near.ids.index(self.ego_lane(k, min(max(k.p, k.lo + 1e-7), k.hi - 1e-7)))
        step = DELTA * self.legs[k.leg].direction
        ps = np.array([k.p, min(max(k.p - step, k.lo), k.hi), min(max(k.p + step, k.lo), k.hi)])
        x, y = self.centre(k, ps)
        return _Sample(float(x[0]), float(y[0]), math.atan2(y[2] - y[1], x[2] - x[1]), near, far, ego)


def route_track(legs: list[Leg], name: str, source: str) -> Track:
    """The track `name` of a route (its legs in driving order) through the file at `source`; OpenDriveError
    where the roads cannot make one."""
    length = sum(leg.road.length for leg in legs)
    if length > MAX_ROUTE_LENGTH:
        raise OpenDriveError(f"{source}: the route {name} is {length:g} m long, longer than {MAX_ROUTE_LENGTH:g} m; "
                             f"choose a shorter route (#ROAD,...)")
    sampler = _Sampler(legs, source)
    roads = ",".join(leg.road.id for leg in legs)
    per_leg = _knots(legs)
    knots, samples, junction = [], [], []
    for i, leg_knots in enumerate(per_leg):
        leg_samples = [sampler.sample(k) for k in leg_knots]
        if samples:
            _check_join(samples[-1], leg_samples[0], f"{source}: road {legs[i - 1].road.id} → road {legs[i].road.id}")
            leg_knots, leg_samples = leg_knots[1:], leg_samples[1:]
        knots += leg_knots
        samples += leg_samples
        junction += [legs[i].road.junction != "-1"] * len(leg_knots)
    outside = [not j for j in junction] if not all(junction) else [True] * len(junction)
    ranks = [s.rank() for s, o in zip(samples, outside, strict=True) if o]
    e = min(inner for inner, _ in ranks)  # the ego lane's index among the track's lanes from the centre side
    n = e + min(outer for _, outer in ranks)

    xs, ys = np.array([s.x for s in samples]), np.array([s.y for s in samples])
    heading = np.unwrap([s.heading for s in samples])
    chord = np.hypot(np.diff(xs), np.diff(ys))
    sigma = np.concatenate([[0.0], np.cumsum(chord * (1.0 + np.diff(heading) ** 2 / 24.0))])
    reference = ReferenceLine(Pose(xs[0], ys[0], heading[0]), fit_segments(sigma, heading))
    _check_radius(sigma, heading, [k.leg for k in knots], legs, source, roads)
    stray = float(np.max(np.hypot(*(reference.points(sigma) - np.column_stack([xs, ys])).T)))
    if stray > FIT_TOLERANCE:
        raise OpenDriveError(f"{source}: route {roads}: the ego lane's centre cannot be followed within "
                             f"{FIT_TOLERANCE * 1000:.0f} mm (off by {stray * 1000:.1f} mm)")

    outward = [_side(legs[k.leg]) * legs[k.leg].direction for k in knots]
    if len(set(outward)) > 1:
        raise OpenDriveError(f"{source}: route {roads}: mixes right- and left-hand traffic roads")
    order = list(range(n)) if outward[0] > 0 else list(range(n - 1, -1, -1))  # track lane -> lane from centre
    m = _oncoming(samples, outside, e) if outward[0] < 0 else 0
    widths = np.array([[*_widths(s, n, e), *_widths_far(s.far, m)] for s in samples])
    for col in widths.T:
        bad = np.isnan(col)
        col[bad] = np.interp(sigma[bad], sigma[~bad], col[~bad])
    widths = widths[:, order + list(range(n, n + m))]
    varies = np.ptp(widths, axis=0).max() > 1e-6
    weights = np.gradient(sigma) * np.array(outside)
    kinds = [_kind([_mark(s.near, s.lane(b, e)) for s in samples], weights)
             for b in (range(n + 1) if outward[0] > 0 else range(n, -1, -1))]
    kinds += [_kind([_mark(s.far, s.far.drivable()[0] + b) for s in samples], weights) for b in range(1, m + 1)]
    outer, inner = _edges(samples, outside, n, m, e)
    right, left = (inner, outer) if outward[0] > 0 else (outer, inner)
    crossings = _intersections(sigma, junction)
    both = f" and {m} oncoming" if m else ""
    description = (f"OpenDRIVE {Path(source).name}, roads {' → '.join(leg.road.id for leg in legs)}: {n}{both} "
                   f"lane(s), {reference.length:.0f} m")
    return Track(name, 0, description, reference, [float(w) for w in np.median(widths, axis=0)], kinds, right,
                 left, ego_lane=order.index(e), intersections=crossings,
                 width_table=(sigma, widths) if varies else None, oncoming=m)


def _check_radius(sigma: np.ndarray, heading: np.ndarray, leg_of: list[int], legs: list[Leg], source: str,
                  roads: str) -> None:
    """TightLaneError where the ego centre's curvature (its heading's slope along the samples) passes 1/MIN_RADIUS."""
    curvature = np.abs(np.gradient(heading, sigma))
    i = int(np.argmax(curvature))
    if curvature[i] * MIN_RADIUS > 1.0:
        leg = leg_of[i]
        raise TightLaneError(f"{source}: route {roads}: the ego lane turns at a radius of {1.0 / curvature[i]:.2f} m "
                             f"on road {legs[leg].road.id}, tighter than the {MIN_RADIUS:g} m a car follows; "
                             f"choose a route around it (#ROAD,...)", leg)


def _oncoming(samples: list[_Sample], outside: list[bool], e: int) -> int:
    """How many of the other direction's drivable lanes start at the centre lane at every sample outside
    junctions where the track's lanes start there too (0 where one side has something else there)."""
    inside = [s for s, o in zip(samples, outside, strict=True) if o]
    if any(s.lane(0, e) != 0 for s in inside):
        return 0
    counts = [s.far.drivable() for s in inside]
    return 0 if any(first != 0 for first, _ in counts) else min(count for _, count in counts)


def _check_join(a: _Sample, b: _Sample, where: str) -> None:
    gap = math.hypot(b.x - a.x, b.y - a.y)
    turn = abs(math.remainder(b.heading - a.heading, 2.0 * math.pi))
    if gap > JOIN_GAP or turn > JOIN_TURN:
        raise OpenDriveError(f"{where}: the ego lane jumps by {gap:.2f} m and "
                             f"{turn:.3f} rad where they meet (at most {JOIN_GAP} m, {JOIN_TURN} rad)")


def _widths(s: _Sample, n: int, e: int) -> list[float]:
    """Widths of the track's n lanes from the centre side at one sample (NaN where its road lacks one)."""
    first, count = s.near.group(s.ego)
    out = []
    for j in range(n):
        i = s.lane(j, e)
        out.append(abs(s.near.borders[i + 1] - s.near.borders[i]) if first <= i < first + count else math.nan)
    return out


def _widths_far(cs: CrossSection, m: int) -> list[float]:
    first, count = cs.drivable()
    return [abs(cs.borders[first + k + 1] - cs.borders[first + k]) if k < count else math.nan for k in range(m)]


def _mark(cs: CrossSection, k: int) -> str:
    """The mark on the lane line at border index k (the centre lane's at 0), none beyond the section's lanes."""
    return cs.marks[k] if 0 <= k < len(cs.marks) else "none"


def _kind(kinds: list[str], weights: np.ndarray) -> str:
    tally: Counter[str] = Counter()
    for kind, w in zip(kinds, weights, strict=True):
        tally[kind] += float(w)
    return max(tally, key=lambda k: tally[k]) if sum(tally.values()) > 0.0 else "none"


def _edges(samples: list[_Sample], outside: list[bool], n: int, m: int, e: int) -> tuple[Edge, Edge]:
    """(outer edge, edge beyond the centre line or beyond the `m` oncoming lanes): paved widths the narrowest
    outside junctions."""
    kept = [s for s, o in zip(samples, outside, strict=True) if o]
    near = _edge([(s.near, s.lane(n, e)) for s in kept])
    if m:
        return near, _edge([(s.far, s.far.drivable()[0] + m) for s in kept])
    inner = min(abs(s.near.borders[s.lane(0, e)] - s.far.borders[-1]) for s in kept)
    return near, Edge("shoulder", inner, "grass")


def _edge(sections: list[tuple[CrossSection, int]]) -> Edge:
    """The edge beyond border index k of each (cross section, k): a curb edge if a curb or sidewalk follows
    anywhere."""
    paved, curb = math.inf, False
    for cs, k in sections:
        width, kerb = cs.paved_beyond(k)
        paved, curb = min(paved, width), curb or kerb
    return Edge("curb", paved, "concrete", bodies=(CURB,)) if curb else Edge("shoulder", paved, "grass")


def _intersections(sigma: np.ndarray, junction: list[bool]) -> list[tuple[float, float]]:
    zones, start = [], None
    for i, inside in enumerate(junction):
        if inside and start is None:
            start = sigma[max(i - 1, 0)]
        if not inside and start is not None:
            zones.append((float(start), float(sigma[i - 1])))
            start = None
    if start is not None:
        zones.append((float(start), float(sigma[-1])))
    return zones
