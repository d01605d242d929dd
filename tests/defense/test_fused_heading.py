import dataclasses
import math

import numpy as np
import pytest

from testbed.defense.fused_heading import FusedHeading, line_relative_heading, station_relative_heading
from testbed.lane_detection import LaneDetection
from tests.control.lane_map import PolylineLaneMap
from tracks.pose import Pose


def lines(slope_left, slope_right, prob=0.9, c0=1.75):
    """Ego lines with the given slopes at x = 0 (None for a missing line)."""
    def cubic(c, s):
        return None if s is None else np.array([c, s, 0.0, 0.0])
    return LaneDetection(0.0, cubic(c0, slope_left), cubic(-c0, slope_right), prob, prob, (0.0, 40.0))


def test_relative_heading_from_the_lines_slope():
    # the car turned left of the lane by 0.02 rad: the lines run to its right, slope -tan(0.02)
    s = -math.tan(0.02)
    assert line_relative_heading(lines(s, s), 0.5) == pytest.approx(0.02)
    # the mean slope of the valid lines; a line below the existence threshold does not count
    assert line_relative_heading(lines(-0.01, -0.03), 0.5) == pytest.approx(math.atan(0.02))
    assert line_relative_heading(lines(-0.01, None), 0.5) == pytest.approx(math.atan(0.01))
    assert line_relative_heading(lines(-0.01, -0.03, prob=0.3), 0.5) is None
    assert line_relative_heading(LaneDetection.empty(0.0), 0.5) is None


def test_the_heading_at_the_cars_station_on_a_corner_with_one_line():
    """On a right corner of radius 7 m, a car yawed 0.2 rad left of the lane: the left line crosses its lateral
    axis behind its station, where the lane heads 0.04 rad further left; the station heading takes that out."""
    radius, psi, width = 7.0, 0.2, 3.5
    smap = PolylineLaneMap([(20.0, 0.0, 0.0), (30.0, -1.0 / radius, -1.0 / radius)], n_lanes=1, lane_width=width)
    s = 35.0
    x, y, h, _ = smap._at(s)
    pose = Pose(x, y, h + psi)
    # the left line (lane centre + w/2) where it crosses the car's lateral axis, by bisection on the arc
    def along_car(t):
        px, py, ph, _ = smap._at(t)
        lx, ly = px - width / 2 * math.sin(ph), py + width / 2 * math.cos(ph)
        return math.cos(pose.yaw) * (lx - x) + math.sin(pose.yaw) * (ly - y), ph, lx, ly
    lo, hi = s - 3.0, s + 3.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if along_car(mid)[0] < 0.0 else (lo, mid)
    _, ph, lx, ly = along_car(lo)
    c0 = -math.sin(pose.yaw) * (lx - x) + math.cos(pose.yaw) * (ly - y)
    left = np.array([c0, math.tan(ph - pose.yaw), 0.0, 0.0])
    ld = LaneDetection(0.0, left, None, 0.9, 0.0, (0.0, 40.0))
    assert abs(line_relative_heading(ld, 0.5) - psi) > 0.03  # the slope at x = 0: the crossing's heading
    assert station_relative_heading(ld, 0.5, smap, pose, 0) == pytest.approx(psi, abs=2e-3)
    # on a straight lane the two agree
    straight = PolylineLaneMap([(60.0, 0.0, 0.0)], n_lanes=1, lane_width=width)
    flat = LaneDetection(0.0, np.array([1.75, -math.tan(psi), 0.0, 0.0]), None, 0.9, 0.0, (0.0, 40.0))
    assert station_relative_heading(flat, 0.5, straight, Pose(30.0, 0.0, psi), 0) == pytest.approx(psi)


def test_msf_and_lane_sources():
    msf = FusedHeading("msf", 0.05, 0.5)
    msf.on_detection(lines(-0.04, -0.04), msf_yaw=1.03, lane_heading=1.0)
    assert msf.yaw(1.03, 1.0) == pytest.approx(1.03) and msf.relative == pytest.approx(0.03)
    lane = FusedHeading("lane", 0.05, 0.5)
    lane.on_detection(lines(-0.04, -0.04), msf_yaw=1.03, lane_heading=1.0)
    assert lane.yaw(1.03, 1.0) == pytest.approx(1.0) and lane.relative == pytest.approx(0.0)


def test_ld_source_uses_the_lines_then_follows_the_msf_yaw_change():
    h = FusedHeading("ld", 0.05, 0.5)
    # before any detection the lane heading stands in
    assert h.yaw(0.7, 0.5) == pytest.approx(0.5)
    # lines say the car is 0.01 rad right of the lane; the (biased) MSF yaw says 0.03 left
    h.on_detection(lines(math.tan(0.01), math.tan(0.01)), msf_yaw=0.53, lane_heading=0.5)
    assert h.yaw(0.53, 0.5) == pytest.approx(0.49) and h.relative == pytest.approx(-0.01)
    # between detections the MSF yaw turns 0.005 left relative to a lane that turned 0.002: ψ = -0.007
    assert h.yaw(0.54, 0.507) == pytest.approx(0.507 - 0.007)
    # a detection without valid lines keeps the last reading
    h.on_detection(LaneDetection.empty(0.1), msf_yaw=0.6, lane_heading=0.5)
    assert h.yaw(0.53, 0.5) == pytest.approx(0.49)


