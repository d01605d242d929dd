"""Named track presets `NAME[@SEED]`, modelled on the paper's simulator scenarios (Table 5).

Seed 0 is each family's canonical layout; other seeds vary curve radii, lengths and order, intersection
spacing, lane widths where the family allows, roadside objects, the LiDAR feature profile and asphalt
tone, while keeping the family's defining numbers (ego lane width, radius limits, roadside distances).
Every preset starts with a straight run-in of at least 100 m (parking-lot: the whole 80 m lane).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tracks.geometry import ReferenceLine, Segment, Straight, bend
from tracks.layout import Edge, RoadsideBody
from tracks.opendrive.load import PREFIX as XODR_PREFIX
from tracks.opendrive.load import load_xodr
from tracks.paint import AsphaltPainter, MarkingPainter
from tracks.pose import Pose
from tracks.road import Track

CURB = RoadsideBody("curb", gap=0.10, thickness=0.30, height=0.15)
DIVIDER = RoadsideBody("divider", gap=0.15, thickness=0.60, height=0.30)


def _pick(rng: np.random.Generator | None, canonical: float, lo: float, hi: float) -> float:
    return canonical if rng is None else float(rng.uniform(lo, hi))


def lidar_profile(
    seed: int, length: float, base: float, poor_stretches: int
) -> tuple[np.ndarray, np.ndarray]:
    """Smooth feature-quality profile on a 5 m grid: `base` plus slow seeded undulation and a few
    Gaussian feature-poor dips (open fields, tunnels of sameness), clipped to [0.05, 1]."""
    rng = np.random.default_rng([seed, 5])
    s = np.arange(0.0, length + 5.0, 5.0)
    q = np.full_like(s, base)
    for _ in range(4):
        q += 0.06 * np.sin(2.0 * math.pi * s / rng.uniform(150.0, 700.0) + rng.uniform(0.0, 2.0 * math.pi))
    for _ in range(poor_stretches):
        centre, sigma, depth = rng.uniform(0.1, 0.95) * length, rng.uniform(20.0, 60.0), rng.uniform(0.3, 0.5)
        q -= depth * np.exp(-0.5 * ((s - centre) / sigma) ** 2)
    return s, np.clip(q, 0.05, 1.0)


def _painters(rng: np.random.Generator | None) -> list:
    return [
        AsphaltPainter(tone=_pick(rng, 1.0, 0.85, 1.15), grain=_pick(rng, 7.0, 5.0, 9.0)),
        MarkingPainter(),
    ]


def _curves(
    rng: np.random.Generator | None,
    canonical: list[tuple[float, float, float]],
    radius: tuple[float, float],
    angle_deg: tuple[float, float],
    straight: tuple[float, float],
    transition: Callable[[float, float], float],
    total: float,
    run_in: float,
) -> list[Segment]:
    """Run-in straight, then bends (signed radius, angle, straight after) until `total` metres.

    Seeded layouts alternate turn direction and flip a bend whose heading would pass ±100°, so the road
    meanders without doubling back on itself; their second bend is within 10 % of the smallest radius.
    """
    segs: list[Segment] = [Straight(run_in)]
    length, heading, i, sign = run_in, 0.0, 0, 1.0 if rng is None or rng.random() < 0.5 else -1.0
    while length < total - 100.0:
        if rng is None:
            r, ang, after = canonical[i % len(canonical)]
            ang = math.radians(ang)
        else:
            ang = math.radians(rng.uniform(*angle_deg))
            if abs(heading + sign * ang) > math.radians(100.0):
                sign = -sign
            tightest = i == 1  # every layout has one bend near the family's smallest radius
            r = sign * (radius[0] * rng.uniform(1.0, 1.1) if tightest else rng.uniform(*radius))
            after = rng.uniform(*straight)
            sign = -sign
        bend_segs = bend(r, ang, transition(abs(r), ang))
        segs += [*bend_segs, Straight(after)]
        heading += math.copysign(ang, r)
        length += sum(s.length for s in bend_segs) + after
        i += 1
    segs.append(Straight(max(100.0, total - length)))
    return segs


def slr(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    length = _pick(rng, 1800.0, 1600.0, 2200.0)
    shoulder = _pick(rng, 2.5, 1.5, 3.0)
    edge = Edge("drop_off", paved=shoulder, ground="drop", roadside=3.0)
    return Track(
        "slr",
        seed,
        "long single-lane straight road (3.56 m) with drop-offs beyond the shoulders",
        ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(length)]),
        [3.56],
        ["solid_white"] * 2,
        edge,
        edge,
        lidar_profile=lidar_profile(seed, length, 0.6, 2),
        painters=_painters(rng),
    )


def urban_straight(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    length = _pick(rng, 1600.0, 1500.0, 2000.0)
    trees = rng is None or rng.random() < 0.6
    roadside = (
        RoadsideBody("tree", gap=0.85, thickness=0.5, height=5.0, spacing=_pick(rng, 8.0, 7.0, 11.0))
        if trees
        else RoadsideBody("barrier", gap=0.85, thickness=0.5, height=0.9)
    )
    right = Edge("curb", paved=0.10, ground="concrete", bodies=(CURB, roadside))
    left = Edge(
        "curb",
        paved=0.30,
        ground="concrete",
        bodies=(RoadsideBody("curb", 0.30, 0.30, 0.15), RoadsideBody("barrier", 1.0, 0.6, 0.9)),
    )
    return Track(
        "urban-straight",
        seed,
        "straight 2-lane urban road (ego 3.90 m), curbs, roadside trees/barriers",
        ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(length)]),
        [3.90, 3.60],
        ["solid_white", "dashed_white", "solid_yellow"],
        right,
        left,
        lidar_profile=lidar_profile(seed, length, 0.85, 2),
        painters=_painters(rng),
    )


URBAN_CURVY_BENDS = [
    (80.0, 60, 60),
    (-60.0, 75, 50),
    (120.0, 50, 80),
    (-90.0, 70, 40),
    (60.0, 80, 70),
    (-150.0, 45, 60),
    (100.0, 65, 50),
    (-70.0, 70, 80),
    (90.0, 60, 60),
    (-110.0, 55, 100),
]


def urban_curvy(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    segs = _curves(
        rng,
        URBAN_CURVY_BENDS,
        (60.0, 200.0),
        (40.0, 85.0),
        (30.0, 120.0),
        lambda r, a: min(25.0, 0.4 * r * a),
        total=1800.0,
        run_in=150.0,
    )
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), segs)
    right = Edge("curb", paved=0.10, ground="concrete", bodies=(CURB,))
    left = Edge("divider", paved=0.15, ground="concrete", bodies=(DIVIDER,), roadside=2.0)
    return Track(
        "urban-curvy",
        seed,
        "curvy single-lane urban road (3.40 m, R >= 60 m), divider left, curb right",
        ref,
        [3.40],
        ["solid_white", "double_yellow"],
        right,
        left,
        lidar_profile=lidar_profile(seed, ref.length, 0.8, 2),
        painters=_painters(rng),
    )


HIGHWAY_BENDS = [(900.0, 15, 300), (-700.0, 20, 250), (1200.0, 12, 350), (-600.0, 18, 300), (800.0, 16, 300)]


def highway(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    segs = _curves(
        rng,
        HIGHWAY_BENDS,
        (600.0, 1500.0),
        (8.0, 22.0),
        (200.0, 400.0),
        lambda r, a: min(80.0, 0.4 * r * a),
        total=3100.0,
        run_in=250.0,
    )
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), segs)
    right = Edge("guardrail", paved=3.0, ground="grass", bodies=(RoadsideBody("guardrail", 3.5, 0.3, 0.75),))
    left = Edge("guardrail", paved=1.2, ground="grass", bodies=(RoadsideBody("guardrail", 1.6, 0.3, 0.75),))
    return Track(
        "highway",
        seed,
        "3-lane highway (3 x 3.75 m, R >= 600 m) with shoulders and guardrails",
        ref,
        [3.75] * 3,
        ["solid_white", "dashed_white", "dashed_white", "solid_yellow"],
        right,
        left,
        ego_lane=1,
        lidar_profile=lidar_profile(seed, ref.length, 0.55, 3),
        painters=_painters(rng),
    )


LOCAL_BLOCKS = [220.0, 300.0, 260.0, 340.0, 240.0, 300.0]


def local(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    widths = [_pick(rng, 3.3, 3.0, 3.5), _pick(rng, 3.3, 3.0, 3.5)]
    blocks = LOCAL_BLOCKS if rng is None else [float(b) for b in rng.uniform(180.0, 380.0, 6)]
    segs: list[Segment] = [Straight(120.0)]
    s, crossings = 120.0, []
    for k, block in enumerate(blocks):
        if k % 2 == 1:
            r = _pick(rng, 250.0 if k == 1 else -300.0, 180.0, 400.0) * (
                1 if rng is None else rng.choice([-1, 1])
            )
            curve = bend(r, math.radians(_pick(rng, 20.0, 10.0, 30.0)), 30.0)
            rest = max(20.0, block - sum(c.length for c in curve))
            segs += [Straight(0.5 * rest), *curve, Straight(0.5 * rest)]
            s += rest + sum(c.length for c in curve)
        else:
            segs.append(Straight(block))
            s += block
        if k < len(blocks) - 1:
            zone = _pick(rng, 20.0, 16.0, 26.0)
            segs.append(Straight(zone + 20.0))
            crossings.append((s + 10.0, s + 10.0 + zone))
            s += zone + 20.0
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), segs)
    edge = Edge("curb", paved=0.30, ground="concrete", bodies=(RoadsideBody("curb", 0.30, 0.30, 0.15),))
    return Track(
        "local",
        seed,
        "2-lane local road (3.0-3.5 m lanes) with curbs and intersections every few 100 m",
        ref,
        widths,
        ["solid_white", "dashed_white", "solid_yellow"],
        edge,
        edge,
        intersections=crossings,
        lidar_profile=lidar_profile(seed, ref.length, 0.8, 2),
        painters=_painters(rng),
    )


TWO_WAY_BENDS = [(250.0, 25, 180), (-180.0, 35, 220), (300.0, 20, 160), (-220.0, 30, 200), (200.0, 25, 150)]


def two_way(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    widths = [3.40, _pick(rng, 3.40, 3.20, 3.60)]
    segs = _curves(
        rng,
        TWO_WAY_BENDS,
        (150.0, 450.0),
        (15.0, 40.0),
        (120.0, 260.0),
        lambda r, a: min(30.0, 0.4 * r * a),
        total=1500.0,
        run_in=150.0,
    )
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), segs)
    trees = RoadsideBody("tree", gap=1.6, thickness=0.5, height=5.0, spacing=_pick(rng, 12.0, 9.0, 15.0))
    edge = Edge("curb", paved=0.30, ground="grass", bodies=(RoadsideBody("curb", 0.30, 0.30, 0.15), trees))
    return Track(
        "two-way",
        seed,
        "two-way road (ego 3.40 m, one oncoming lane, double yellow centre line, R >= 150 m), curbs and trees",
        ref,
        widths,
        ["solid_white", "double_yellow", "solid_white"],
        edge,
        edge,
        lidar_profile=lidar_profile(seed, ref.length, 0.75, 2),
        painters=_painters(rng),
        oncoming=1,
    )


def parking_lot(seed: int) -> Track:
    rng = None if seed == 0 else np.random.default_rng(seed)
    edge = Edge("open", paved=12.0, ground="asphalt", roadside=2.0)
    return Track(
        "parking-lot",
        seed,
        "one 3.5 m straight lane (80 m) marked on open asphalt, for chassis tests",
        ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(80.0)]),
        [3.5],
        ["solid_white"] * 2,
        edge,
        edge,
        lidar_profile=lidar_profile(seed, 80.0, 0.9, 0),
        painters=_painters(rng),
    )


PRESETS: dict[str, Callable[[int], Track]] = {
    "slr": slr,
    "urban-straight": urban_straight,
    "urban-curvy": urban_curvy,
    "highway": highway,
    "local": local,
    "parking-lot": parking_lot,
    "two-way": two_way,
}


def list_presets() -> list[tuple[str, str]]:
    """(name, one-line description) of every preset, canonical seed."""
    return [(name, build(0).description) for name, build in PRESETS.items()]


def parse_track_spec(spec: str) -> tuple[str, int]:
    """(name, seed) of `NAME` or `NAME@SEED` (seed a non-negative integer, default 0), ("xodr", 0) of an OpenDRIVE
    file `xodr:PATH[#ROUTE]`; ValueError otherwise."""
    if spec.startswith(XODR_PREFIX):
        return "xodr", 0
    name, at, seed_text = spec.partition("@")
    if not at:
        return name, 0
    if not seed_text.isdigit():
        raise ValueError(f"bad seed {seed_text!r} in {spec!r}: expected a non-negative integer")
    return name, int(seed_text)


def load_track(spec: str) -> Track:
    """Build the preset track `NAME` or `NAME@SEED`, or read `xodr:PATH[#ROUTE]` (`tracks.opendrive.load`)."""
    if spec.startswith(XODR_PREFIX):
        return load_xodr(spec.removeprefix(XODR_PREFIX))
    name, seed = parse_track_spec(spec)
    if name not in PRESETS:
        raise ValueError(f"unknown track {name!r}; known: {', '.join(PRESETS)}")
    return PRESETS[name](seed)
