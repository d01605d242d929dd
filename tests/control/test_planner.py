"""LanePlanner: path errors, preview curvature, cruise ramp, stop profile, off-map hold, the curve limit."""

from __future__ import annotations

import itertools
import math

import pytest

from testbed.control.planner import AR_DECEL, CURVE_DECEL, LanePlanner
from tests.control.lane_map import PolylineLaneMap, curvy_urban, straight
from tracks.pose import Pose


def test_errors_follow_the_sign_conventions() -> None:
    smap = straight()
    p = LanePlanner(smap, 0, 10.0).plan(Pose(100.0, 0.5, 0.1), 10.0, 0.0)
    assert (p.lateral_error, p.heading_error) == (pytest.approx(0.5), pytest.approx(0.1))
    p = LanePlanner(smap, 1, 10.0).plan(Pose(100.0, 0.2, -0.05), 10.0, 0.0)  # lane 1 is 3.5 m to the left
    assert (p.lateral_error, p.heading_error) == (pytest.approx(-3.3), pytest.approx(-0.05))
    p = LanePlanner(smap, 0, 10.0).plan(Pose(100.0, 0.0, 2 * math.pi - 0.1), 10.0, 0.0)
    assert p.heading_error == pytest.approx(-0.1)
    assert p.curvature == 0.0 and p.local_curvature == 0.0 and not p.off_map


def test_curvature_is_previewed_along_the_centreline() -> None:
    smap = curvy_urban()  # clothoid from s = 30 m to 60 m reaching 1/60
    k = 1.0 / 60.0
    planner = LanePlanner(smap, 0, 10.0, preview_time=0.5)
    p = planner.plan(Pose(40.0, 0.0, 0.0), 10.0, 0.0)  # 10 m into the clothoid, preview 5 m
    assert p.local_curvature == pytest.approx(k * 10 / 30, rel=0.02)
    assert p.curvature == pytest.approx(k * 15 / 30, rel=0.02)
    s0 = 65.0  # on the arc: the preview walk stays on the lane
    x, y, h, _ = smap._at(s0)
    p = LanePlanner(smap, 0, 20.0, preview_time=1.0).plan(Pose(x, y, h), 20.0, 0.0)
    assert p.curvature == pytest.approx(k, rel=1e-3)
    assert abs(p.lateral_error) < 1e-3
    end = smap.s[-1]  # the road ends inside the preview: the last reachable curvature, not off-map
    x, y, h, _ = smap._at(end - 2.0)
    p = LanePlanner(smap, 0, 20.0).plan(Pose(x, y, h), 20.0, 0.0)
    assert not p.off_map and p.curvature == 0.0


def test_cruise_ramps_gently_to_the_cruise_speed() -> None:
    planner = LanePlanner(straight(), 0, 10.0, max_accel=1.0)
    pose = Pose(50.0, 0.0, 0.0)
    plans = [planner.plan(pose, 0.0, i * 0.01) for i in range(1500)]
    assert plans[0].target_speed == 0.0 and plans[0].target_accel == 1.0
    assert plans[500].target_speed == pytest.approx(5.0) and plans[500].target_accel == 1.0
    assert all(p.target_speed == 10.0 and p.target_accel == 0.0 for p in plans[1001:])
    planner.cruise_speed = 8.0  # a lower cruise speed ramps down
    p = planner.plan(pose, 10.0, 15.99)  # one second after the last plan
    assert p.target_speed == pytest.approx(9.0) and p.target_accel == -1.0


def test_stop_profile_decelerates_then_holds_zero() -> None:
    planner = LanePlanner(straight(), 0, 20.0)
    pose = Pose(50.0, 0.0, 0.0)
    planner.plan(pose, 20.0, 1.0)
    assert not planner.stopping
    planner.start_stop(2.0, 20.0)
    assert planner.stopping
    p = planner.plan(pose, 19.0, 3.0)
    assert p.target_speed == pytest.approx(20.0 - AR_DECEL) and p.target_accel == -AR_DECEL
    assert planner.plan(pose, 1.0, 6.9).target_speed == pytest.approx(0.4)
    p = planner.plan(pose, 0.16, 7.0)  # the car lags the profile at its end: the stop's braking goes on
    assert (p.target_speed, p.target_accel) == (0.0, -AR_DECEL)
    for t in (7.0, 8.0, 100.0):
        p = planner.plan(pose, 0.0, t)
        assert (p.target_speed, p.target_accel) == (0.0, 0.0)
    planner.start_stop(0.0, 27.0, decel=2.5)  # a new stop replaces the profile (chassis runs use < 3 m/s²)
    assert planner.plan(pose, 27.0, 2.0).target_speed == pytest.approx(22.0)
    with pytest.raises(ValueError):
        planner.start_stop(0.0, 10.0, decel=0.0)