def test_ld_source_is_clamped():
    h = FusedHeading("ld", 0.05, 0.5)
    h.on_detection(lines(math.tan(-0.2), math.tan(-0.2)), msf_yaw=0.0, lane_heading=0.0)  # a bent patch: ψ = 0.2
    assert h.yaw(0.0, 0.0) == pytest.approx(0.05)
    h.on_detection(lines(math.tan(0.01), math.tan(0.01)), msf_yaw=0.0, lane_heading=0.0)
    assert h.yaw(-0.3, 0.0) == pytest.approx(-0.05)  # the propagated value is clamped too
    wrapped = FusedHeading("ld", 0.05, 0.5)
    wrapped.on_detection(lines(0.0, 0.0), msf_yaw=math.pi - 0.01, lane_heading=-math.pi + 0.01)
    assert wrapped.relative is None and wrapped.yaw(math.pi - 0.01, -math.pi + 0.01) == pytest.approx(-math.pi + 0.01)


def test_fused_source_weighs_the_headings_by_the_fusion_uncertainties():
    h = FusedHeading("fused", 0.05, 0.5)
    # ψ_LD = 0.02, ψ_MSF = -0.01; R_MSF = 3, R_LD = 1: LD weight 3/4 -> 0.75·0.02 + 0.25·(-0.01) = 0.0125
    h.on_detection(lines(math.tan(-0.02), math.tan(-0.02)), msf_yaw=-0.01, lane_heading=0.0, uncertainties=(3.0, 1.0))
    assert h.yaw(-0.01, 0.0) == pytest.approx(0.0125)


def test_with_the_msf_left_out_fused_follows_its_own_yaw_in_fail_closed_mode_and_the_lines_in_paper_mode():
    # the car turned 0.3 rad against the lane; the lines say so but are clamped to 0.02; R_MSF = ∞ (MSF left out)
    ld = lines(math.tan(-0.3), math.tan(-0.3))
    own = FusedHeading("fused", 0.02, 0.5, own_yaw=True)  # the yaw passed is odometry's
    own.on_detection(ld, msf_yaw=0.3, lane_heading=0.0, uncertainties=(math.inf, 0.2))
    assert own.yaw(0.3, 0.0) == pytest.approx(0.3)
    paper = FusedHeading("fused", 0.02, 0.5)  # the yaw passed is the attacked MSF's
    paper.on_detection(ld, msf_yaw=0.3, lane_heading=0.0, uncertainties=(math.inf, 0.2))
    assert paper.yaw(0.3, 0.0) == pytest.approx(0.02)


def at(t: float, ld: LaneDetection) -> LaneDetection:
    return dataclasses.replace(ld, timestamp=t)


def test_with_the_own_yaw_the_lines_turn_it_no_faster_than_the_turn_rate():
    # the car aligned with the lane (odometry says so); a road patch reads the lines 0.1 rad left of it
    h = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002)
    bent = lines(math.tan(-0.1), math.tan(-0.1))
    for k in range(61):
        t = 0.05 * k
        h.on_detection(at(t, bent), msf_yaw=0.0, lane_heading=0.0)
        assert 0.0 <= h.yaw(0.0, 0.0) <= 0.002 * t + 1e-12
    assert h.yaw(0.0, 0.0) == pytest.approx(0.006)
    # the car's own turn since the last reading passes whole: the lines' disagreement is carried, not their ψ
    assert h.yaw(0.05, 0.0) == pytest.approx(0.056)


def test_with_the_own_yaw_honest_lines_correct_its_drift_within_the_clamp():
    h = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002)
    straight = lines(0.0, 0.0)  # the lines say the car is aligned; odometry's yaw drifted 0.004 rad left
    for k in range(61):
        h.on_detection(at(0.05 * k, straight), msf_yaw=0.004, lane_heading=0.0)
    assert h.yaw(0.004, 0.0) == pytest.approx(0.0)
    moved = FusedHeading("ld", 0.02, 0.5, own_yaw=True)  # without a rate the lines' ψ is taken at once
    moved.on_detection(at(0.0, lines(math.tan(-0.1), math.tan(-0.1))), msf_yaw=0.0, lane_heading=0.0)
    assert moved.yaw(0.0, 0.0) == pytest.approx(0.02)


def test_with_the_msf_heading_the_lines_turn_the_own_yaw_only_into_the_interval_between_the_two():
    """Lines bent 0.03 rad beside an MSF heading with the car (wandering ±6 mrad), the own yaw the car's: the yaw stays
    the own one, where lines alone turned it at the turn rate (0.006 rad in 3 s). Honest lines and an MSF heading
    0.03 rad off leave it too. An own yaw 0.004 rad outside the sources' agreement is turned back into it."""
    bent = lines(math.tan(-0.03), math.tan(-0.03))
    held = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002, yaw_margin=0.01)
    alone = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002)
    for k in range(61):
        t, wander = 0.05 * k, 0.006 * math.sin(2.0 * math.pi * 0.05 * k / 3.0)
        held.on_detection(at(t, bent), msf_yaw=0.0, lane_heading=0.0, msf_heading=wander)
        alone.on_detection(at(t, bent), msf_yaw=0.0, lane_heading=0.0, msf_heading=wander)
    assert held.yaw(0.0, 0.0) == pytest.approx(0.0) and alone.yaw(0.0, 0.0) == pytest.approx(0.006)
    honest = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002, yaw_margin=0.01)
    for k in range(61):
        honest.on_detection(at(0.05 * k, lines(0.0, 0.0)), msf_yaw=0.0, lane_heading=0.0, msf_heading=0.03)
    assert honest.yaw(0.0, 0.0) == pytest.approx(0.0)
    drifted = FusedHeading("ld", 0.02, 0.5, own_yaw=True, turn_rate=0.002, yaw_margin=0.01)
    for k in range(61):
        drifted.on_detection(at(0.05 * k, lines(0.0, 0.0)), msf_yaw=0.004, lane_heading=0.0, msf_heading=0.0)
    assert drifted.yaw(0.004, 0.0) == pytest.approx(0.0)
