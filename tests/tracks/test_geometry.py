import math

import numpy as np
import pytest
from scipy.special import fresnel

from tracks.geometry import Arc, Clothoid, ReferenceLine, Straight, bend
from tracks.pose import Pose

R = 60.0


@pytest.fixture(scope="module")
def circle_line() -> ReferenceLine:
    return ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(100.0), Arc(R, R * math.pi)])


def test_arc_positions_match_the_analytic_circle(circle_line):
    for s in (100.0, 123.4, 187.77, 100.0 + R * math.pi):
        phi = (s - 100.0) / R
        x, y, h = circle_line.frame(s)
        assert x == pytest.approx(100.0 + R * math.sin(phi), abs=1e-9)
        assert y == pytest.approx(R - R * math.cos(phi), abs=1e-9)
        assert h == pytest.approx(phi, abs=1e-12)


def test_projection_on_an_arc_matches_the_circle(circle_line):
    rng = np.random.default_rng(1)
    for _ in range(300):
        phi, r = rng.uniform(0.05, 3.0), rng.uniform(R - 8.0, R + 8.0)
        s, t = circle_line.project(100.0 + r * math.sin(phi), R - r * math.cos(phi))
        assert s == pytest.approx(100.0 + R * phi, abs=1e-6)
        assert t == pytest.approx(R - r, abs=1e-6)  # inside the left turn is + (left)


def test_projection_does_not_depend_on_the_query_history(circle_line):
    rng = np.random.default_rng(3)
    points = [
        circle_line.point(s, t) for s, t in zip(rng.uniform(90, 280, 50), rng.uniform(-9, 9, 50), strict=True)
    ]
    cold = [ReferenceLine(circle_line.start, circle_line.segments).project(*p) for p in points]
    circle_line.forget()
    circle_line.project(0.0, 0.0)
    warm = [circle_line.project(*p) for p in points]
    assert warm == cold  # bit-identical, so repeated runs in one process give identical outputs
    repeated = [circle_line.project(*points[k % 7]) for k in range(40)]  # the memo answers again
    assert repeated == [cold[k % 7] for k in range(40)]


@pytest.mark.parametrize("compiled", [True, False])
def test_a_point_projected_aside_leaves_the_next_walk_where_it_was(compiled):
    """A hairpin whose two straights run 12 m apart: a point beyond the second one (22 m from the first), projected
    aside, does not move the walk, so the next query of a point on the first straight still settles there
    (projected plainly, the walk from the second straight settles on it, 12 m off)."""
    hairpin = [Straight(100.0), Arc(6.0, 6.0 * math.pi), Straight(100.0)]
    line = ReferenceLine(Pose(0.0, 0.0, 0.0), hairpin)
    if not compiled:
        line._kernel = None
    line.project(50.0, 0.0)
    aside = line.project_aside(60.0, 22.0)
    assert aside == pytest.approx((100.0 + 6.0 * math.pi + 40.0, -10.0), abs=1e-6)
    assert line.project(55.0, 0.1) == pytest.approx((55.0, 0.1), abs=1e-6)
    line.project(60.0, 22.0)
    assert line.project(55.0, 0.2)[0] > 100.0  # the walk the plain projection left settles on the other straight


def test_clothoid_matches_fresnel_integrals():
    length, k1 = 40.0, 1.0 / 50.0
    line = ReferenceLine(Pose(0.0, 0.0, 0.0), [Clothoid(0.0, k1, length)])
    a = math.sqrt(math.pi * length / k1)  # k(s) = s / (a^2 / pi) -> x = a C(s/a), y = a S(s/a)
    for s in (10.0, 25.0, 40.0):
        fs, fc = fresnel(s / a)
        x, y, h = line.frame(s)
        assert x == pytest.approx(a * fc, abs=1e-7)
        assert y == pytest.approx(a * fs, abs=1e-7)
        assert h == pytest.approx(0.5 * k1 * s * s / length, abs=1e-12)
    s, t = line.project(*line.point(33.0, -1.5))
    assert (s, t) == pytest.approx((33.0, -1.5), abs=1e-6)


def test_bend_is_curvature_continuous_and_turns_the_angle():
    segs = [Straight(50.0), *bend(-80.0, math.radians(70.0), 25.0), Straight(50.0)]
    line = ReferenceLine(Pose(5.0, -3.0, 0.3), segs, step=0.25)
    jumps = np.abs(np.diff(line.curvature))
    assert jumps.max() <= (1.0 / 80.0) / 25.0 * line.ds + 1e-12
    assert line.heading[-1] == pytest.approx(0.3 - math.radians(70.0), abs=1e-12)
    assert line.curvature.min() == pytest.approx(-1.0 / 80.0)


def test_bend_rejects_a_transition_longer_than_the_bend():
    with pytest.raises(ValueError):
        bend(60.0, math.radians(10.0), 30.0)


def test_points_vectorised_agree_with_point(circle_line):
    s = np.array([3.0, 99.9, 140.0, 250.0])
    pts = circle_line.points(s, 1.25)
    for (x, y), sv in zip(pts, s, strict=True):
        assert (x, y) == pytest.approx(circle_line.point(float(sv), 1.25), abs=1e-9)


def test_beyond_the_end_extends_straight(circle_line):
    x_end, y_end, h_end = circle_line.frame(circle_line.length)
    s, t = circle_line.project(x_end + 5.0 * math.cos(h_end), y_end + 5.0 * math.sin(h_end))
    assert s == pytest.approx(circle_line.length + 5.0, abs=1e-6)
    assert t == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("preset", ["highway", "urban-curvy", "local", "two-way"])
def test_one_point_is_the_vectorised_point_of_a_one_element_array_to_the_bit(preset):
    from testbed.presets import build_track

    line = build_track(preset).reference
    rng = np.random.default_rng(7)
    s_values = [*rng.uniform(-20.0, line.length + 20.0, 400), 0.0, -0.0, line.length, *line.s[:50].tolist(),
                *[float(v) for v in line._seg_s0]]
    for s in s_values:
        for t in (0.0, -1.875, float(rng.uniform(-9.0, 9.0))):
            x, y = line.points(np.array([s]), t)[0]
            assert line.points_one(float(s), t) == (x, y), (s, t)