def test_off_map_holds_the_last_path_terms_and_flags_it() -> None:
    planner = LanePlanner(straight(), 0, 20.0)
    assert planner.plan(Pose(50.0, 30.0, 0.0), 20.0, 0.0).off_map  # before any fix: zero path terms
    good = planner.plan(Pose(50.0, 0.4, 0.02), 20.0, 0.1)
    planner.start_stop(0.2, 20.0)
    held = planner.plan(Pose(50.0, 30.0, 0.0), 20.0, 1.2)
    assert held.off_map and not good.off_map
    assert (held.lateral_error, held.heading_error) == (good.lateral_error, good.heading_error)
    assert held.target_speed == pytest.approx(16.0)  # the speed profile keeps running
    assert planner.plan(Pose(math.nan, 0.0, 0.0), 20.0, 1.3).off_map


def _corner() -> PolylineLaneMap:
    """120 m straight, a 90° corner of radius 7 m (a town junction's), 60 m straight."""
    return PolylineLaneMap([(120.0, 0.0, 0.0), (7.0 * math.pi / 2, 1 / 7, 1 / 7), (60.0, 0.0, 0.0)])


def test_the_speed_is_limited_by_the_curvature_ahead() -> None:
    smap, a_lat = _corner(), 2.5
    planner = LanePlanner(smap, 0, 15.0, max_accel=1.0, lateral_accel=a_lat)
    s, v, dt, refs = 20.0, 15.0, 0.025, []
    while s < smap.s[-1] - 5.0:
        x, y, h, k = smap._at(s)
        p = planner.plan(Pose(x, y, h), v, len(refs) * dt)
        refs.append((s, p.target_speed, p.target_accel, k))
        v = p.target_speed  # the car follows the reference exactly
        s += v * dt
    in_corner = [(ref, k) for s_, ref, _, k in refs if 120.0 <= s_ <= 120.0 + 7.0 * math.pi / 2]
    assert in_corner and max(ref**2 * k for ref, k in in_corner) <= a_lat * 1.02
    assert refs[0][1] == pytest.approx(15.0)  # far from the corner: the cruise speed
    first_slow = next(s_ for s_, ref, _, _ in refs if ref < 15.0)
    # it brakes into the corner gently, not at the last moment: from where CURVE_DECEL is enough, in small steps
    assert first_slow <= 120.0 - (15.0**2 - a_lat * 7.0) / (2 * CURVE_DECEL)
    assert min(b - a for (_, a, _, _), (_, b, _, _) in itertools.pairwise(refs)) > -0.5
    assert refs[-1][1] > 10.0  # and picks the cruise back up after it


def test_a_curve_limit_above_the_cruise_speed_changes_nothing() -> None:
    plain, bounded = LanePlanner(_corner(), 0, 4.0), LanePlanner(_corner(), 0, 4.0, lateral_accel=3.0)
    unbounded = LanePlanner(_corner(), 0, 4.0, lateral_accel=1e6)
    x, y, h, _ = _corner()._at(118.0)
    for i in range(40):
        a, b = bounded.plan(Pose(x, y, h), 3.0, 0.025 * i), unbounded.plan(Pose(x, y, h), 3.0, 0.025 * i)
        assert (a.target_speed, a.target_accel) == (b.target_speed, b.target_accel)
    assert plain.lateral_accel == 3.0


def test_the_stop_holds_the_curve_limit() -> None:
    smap = _corner()
    planner = LanePlanner(smap, 0, 15.0, lateral_accel=2.5)
    x, y, h, _ = smap._at(110.0)  # 10 m before the corner at 15 m/s: a 4 m/s² stop alone is too fast there
    planner.start_stop(0.0, 15.0)
    p = planner.plan(Pose(x, y, h), 15.0, 0.5)
    assert p.target_speed <= math.sqrt(2.5 * 7.0 + 2 * CURVE_DECEL * 10.0) + 1e-6 and p.target_accel == -AR_DECEL
    with pytest.raises(ValueError):
        LanePlanner(smap, 0, 15.0, lateral_accel=0.0)
